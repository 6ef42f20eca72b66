#include "opl/calibrate/calibrate_module.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "opl/pipeline/measure.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_slices.h"
#include "opl/sim/simulate_spots.h"
#include "support/calibration_session.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

// A calibration session of `design` (screens 750..1335 mm, 10 depths), slices
// numbered one grid per slice, as CalibrateModule expects.
struct SessionData {
  std::vector<Spot> spots;
  std::vector<int> slices;
};

SessionData Session(const ModuleDesign& design, uint64_t seed, double missing, double tilt_deg = 0.0,
                    double curvature = 0.0) {
  ScreenSlicesOptions screens;
  screens.depths_mm = *ParseDepthList("750:65:1335");
  screens.tilt_deg = tilt_deg;
  screens.curvature_per_mm = curvature;
  Result<std::vector<Surface>> surfaces = MakeCalibrationScreens(design, screens);
  EXPECT_TRUE(surfaces.ok()) << surfaces.status().message();
  SpotSimulationOptions options;
  options.seed = seed;
  options.missing_fraction = missing;
  options.attach_covariance = design.spot_noise_mm.minCoeff() > 0.0;
  Result<std::vector<SimulatedSpot>> spots = SimulateSlices(design, *surfaces, options);
  EXPECT_TRUE(spots.ok()) << spots.status().message();
  return {SpotsOf(*spots), test::OneGridPerSlice(*spots, design)};
}

ModuleDesign ThreeSources() {
  ModuleDesign d = test::Prototype();
  d.sources.push_back(test::Source("C", Eigen::Vector3d(-39.0, 0.0, 30.0), Eigen::Vector3d(0.0, -0.03, 0.02)));
  d.sources[2].pattern = PatternModel::kGrating;
  return d;
}

TEST(CalibrateModule, NoiseFreeSeparationsAreExact) {
  std::mt19937_64 rng(5);
  double worst = 0.0;
  for (int trial = 0; trial < 8; ++trial) {
    ModuleDesign d = ThreeSources();
    d.spot_noise_mm.setZero();
    d = d.Transformed(test::RandomMotion(rng, 3000.0));
    const SessionData s = Session(d, trial, 0.2, trial % 2 ? 10.0 : 0.0, trial % 2 ? 0.0 : 3e-4);
    Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
    ASSERT_TRUE(r.ok()) << r.status().message();
    ASSERT_EQ(r->calibration.separations.size(), 3u);
    for (const Separation& sep : r->calibration.separations) {
      const Eigen::Vector3d a = d.FindSource(sep.from)->scene_from_source.translation;
      const Eigen::Vector3d b = d.FindSource(sep.to)->scene_from_source.translation;
      worst = std::max(worst, std::abs(sep.length_mm - (a - b).norm()));
    }
    EXPECT_EQ(r->calibration.sources[0].name, "A");  // order of first appearance
    EXPECT_EQ(r->calibration.sources[2].name, "C");
  }
  EXPECT_LT(worst, 1e-6);
  std::printf("noise-free separations: worst error %.2e mm\n", worst);
}

// Reported first-order uncertainties against the spread over 500 seeded
// sessions of the prototype-like module (spot noise 0.110/0.073/0.073 mm).
TEST(CalibrateModule, ReportedUncertaintiesMatchTheSpreadOver500Sessions) {
  const ModuleDesign d = test::Prototype();
  const int trials = 500;
  std::vector<Eigen::Vector3d> origins;
  std::vector<double> lengths;
  Eigen::Vector3d mean_var_origin = Eigen::Vector3d::Zero();
  double mean_var_length = 0.0;
  for (int trial = 0; trial < trials; ++trial) {
    const SessionData s = Session(d, 1000 + trial, 0.1);
    Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
    ASSERT_TRUE(r.ok()) << r.status().message();
    origins.push_back(r->calibration.sources[0].calibration_from_source.translation);
    mean_var_origin += r->sources[0].pose_covariance.bottomRightCorner<3, 3>().diagonal() / trials;
    lengths.push_back(r->calibration.separations[0].length_mm);
    mean_var_length += std::pow(r->calibration.separations[0].u_length_mm, 2) / trials;
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& o : origins) mean += o / trials;
  Eigen::Vector3d var = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& o : origins) var += (o - mean).cwiseAbs2() / (trials - 1);
  double mean_l = 0.0, var_l = 0.0;
  for (double l : lengths) mean_l += l / trials;
  for (double l : lengths) var_l += (l - mean_l) * (l - mean_l) / (trials - 1);
  for (int k = 0; k < 3; ++k) {
    const double ratio = std::sqrt(var[k] / mean_var_origin[k]);
    std::printf("origin %c: empirical %.4f mm, reported %.4f mm, ratio %.3f\n", "xyz"[k],
                std::sqrt(var[k]), std::sqrt(mean_var_origin[k]), ratio);
    EXPECT_NEAR(ratio, 1.0, 0.1) << "axis " << k;
  }
  const double ratio_l = std::sqrt(var_l / mean_var_length);
  std::printf("separation: empirical %.4f mm, reported %.4f mm, ratio %.3f; mean error %.4f mm\n",
              std::sqrt(var_l), std::sqrt(mean_var_length), ratio_l, mean_l - 55.0);
  EXPECT_NEAR(ratio_l, 1.0, 0.1);
  // No bias beyond what 500 trials can resolve (4 standard errors).
  EXPECT_LT(std::abs(mean_l - 55.0), 4.0 * std::sqrt(var_l / trials));
}

