// VerifyLengths (pipeline/verify_lengths.h): the acceptance test's lengths,
// errors and uncertainties.
//
// 1. On a hand-built measurement (tag centres, their own covariances and
//    shared factors, s with its own variance and shared gradient): L, E and
//    u(L) of both columns against an independent computation written here:
//    the full joint covariance matrix of (s, every tag centre, L_bar)
//    assembled explicitly, the Jacobian of L by central differences of the
//    nonlinear L(s, T, L_bar), and u(L)^2 = J C J^T; the warnings (fewer
//    than 7 lengths, longest under 2/3 of the space diagonal, no error
//    split) and the errors (no check length, a tag not adjusted).
// 2. A rendered lab run (examples/scene_small.json with seven check lengths
//    between its wall tags): noise-free, |E| / L_cal tiny; with the scene's
//    noise and speckle, every |E| within 2 U(E).
#include "opl/pipeline/verify_lengths.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/sim/module_design.h"
#include "support/scene_images.h"

namespace opl {
namespace {

using ::testing::HasSubstr;

constexpr int kShared = 4;  // m, shared components

// A measured session by hand: six tags, s, the bar (tags 4, 5).
struct HandMade {
  Scene scene;
  ImageMeasureReport measured;
};

Eigen::Matrix3d RandomSpd(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix3d a;
  for (int i = 0; i < 9; ++i) a(i / 3, i % 3) = n(rng);
  return sigma * sigma * (a * a.transpose() / 3.0 + 0.2 * Eigen::Matrix3d::Identity());
}

HandMade MakeHandMade() {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  HandMade h;
  const std::map<int, Eigen::Vector3d> centres = {
      {0, {0.0, 0.0, 0.0}},         {1, {1800.0, 50.0, -20.0}},  {2, {30.0, 1500.0, 40.0}},
      {3, {1750.0, 1480.0, 1200.0}}, {4, {400.0, 300.0, 10.0}},  {5, {1300.0, 420.0, 15.0}}};
  FrontEndResult& fe = h.measured.front_end;
  for (const auto& [id, c] : centres) {
    fe.tag_centers[id] = c;
    const Eigen::Matrix3d own = RandomSpd(rng, 0.02);
    Eigen::MatrixXd k(3, kShared);
    for (int i = 0; i < 3 * kShared; ++i) k(i / kShared, i % kShared) = 0.015 * n(rng);
    fe.tag_center_own_covariances[id] = own;
    fe.tag_center_shared_factors[id] = k;
    fe.tag_center_covariances[id] = own + k * k.transpose();
  }
  h.measured.scale_shared_gradient = Eigen::VectorXd(kShared);
  for (int i = 0; i < kShared; ++i) h.measured.scale_shared_gradient[i] = 4e-5 * n(rng);
  h.measured.u_scale_factor_own = 3e-5;
  h.measured.measure.scale.scale_factor = 1.0012;
  h.measured.measure.scale.u_scale_factor =
      std::hypot(3e-5, h.measured.scale_shared_gradient.norm());
  h.scene.artifact = SceneArtifact{4, 5, 908.5, 0.01};
  h.scene.check_lengths = {
      {"diagonal", 0, 3, 2705.2, 0.002},
      {"x edge", 0, 1, 1802.9, 0.002},
      {"with a bar tag", 4, 3, 1745.0, 0.003},  // shares tag 4 with the bar
  };
  return h;
}

// The joint covariance of p = (s, T_0 .. T_5, L_bar) assembled explicitly:
// Var(s) = u_own^2 + g^T g, Cov(s, T_a) = K_a g, Cov(T_a, T_b) = K_a K_b^T
// (+ own_a when a = b), L_bar independent of the rest.
Eigen::MatrixXd JointCovariance(const HandMade& h, bool split) {
  const FrontEndResult& fe = h.measured.front_end;
  const int n = 1 + 3 * static_cast<int>(fe.tag_centers.size()) + 1;
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(n, n);
  const Eigen::VectorXd& g = h.measured.scale_shared_gradient;
  if (!split) {
    c(0, 0) = std::pow(h.measured.measure.scale.u_scale_factor, 2);
    for (const auto& [a, cov] : fe.tag_center_covariances) c.block<3, 3>(1 + 3 * a, 1 + 3 * a) = cov;
  } else {
    c(0, 0) = std::pow(h.measured.u_scale_factor_own, 2) + g.squaredNorm();
    for (const auto& [a, ka] : fe.tag_center_shared_factors) {
      c.block<3, 1>(1 + 3 * a, 0) = ka * g;
      c.block<1, 3>(0, 1 + 3 * a) = (ka * g).transpose();
      for (const auto& [b, kb] : fe.tag_center_shared_factors) {
        c.block<3, 3>(1 + 3 * a, 1 + 3 * b) = ka * kb.transpose();
      }
      c.block<3, 3>(1 + 3 * a, 1 + 3 * a) += fe.tag_center_own_covariances.at(a);
    }
  }
  c(n - 1, n - 1) = std::pow(h.scene.artifact->length_sigma_mm, 2);
  return c;
}

Eigen::VectorXd Parameters(const HandMade& h) {
  const FrontEndResult& fe = h.measured.front_end;
  Eigen::VectorXd p(1 + 3 * fe.tag_centers.size() + 1);
  p[0] = h.measured.measure.scale.scale_factor;
  for (const auto& [a, c] : fe.tag_centers) p.segment<3>(1 + 3 * a) = c;
  p[p.size() - 1] = h.scene.artifact->length_mm;
  return p;
}

// u of f(p) by central differences: sqrt(J C J^T).
double PropagatedU(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& p,
                   const Eigen::MatrixXd& c) {
  Eigen::RowVectorXd j(p.size());
  for (Eigen::Index i = 0; i < p.size(); ++i) {
    const double step = 1e-6 * std::max(1.0, std::abs(p[i]));
    Eigen::VectorXd plus = p, minus = p;
    plus[i] += step;
    minus[i] -= step;
    j[i] = (f(plus) - f(minus)) / (2.0 * step);
  }
  return std::sqrt((j * c * j.transpose())(0, 0));
}

double Distance(const Eigen::VectorXd& p, int a, int b) {
  return (p.segment<3>(1 + 3 * b) - p.segment<3>(1 + 3 * a)).norm();
}

void ExpectLengthsMatchIndependentComputation(const HandMade& h, const VerifyReport& report,
                                              bool split) {
  const Eigen::VectorXd p = Parameters(h);
  const Eigen::MatrixXd c = JointCovariance(h, split);
  const int bar_1 = h.scene.artifact->tag_1, bar_2 = h.scene.artifact->tag_2;
  ASSERT_EQ(report.lengths.size(), h.scene.check_lengths.size());
  for (size_t k = 0; k < h.scene.check_lengths.size(); ++k) {
    const SceneCheckLength& check = h.scene.check_lengths[k];
    const CheckLengthResult& r = report.lengths[k];
    SCOPED_TRACE(check.name);
    EXPECT_EQ(r.name, check.name);
    const auto opl_length = [&](const Eigen::VectorXd& q) {
      return q[0] * Distance(q, check.tag_1, check.tag_2);
    };
    const auto bar_length = [&](const Eigen::VectorXd& q) {
      return q[q.size() - 1] / Distance(q, bar_1, bar_2) * Distance(q, check.tag_1, check.tag_2);
    };
    EXPECT_NEAR(r.unscaled, Distance(p, check.tag_1, check.tag_2), 1e-9);
    EXPECT_NEAR(r.opl.measured_mm, opl_length(p), 1e-9);
    EXPECT_NEAR(r.opl.error_mm, opl_length(p) - check.length_mm, 1e-9);
    const double u_opl = PropagatedU(opl_length, p, c);
    EXPECT_NEAR(r.opl.u_measured_mm, u_opl, 1e-6 * u_opl);
    EXPECT_NEAR(r.opl.u_error_mm, std::hypot(u_opl, check.length_sigma_mm), 1e-6 * u_opl);
    EXPECT_NEAR(r.opl.expanded_u_error_mm, 2.0 * std::hypot(u_opl, check.length_sigma_mm),
                2e-6 * u_opl);
    ASSERT_TRUE(r.bar.has_value());
    EXPECT_NEAR(r.bar->measured_mm, bar_length(p), 1e-9);
    EXPECT_NEAR(r.bar->error_mm, bar_length(p) - check.length_mm, 1e-9);
    const double u_bar = PropagatedU(bar_length, p, c);
    EXPECT_NEAR(r.bar->u_measured_mm, u_bar, 1e-6 * u_bar);
    EXPECT_NEAR(r.bar->expanded_u_error_mm, 2.0 * std::hypot(u_bar, check.length_sigma_mm),
                2e-6 * u_bar);
  }
  ASSERT_TRUE(report.bar_scale_factor.has_value());
  const auto bar_scale = [&](const Eigen::VectorXd& q) {
    return q[q.size() - 1] / Distance(q, bar_1, bar_2);
  };
  EXPECT_NEAR(*report.bar_scale_factor, bar_scale(p), 1e-12);
  EXPECT_NEAR(report.u_bar_scale_factor, PropagatedU(bar_scale, p, c), 1e-6 * report.u_bar_scale_factor);
}

TEST(VerifyLengths, LengthsErrorsAndUncertaintiesMatchTheJointCovariance) {
  const HandMade h = MakeHandMade();
  Result<VerifyReport> report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->correlations_kept);
  ExpectLengthsMatchIndependentComputation(h, *report, /*split=*/true);
  // The correlations matter here: taking s and the tags as independent
  // gives a different u(L) for the diagonal (else the test above could not
  // tell a model that drops them).
  const Eigen::VectorXd p = Parameters(h);
  Eigen::MatrixXd independent = JointCovariance(h, true);
  for (int a = 0; a < 6; ++a) {
    independent.block<3, 1>(1 + 3 * a, 0).setZero();
    independent.block<1, 3>(0, 1 + 3 * a).setZero();
  }
  const double u_no_corr = PropagatedU(
      [](const Eigen::VectorXd& q) { return q[0] * Distance(q, 0, 3); }, p, independent);
  EXPECT_GT(std::abs(u_no_corr - report->lengths[0].opl.u_measured_mm),
            0.01 * report->lengths[0].opl.u_measured_mm);

