// The measurement Monte Carlo (JCGM 101) against the first-order uncertainty,
// its linearity in the spot noise, its determinism across thread counts, and
// its errors. Run time: about 3000 locate solves in all.
#include "opl/uncertainty/monte_carlo.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/io/module_design_json.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

// examples/staggered_design.json (OPL_EXAMPLES_DIR: tests/uncertainty/CMakeLists.txt).
ModuleDesign StaggeredDesign() {
  Result<ModuleDesign> design =
      ReadModuleDesignJson(std::string(OPL_EXAMPLES_DIR) + "/staggered_design.json");
  EXPECT_TRUE(design.ok()) << design.status().message();
  return design.ok() ? *design : ModuleDesign();
}

TEST(IterationSeedTest, IsTheIterationsSplitMixOutput) {
  SplitMix64 stream(42);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(IterationSeed(42, i), stream.Next());
}

TEST(SummarizeTest, MeanStdAndInterval) {
  const SampleSummary s = Summarize({1.0, 2.0, 3.0, 4.0}, 0.95);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.std_dev, std::sqrt(5.0 / 3.0));
  EXPECT_FALSE(s.has_interval);  // M = 4 is too small for a 95 % interval
}

// The staggered prototype-like design (examples/staggered_design.json): the
// Monte Carlo standard deviations agree with the first-order ones within 10 %
// (sampling error of a std from 600 draws: ~3 %), s is 1 on average and the
// 95 % interval of L is about mean +- 1.96 std.
TEST(MonteCarloTest, StaggeredDesignMatchesFirstOrder) {
  const ModuleDesign design = StaggeredDesign();
  MonteCarloOptions options;
  options.iterations = 600;
  options.seed = 7;
  options.threads = 2;
  Result<MonteCarloReport> report = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->succeeded, 600);
  EXPECT_EQ(report->failed, 0);
  ASSERT_EQ(report->lengths.size(), 1u);
  const MonteCarloLength& l = report->lengths[0];
  EXPECT_EQ(l.from, "A");
  EXPECT_EQ(l.to, "B");
  EXPECT_NEAR(l.true_mm, 39.0 * std::sqrt(2.0), 1e-9);
  ASSERT_GT(l.photo_mm.first_order_std, 0.0);
  EXPECT_NEAR(l.photo_mm.std_dev / l.photo_mm.first_order_std, 1.0, 0.10);
  EXPECT_NEAR(l.photo_mm.mean, l.true_mm, 4.0 * l.photo_mm.std_dev / std::sqrt(600.0));
  ASSERT_TRUE(l.photo_mm.has_interval);
  EXPECT_NEAR(l.photo_mm.symmetric.low, l.photo_mm.mean - 1.96 * l.photo_mm.std_dev,
              0.25 * l.photo_mm.std_dev);
  EXPECT_NEAR(l.photo_mm.symmetric.high, l.photo_mm.mean + 1.96 * l.photo_mm.std_dev,
              0.25 * l.photo_mm.std_dev);
  EXPECT_EQ(l.samples_mm.size(), 600u);

  const SampleSummary& s = report->scale_factor;
  EXPECT_NEAR(s.std_dev / s.first_order_std, 1.0, 0.10);
  EXPECT_NEAR(s.mean, 1.0, 4.0 * s.std_dev / std::sqrt(600.0));
  // For two sources s = L_cal / L_photo: u(s) = u(L) / L to first order.
  EXPECT_NEAR(s.first_order_std, l.photo_mm.first_order_std / l.true_mm, 1e-3 * s.first_order_std);

  ASSERT_EQ(report->sources.size(), 2u);
  for (const MonteCarloSource& src : report->sources) {
    EXPECT_EQ(src.spots, 121);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(src.origin_std_mm[k] / src.origin_first_order_std_mm[k], 1.0, 0.10)
          << src.name << " origin axis " << k;
      EXPECT_NEAR(src.rotation_std_rad[k] / src.rotation_first_order_std_rad[k], 1.0, 0.10)
          << src.name << " angle " << k;
      EXPECT_NEAR(src.origin_mean_mm[k], src.true_origin_mm[k],
                  4.0 * src.origin_std_mm[k] / std::sqrt(600.0));
    }
  }
}