// Calibrate a simulated session, then measure a scene of the same module at
// a new pose with that calibration: s must agree with 1 within its reported
// expanded uncertainty (k = 2) in at least 95% of 200 seeded trials.
TEST(CalibrateModule, RoundTripThroughAMeasurementCoversTheTruth) {
  const ModuleDesign d = test::Prototype();
  std::mt19937_64 rng(77);
  const int trials = 200;
  int covered_k1 = 0, covered_k2 = 0;
  double mean_u = 0.0;
  for (int trial = 0; trial < trials; ++trial) {
    const SessionData s = Session(d, 5000 + trial, 0.1);
    Result<ModuleCalibrationResult> cal = CalibrateModule(s.spots, s.slices, std::nullopt);
    ASSERT_TRUE(cal.ok()) << cal.status().message();
    // The measurement: same module, new pose, a wall about 1 m ahead.
    ModuleDesign scene = d.Transformed(test::RandomMotion(rng, 2000.0));
    SpotSimulationOptions options;
    options.seed = 9000 + trial;
    options.missing_fraction = 0.1;
    Result<std::vector<SimulatedSpot>> spots = SimulateSpots(scene, options);
    ASSERT_TRUE(spots.ok());
    Result<MeasureReport> m = MeasureScale(cal->calibration, SpotsOf(*spots));
    ASSERT_TRUE(m.ok()) << m.status().message();
    const double err = std::abs(m->scale.scale_factor - 1.0);
    covered_k1 += err <= m->scale.u_scale_factor;
    covered_k2 += err <= 2.0 * m->scale.u_scale_factor;
    mean_u += m->scale.u_scale_factor / trials;
  }
  std::printf("round trip: |s - 1| <= u in %d/%d, <= 2u in %d/%d; mean u(s) = %.2e\n", covered_k1,
              trials, covered_k2, trials, mean_u);
  EXPECT_GE(covered_k2, 190);
  // Not a vacuous interval: k = 1 covers about 68%.
  EXPECT_GE(covered_k1, 120);
  EXPECT_LE(covered_k1, 160);
}

TEST(CalibrateModule, ArtifactScalesTheSessionAndItsUncertaintyReachesTheSeparations) {
  ModuleDesign d = test::Prototype();
  d.spot_noise_mm.setZero();
  SessionData s = Session(d, 3, 0.0);
  // The photogrammetry frame is 0.8 times the true size.
  for (Spot& spot : s.spots) spot.observation.point_in_scene *= 0.8;
  ArtifactMeasurement artifact;
  artifact.from_target = "T1";
  artifact.to_target = "T2";
  artifact.from_point = Eigen::Vector3d(100, 200, 300) * 0.8;
  artifact.to_point = (Eigen::Vector3d(100, 200, 300) + 1677.66 * Eigen::Vector3d(0.6, 0.8, 0.0)) * 0.8;
  artifact.length_mm = 1677.66;
  artifact.u_length_mm = 0.0167766;  // 1e-5 relative
  Result<CalibrationScaling> scaling = ComputeArtifactScaling(artifact);
  ASSERT_TRUE(scaling.ok());
  EXPECT_NEAR(scaling->scale, 1.25, 1e-12);
  EXPECT_NEAR(scaling->u_scale_relative, 1e-5, 1e-15);
  Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, *scaling);
  ASSERT_TRUE(r.ok()) << r.status().message();
  const Separation& sep = r->calibration.separations[0];
  EXPECT_NEAR(sep.length_mm, 55.0, 1e-6);
  // Noise-free spots: the separation's uncertainty is the artifact's alone.
  EXPECT_NEAR(sep.u_length_mm, 55.0 * 1e-5, 1e-9);
  ASSERT_TRUE(r->calibration.scaling.has_value());

  artifact.to_point = artifact.from_point;
  EXPECT_FALSE(ComputeArtifactScaling(artifact).ok());
  artifact.to_point.x() += 1.0;
  artifact.length_mm = -1.0;
  Result<CalibrationScaling> bad = ComputeArtifactScaling(artifact);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("length must be finite and > 0"), std::string::npos);
}

