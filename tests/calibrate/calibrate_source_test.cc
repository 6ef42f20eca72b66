#include "opl/calibrate/calibrate_source.h"

#include <map>
#include <random>

#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_slices.h"
#include "support/calibration_session.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

struct Session {
  ModuleDesign design;
  std::vector<SimulatedSpot> spots;
};

// A module at a random pose, screens at 10 depths (750..1335 mm), tilted or
// curved as asked.
Session MakeSession(uint64_t seed, PatternModel model, double tilt_deg, double curvature,
                    double missing, double noise_scale, double outliers = 0.0) {
  std::mt19937_64 rng(seed);
  Session s;
  ModuleDesign d = test::Prototype();
  for (SourceDesign& src : d.sources) src.pattern = model;
  d.spot_noise_mm *= noise_scale;
  s.design = d.Transformed(test::RandomMotion(rng, 2000.0));
  ScreenSlicesOptions screens;
  screens.depths_mm = *ParseDepthList("750:65:1335");
  screens.tilt_deg = tilt_deg;
  screens.curvature_per_mm = curvature;
  Result<std::vector<Surface>> surfaces = MakeCalibrationScreens(s.design, screens);
  EXPECT_TRUE(surfaces.ok()) << surfaces.status().message();
  SpotSimulationOptions options;
  options.seed = seed;
  options.missing_fraction = missing;
  options.outlier_fraction = outliers;
  options.attach_covariance = noise_scale > 0.0;
  Result<std::vector<SimulatedSpot>> spots = SimulateSlices(s.design, *surfaces, options);
  EXPECT_TRUE(spots.ok()) << spots.status().message();
  s.spots = *spots;
  return s;
}

TEST(CalibrateSource, NoiseFreeRecoversDirectionsAndPoseExactly) {
  struct Case {
    PatternModel model;
    double tilt_deg, curvature;
  };
  const Case cases[] = {{PatternModel::kEqualAngle, 12.0, 0.0},
                        {PatternModel::kGrating, 12.0, 0.0},
                        {PatternModel::kEqualAngle, 0.0, 4e-4},
                        {PatternModel::kGrating, -8.0, -3e-4}};
  double worst_dir = 0.0, worst_origin = 0.0, worst_rot = 0.0;
  int trial = 0;
  for (const Case& c : cases) {
    for (int k = 0; k < 6; ++k, ++trial) {
      const Session s = MakeSession(100 + trial, c.model, c.tilt_deg, c.curvature, 0.2, 0.0);
      for (const SourceDesign& src : s.design.sources) {
        Result<BeamPattern> truth = MakePattern(src);
        ASSERT_TRUE(truth.ok());
        Result<SourceCalibrationResult> r =
            CalibrateSource(src.name, 11, test::SamplesOf(s.spots, src.name));
        ASSERT_TRUE(r.ok()) << r.status().message();
        EXPECT_TRUE(r->dropped_beam_ids.empty());
        EXPECT_EQ(r->calibration.quality->samples_flagged, 0);
        for (const Beam& b : r->calibration.pattern.beams()) {
          const Beam* t = truth->Find(b.id);
          ASSERT_NE(t, nullptr);
          const double err = (b.DirectionInSource() - t->DirectionInSource()).norm();
          worst_dir = std::max(worst_dir, err);
        }
        EXPECT_EQ(r->calibration.pattern.beams().size(), 121u);
        worst_origin = std::max(worst_origin, (r->calibration.calibration_from_source.translation -
                                               src.scene_from_source.translation)
                                                  .norm());
        worst_rot = std::max(worst_rot, RotationAngleBetweenRad(
                                            r->calibration.calibration_from_source.RotationMatrix(),
                                            src.scene_from_source.RotationMatrix()));
      }
    }
  }
  EXPECT_LT(worst_dir, 1e-9);
  EXPECT_LT(worst_origin, 1e-6);
  EXPECT_LT(worst_rot, 1e-9);
  std::printf("noise-free, %d sessions: worst direction %.2e rad, origin %.2e mm, rotation %.2e rad\n",
              trial, worst_dir, worst_origin, worst_rot);
}

