// FrontEndOptions::scale_in_adjustment on rendered photographs of the
// virtual lab (examples/scene_small.json, noise-free render): the projector
// adjustment started from the two-step solution gives s in agreement with
// the true scale (found independently: the identified spots fitted to their
// true points, tests/support/lab_truth.h) and with the two-step s, and
// cameras and tags in millimetres. Rendering and detection are not exact
// (spot light integrated per pixel: the two-step s is within 2e-5 of the
// truth), so exactness to 1e-6 is shown on exact observations instead
// (tests/pipeline/projector_lab_test.cc).
#include <cmath>
#include <iostream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "opl/io/scene_json.h"
#include "opl/pipeline/measure_images.h"
#include "opl/pipeline/projector_measure.h"
#include "opl/sim/module_design.h"
#include "opl/vision/scene_frame.h"
#include "support/lab_truth.h"
#include "support/scene_images.h"

namespace opl {
namespace {

TEST(ScaleInAdjustment, NoiseFreeRenderAgreesWithTheTruthAndTheTwoStepPath) {
  Result<Scene> read = ReadSceneJson(test::SourceDir() + "/examples/scene_small.json");
  ASSERT_TRUE(read.ok());
  Scene scene = *read;
  scene.image.read_noise = 0.0;
  scene.image.gain_e_per_dn = 0.0;
  scene.image.bit_depth = 16;
  scene.spots.speckle_contrast = 0.0;
  const std::filesystem::path dir = test::FreshTempDir("projector_measure_clean");
  Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
  ASSERT_TRUE(truth.ok());
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ASSERT_TRUE(calibration.ok());
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  Result<ImageMeasureReport> report = MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_TRUE(report->projector.has_value());
  const ProjectorAdjustmentResult& p = *report->projector;
  std::cout << p.Report();
  const test::TruthFit fit = test::FitToTruth(*report, *truth);
  const double s_two = report->measure.scale.scale_factor;
  std::cout.precision(10);
  std::cout << "true s " << fit.scale << "; two-step " << s_two << " +- "
            << report->measure.scale.u_scale_factor << "; in the adjustment " << p.scale_factor
            << " +- " << p.u_scale_factor << "\n";
  EXPECT_LT(std::abs(p.scale_factor / fit.scale - 1.0), 3e-5);
  EXPECT_LT(std::abs(p.scale_factor - s_two), 3.0 * report->measure.scale.u_scale_factor);
  EXPECT_GT(p.u_scale_factor, 0.0);
  EXPECT_LT(p.rms_spot_px, 0.1);

  // Tags in mm: every adjusted tag centre against the truth, in the frame
  // of the frame tags' true centres.
  std::map<int, Eigen::Vector3d> true_centre;
  for (const SceneTagTruth& t : truth->tags()) true_centre[t.id] = t.center_in_scene;
  const std::array<int, 3>& f = report->front_end.frame_tags;
  Result<Rigid3d> frame = SceneFromThreePoints(true_centre[f[0]], true_centre[f[1]], true_centre[f[2]]);
  ASSERT_TRUE(frame.ok());
  ProjectorAdjustmentOptions unused;
  Result<ProjectorAdjustmentData> data = ProjectorDataFromTwoStep(*report, *calibration, &unused);
  ASSERT_TRUE(data.ok());
  double worst = 0.0;
  int tags = 0;
  for (const auto& [id, first] : report->front_end.tag_first_point) {
    (void)first;
    // The adjusted points are the data's in order: find this tag's corners
    // by their position (the start is the two-step's, scaled).
    Eigen::Vector3d start_centre = report->front_end.tag_centers.at(id) * s_two;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    int n = 0;
    for (size_t j = 0; j < data->bundle.points.size(); ++j) {
      const Eigen::Vector3d& x = data->bundle.points[j].point_in_scene;
      if ((x - start_centre).norm() < 0.75 * scene.tags.size_mm) {
        centre += p.bundle.points[j].point_in_scene;
        ++n;
      }
    }
    if (n != 4) continue;
    worst = std::max(worst, (centre / 4.0 - *frame * true_centre[id]).norm());
    ++tags;
  }
  std::cout << tags << " tags; worst tag centre error " << worst << " mm\n";
  EXPECT_GE(tags, 6);
  EXPECT_LT(worst, 0.1);
  const nlohmann::json doc = nlohmann::json::parse(report->ToJson());
  EXPECT_DOUBLE_EQ(doc.at("projector").at("scale_factor").get<double>(), p.scale_factor);
  // The reported s is the adjustment's.
  EXPECT_EQ(report->scale_method, ScaleMethod::kAdjustment);
  EXPECT_EQ(report->scale_factor, p.scale_factor);
  EXPECT_EQ(report->u_scale_factor, p.u_scale_factor);
  EXPECT_EQ(doc.at("scale_method").get<std::string>(), "adjustment");
  EXPECT_TRUE(report->projector_status.ok());
  EXPECT_EQ(report->front_end.warnings.size(), 0u);

  // Fallbacks on the same front end. Not asked for: the two-step s, said so.
  ImageMeasureOptions off = options;
  off.front_end.scale_in_adjustment = false;
  Result<ImageMeasureReport> two_step = MeasureScaleFromFrontEnd(report->front_end, *calibration, off);
  ASSERT_TRUE(two_step.ok()) << two_step.status().ToString();
  EXPECT_FALSE(two_step->projector.has_value());
  EXPECT_EQ(two_step->scale_method, ScaleMethod::kTwoStep);
  EXPECT_EQ(two_step->scale_factor, s_two);
  EXPECT_EQ(two_step->u_scale_factor, report->measure.scale.u_scale_factor);
  EXPECT_THAT(two_step->scale_method_note, ::testing::HasSubstr("not asked for"));
  // Failed (a frame tag's corners missing from the kept adjustment): the
  // two-step s, the error in the note and as a warning, not a failed run.
  FrontEndResult broken = report->front_end;
  broken.tag_first_point.erase(broken.frame_tags[1]);
  Result<ImageMeasureReport> fallback = MeasureScaleFromFrontEnd(broken, *calibration, options);
  ASSERT_TRUE(fallback.ok()) << fallback.status().ToString();
  EXPECT_FALSE(fallback->projector.has_value());
  EXPECT_EQ(fallback->scale_method, ScaleMethod::kTwoStep);
  EXPECT_EQ(fallback->scale_factor, s_two);
  EXPECT_FALSE(fallback->projector_status.ok());
  EXPECT_THAT(fallback->scale_method_note,
              ::testing::HasSubstr("the scale inside the adjustment failed (scale_in_adjustment: frame tag " +
                                   std::to_string(broken.frame_tags[1])));
  ASSERT_EQ(fallback->front_end.warnings.size(), 1u);
  EXPECT_THAT(fallback->front_end.warnings[0], ::testing::HasSubstr("; s is the two-step s"));
  EXPECT_THAT(fallback->ToText(), ::testing::HasSubstr("Result: s = " + FormatPrintf("%.9f", s_two) +
                                                       " +- "));
  std::filesystem::remove_all(dir);
}


// Speckled, noisy renders (the scene's own noise and speckle, seeds 1-N):
// the scale inside the adjustment against the two-step path on the same
// photographs. The true s of each run: the frame tags' true centre distance
// over their distance in the run's unscaled frame (what both paths' s
// multiply). Figures printed; each error within 4 u.
TEST(ScaleInAdjustment, NoisyRendersSideBySideWithTheTwoStepPath) {
  Result<Scene> read = ReadSceneJson(test::SourceDir() + "/examples/scene_small.json");
  ASSERT_TRUE(read.ok());
  Result<ModuleCalibration> calibration = ExactCalibration(*read->module);
  ASSERT_TRUE(calibration.ok());
  const int runs = 6;
  double e2_joint = 0.0, e2_two = 0.0, u_joint = 0.0, u_two = 0.0;
  for (int seed = 1; seed <= runs; ++seed) {
    Scene scene = *read;
    scene.seed = static_cast<uint64_t>(seed);
    const std::filesystem::path dir = test::FreshTempDir("projector_measure_noisy");
    Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
    ASSERT_TRUE(truth.ok());
    ImageMeasureOptions options;
    options.front_end.num_threads = 2;
      Result<ImageMeasureReport> report = MeasureScaleFromImages(scene, dir.string(), *calibration, options);
    std::filesystem::remove_all(dir);
    ASSERT_TRUE(report.ok()) << report.status().ToString();
    ASSERT_TRUE(report->projector.has_value());
    std::map<int, Eigen::Vector3d> centre;
    for (const SceneTagTruth& t : truth->tags()) centre[t.id] = t.center_in_scene;
    const std::array<int, 3>& f = report->front_end.frame_tags;
    const double unscaled = (report->front_end.tag_centers.at(f[1]) - report->front_end.tag_centers.at(f[0])).norm();
    const double s_true = (centre[f[1]] - centre[f[0]]).norm() / unscaled;
    const double ej = report->projector->scale_factor / s_true - 1.0;
    const double et = report->measure.scale.scale_factor / s_true - 1.0;
    const double uj = report->projector->u_scale_factor / s_true;
    const double ut = report->measure.scale.u_scale_factor / s_true;
    std::cout << "seed " << seed << ": in the adjustment " << ej << " +- " << uj << "; two-step " << et
              << " +- " << ut << " (relative)\n";
    EXPECT_LT(std::abs(ej), 4.0 * uj) << "seed " << seed;
    EXPECT_LT(std::abs(et), 4.0 * ut) << "seed " << seed;
    e2_joint += ej * ej;
    e2_two += et * et;
    u_joint += uj;
    u_two += ut;
  }
  std::cout << runs << " noisy renders: in the adjustment RMS error " << std::sqrt(e2_joint / runs)
            << ", mean u(s) " << u_joint / runs << "; two-step RMS error " << std::sqrt(e2_two / runs)
            << ", mean u(s) " << u_two / runs << " (relative to s)\n";
}

}  // namespace
}  // namespace opl
