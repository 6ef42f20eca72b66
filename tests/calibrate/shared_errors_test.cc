#include "opl/calibrate/shared_errors.h"

#include <cmath>
#include <cstdio>
#include <algorithm>
#include <random>

#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/sim/simulate_slices.h"
#include "support/calibration_session.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

// A session of the prototype-like module (two 11 x 11 sources 55 mm apart)
// at three screen depths, one grid per slice, every spot at its true point
// and carrying the design's noise covariance (its own error). Each slice was
// "photographed" by a camera at kCamera whose pose error moves the whole
// slice: a translation (sd kShiftMm per axis) and a rotation about the
// camera (sd kTurnRad per axis), 6 shared components per slice.
constexpr double kShiftMm = 0.005;
constexpr double kTurnRad = 4e-6;
const Eigen::Vector3d kCamera(-1250.0, 400.0, 900.0);

struct SharedSession {
  std::vector<Spot> spots;          // true points, own covariances
  std::vector<int> slices;
  std::vector<Eigen::MatrixXd> factors;
};

SharedSession MakeSession() {
  ScreenSlicesOptions screens;
  screens.depths_mm = {900.0, 1200.0, 1500.0};
  const ModuleDesign design = test::Prototype();
  Result<std::vector<Surface>> surfaces = MakeCalibrationScreens(design, screens);
  EXPECT_TRUE(surfaces.ok()) << surfaces.status().message();
  Result<std::vector<SimulatedSpot>> simulated = SimulateSlices(design, *surfaces, {});
  EXPECT_TRUE(simulated.ok()) << simulated.status().message();
  SharedSession s;
  s.slices = test::OneGridPerSlice(*simulated, design);
  std::vector<int> slice_ids = s.slices;
  std::sort(slice_ids.begin(), slice_ids.end());
  slice_ids.erase(std::unique(slice_ids.begin(), slice_ids.end()), slice_ids.end());
  const Eigen::Index m = 6 * static_cast<Eigen::Index>(slice_ids.size());
  for (size_t i = 0; i < simulated->size(); ++i) {
    Spot spot = (*simulated)[i].spot;
    spot.observation.point_in_scene = (*simulated)[i].true_point_in_scene;
    const Eigen::Index c = 6 * (std::lower_bound(slice_ids.begin(), slice_ids.end(), s.slices[i]) -
                                slice_ids.begin());
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3, m);
    K.block<3, 3>(0, c) = kShiftMm * Eigen::Matrix3d::Identity();
    K.block<3, 3>(0, c + 3) = -kTurnRad * Skew(spot.observation.point_in_scene - kCamera);
    s.spots.push_back(spot);
    s.factors.push_back(K);
  }
  return s;
}

// Draws own + shared errors.
std::vector<Spot> Draw(const SharedSession& s, std::mt19937_64& rng) {
  std::normal_distribution<double> n01;
  const Eigen::Index m = s.factors.front().cols();
  Eigen::VectorXd z(m);
  for (Eigen::Index k = 0; k < m; ++k) z(k) = n01(rng);
  std::vector<Spot> out = s.spots;
  for (size_t i = 0; i < out.size(); ++i) {
    const Eigen::Matrix3d L = Eigen::Matrix3d(out[i].observation.cov_in_scene->llt().matrixL());
    const Eigen::Vector3d e(n01(rng), n01(rng), n01(rng));
    out[i].observation.point_in_scene += L * e + s.factors[i] * z;
  }
  return out;
}