TEST(CalibrateSource, GaugeIsFixedExactlyOnAPatternThatBreaksIt) {
  // True beams d'_b = G p_b: an equal-angle pattern with every beam moved by
  // up to 2 mrad (p_b), then turned by G, so that the central beam is off axis,
  // the central row neither level nor of mean elevation 0. The calibration must
  // return the same bundle of rays, in the gauge: central beam az = el = 0 and
  // the central row level (sum_j az_j el_j = 0, docs/calibrate.md "Gauge").
  SourceDesign design = test::Source("A", Eigen::Vector3d(10, 20, 30), Eigen::Vector3d(0.3, -0.2, 1.0));
  Result<BeamPattern> designed = MakePattern(design);
  ASSERT_TRUE(designed.ok());
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Matrix3d G = RotationFromXyzAnglesRad(Eigen::Vector3d(0.05, 0.02, -0.03));
  std::map<int, Eigen::Vector3d> truth;  // true directions in the scene
  const Eigen::Matrix3d R = design.scene_from_source.RotationMatrix();
  const Eigen::Vector3d t = design.scene_from_source.translation;
  for (const Beam& b : designed->beams()) {
    truth[b.id] = R * G * DirectionFromAzElRad(b.az_rad + 2e-3 * u(rng), b.el_rad + 2e-3 * u(rng));
  }
  std::vector<CalibrationSample> samples;
  for (int k = 0; k < 10; ++k) {
    const double depth = 750.0 + 65.0 * k;
    for (const auto& [id, d] : truth) {
      const Eigen::Vector3d local = R.transpose() * d;
      samples.push_back({id, k, t + (depth / local.x()) * d, std::nullopt});
    }
  }
  Result<SourceCalibrationResult> r = CalibrateSource("A", 11, samples);
  ASSERT_TRUE(r.ok()) << r.status().message();
  const BeamPattern& p = r->calibration.pattern;
  const Beam* central = p.Find(61);
  ASSERT_NE(central, nullptr);
  EXPECT_EQ(central->az_rad, 0.0);
  EXPECT_EQ(central->el_rad, 0.0);
  double level = 0.0, mean = 0.0;
  for (int col = 0; col < 11; ++col) {
    const Beam* b = p.Find(BeamId(5, col, 11));
    level += b->az_rad * b->el_rad;
    mean += b->el_rad / 11.0;
  }
  EXPECT_LT(std::abs(level), 1e-16);
  // The perturbed row's mean elevation is a property of the pattern, not of
  // the gauge: it is not zero here.
  EXPECT_GT(std::abs(mean), 1e-5);
  // The calibrated rays are the true rays.
  const Eigen::Matrix3d Rc = r->calibration.calibration_from_source.RotationMatrix();
  double worst = 0.0;
  for (const Beam& b : p.beams()) worst = std::max(worst, (Rc * b.DirectionInSource() - truth[b.id]).norm());
  EXPECT_LT(worst, 1e-9);
  EXPECT_LT((r->calibration.calibration_from_source.translation - t).norm(), 1e-6);
}

TEST(CalibrateSource, WrongSamplesAreFlaggedAndDoNotMoveTheOrigin) {
  int exact = 0;
  const int trials = 20;
  for (int trial = 0; trial < trials; ++trial) {
    const Session s = MakeSession(300 + trial, PatternModel::kEqualAngle, 0.0, 0.0, 0.1, 1.0, 0.03);
    const SourceDesign& src = s.design.sources[trial % 2];
    std::vector<CalibrationSample> samples = test::SamplesOf(s.spots, src.name);
    std::vector<char> truly_wrong;
    for (const SimulatedSpot& sp : s.spots) {
      if (sp.spot.source == src.name) truly_wrong.push_back(sp.outlier);
    }
    Result<SourceCalibrationResult> r = CalibrateSource(src.name, 11, samples);
    ASSERT_TRUE(r.ok()) << r.status().message();
    bool same = true;
    for (size_t i = 0; i < samples.size(); ++i) {
      same &= r->residuals[i].outlier == static_cast<bool>(truly_wrong[i]);
    }
    exact += same;
    const Eigen::Vector3d err =
        r->calibration.calibration_from_source.translation - src.scene_from_source.translation;
    const Eigen::Matrix3d C = r->pose_covariance.bottomRightCorner<3, 3>();
    // Mahalanobis distance of the origin error: chi^2 with 3 dof, < 16.3 at 99.9%.
    EXPECT_LT(err.dot(C.ldlt().solve(err)), 16.3) << "trial " << trial;
  }
  EXPECT_EQ(exact, trials);
}

