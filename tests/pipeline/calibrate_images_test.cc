// From rendered photographs of a calibration session to a module calibration,
// against the truth of the virtual lab (examples/calibration_session_small.json:
// three 1024 x 768 cameras, tags on the floor and the side walls, the
// prototype-like module of two 11 x 11 grids 55 mm apart with a fabricated
// 0.3 mrad DOE error, a screen at 0.9, 1.2 and 1.5 m; each grid on each screen
// position shot by every camera: 18 images).
//
// Independent truths:
//  - the separation: the design's origins are 55 mm apart;
//  - every beam's direction: the design's fabricated pattern (MakePattern of
//    the design's source, the pattern the renderer throws);
//  - the scale of the measured frame: a similarity fit (Umeyama) of the front
//    end's tag centres onto the renderer's true tag centres gives the true mm
//    per scene unit, which the artifact's scale must equal; the nominal tag
//    size is the true one, so both are also 1 within the artifact's
//    uncertainty.
#include "opl/pipeline/calibrate_images.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/sim/module_design.h"
#include "support/scene_images.h"

namespace opl {
namespace {

using test::FreshTempDir;
using test::SourceDir;

Scene SessionScene() {
  Result<Scene> scene =
      ReadSceneJson(SourceDir() + "/examples/calibration_session_small.json");
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  return std::move(scene).value();
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// The true mm per scene unit of the measured frame: the similarity that maps
// the front end's tag centres onto the true ones.
double TrueFrameScale(const FrontEndResult& front_end, const SceneRenderer& truth,
                      int* num_tags) {
  std::vector<Eigen::Vector3d> measured, truths;
  for (const SceneTagTruth& t : truth.tags()) {
    const auto found = front_end.tag_centers.find(t.id);
    if (found == front_end.tag_centers.end()) continue;
    measured.push_back(found->second);
    truths.push_back(t.center_in_scene);
  }
  *num_tags = static_cast<int>(measured.size());
  if (measured.size() < 4) return 0.0;
  Eigen::Matrix3Xd src(3, *num_tags), dst(3, *num_tags);
  for (int i = 0; i < *num_tags; ++i) {
    src.col(i) = measured[static_cast<size_t>(i)];
    dst.col(i) = truths[static_cast<size_t>(i)];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
  return t.topLeftCorner<3, 3>().col(0).norm();
}

TEST(CalibrateFromImages, NoiseFreeSessionGivesTheTrueModule) {
  Scene scene = SessionScene();
  // Noise-free: no sensor noise, no speckle, 16 bit.
  scene.image.read_noise = 0.0;
  scene.image.gain_e_per_dn = 0.0;
  scene.image.bit_depth = 16;
  scene.spots.speckle_contrast = 0.0;
  ASSERT_TRUE(scene.module.has_value());
  const ModuleDesign& design = *scene.module;
  const std::filesystem::path dir = FreshTempDir("calibrate_images_clean");

  auto start = std::chrono::steady_clock::now();
  Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();
  const double render_s = Seconds(start);

  Result<ModuleCalibration> nominal = ExactCalibration(design);
  ASSERT_TRUE(nominal.ok()) << nominal.status().ToString();
  ImageCalibrationOptions options;
  options.front_end.num_threads = 2;
  start = std::chrono::steady_clock::now();
  Result<ImageCalibrationReport> report =
      CalibrateFromImages(scene, dir.string(), *nominal, options);
  const double calibrate_s = Seconds(start);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  std::cout << report->ToText();
  std::printf("render %.2f s, calibrate from images %.2f s (%zu images)\n", render_s,
              calibrate_s, scene.shots.size());

  // Per image: every image placed, its tags and spots fitted to a small
  // fraction of a pixel (noise-free renders).
  ASSERT_EQ(report->front_end.images.size(), scene.shots.size());
  for (const ImageFindings& f : report->front_end.images) {
    EXPECT_TRUE(f.placed) << f.file;
    EXPECT_GE(f.tag_ids.size(), 8u) << f.file;
    EXPECT_GE(f.spots_matched, 110) << f.file;
    EXPECT_LT(f.tag_rms_px, 0.1) << f.file;
    EXPECT_LT(f.spot_rms_px, 0.1) << f.file;
  }
  // One exposure group per (laser, slice), each identified as its laser.
  ASSERT_EQ(report->front_end.groups.size(), 6u);
  ASSERT_EQ(report->identification.per_slice.size(), 6u);
  for (const SliceIdentification& s : report->identification.per_slice) {
    const ExposureGroup& g = report->front_end.groups[static_cast<size_t>(s.slice)];
    ASSERT_EQ(g.lasers.size(), 1u);
    EXPECT_EQ(s.source, g.lasers[0]) << "group " << s.slice << ": " << s.detail;
    EXPECT_GE(s.assigned, 115) << "group " << s.slice;
  }

  // Scale: the artifact's against the frame's true scale (tag centres fitted
  // to the truth), and 1 within the artifact's uncertainty.
  int fitted_tags = 0;
  const double true_scale = TrueFrameScale(report->front_end, *truth, &fitted_tags);
  const CalibrationScaling& scaling = report->scaling;
  std::printf("artifact scale %.9f (u_rel %.2e); true frame scale %.9f from %d tags\n",
              scaling.scale, scaling.u_scale_relative, true_scale, fitted_tags);
  EXPECT_GE(fitted_tags, 20);
  EXPECT_GT(scaling.u_scale_relative, 0.0);
  EXPECT_LT(scaling.u_scale_relative, 1e-4);
  EXPECT_LT(std::abs(scaling.scale / true_scale - 1.0), 3.0 * scaling.u_scale_relative);
  EXPECT_LT(std::abs(scaling.scale - 1.0), 3.0 * scaling.u_scale_relative);

  // Separation A-B against the design's 55 mm.
  const ModuleCalibration& calibration = report->calibration.calibration;
  ASSERT_EQ(calibration.separations.size(), 1u);
  const Separation& sep = calibration.separations[0];
  const double true_length = (design.sources[0].scene_from_source.translation -
                              design.sources[1].scene_from_source.translation)
                                 .norm();
  EXPECT_NEAR(true_length, 55.0, 1e-12);
  std::printf("separation %.5f mm +- %.5f mm (true %.3f mm): error %.5f mm\n", sep.length_mm,
              sep.u_length_mm, true_length, sep.length_mm - true_length);
  EXPECT_LT(std::abs(sep.length_mm - true_length), 3.0 * sep.u_length_mm);
  EXPECT_LT(std::abs(sep.length_mm - true_length), 0.02);
  EXPECT_LT(sep.u_length_mm, 0.05);
  // Its u carries the errors the spots share (camera poses, datum tags):
  // 9 + 6 components per image.
  EXPECT_EQ(report->shared.components, 9 + 6 * static_cast<int>(scene.shots.size()));
  ASSERT_EQ(report->shared.u_separation_shared_mm.size(), 1u);
  EXPECT_GT(report->shared.u_separation_shared_mm[0], 0.2 * report->shared.u_separation_own_mm[0]);
  EXPECT_NEAR(sep.u_length_mm,
              std::hypot(report->shared.u_separation_own_mm[0],
                         report->shared.u_separation_shared_mm[0]),
              1e-12);

  // Every beam's direction against the fabricated pattern, microradians.
  for (const SourceDesign& source : design.sources) {
    Result<BeamPattern> fabricated = MakePattern(source);
    ASSERT_TRUE(fabricated.ok());
    const SourceCalibration* calibrated = calibration.FindSource(source.name);
    ASSERT_NE(calibrated, nullptr) << source.name;
    EXPECT_EQ(calibrated->pattern.beams().size(), 121u) << source.name;
    double sum2 = 0.0, worst = 0.0;
    for (const Beam& beam : calibrated->pattern.beams()) {
      ASSERT_NE(fabricated->Find(beam.id), nullptr);
      const double angle_urad =
          1e6 * std::acos(std::min(1.0, calibrated->pattern.DirectionInSource(beam.id).dot(
                                            fabricated->DirectionInSource(beam.id))));
      sum2 += angle_urad * angle_urad;
      worst = std::max(worst, angle_urad);
    }
    const double rms = std::sqrt(sum2 / static_cast<double>(calibrated->pattern.beams().size()));
    std::printf("source %s: beam directions vs the fabricated pattern: RMS %.1f urad, max %.1f "
                "urad (fabrication error 300 urad)\n",
                source.name.c_str(), rms, worst);
    EXPECT_LT(rms, 5.0) << source.name;
    EXPECT_LT(worst, 10.0) << source.name;
    // The origin in the scene frame (the frame tags define the design's frame).
    const Eigen::Vector3d origin_error =
        calibrated->calibration_from_source.translation - source.scene_from_source.translation;
    std::printf("source %s: origin error %.3f mm\n", source.name.c_str(), origin_error.norm());
    EXPECT_LT(origin_error.norm(), 0.5) << source.name;
  }

  // The same images with one pose per camera (the cameras did not move):
  // 9 + 6 per camera shared components, the same module, a smaller u.
  ImageCalibrationOptions per_camera = options;
  per_camera.front_end.one_pose_per_camera = true;
  Result<ImageCalibrationReport> fixed = CalibrateFromImages(scene, dir.string(), *nominal, per_camera);
  ASSERT_TRUE(fixed.ok()) << fixed.status().ToString();
  EXPECT_EQ(fixed->shared.components, 9 + 6 * static_cast<int>(scene.cameras.size()));
  const Separation& fixed_sep = fixed->calibration.calibration.separations[0];
  std::printf("one pose per camera: separation %.5f mm +- %.5f mm (own %.5f, shared %.5f)\n",
              fixed_sep.length_mm, fixed_sep.u_length_mm, fixed->shared.u_separation_own_mm[0],
              fixed->shared.u_separation_shared_mm[0]);
  EXPECT_LT(std::abs(fixed_sep.length_mm - true_length), 0.02);
  EXPECT_LT(std::abs(fixed_sep.length_mm - true_length), 3.0 * fixed_sep.u_length_mm);
  EXPECT_LT(fixed->shared.u_separation_shared_mm[0], 0.6 * report->shared.u_separation_shared_mm[0]);
  for (const ImageFindings& f : fixed->front_end.images) {
    EXPECT_TRUE(f.placed) << f.file;
    EXPECT_LT(f.tag_rms_px, 0.1) << f.file;
    EXPECT_LT(f.spot_rms_px, 0.1) << f.file;
  }
  // A camera that "moved": cam1's shots relabelled as cam0's (cameras 1.8 m
  // apart) are refused, naming the camera and two of its shots.
  Scene moved = scene;
  for (SceneShot& shot : moved.shots) {
    if (shot.camera == "cam1") shot.camera = "cam0";
  }
  Result<ImageCalibrationReport> refused = CalibrateFromImages(moved, dir.string(), *nominal, per_camera);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("camera 'cam0' moved between shots s0_A_cam0.png and "
                                            "s0_A_cam1.png"),
            std::string::npos)
      << refused.status().message();
  std::filesystem::remove_all(dir);
}

TEST(CalibrateFromImages, ASceneWithoutArtifactIsRefused) {
  Scene scene = SessionScene();
  scene.artifact.reset();
  Result<ModuleCalibration> nominal = ExactCalibration(*scene.module);
  ASSERT_TRUE(nominal.ok());
  // Checked before any image is read: the folder does not exist.
  Result<ImageCalibrationReport> r =
      CalibrateFromImages(scene, "/nonexistent/opl_calibrate_images", *nominal);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(),
            "scene: no 'artifact': a calibration session needs the scale artifact's two tags");
}

}  // namespace
}  // namespace opl