TEST(AddSharedErrors, MatchesTheScatterOfSessionsWithSharedErrors) {
  const SharedSession s = MakeSession();
  Result<ModuleCalibrationResult> base = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_TRUE(base.ok()) << base.status().message();
  ModuleCalibrationResult r = *base;
  Result<SharedErrorSummary> summary = AddSharedErrors(s.spots, s.slices, std::nullopt, {}, s.factors, &r);
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  ASSERT_EQ(summary->components, 36);
  ASSERT_EQ(summary->u_separation_own_mm.size(), 1u);
  const double u_own = summary->u_separation_own_mm[0];
  const double u_total = r.calibration.separations[0].u_length_mm;
  EXPECT_DOUBLE_EQ(u_own, base->calibration.separations[0].u_length_mm);
  EXPECT_NEAR(u_total, std::hypot(u_own, summary->u_separation_shared_mm[0]), 1e-15);

  // The scatter of the calibration over sessions drawn with both errors.
  std::mt19937_64 rng(11);
  const int kDraws = 300;
  double sum = 0.0, sum2 = 0.0;
  Eigen::Vector3d t_sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d t_sum2 = Eigen::Matrix3d::Zero();
  double az_sum = 0.0, az_sum2 = 0.0;
  const int beam = 1;  // a corner beam of source A
  const double az0 = r.calibration.sources[0].pattern.Find(beam)->az_rad;
  for (int d = 0; d < kDraws; ++d) {
    Result<ModuleCalibrationResult> c = CalibrateModule(Draw(s, rng), s.slices, std::nullopt);
    ASSERT_TRUE(c.ok()) << c.status().message();
    const double L = c->calibration.separations[0].length_mm;
    sum += L;
    sum2 += L * L;
    const Eigen::Vector3d t = c->calibration.sources[0].calibration_from_source.translation;
    t_sum += t;
    t_sum2 += t * t.transpose();
    const double az = c->calibration.sources[0].pattern.Find(beam)->az_rad - az0;
    az_sum += az;
    az_sum2 += az * az;
  }
  const double std_L = std::sqrt((sum2 - sum * sum / kDraws) / (kDraws - 1));
  std::printf("A-B over %d sessions: std %.4f mm; reported u %.4f = sqrt(own %.4f^2 + shared %.4f^2)\n",
              kDraws, std_L, u_total, u_own, summary->u_separation_shared_mm[0]);
  // With 300 draws a standard deviation is known to about 4%.
  EXPECT_NEAR(std_L / u_total, 1.0, 0.12) << "std " << std_L << " u " << u_total;
  // The own errors alone would claim far too little.
  EXPECT_LT(u_own / std_L, 0.75) << "u_own " << u_own;
  const Eigen::Matrix3d cov_t = (t_sum2 - t_sum * t_sum.transpose() / kDraws) / (kDraws - 1);
  const Eigen::Matrix3d reported = r.calibration.sources[0].quality->origin_cov_mm2;
  for (int k = 0; k < 3; ++k) {
    std::printf("origin A axis %d: std %.4f mm, reported u %.4f mm, own only %.4f mm\n", k,
                std::sqrt(cov_t(k, k)), std::sqrt(reported(k, k)),
                std::sqrt(base->calibration.sources[0].quality->origin_cov_mm2(k, k)));
    EXPECT_NEAR(std::sqrt(cov_t(k, k) / reported(k, k)), 1.0, 0.12) << "origin axis " << k;
  }
  const double std_az = std::sqrt((az_sum2 - az_sum * az_sum / kDraws) / (kDraws - 1));
  const double u_az = std::sqrt((*r.calibration.sources[0].pattern.Find(beam)->cov_azel_rad2)(0, 0));
  std::printf("beam %d azimuth: std %.2f urad, reported u %.2f urad\n", beam, 1e6 * std_az, 1e6 * u_az);
  EXPECT_NEAR(std_az / u_az, 1.0, 0.12);
}

TEST(AddSharedErrors, AFlaggedSampleStaysOutOfTheReSolves) {
  SharedSession s = MakeSession();
  size_t k = 0;  // source B's first spot
  while (s.spots[k].source != "B") ++k;
  // The session without that spot...
  SharedSession without = s;
  without.spots.erase(without.spots.begin() + static_cast<long>(k));
  without.slices.erase(without.slices.begin() + static_cast<long>(k));
  without.factors.erase(without.factors.begin() + static_cast<long>(k));
  Result<ModuleCalibrationResult> clean = CalibrateModule(without.spots, without.slices, std::nullopt);
  ASSERT_TRUE(clean.ok());
  ASSERT_TRUE(
      AddSharedErrors(without.spots, without.slices, std::nullopt, {}, without.factors, &*clean).ok());
  // ... and with it moved 5 mm across its beam: flagged, it must not count.
  s.spots[k].observation.point_in_scene.z() += 5.0;
  Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r->sources[1].calibration.quality->samples_flagged, 1);
  ModuleCalibrationResult threaded = *r;
  Result<SharedErrorSummary> summary = AddSharedErrors(s.spots, s.slices, std::nullopt, {}, s.factors, &*r);
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  // The threads share out the re-solves; the sums do not depend on them.
  ASSERT_TRUE(AddSharedErrors(s.spots, s.slices, std::nullopt, {}, s.factors, &threaded, 3).ok());
  EXPECT_EQ(threaded.calibration.separations[0].u_length_mm, r->calibration.separations[0].u_length_mm);
  EXPECT_NEAR(r->calibration.separations[0].u_length_mm,
              clean->calibration.separations[0].u_length_mm, 1e-9);
  EXPECT_NEAR(r->calibration.sources[1].quality->origin_cov_mm2(1, 1),
              clean->calibration.sources[1].quality->origin_cov_mm2(1, 1), 1e-12);
}

TEST(AddSharedErrors, BadInputIsRefusedAndLeavesTheResult) {
  const SharedSession s = MakeSession();
  Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_TRUE(r.ok());
  const double u = r->calibration.separations[0].u_length_mm;
  std::vector<Eigen::MatrixXd> few(s.factors.begin(), s.factors.end() - 1);
  Result<SharedErrorSummary> bad = AddSharedErrors(s.spots, s.slices, std::nullopt, {}, few, &*r);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  std::vector<Eigen::MatrixXd> ragged = s.factors;
  ragged[5] = Eigen::MatrixXd::Zero(3, 4);
  bad = AddSharedErrors(s.spots, s.slices, std::nullopt, {}, ragged, &*r);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("expected 3 x 36"), std::string::npos) << bad.status().message();
  EXPECT_EQ(r->calibration.separations[0].u_length_mm, u);
  // No component: nothing added.
  std::vector<Eigen::MatrixXd> none(s.factors.size(), Eigen::MatrixXd(3, 0));
  Result<SharedErrorSummary> zero = AddSharedErrors(s.spots, s.slices, std::nullopt, {}, none, &*r);
  ASSERT_TRUE(zero.ok());
  EXPECT_EQ(zero->components, 0);
  EXPECT_EQ(r->calibration.separations[0].u_length_mm, u);
}

}  // namespace
}  // namespace opl