TEST(CalibrateSource, UnweightedSamplesGiveTheSameFitAndAScaledCovariance) {
  const Session s = MakeSession(11, PatternModel::kGrating, 5.0, 0.0, 0.1, 1.0);
  const std::string name = s.design.sources[1].name;
  std::vector<CalibrationSample> samples = test::SamplesOf(s.spots, name);
  Result<SourceCalibrationResult> weighted = CalibrateSource(name, 11, samples);
  for (CalibrationSample& c : samples) c.cov_mm2.reset();
  Result<SourceCalibrationResult> unweighted = CalibrateSource(name, 11, samples);
  ASSERT_TRUE(weighted.ok() && unweighted.ok());
  EXPECT_TRUE(weighted->weighted);
  EXPECT_FALSE(unweighted->weighted);
  EXPECT_TRUE(unweighted->covariance_scaled);
  // Variance factor near 1 with the true sigmas (2N - p ~ 2000 dof: +-0.1).
  EXPECT_NEAR(weighted->variance_factor, 1.0, 0.1);
  const double d = (weighted->calibration.calibration_from_source.translation -
                    unweighted->calibration.calibration_from_source.translation)
                       .norm();
  EXPECT_LT(d, 3.0 * std::sqrt(weighted->pose_covariance.bottomRightCorner<3, 3>().trace()));
  const double ratio = std::sqrt(unweighted->pose_covariance(3, 3) / weighted->pose_covariance(3, 3));
  EXPECT_GT(ratio, 0.7);
  EXPECT_LT(ratio, 1.4);
}

TEST(CalibrateSource, BadInputIsRefusedWithAClearMessage) {
  const Session s = MakeSession(21, PatternModel::kEqualAngle, 0.0, 0.0, 0.0, 1.0);
  const std::string name = s.design.sources[0].name;
  const std::vector<CalibrationSample> all = test::SamplesOf(s.spots, name);

  std::vector<CalibrationSample> one_slice;
  for (const CalibrationSample& c : all) {
    if (c.slice == 3) one_slice.push_back(c);
  }
  Result<SourceCalibrationResult> r = CalibrateSource(name, 11, one_slice);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
  EXPECT_NE(r.status().message().find("one slice (3)"), std::string::npos) << r.status().message();

  std::vector<CalibrationSample> few;
  for (const CalibrationSample& c : all) {
    if (c.beam_id == 61 || c.beam_id == 60) few.push_back(c);
  }
  r = CalibrateSource(name, 11, few);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("at least three"), std::string::npos) << r.status().message();

  std::vector<CalibrationSample> no_central;
  for (const CalibrationSample& c : all) {
    if (c.beam_id != 61) no_central.push_back(c);
  }
  r = CalibrateSource(name, 11, no_central);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("central beam 61"), std::string::npos) << r.status().message();

  std::vector<CalibrationSample> duplicate = all;
  duplicate.push_back(all[5]);
  r = CalibrateSource(name, 11, duplicate);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("a second sample of beam"), std::string::npos);

  std::vector<CalibrationSample> bad_id = all;
  bad_id[0].beam_id = 122;
  r = CalibrateSource(name, 11, bad_id);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("outside 1..121"), std::string::npos);

  std::vector<CalibrationSample> nan = all;
  nan[4].point_mm.y() = std::nan("");
  r = CalibrateSource(name, 11, nan);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("not finite"), std::string::npos);

  std::vector<CalibrationSample> mirrored = all;
  for (CalibrationSample& c : mirrored) {
    c.beam_id = BeamId(10 - BeamRow(c.beam_id, 11), BeamCol(c.beam_id, 11), 11);
  }
  r = CalibrateSource(name, 11, mirrored);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("mirrored"), std::string::npos) << r.status().message();
}

}  // namespace
}  // namespace opl
