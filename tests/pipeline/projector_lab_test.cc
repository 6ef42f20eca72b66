// The projector adjustment on the virtual lab's scene (examples/
// scene_small.json: four 1024 x 768 cameras, tags on the walls, a module of
// two 11 x 11 grids 55 mm apart), observed without rendering (tests/support/
// projector_scene.h: exact projections, plus Gaussian noise of known sigma):
//  - noise-free: cameras, tags, the module and s agree with the truth to
//    1e-6 relative;
//  - noisy, over seeded scenes: u(s) from the adjustment's covariance against
//    the spread of s, and side by side with the two-step path (bundle
//    adjustment unscaled, locate, s = L_cal / L_photo) on the same seeds.
#include <algorithm>
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "opl/io/scene_json.h"
#include "opl/vision/scene_frame.h"
#include "support/projector_scene.h"
#include "support/scene_images.h"

namespace opl {
namespace {

Scene SmallScene() {
  Result<Scene> scene = ReadSceneJson(test::SourceDir() + "/examples/scene_small.json");
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  return std::move(scene).value();
}

std::array<Eigen::Vector3d, 3> DatumPoints(const BundleData& b, const std::array<std::vector<int>, 3>& sets) {
  std::array<Eigen::Vector3d, 3> abc;
  for (size_t a = 0; a < 3; ++a) {
    abc[a].setZero();
    for (int j : sets[a]) abc[a] += b.points[static_cast<size_t>(j)].point_in_scene / static_cast<double>(sets[a].size());
  }
  return abc;
}

TEST(ProjectorAdjust, NoiseFreeLabSceneComesOutMetricAndExact) {
  const Scene scene = SmallScene();
  Result<ModuleCalibration> cal = ExactCalibration(*scene.module);
  ASSERT_TRUE(cal.ok());
  const test::ProjectorLabCase c = test::MakeProjectorLabCase(scene, *cal, 0.0, 0.0, 1);
  ASSERT_GT(c.truth.spots.size(), 200u);
  ASSERT_GT(c.truth.bundle.points.size(), 20u);
  for (const auto& set : c.datum_sets) ASSERT_EQ(set.size(), 4u);
  const std::array<Eigen::Vector3d, 3> abc = DatumPoints(c.truth.bundle, c.datum_sets);
  const double true_length = (abc[1] - abc[0]).norm();
  const double unscaled_per_mm = 0.9;  // a made-up unscaled frame: s_true = 1 / 0.9
  ProjectorAdjustmentOptions options;
  options.datum_point_sets = c.datum_sets;
  options.unscaled_datum_length = true_length * unscaled_per_mm;
  Result<ProjectorAdjustmentResult> r = ProjectorAdjust(c.start, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  std::cout << r->Report();
  EXPECT_LT(r->rms_spot_px, 1e-6);
  EXPECT_LT(r->rms_tag_px, 1e-6);
  EXPECT_LT(std::abs(r->scale_factor * unscaled_per_mm - 1.0), 1e-6);

  const Result<Rigid3d> frame = SceneFromThreePoints(abc[0], abc[1], abc[2]);
  ASSERT_TRUE(frame.ok());
  double extent = 0.0;
  for (const BundlePoint& p : c.truth.bundle.points) extent = std::max(extent, (*frame * p.point_in_scene).norm());
  double worst_point = 0.0, worst_camera = 0.0, worst_spot = 0.0;
  for (size_t j = 0; j < c.truth.bundle.points.size(); ++j) {
    worst_point = std::max(worst_point, (r->bundle.points[j].point_in_scene -
                                         *frame * c.truth.bundle.points[j].point_in_scene).norm());
  }
  for (size_t i = 0; i < c.truth.bundle.cameras.size(); ++i) {
    const Eigen::Vector3d truth = *frame * c.truth.bundle.CameraAt(static_cast<int>(i)).CenterInScene();
    worst_camera = std::max(worst_camera, (r->bundle.CameraAt(static_cast<int>(i)).CenterInScene() - truth).norm());
    const Eigen::Quaterniond dq = r->bundle.cameras[i].cam_from_scene.rotation *
                                  (c.truth.bundle.cameras[i].cam_from_scene * frame->Inverse()).rotation.conjugate();
    EXPECT_LT(Eigen::AngleAxisd(dq).angle(), 1e-6) << "camera " << i;
  }
  for (size_t k = 0; k < c.spot_truth_mm.size(); ++k) {
    worst_spot = std::max(worst_spot, (r->spot_in_scene[k] - *frame * c.spot_truth_mm[k]).norm());
  }
  const Eigen::Vector3d module_truth = *frame * c.truth.placements[0].scene_from_module.translation;
  std::cout << "extent " << extent << " mm; worst error: tag point " << worst_point << " mm, camera centre "
            << worst_camera << " mm, spot " << worst_spot << " mm, module origin "
            << (r->scene_from_module[0].translation - module_truth).norm() << " mm\n";
  EXPECT_LT(worst_point, 1e-6 * extent);
  EXPECT_LT(worst_camera, 1e-6 * extent);
  EXPECT_LT(worst_spot, 1e-6 * extent);
  EXPECT_LT((r->scene_from_module[0].translation - module_truth).norm(), 1e-6 * extent);
  EXPECT_NEAR(r->module_length_factor, 1.0, 1e-12);  // held: the exact calibration has u(L) = 0
  ASSERT_EQ(r->point_covariances_mm2.size(), c.truth.bundle.points.size());
  EXPECT_EQ(r->camera_center_covariances_mm2.size(), c.truth.bundle.cameras.size());
}

// Seeded noisy scenes: the adjustment's u(s) against the spread of s, and
// the two-step path on the same observations. Pixel noise 0.1 px on tag
// corners, 0.15 px on spots, with those covariances.
TEST(ProjectorAdjust, UncertaintyOfScaleMatchesItsSpreadAndTheTwoStepPath) {
  const Scene scene = SmallScene();
  Result<ModuleCalibration> cal = ExactCalibration(*scene.module);
  ASSERT_TRUE(cal.ok());
  const int scenes = 50;
  const double unscaled_per_mm = 1.0 / 1037.0;  // about metres: the two-step bundle adjustment tells its 7 gauge directions apart best there
  double sum_joint = 0.0, sum2_joint = 0.0, sum_two = 0.0, sum2_two = 0.0;
  double u_joint = 0.0, u_two = 0.0, mahalanobis = 0.0;
  int inside_joint = 0, inside_two = 0, mahalanobis_n = 0;
  for (int seed = 1; seed <= scenes; ++seed) {
    const test::ProjectorLabCase c =
        test::MakeProjectorLabCase(scene, *cal, 0.1, 0.15, static_cast<uint64_t>(seed));
    Result<test::TwoStepResult> two = test::RunTwoStep(c, unscaled_per_mm);
    ASSERT_TRUE(two.ok()) << two.status().ToString();
    ProjectorAdjustmentOptions options;
    options.datum_point_sets = c.datum_sets;
    options.unscaled_datum_length = two->unscaled_datum_length;
    Result<ProjectorAdjustmentResult> r = ProjectorAdjust(c.start, options);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_FALSE(r->point_covariances_mm2.empty()) << r->covariance_method;
    const std::array<Eigen::Vector3d, 3> abc = DatumPoints(c.truth.bundle, c.datum_sets);
    const double s_true = (abc[1] - abc[0]).norm() / two->unscaled_datum_length;
    const double e_joint = r->scale_factor / s_true - 1.0;
    const double e_two = two->report.measure.scale.scale_factor / s_true - 1.0;
    const double uj = r->u_scale_factor / s_true, ut = two->report.measure.scale.u_scale_factor / s_true;
    sum_joint += e_joint;
    sum2_joint += e_joint * e_joint;
    sum_two += e_two;
    sum2_two += e_two * e_two;
    u_joint += uj;
    u_two += ut;
    inside_joint += std::abs(e_joint) <= 2.0 * uj ? 1 : 0;
    inside_two += std::abs(e_two) <= 2.0 * ut ? 1 : 0;
    // The tag points' covariances: mean Mahalanobis distance^2 / 3 ~ 1.
    const Result<Rigid3d> frame = SceneFromThreePoints(abc[0], abc[1], abc[2]);
    ASSERT_TRUE(frame.ok());
    for (size_t j = 0; j < c.truth.bundle.points.size(); ++j) {
      bool in_datum = false;
      for (const auto& set : c.datum_sets) in_datum = in_datum || std::find(set.begin(), set.end(), static_cast<int>(j)) != set.end();
      if (in_datum) continue;  // partly fixed by the datum: rank-deficient
      const Eigen::Vector3d e = r->bundle.points[j].point_in_scene - *frame * c.truth.bundle.points[j].point_in_scene;
      mahalanobis += e.dot(r->point_covariances_mm2[j].ldlt().solve(e)) / 3.0;
      ++mahalanobis_n;
    }
  }
  const double n = scenes;
  const double rms_joint = std::sqrt(sum2_joint / n), rms_two = std::sqrt(sum2_two / n);
  u_joint /= n;
  u_two /= n;
  mahalanobis /= mahalanobis_n;
  std::cout.precision(4);
  std::cout << scenes << " scenes (relative to s): projector adjustment: RMS error " << rms_joint
            << " (mean " << sum_joint / n << "), mean u(s) " << u_joint << ", ratio "
            << rms_joint / u_joint << ", within 2u " << inside_joint << "/" << scenes
            << "\n  two-step: RMS error " << rms_two << " (mean " << sum_two / n << "), mean u(s) "
            << u_two << ", ratio " << rms_two / u_two << ", within 2u " << inside_two << "/" << scenes
            << "\n  tag points: mean Mahalanobis^2 / 3 = " << mahalanobis << " over " << mahalanobis_n << "\n";
  // 50 scenes: the RMS of a normal sample scatters by ~10%: 0.7-1.4 is 3 sigma.
  EXPECT_GT(rms_joint / u_joint, 0.7);
  EXPECT_LT(rms_joint / u_joint, 1.4);
  EXPECT_GT(mahalanobis, 0.85);
  EXPECT_LT(mahalanobis, 1.15);
}


// Observations that scatter twice as much as their covariances say: the
// variance factor comes out about 4, and u(s) and the covariances are
// enlarged by it, to what the honest covariances give; without the option
// they would be half that.
TEST(ProjectorAdjust, VarianceFactorEnlargesTheUncertainties) {
  const Scene scene = SmallScene();
  Result<ModuleCalibration> cal = ExactCalibration(*scene.module);
  ASSERT_TRUE(cal.ok());
  const test::ProjectorLabCase c = test::MakeProjectorLabCase(scene, *cal, 0.1, 0.15, 7);
  ProjectorAdjustmentOptions options;
  options.datum_point_sets = c.datum_sets;
  options.unscaled_datum_length = 1500.0;
  Result<ProjectorAdjustmentResult> honest = ProjectorAdjust(c.start, options);
  ASSERT_TRUE(honest.ok()) << honest.status().ToString();
  ASSERT_GT(honest->u_scale_factor, 0.0) << honest->covariance_method;

  ProjectorAdjustmentData claimed = c.start;  // the same pixels, covariances 4x too small
  for (BundleObservation& o : claimed.bundle.observations) o.covariance_px2 /= 4.0;
  for (ProjectorSpot& spot : claimed.spots) {
    for (ProjectorSpotObservation& o : spot.observations) o.covariance_px2 /= 4.0;
  }
  Result<ProjectorAdjustmentResult> scaled = ProjectorAdjust(claimed, options);
  ASSERT_TRUE(scaled.ok()) << scaled.status().ToString();
  EXPECT_NEAR(scaled->variance_factor, 4.0 * honest->variance_factor, 1e-6 * scaled->variance_factor);
  EXPECT_GT(scaled->variance_factor, 1.0);
  EXPECT_NE(scaled->covariance_method.find("scaled by the variance factor"), std::string::npos);
  const double expected = honest->u_scale_factor * std::sqrt(scaled->variance_factor / 4.0) /
                          std::sqrt(std::max(1.0, honest->variance_factor));
  EXPECT_NEAR(scaled->u_scale_factor, expected, 1e-6 * expected);
  EXPECT_NEAR(scaled->scale_factor, honest->scale_factor, 1e-9 * honest->scale_factor);
  const Eigen::Matrix3d ratio = scaled->point_covariances_mm2[5].cwiseQuotient(honest->point_covariances_mm2[5]);
  EXPECT_NEAR(ratio(0, 0), scaled->variance_factor / 4.0 / std::max(1.0, honest->variance_factor), 1e-6);

  ProjectorAdjustmentOptions unscaled = options;
  unscaled.scale_by_variance_factor = false;
  Result<ProjectorAdjustmentResult> raw = ProjectorAdjust(claimed, unscaled);
  ASSERT_TRUE(raw.ok());
  EXPECT_NEAR(raw->u_scale_factor, scaled->u_scale_factor / std::sqrt(scaled->variance_factor),
              1e-6 * raw->u_scale_factor);
}

// The calibration as a prior. With the separation's u(L) > 0 the module's
// length factor lambda is free under it; the photographs say nothing about
// it (the scene's scale and the module's trade exactly), so its posterior
// u equals the prior's u(L) / L and u(s)^2 grows by (s u(L) / L)^2. With
// beam and source-rotation covariances those blocks are free under their
// priors: noise-free observations leave them at the calibration and s exact,
// and u(s) can only grow.
TEST(ProjectorAdjust, CalibrationPriorEntersTheUncertainty) {
  const Scene scene = SmallScene();
  Result<ModuleCalibration> exact = ExactCalibration(*scene.module);
  ASSERT_TRUE(exact.ok());
  const test::ProjectorLabCase c = test::MakeProjectorLabCase(scene, *exact, 0.0, 0.0, 2);
  const std::array<Eigen::Vector3d, 3> abc = DatumPoints(c.truth.bundle, c.datum_sets);
  ProjectorAdjustmentOptions options;
  options.datum_point_sets = c.datum_sets;
  options.unscaled_datum_length = (abc[1] - abc[0]).norm();
  // The observations' covariances are nominal (0.1 px): u(s) is what they imply.
  Result<ProjectorAdjustmentResult> held = ProjectorAdjust(c.start, options);
  ASSERT_TRUE(held.ok()) << held.status().ToString();
  ASSERT_GT(held->u_scale_factor, 0.0);

  ProjectorAdjustmentData with_prior = c.start;
  ASSERT_EQ(with_prior.calibration.separations.size(), 1u);
  Separation& sep = with_prior.calibration.separations[0];
  sep.u_length_mm = 0.02;
  const double rel = sep.u_length_mm / sep.length_mm;
  Result<ProjectorAdjustmentResult> free_length = ProjectorAdjust(with_prior, options);
  ASSERT_TRUE(free_length.ok()) << free_length.status().ToString();
  EXPECT_TRUE(free_length->free_module_length);
  EXPECT_NEAR(free_length->module_length_factor, 1.0, 1e-9);
  EXPECT_NEAR(free_length->u_module_length_factor / rel, 1.0, 1e-6);
  const double expected = std::hypot(held->u_scale_factor, free_length->scale_factor * rel);
  std::cout << "u(s): held " << held->u_scale_factor << ", with u(L)/L = " << rel << ": "
            << free_length->u_scale_factor << " (expected " << expected << ")\n";
  EXPECT_NEAR(free_length->u_scale_factor / expected, 1.0, 1e-6);

  // Beams and source rotations under priors of 50 urad.
  for (SourceCalibration& src : with_prior.calibration.sources) {
    std::vector<Beam> beams = src.pattern.beams();
    for (Beam& b : beams) b.cov_azel_rad2 = Eigen::Matrix2d::Identity() * 2.5e-9;
    Result<BeamPattern> pattern = BeamPattern::Create(src.pattern.beams_per_side(), beams);
    ASSERT_TRUE(pattern.ok());
    src.pattern = *pattern;
    SourceCalibrationQuality q;
    q.rotation_xyz_cov_rad2 = Eigen::Matrix3d::Identity() * 2.5e-9;
    src.quality = q;
  }
  Result<ProjectorAdjustmentResult> all = ProjectorAdjust(with_prior, options);
  ASSERT_TRUE(all.ok()) << all.status().ToString();
  std::cout << all->Report();
  EXPECT_EQ(all->free_beams, static_cast<int>(c.truth.spots.size()));
  EXPECT_EQ(all->free_source_rotations, 2);
  EXPECT_LT(std::abs(all->scale_factor - 1.0), 1e-9);
  EXPECT_GT(all->u_scale_factor, free_length->u_scale_factor);
  ASSERT_FALSE(all->point_covariances_mm2.empty()) << all->covariance_method;
}


// Several placements in one adjustment (issue 20's API): the module shown
// at two places (the second 300 mm to the side and turned 8 deg), one pose
// each, the calibration shared. Noise-free: both poses exact; noisy: u(s)
// below the one placement's (more spots, two baselines' directions).
TEST(ProjectorAdjust, TwoPlacementsInOneAdjustment) {
  const Scene scene = SmallScene();
  Result<ModuleCalibration> cal = ExactCalibration(*scene.module);
  ASSERT_TRUE(cal.ok());
  const Rigid3d move(Eigen::Quaterniond(Eigen::AngleAxisd(8.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ())),
                     Eigen::Vector3d(0.0, 300.0, 0.0));
  const test::ProjectorLabCase c = test::MakeProjectorLabCase(scene, *cal, 0.0, 0.0, 3, {move});
  ASSERT_EQ(c.truth.placements.size(), 2u);
  int second = 0;
  for (const ProjectorSpot& s : c.truth.spots) second += s.placement == 1 ? 1 : 0;
  ASSERT_GT(second, 100);
  const std::array<Eigen::Vector3d, 3> abc = DatumPoints(c.truth.bundle, c.datum_sets);
  ProjectorAdjustmentOptions options;
  options.datum_point_sets = c.datum_sets;
  options.unscaled_datum_length = (abc[1] - abc[0]).norm();
  Result<ProjectorAdjustmentResult> r = ProjectorAdjust(c.start, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const Result<Rigid3d> frame = SceneFromThreePoints(abc[0], abc[1], abc[2]);
  ASSERT_TRUE(frame.ok());
  for (size_t m = 0; m < 2; ++m) {
    const Rigid3d truth = *frame * c.truth.placements[m].scene_from_module;
    EXPECT_LT((r->scene_from_module[m].translation - truth.translation).norm(), 1e-6) << m;
    EXPECT_LT(Eigen::AngleAxisd(r->scene_from_module[m].rotation * truth.rotation.conjugate()).angle(), 1e-9) << m;
  }
  EXPECT_LT(std::abs(r->scale_factor - 1.0), 1e-9);
  // Nominal covariances (0.1 px): u(s) with both placements against the first alone.
  ProjectorAdjustmentData first = c.start;
  first.placements.resize(1);
  first.spots.erase(std::remove_if(first.spots.begin(), first.spots.end(),
                                   [](const ProjectorSpot& s) { return s.placement != 0; }),
                    first.spots.end());
  Result<ProjectorAdjustmentResult> one = ProjectorAdjust(first, options);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  std::cout << "u(s): one placement " << one->u_scale_factor << " (" << first.spots.size()
            << " spots), two " << r->u_scale_factor << " (" << c.start.spots.size() << " spots)\n";
  EXPECT_LT(r->u_scale_factor, 0.9 * one->u_scale_factor);
  ASSERT_EQ(r->module_origin_covariances_mm2.size(), 2u);
}


TEST(ProjectorAdjust, BadSpotsNameTheSpotAndTheField) {
  const Scene scene = SmallScene();
  Result<ModuleCalibration> cal = ExactCalibration(*scene.module);
  ASSERT_TRUE(cal.ok());
  const test::ProjectorLabCase c = test::MakeProjectorLabCase(scene, *cal, 0.0, 0.0, 4);
  ProjectorAdjustmentOptions options;
  options.datum_point_sets = c.datum_sets;
  auto message = [&](const ProjectorAdjustmentData& d) {
    Result<ProjectorAdjustmentResult> r = ProjectorAdjust(d, options);
    return r.ok() ? std::string("ok") : r.status().message();
  };
  ProjectorAdjustmentData d = c.start;
  d.spots.push_back(d.spots[3]);
  EXPECT_EQ(message(d), "projector adjustment: spots[" + std::to_string(d.spots.size() - 1) +
                            "]: source '" + d.spots[3].source + "' beam " +
                            std::to_string(d.spots[3].beam_id) + " at placement 0 again (spots[3] has it)");
  d = c.start;
  d.spots[5].beam_id = 999;
  EXPECT_EQ(message(d), "projector adjustment: spots[5].beam_id 999 is not a beam of source '" +
                            d.spots[5].source + "'");
  d = c.start;
  d.spots[2].observations[0].camera = 17;
  EXPECT_EQ(message(d), "projector adjustment: spots[2].observations[0].camera 17 is not a camera index");
  d = c.start;
  d.spots[1].placement = 1;
  EXPECT_EQ(message(d), "projector adjustment: spots[1].placement 1 is not a placement index");
  d = c.start;
  d.bundle.intrinsics[0].constant = false;
  EXPECT_EQ(message(d), "projector adjustment: bundle.intrinsics[0].constant is false: the intrinsics "
                        "are held (calibrated cameras)");
}

}  // namespace
}  // namespace opl