  EXPECT_DOUBLE_EQ(report->scale_factor, 1.0012);
  EXPECT_NEAR(report->max_abs_error_opl_mm,
              std::max({std::abs(report->lengths[0].opl.error_mm), std::abs(report->lengths[1].opl.error_mm),
                        std::abs(report->lengths[2].opl.error_mm)}),
              1e-12);
  double sum = 0.0;
  for (const CheckLengthResult& r : report->lengths) sum += r.bar->error_mm * r.bar->error_mm;
  EXPECT_NEAR(report->rms_error_bar_mm, std::sqrt(sum / 3.0), 1e-12);
  // The space diagonal: the box of every tag centre ((0, 0, -20) to (1800,
  // 1500, 1200)), scaled by s; the longest length is the diagonal's own, over
  // 2/3 of it: only the count is warned about.
  EXPECT_NEAR(report->space_diagonal_mm, 1.0012 * Eigen::Vector3d(1800, 1500, 1220).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(report->longest_mm, 2705.2);
  ASSERT_EQ(report->warnings.size(), 1u);
  EXPECT_THAT(report->warnings[0], HasSubstr("3 check lengths: VDI/VDE 2634-1 asks for at least 7"));
}

TEST(VerifyLengths, WithoutTheErrorSplitTermsAreIndependentAndTheReportSaysSo) {
  HandMade h = MakeHandMade();
  h.measured.front_end.tag_center_own_covariances.clear();
  h.measured.front_end.tag_center_shared_factors.clear();
  h.measured.scale_shared_gradient.resize(0);
  Result<VerifyReport> report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_FALSE(report->correlations_kept);
  ExpectLengthsMatchIndependentComputation(h, *report, /*split=*/false);
  EXPECT_THAT(report->ToText(), HasSubstr("warning: the front end gave no split"));
}

TEST(VerifyLengths, WarnsWhenTheLongestLengthIsShortAndCountsSevenWithoutWarning) {
  HandMade h = MakeHandMade();
  h.scene.check_lengths.clear();
  for (int k = 0; k < 7; ++k) {
    h.scene.check_lengths.push_back({"short " + std::to_string(k), 4, 5, 906.0 + k, 0.002});
  }
  Result<VerifyReport> report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->warnings.size(), 1u);
  EXPECT_THAT(report->warnings[0],
              HasSubstr("the longest check length (912.0 mm) is under 2/3 of the volume's space "
                        "diagonal (2644.8 mm"));
  // With the diagonal among them: no warning at all.
  h.scene.check_lengths[6] = {"diagonal", 0, 3, 2705.2, 0.002};
  report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok());
  EXPECT_TRUE(report->warnings.empty()) << report->warnings[0];
}