// method.md: "uncertainty linear in spot noise". The same seed draws the same
// standard normals, so doubling the noise doubles every deviation to first
// order: std(L) doubles within a few %.
TEST(MonteCarloTest, StdOfLengthIsLinearInSpotNoise) {
  ModuleDesign design = StaggeredDesign();
  MonteCarloOptions options;
  options.iterations = 300;
  options.seed = 3;
  Result<MonteCarloReport> once = RunMeasurementMonteCarlo(design, options);
  design.spot_noise_mm *= 2.0;
  Result<MonteCarloReport> twice = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(once.ok()) << once.status().message();
  ASSERT_TRUE(twice.ok()) << twice.status().message();
  const double ratio = twice->lengths[0].photo_mm.std_dev / once->lengths[0].photo_mm.std_dev;
  EXPECT_NEAR(ratio, 2.0, 0.04);
  EXPECT_NEAR(twice->lengths[0].photo_mm.first_order_std / once->lengths[0].photo_mm.first_order_std,
              2.0, 1e-6);
  EXPECT_NEAR(twice->scale_factor.std_dev / once->scale_factor.std_dev, 2.0, 0.04);
}

// Per-spot noise (MonteCarloOptions::spot_covariance_mm2). A spot's error
// along its own beam does not change the beam's direction seen from the
// origin, so it cannot move the located origin (to first order): noise
// stretched 20x along each beam gives the same std(s) as isotropic noise
// (the symmetric square root draws the same across-beam noise from the
// same seed), while the same stretch along one fixed axis (X, the mean
// beam direction, as one design-level Sigma for every spot would put it)
// gives a much larger std(s). Isotropic per-spot noise reproduces the
// design-level first-order std exactly.
TEST(MonteCarloTest, PerSpotNoiseAlongTheBeamsDoesNotMoveTheOrigins) {
  ModuleDesign design = StaggeredDesign();
  const double sigma = 0.08;  // mm
  std::map<std::string, Eigen::Vector3d> origin;
  for (const SourceDesign& d : design.sources) origin[d.name] = d.scene_from_source.translation;
  const auto stretched = [&](double along, bool along_beam) {
    return [&origin, sigma, along, along_beam](const std::string& source, int,
                                               const Eigen::Vector3d& point) {
      const Eigen::Vector3d b =
          along_beam ? Eigen::Vector3d((point - origin.at(source)).normalized()) : Eigen::Vector3d::UnitX();
      return Eigen::Matrix3d(sigma * sigma * (Eigen::Matrix3d::Identity() - b * b.transpose()) +
                             along * along * b * b.transpose());
    };
  };
  MonteCarloOptions options;
  options.iterations = 300;
  options.seed = 11;
  options.threads = 2;
  options.spot_covariance_mm2 = stretched(sigma, true);
  Result<MonteCarloReport> isotropic = RunMeasurementMonteCarlo(design, options);
  options.spot_covariance_mm2 = stretched(20.0 * sigma, true);
  Result<MonteCarloReport> along_beams = RunMeasurementMonteCarlo(design, options);
  options.spot_covariance_mm2 = stretched(20.0 * sigma, false);
  Result<MonteCarloReport> along_x = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(isotropic.ok()) << isotropic.status().message();
  ASSERT_TRUE(along_beams.ok()) << along_beams.status().message();
  ASSERT_TRUE(along_x.ok()) << along_x.status().message();
  EXPECT_TRUE(isotropic->per_spot_noise);
  EXPECT_NE(isotropic->ToText().find("spot noise per spot"), std::string::npos);
  const SampleSummary& iso = isotropic->scale_factor;
  const SampleSummary& beams = along_beams->scale_factor;
  const SampleSummary& x = along_x->scale_factor;
  std::cout << "std(s) ppm: isotropic " << iso.std_dev * 1e6 << " (FO " << iso.first_order_std * 1e6
            << "), 20x along the beams " << beams.std_dev * 1e6 << " (FO " << beams.first_order_std * 1e6
            << "), 20x along X " << x.std_dev * 1e6 << " (FO " << x.first_order_std * 1e6 << ")\n";
  EXPECT_EQ(along_beams->succeeded, 300);
  EXPECT_NEAR(beams.first_order_std / iso.first_order_std, 1.0, 1e-6);
  EXPECT_NEAR(beams.std_dev / iso.std_dev, 1.0, 0.03);
  EXPECT_GT(x.first_order_std / iso.first_order_std, 2.0);
  EXPECT_NEAR(x.std_dev / x.first_order_std, 1.0, 0.15);

  // The design-level isotropic Sigma: the same first-order std.
  design.spot_noise_mm = Eigen::Vector3d::Constant(sigma);
  options.spot_covariance_mm2 = nullptr;
  Result<MonteCarloReport> design_level = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(design_level.ok()) << design_level.status().message();
  EXPECT_FALSE(design_level->per_spot_noise);
  EXPECT_NEAR(design_level->scale_factor.first_order_std / iso.first_order_std, 1.0, 1e-9);
  EXPECT_NEAR(design_level->scale_factor.cramer_rao_std / iso.cramer_rao_std, 1.0, 1e-9);

  // A covariance that is not one: the spot is named.
  options.spot_covariance_mm2 = [](const std::string&, int beam, const Eigen::Vector3d&) {
    const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();
    return Eigen::Matrix3d(beam == 5 ? -identity : identity);
  };
  Result<MonteCarloReport> bad = RunMeasurementMonteCarlo(design, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("source 'A' beam 5: not positive semi-definite"),
            std::string::npos)
      << bad.status().message();
}