TEST(CalibrateModule, ASliceMixingTwoSourcesIsRefused) {
  ModuleDesign d = test::Prototype();
  SessionData s = Session(d, 4, 0.0);
  // Give slice of a B spot the number of an A slice.
  size_t b = 0;
  while (s.spots[b].source != "B") ++b;
  s.slices[b] = s.slices[0];
  s.spots[0].where = "slices.csv:2";
  s.spots[b].where = "slices.csv:999";
  Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(),
            "slices.csv:999: slice " + std::to_string(s.slices[0]) +
                " holds spots of source 'B' and of source 'A' (slices.csv:2): a slice is one grid "
                "at one screen position");
  r = CalibrateModule(s.spots, {}, std::nullopt);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("no slice column"), std::string::npos);
}

TEST(CalibrateModule, GridsBeyondTheLimitAreRefusedWithoutOverflow) {
  // Issue 19: a beam id of 2^31 - 1 made the grid inference square an n of
  // 46341 (int overflow); --beams-per-side 100001 allocated n^2.
  ModuleDesign d = test::Prototype();
  SessionData s = Session(d, 4, 0.0);
  s.spots[0].observation.beam_id = 2147483647;
  Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(),
            s.spots[0].where + ": source '" + s.spots[0].source +
                "': beam id 2147483647 is beyond the largest grid (201 x 201 = 40401 beams)");
  s = Session(d, 4, 0.0);
  CalibrateModuleOptions options;
  for (int n : {203, 46341, 100001}) {
    options.beams_per_side = n;
    r = CalibrateModule(s.spots, s.slices, std::nullopt, options);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().message(),
              "beams per side must be odd and in [3, 201], got " + std::to_string(n));
  }
}

TEST(CalibrateModule, BadBeamIdsAndRepeatedSpotsNameTheirLines) {
  // Issue 19: these were refused without the file and line of the spot.
  ModuleDesign d = test::Prototype();
  SessionData s = Session(d, 4, 0.0);
  ASSERT_GE(s.spots.size(), 3u);
  s.spots[2].where = "slices.csv:4";
  s.spots[2].observation.beam_id = 0;
  Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(),
            "slices.csv:4: beam id 0 of source '" + s.spots[2].source + "' must be >= 1");

  s = Session(d, 4, 0.0);
  s.spots[2].where = "slices.csv:4";
  CalibrateModuleOptions options;
  options.beams_per_side = 3;
  s.spots[2].observation.beam_id = 10;
  r = CalibrateModule(s.spots, s.slices, std::nullopt, options);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "slices.csv:4: beam id 10 of source '" + s.spots[2].source +
                                      "' is outside 1..9 (a grid of 3 x 3 beams)");

  // The same beam twice in one slice: both lines are named.
  s = Session(d, 4, 0.0);
  ASSERT_EQ(s.slices[0], s.slices[1]);
  s.spots[0].where = "slices.csv:2";
  s.spots[1].where = "slices.csv:3";
  s.spots[1].observation.beam_id = s.spots[0].observation.beam_id;
  r = CalibrateModule(s.spots, s.slices, std::nullopt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(),
            "slices.csv:3: a second spot of beam " + std::to_string(s.spots[0].observation.beam_id) +
                " of source '" + s.spots[0].source + "' in slice " + std::to_string(s.slices[0]) +
                " (the first is slices.csv:2): a slice holds each beam's spot once");
}

}  // namespace
}  // namespace opl