TEST(VerifyLengths, NoBarColumnWithoutAnArtifactOrWhenItsTagsWereNotAdjusted) {
  HandMade h = MakeHandMade();
  h.scene.artifact.reset();
  Result<VerifyReport> report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok());
  EXPECT_FALSE(report->bar_scale_factor.has_value());
  for (const CheckLengthResult& r : report->lengths) EXPECT_FALSE(r.bar.has_value());
  EXPECT_THAT(report->ToCsv(), HasSubstr(",,,\n"));
  EXPECT_TRUE(nlohmann::json::parse(report->ToJson())["bar_scale_factor"].is_null());

  h = MakeHandMade();
  h.scene.check_lengths.pop_back();  // the one using tag 4
  h.measured.front_end.tag_centers.erase(5);
  h.measured.front_end.tag_center_own_covariances.erase(5);
  h.measured.front_end.tag_center_shared_factors.erase(5);
  h.measured.front_end.tag_center_covariances.erase(5);
  report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_FALSE(report->bar_scale_factor.has_value());
  EXPECT_THAT(report->warnings,
              testing::Contains(HasSubstr("no bar column: artifact tag 5 was not adjusted")));
}

TEST(VerifyLengths, Errors) {
  HandMade h = MakeHandMade();
  h.scene.check_lengths.clear();
  Result<VerifyReport> report = VerifyLengths(h.scene, h.measured);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(report.status().message(), HasSubstr("check_lengths: the scene lists no check length"));
  EXPECT_FALSE(CheckSceneHasCheckLengths(h.scene).ok());

  h = MakeHandMade();
  h.scene.check_lengths[1].tag_2 = 9;  // never adjusted
  report = VerifyLengths(h.scene, h.measured);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNoSolution);
  EXPECT_EQ(report.status().message(),
            "check length 'x edge': tag 9 was not adjusted (not seen from two camera positions)");

  h = MakeHandMade();
  h.measured.measure.scale.scale_factor = 0.0;
  report = VerifyLengths(h.scene, h.measured);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNoSolution);
}