// Per-iteration seeds and an index-ordered reduction: 1 and 3 threads give
// bit-identical samples and reports.
TEST(MonteCarloTest, IdenticalWhateverTheThreadCount) {
  const ModuleDesign design = StaggeredDesign();
  MonteCarloOptions options;
  options.iterations = 60;
  options.seed = 99;
  options.threads = 1;
  Result<MonteCarloReport> one = RunMeasurementMonteCarlo(design, options);
  options.threads = 3;
  Result<MonteCarloReport> three = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(one.ok() && three.ok());
  EXPECT_EQ(one->threads, 1);
  EXPECT_EQ(three->threads, 3);
  EXPECT_EQ(one->lengths[0].samples_mm, three->lengths[0].samples_mm);  // exact ==
  EXPECT_EQ(one->scale_samples, three->scale_samples);
  EXPECT_EQ(one->ToJson(), three->ToJson());
  EXPECT_EQ(one->ToText(), three->ToText());
  // A different seed gives different draws.
  options.seed = 100;
  Result<MonteCarloReport> other = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(other.ok());
  EXPECT_NE(other->lengths[0].samples_mm, one->lengths[0].samples_mm);
}

// The values of every iteration: what the summaries are computed from, and
// in the JSON only when asked for, exactly (numbers round-trip).
TEST(MonteCarloTest, SamplesOfEveryIteration) {
  const ModuleDesign design = StaggeredDesign();
  MonteCarloOptions options;
  options.iterations = 50;
  options.seed = 4;
  options.threads = 2;
  Result<MonteCarloReport> r = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r->sample_iterations.size(), 50u);
  EXPECT_EQ(r->sample_iterations[49], 49);
  ASSERT_EQ(r->sources.size(), 2u);
  for (const MonteCarloSource& s : r->sources) {
    ASSERT_EQ(s.origin_samples_mm.size(), 50u);
    ASSERT_EQ(s.rotation_samples_rad.size(), 50u);
    Eigen::Vector3d origin_sum = Eigen::Vector3d::Zero(), rotation_sum = Eigen::Vector3d::Zero();
    for (int i = 0; i < 50; ++i) {
      origin_sum += s.origin_samples_mm[static_cast<size_t>(i)];
      rotation_sum += s.rotation_samples_rad[static_cast<size_t>(i)];
    }
    EXPECT_LT((origin_sum / 50.0 - s.origin_mean_mm).norm(), 1e-12);
    EXPECT_LT((rotation_sum / 50.0 - s.rotation_mean_rad).norm(), 1e-12);
    double ss = 0.0;
    for (const Eigen::Vector3d& o : s.origin_samples_mm) ss += std::pow(o.y() - s.origin_mean_mm.y(), 2);
    EXPECT_NEAR(std::sqrt(ss / 49.0), s.origin_std_mm.y(), 1e-12);
  }
  // The length between the located origins of every iteration.
  for (size_t i = 0; i < 50; i += 7) {
    const double l = (r->sources[0].origin_samples_mm[i] - r->sources[1].origin_samples_mm[i]).norm();
    EXPECT_NEAR(l, r->lengths[0].samples_mm[i], 1e-9) << i;
  }

  const nlohmann::json plain = nlohmann::json::parse(r->ToJson());
  EXPECT_FALSE(plain.contains("sample_iterations"));
  EXPECT_FALSE(plain["lengths"][0].contains("samples_mm"));
  EXPECT_FALSE(plain["sources"][0].contains("origin_samples_mm"));
  EXPECT_FALSE(plain["scale_factor"].contains("samples"));
  nlohmann::json full = nlohmann::json::parse(r->ToJson(true));
  EXPECT_EQ(full["sample_iterations"].get<std::vector<int>>(), r->sample_iterations);
  EXPECT_EQ(full["lengths"][0]["samples_mm"].get<std::vector<double>>(), r->lengths[0].samples_mm);
  EXPECT_EQ(full["scale_factor"]["samples"].get<std::vector<double>>(), r->scale_samples);
  const nlohmann::json& o = full["sources"][1]["origin_samples_mm"][13];
  for (int k = 0; k < 3; ++k) EXPECT_EQ(o[k].get<double>(), r->sources[1].origin_samples_mm[13][k]);
  const nlohmann::json& a = full["sources"][0]["rotation_samples_rad"][49];
  for (int k = 0; k < 3; ++k) EXPECT_EQ(a[k].get<double>(), r->sources[0].rotation_samples_rad[49][k]);
  // The rest is the plain report.
  full.erase("sample_iterations");
  full["lengths"][0].erase("samples_mm");
  full["scale_factor"].erase("samples");
  for (nlohmann::json& s : full["sources"]) {
    s.erase("origin_samples_mm");
    s.erase("rotation_samples_rad");
  }
  EXPECT_EQ(full, plain);
  // Numbers arrays on one line: a vector per line, not a number per line.
  EXPECT_NE(r->ToJson().find("\"spot_noise_mm\": [0.11, 0.073, 0.073]"), std::string::npos);
}

