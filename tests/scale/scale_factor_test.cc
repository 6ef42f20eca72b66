#include "opl/scale/scale_factor.h"

#include <random>

#include <gtest/gtest.h>

#include "opl/locate/locate_source.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

ModuleCalibration ThreeSourceCalibration(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                         const Eigen::Vector3d& c, double u_cal) {
  ModuleCalibration cal;
  const BeamPattern pattern = test::TangentLatticePattern(5, 0.4);
  cal.sources = {{"A", pattern, Rigid3d(Eigen::Matrix3d::Identity(), a), {}},
                 {"B", pattern, Rigid3d(Eigen::Matrix3d::Identity(), b), {}},
                 {"C", pattern, Rigid3d(Eigen::Matrix3d::Identity(), c), {}}};
  cal.separations = ModuleCalibration::SeparationsFromOrigins(cal.sources);
  for (auto& s : cal.separations) s.u_length_mm = u_cal;
  return cal;
}

TEST(ScaleFactor, ExactForAnUnscaledRotatedScene) {
  const Eigen::Vector3d a(0, 27.5, 0), b(0, -27.5, 0), c(39, 0, 20);
  const ModuleCalibration cal = ThreeSourceCalibration(a, b, c, 0.0);
  // The scene: rotated, shifted, and in metres instead of millimetres.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(5, -3, 2);
  auto scene = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d { return R * p * 1e-3 + t; };
  const Eigen::Matrix3d C = 1e-10 * Eigen::Matrix3d::Identity();
  auto result = ComputeScaleFactor(cal, {{"A", scene(a), C}, {"B", scene(b), C}, {"C", scene(c), C}});
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  EXPECT_NEAR(result->scale_factor, 1000.0, 1e-9);
  ASSERT_EQ(result->lengths.size(), 3u);
  EXPECT_NEAR(result->lengths[0].photo, 0.055, 1e-15);
  EXPECT_NEAR(result->chi2, 0.0, 1e-12);
  EXPECT_EQ(result->dof, 2);
}

TEST(ScaleFactor, OnePairUncertaintyInClosedForm) {
  ModuleCalibration cal = ThreeSourceCalibration({0, 0, 0}, {0, 50, 0}, {0, 0, 50}, 0.002);
  cal.separations.resize(1);  // A-B only
  // Origins 100 scene units apart along X, covariances with known X variances.
  Eigen::Matrix3d Ca = Eigen::Vector3d(0.04, 1, 1).asDiagonal();
  Eigen::Matrix3d Cb = Eigen::Vector3d(0.09, 1, 1).asDiagonal();
  auto r = ComputeScaleFactor(cal, {{"A", {0, 0, 0}, Ca}, {"B", {100, 0, 0}, Cb}});
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r->scale_factor, 0.5);
  // u(L) = sqrt(0.04 + 0.09): only the component along the baseline counts.
  EXPECT_NEAR(r->lengths[0].u_photo, std::sqrt(0.13), 1e-15);
  const double rel = std::hypot(0.002 / 50.0, std::sqrt(0.13) / 100.0);
  EXPECT_NEAR(r->u_scale_factor, 0.5 * rel, 1e-15);
}

// The first-order propagation against a direct simulation of the origins.
TEST(ScaleFactor, PropagationAgreesWithMonteCarloOfOrigins) {
  const Eigen::Vector3d a(0, 27.5, 0), b(0, -27.5, 0), c(39, 0, 39);
  const ModuleCalibration cal = ThreeSourceCalibration(a, b, c, 0.0);
  Eigen::Matrix3d C;
  C << 0.04, 0.01, 0.0, 0.01, 0.02, 0.005, 0.0, 0.005, 0.03;
  C *= 1e-2;
  const std::vector<LocatedOrigin> located = {{"A", a, C}, {"B", b, 2.0 * C}, {"C", c, C}};
  auto first = ComputeScaleFactor(cal, located);
  ASSERT_TRUE(first.ok());
  std::mt19937_64 rng(51);
  std::normal_distribution<double> g(0, 1);
  const int trials = 20000;
  std::vector<double> s;
  for (int k = 0; k < trials; ++k) {
    std::vector<LocatedOrigin> noisy = located;
    for (auto& o : noisy) {
      const Eigen::Matrix3d L = Eigen::LLT<Eigen::Matrix3d>(o.origin_covariance).matrixL();
      o.origin_in_scene += L * Eigen::Vector3d(g(rng), g(rng), g(rng));
    }
    auto r = ComputeScaleFactor(cal, noisy);
    ASSERT_TRUE(r.ok());
    s.push_back(r->scale_factor);
  }
  double mean = 0, var = 0;
  for (double v : s) mean += v;
  mean /= trials;
  for (double v : s) var += (v - mean) * (v - mean);
  var /= trials - 1;
  EXPECT_NEAR(std::sqrt(var) / first->u_scale_factor, 1.0, 0.03);
}

TEST(ScaleFactor, InconsistentPairsShowInChi2) {
  const Eigen::Vector3d a(0, 27.5, 0), b(0, -27.5, 0), c(39, 0, 39);
  const ModuleCalibration cal = ThreeSourceCalibration(a, b, c, 0.0);
  const Eigen::Matrix3d C = 1e-4 * Eigen::Matrix3d::Identity();
  // Source C located 1 mm off: far outside u = 0.01 mm.
  auto r = ComputeScaleFactor(cal, {{"A", a, C}, {"B", b, C}, {"C", c + Eigen::Vector3d(1, 0, 0), C}});
  ASSERT_TRUE(r.ok());
  EXPECT_GT(r->chi2, 1000.0);
  EXPECT_GT(r->max_normalized_deviation, 10.0);
}