TEST(VerifyLengths, CsvJsonAndPlotCarryTheRows) {
  const HandMade h = MakeHandMade();
  Result<VerifyReport> report = VerifyLengths(h.scene, h.measured);
  ASSERT_TRUE(report.ok());
  const std::string csv = report->ToCsv();
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "name,tag_1,tag_2,calibrated_mm,u_calibrated_mm,opl_mm,u_opl_mm,opl_error_mm,"
            "opl_expanded_u_error_mm,bar_mm,u_bar_mm,bar_error_mm,bar_expanded_u_error_mm,"
            "adjustment_mm,u_adjustment_mm,adjustment_error_mm,adjustment_expanded_u_error_mm");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 4);
  EXPECT_THAT(csv, HasSubstr("\nx edge,0,1,1802.9,0.002,"));
  const nlohmann::json j = nlohmann::json::parse(report->ToJson());
  EXPECT_EQ(j["format"], "opl.verify_report");
  EXPECT_EQ(j["version"], 1);
  ASSERT_EQ(j["lengths"].size(), 3u);
  EXPECT_DOUBLE_EQ(j["lengths"][0]["opl"]["error_mm"].get<double>(), report->lengths[0].opl.error_mm);
  EXPECT_DOUBLE_EQ(j["lengths"][2]["bar"]["expanded_u_error_mm"].get<double>(),
                   report->lengths[2].bar->expanded_u_error_mm);
  EXPECT_EQ(j["lengths"][1]["opl"]["within_uncertainty"].get<bool>(),
            report->lengths[1].opl.within_uncertainty());

  const LinePlot plot = report->ToPlot("scene.json");
  EXPECT_THAT(plot.title, HasSubstr("scene.json"));
  ASSERT_EQ(plot.panels.size(), 2u);  // every column; the small ones on their own scale
  const std::vector<PlotSeries>& series = plot.panels[0].series;
  ASSERT_EQ(series.size(), 4u);  // OPL, in the adjustment (none here), bar, E = 0
  // Drawn 1 % of the lengths' span (2705.2 - 1745.0) either side of L_cal.
  const double shift = 0.01 * (2705.2 - 1745.0);
  EXPECT_NEAR(series[0].x[1], 1802.9 - shift, 1e-9);
  EXPECT_TRUE(std::isnan(series[1].y[0]));  // no adjustment column: an empty series keeps its colour
  EXPECT_NEAR(series[2].x[1], 1802.9 + shift, 1e-9);
  EXPECT_DOUBLE_EQ(series[0].y[1], report->lengths[1].opl.error_mm);
  EXPECT_DOUBLE_EQ(series[2].y_err[1], report->lengths[1].bar->expanded_u_error_mm);
  EXPECT_EQ(series[3].y, std::vector<double>({0.0, 0.0}));
  ASSERT_EQ(plot.panels[1].series.size(), 4u);
  EXPECT_TRUE(std::isnan(plot.panels[1].series[0].y[0]));  // OPL two-step left out, colours kept
  EXPECT_EQ(plot.panels[1].series[2].y, series[2].y);
  EXPECT_TRUE(RenderLinePlotPng(plot).ok());
}

// --- A rendered lab run -------------------------------------------------