TEST(MonteCarloTest, ReportsProgressOnTheCallingThread) {
  const ModuleDesign design = StaggeredDesign();
  MonteCarloOptions options;
  options.iterations = 20;
  options.threads = 2;
  options.progress_interval_s = 0.001;
  std::vector<int> seen;
  options.progress = [&](int done, int total) {
    EXPECT_EQ(total, 20);
    seen.push_back(done);
  };
  ASSERT_TRUE(RunMeasurementMonteCarlo(design, options).ok());
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 20);
  for (size_t i = 1; i < seen.size(); ++i) EXPECT_LE(seen[i - 1], seen[i]);
}

// A tiny 3 x 3, 2 deg grid with the noise times 40 (4 mm at 1 m, beside
// 17 mm between spots) or 1000: some locates fail. They are counted and left out; when all
// fail, the run fails.
TEST(MonteCarloTest, FailedIterationsAreCountedNotFatal) {
  ModuleDesign design = StaggeredDesign();
  for (SourceDesign& s : design.sources) {
    s.beams_per_side = 3;
    s.full_angle_deg = 2.0;
  }
  const ModuleDesign base = design;
  design.spot_noise_mm *= 40.0;
  MonteCarloOptions options;
  options.iterations = 60;
  options.threads = 2;
  Result<MonteCarloReport> r = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_GT(r->failed, 0);
  EXPECT_GT(r->succeeded, 0);
  EXPECT_EQ(r->succeeded + r->failed, 60);
  EXPECT_EQ(r->lengths[0].samples_mm.size(), static_cast<size_t>(r->succeeded));
  EXPECT_EQ(r->first_failure.rfind("iteration ", 0), 0u) << r->first_failure;
  // The samples name their iterations: the failed ones are missing.
  ASSERT_EQ(r->sample_iterations.size(), static_cast<size_t>(r->succeeded));
  for (size_t k = 1; k < r->sample_iterations.size(); ++k) {
    EXPECT_LT(r->sample_iterations[k - 1], r->sample_iterations[k]);
  }
  EXPECT_GE(r->sample_iterations.front(), 0);
  EXPECT_LT(r->sample_iterations.back(), 60);
  const int first_failed = std::stoi(r->first_failure.substr(10));
  EXPECT_EQ(std::count(r->sample_iterations.begin(), r->sample_iterations.end(), first_failed), 0);
  EXPECT_NE(r->ToText().find("first failure: iteration"), std::string::npos);

  design = base;
  design.spot_noise_mm *= 1000.0;
  r = RunMeasurementMonteCarlo(design, options);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
  EXPECT_NE(r.status().message().find("every one of the 60 iterations failed"), std::string::npos)
      << r.status().message();
}

TEST(MonteCarloTest, Errors) {
  ModuleDesign design = StaggeredDesign();
  MonteCarloOptions options;
  options.iterations = 0;
  Result<MonteCarloReport> r = RunMeasurementMonteCarlo(design, options);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("iterations"), std::string::npos);

  options.iterations = 10;
  options.threads = -1;
  EXPECT_EQ(RunMeasurementMonteCarlo(design, options).status().code(),
            StatusCode::kInvalidArgument);
  options.threads = 0;

  ModuleDesign quiet = design;
  quiet.spot_noise_mm.setZero();
  r = RunMeasurementMonteCarlo(quiet, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("spot_noise_mm"), std::string::npos);

  ModuleDesign single = design;
  single.sources.resize(1);
  EXPECT_EQ(RunMeasurementMonteCarlo(single, options).status().code(), StatusCode::kNoSolution);

  ModuleDesign away = design;  // the screen behind the module: no spot
  away.surface = PlaneSurface{Eigen::Vector3d(-1000.0, 0.0, 0.0), Eigen::Vector3d::UnitX()};
  r = RunMeasurementMonteCarlo(away, options);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
}

}  // namespace
}  // namespace opl