TEST(ScaleFactor, Errors) {
  const ModuleCalibration cal = ThreeSourceCalibration({0, 0, 0}, {0, 50, 0}, {0, 0, 50}, 0.0);
  const Eigen::Matrix3d C = Eigen::Matrix3d::Identity();
  EXPECT_EQ(ComputeScaleFactor(cal, {{"A", {0, 0, 0}, C}}).status().code(), StatusCode::kNoSolution);
  EXPECT_EQ(ComputeScaleFactor(cal, {{"A", {1, 1, 1}, C}, {"B", {1, 1, 1}, C}}).status().code(),
            StatusCode::kNoSolution);
  EXPECT_EQ(ComputeScaleFactor(cal, {{"A", {NAN, 1, 1}, C}, {"B", {1, 1, 1}, C}}).status().code(),
            StatusCode::kInvalidArgument);
}

// 1000 seeded noisy scenes of two sources: the spread of L_photo agrees with
// the reported first-order u(L_photo) within 10%.
TEST(ScaleFactor, LengthUncertaintyMatchesEmpiricalSpread) {
  std::mt19937_64 rng(52);
  const BeamPattern pattern = test::TangentLatticePattern(11, 29.0 * M_PI / 180.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, -0.4).normalized()).toRotationMatrix();
  const Rigid3d pose_a(R, Eigen::Vector3d(10, 27.5, 5));
  const Rigid3d pose_b(R, pose_a.translation + R * Eigen::Vector3d(0, -55, 0));
  ModuleCalibration cal;
  cal.sources = {{"A", pattern, Rigid3d(), {}},
                 {"B", pattern, Rigid3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, -55, 0)), {}}};
  cal.separations = ModuleCalibration::SeparationsFromOrigins(cal.sources);
  const int trials = 1000;
  std::vector<double> L;
  double reported = 0.0, s_reported = 0.0;
  std::vector<double> s;
  for (int k = 0; k < trials; ++k) {
    // Both grids on the same screen plane, ~1 m ahead of the module.
    auto spots_a = test::SpotsOnPlane(pattern, pose_a, 1000.0, 0.0, 0.1, rng);
    auto spots_b = test::SpotsOnPlane(pattern, pose_b, 1000.0, 0.0, 0.1, rng);
    auto ra = LocateSource(pattern, spots_a);
    auto rb = LocateSource(pattern, spots_b);
    ASSERT_TRUE(ra.ok() && rb.ok());
    auto r = ComputeScaleFactor(cal, {{"A", ra->scene_from_source.translation, ra->origin_covariance},
                                      {"B", rb->scene_from_source.translation, rb->origin_covariance}});
    ASSERT_TRUE(r.ok());
    L.push_back(r->lengths[0].photo);
    reported += r->lengths[0].u_photo * r->lengths[0].u_photo;
    s.push_back(r->scale_factor);
    s_reported += r->u_scale_factor * r->u_scale_factor;
  }
  auto stddev = [](const std::vector<double>& v) {
    double m = 0, q = 0;
    for (double x : v) m += x;
    m /= v.size();
    for (double x : v) q += (x - m) * (x - m);
    return std::sqrt(q / (v.size() - 1));
  };
  EXPECT_NEAR(stddev(L) / std::sqrt(reported / trials), 1.0, 0.10);
  EXPECT_NEAR(stddev(s) / std::sqrt(s_reported / trials), 1.0, 0.10);
}

// Two placements of the module (issue 20): a pair joins two sources of one
// placement only, the photogrammetric errors of the placements average down,
// and the calibrated length's error, shared by both, does not.
TEST(ScaleFactor, PlacementsShareTheCalibrationError) {
  ModuleCalibration cal = ThreeSourceCalibration({0, 0, 0}, {0, 50, 0}, {0, 0, 50}, 0.002);
  cal.separations.resize(1);  // A-B only
  const Eigen::Matrix3d Ca = Eigen::Vector3d(0.04, 1, 1).asDiagonal();
  const Eigen::Matrix3d Cb = Eigen::Vector3d(0.09, 1, 1).asDiagonal();
  std::vector<LocatedOrigin> located = {{"A", {0, 0, 0}, Ca, "P1"},
                                        {"B", {100, 0, 0}, Cb, "P1"},
                                        {"A", {0, 300, 10}, Ca, "P2"},
                                        {"B", {100, 300, 10}, Cb, "P2"}};
  auto r = ComputeScaleFactor(cal, located);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->lengths.size(), 2u);
  EXPECT_EQ(r->lengths[0].placement, "P1");
  EXPECT_EQ(r->lengths[1].placement, "P2");
  EXPECT_DOUBLE_EQ(r->scale_factor, 0.5);
  // Each pair: u(s_p)^2 = s^2 (0.13 / 100^2) + (u_cal / 100)^2; the mean of
  // two: the first term halves, the second (one calibration) stays.
  const double photo2 = 0.25 * 0.13 / 1e4, cal2 = std::pow(0.002 / 100.0, 2);
  EXPECT_NEAR(r->lengths[0].u_scale, std::sqrt(photo2 + cal2), 1e-15);
  EXPECT_NEAR(r->u_scale_factor, std::sqrt(photo2 / 2.0 + cal2), 1e-15);
  EXPECT_EQ(r->dof, 1);
  // Sources of different placements are never paired.
  auto apart = ComputeScaleFactor(cal, {located[0], located[3]});
  ASSERT_FALSE(apart.ok());
  EXPECT_EQ(apart.status().message(), "no calibrated separation joins two located sources");
}

}  // namespace
}  // namespace opl