// examples/scene_small.json with seven check lengths between its wall tags
// (the wall's diagonals and edges), each the true distance of the two tag
// centres.
Scene SmallSceneWithCheckLengths(bool noise_free) {
  Result<Scene> read = ReadSceneJson(test::SourceDir() + "/examples/scene_small.json");
  EXPECT_TRUE(read.ok()) << read.status().ToString();
  Scene scene = std::move(read).value();
  if (noise_free) {
    scene.image.read_noise = 0.0;
    scene.image.gain_e_per_dn = 0.0;
    scene.image.bit_depth = 16;
    scene.spots.speckle_contrast = 0.0;
  }
  const std::vector<std::pair<int, int>> pairs = {{0, 3}, {1, 2}, {4, 5}, {6, 7},
                                                  {0, 1}, {2, 3}, {8, 5}};
  for (const auto& [a, b] : pairs) {
    const double d = (scene.FindTag(a)->scene_from_tag.translation -
                      scene.FindTag(b)->scene_from_tag.translation)
                         .norm();
    scene.check_lengths.push_back(
        {"t" + std::to_string(a) + "-t" + std::to_string(b), a, b, d, 0.002});
  }
  return scene;
}

VerifyReport RenderMeasureVerify(const Scene& scene, const std::string& name) {
  const std::filesystem::path dir = test::FreshTempDir(name);
  Result<SceneRenderer> renderer = test::RenderShotsTo(scene, dir, 2);
  EXPECT_TRUE(renderer.ok()) << renderer.status().ToString();
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  EXPECT_TRUE(calibration.ok());
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  options.front_end.scale_in_adjustment = true;  // the third column
  options.projector_tag_lengths = CheckLengthTags(scene);
  Result<ImageMeasureReport> measured =
      MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  EXPECT_TRUE(measured.ok()) << measured.status().ToString();
  Result<VerifyReport> report = VerifyLengths(scene, *measured);
  EXPECT_TRUE(report.ok()) << report.status().ToString();
  std::filesystem::remove_all(dir);
  std::cout << report->ToText();
  return std::move(report).value();
}

TEST(VerifyLengthsLab, NoiseFreeRenderMeasuresTheLengths) {
  const VerifyReport report =
      RenderMeasureVerify(SmallSceneWithCheckLengths(true), "verify_lengths_clean");
  ASSERT_EQ(report.lengths.size(), 7u);
  EXPECT_TRUE(report.correlations_kept);
  ASSERT_TRUE(report.bar_scale_factor.has_value());
  for (const CheckLengthResult& r : report.lengths) {
    SCOPED_TRACE(r.name);
    // s is within 2e-5 of the truth on this render (measure_images_test);
    // the tag centres add less.
    EXPECT_LT(std::abs(r.opl.error_mm) / r.calibrated_mm, 5e-5);
    EXPECT_LT(std::abs(r.bar->error_mm) / r.calibrated_mm, 5e-5);
    EXPECT_GT(r.opl.expanded_u_error_mm, 0.0);
    // In the adjustment: the metric scene straight from the module.
    ASSERT_TRUE(r.projector.has_value());
    EXPECT_LT(std::abs(r.projector->error_mm) / r.calibrated_mm, 5e-5);
    EXPECT_GT(r.projector->expanded_u_error_mm, 0.0);
    EXPECT_LT(r.projector->expanded_u_error_mm, r.opl.expanded_u_error_mm);
  }
  ASSERT_TRUE(report.projector_scale_factor.has_value());
}

TEST(VerifyLengthsLab, NoisyRenderErrorsAreWithinTheirUncertainty) {
  const VerifyReport report =
      RenderMeasureVerify(SmallSceneWithCheckLengths(false), "verify_lengths_noisy");
  ASSERT_EQ(report.lengths.size(), 7u);
  ASSERT_TRUE(report.bar_scale_factor.has_value());
  for (const CheckLengthResult& r : report.lengths) {
    SCOPED_TRACE(r.name);
    EXPECT_LT(std::abs(r.opl.error_mm), 2.0 * r.opl.expanded_u_error_mm);
    EXPECT_LT(std::abs(r.bar->error_mm), 2.0 * r.bar->expanded_u_error_mm);
    ASSERT_TRUE(r.projector.has_value());
    EXPECT_LT(std::abs(r.projector->error_mm), 2.0 * r.projector->expanded_u_error_mm);
    // U(E) is not vacuous: u(s) of this small scene is about 1 % at most.
    EXPECT_LT(r.opl.expanded_u_error_mm, 0.05 * r.calibrated_mm);
  }
}

}  // namespace
}  // namespace opl
