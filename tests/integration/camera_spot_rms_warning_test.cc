// Issue 17: the per-camera spot RMS warning (FrontEndOptions::
// warn_camera_spot_rms_min_px; docs/images.md, "Warnings and the refusal").
//
// The lab: examples/scene_small.json (four cameras, two grids, speckle
// contrast 0.3), written 16 bit without sensor noise so that a shot's spot
// light is exactly its lit image minus its laser-off image. One camera is
// made bad: in both its shots every spot's light is moved by a seeded
// Gaussian offset of sigma 0.35 px per axis (the patch of 5 sigma around the
// spot, resampled bilinearly), the room kept in place, as a camera out of
// focus or shaken would scatter its centroids while its tags stay sharp.
// The truth is known: the offsets are drawn here. Two runs: all cameras
// clean (no camera warning) and cam2 bad (the warning names cam2 and only
// cam2).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "opl/io/atomic_file.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/shot_file.h"
#include "opl/pipeline/image_front_end.h"
#include "support/scene_images.h"

namespace opl {
namespace {

Scene QuietSmallScene() {
  Result<Scene> scene = ReadSceneJson(test::SourceDir() + "/examples/scene_small.json");
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  if (!scene.ok()) return Scene();
  scene->image.bit_depth = 16;
  scene->image.read_noise = 0.0;
  scene->image.gain_e_per_dn = 0.0;
  return *scene;
}

// The image of `lit` with every visible spot's light (lit - dark) moved by
// N(0, sigma_px^2) per axis.
cv::Mat JitterSpots(const RenderedShot& lit, const cv::Mat& dark, double sigma_px,
                    std::mt19937_64& rng) {
  cv::Mat lit_f, dark_f;
  lit.image.convertTo(lit_f, CV_64F);
  dark.convertTo(dark_f, CV_64F);
  const cv::Mat light = lit_f - dark_f;
  cv::Mat moved = cv::Mat::zeros(light.size(), CV_64F);
  std::normal_distribution<double> normal(0.0, sigma_px);
  for (const SpotView& v : lit.spots) {
    if (!v.center_px.allFinite()) continue;
    const Eigen::Matrix2d& c = v.shape_covariance_px2;
    const double half_trace = 0.5 * c.trace();
    const double sigma =  // of the major axis
        std::sqrt(half_trace + std::sqrt(std::max(0.0, half_trace * half_trace - c.determinant())));
    const int half = static_cast<int>(std::ceil(5.0 * sigma)) + 2;
    const cv::Rect patch(static_cast<int>(std::lround(v.center_px.x())) - half,
                         static_cast<int>(std::lround(v.center_px.y())) - half, 2 * half + 1,
                         2 * half + 1);
    const cv::Rect inside = patch & cv::Rect(0, 0, light.cols, light.rows);
    if (inside.area() == 0) continue;
    const double dx = normal(rng), dy = normal(rng);
    const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, dx, 0, 1, dy);
    cv::Mat shifted;
    cv::warpAffine(light(inside), shifted, shift, inside.size(), cv::INTER_LINEAR,
                   cv::BORDER_CONSTANT, cv::Scalar(0));
    moved(inside) += shifted;
  }
  cv::Mat out_f = dark_f + moved, out;
  out_f.convertTo(out, lit.image.type());  // rounds and saturates
  return out;
}

// Renders `scene` into `dir`, the shots of `bad_camera` (if any) with their
// spots jittered, and runs the front end.
Result<FrontEndResult> RunWithBadCamera(const Scene& scene, const std::string& bad_camera,
                                        double sigma_px, const std::filesystem::path& dir) {
  // The renderer's scene: the measured shots, then one laser-off shot per
  // shot of the bad camera (its room without the spots).
  Scene rendered = scene;
  for (const SceneShot& shot : scene.shots) {
    if (shot.camera != bad_camera) continue;
    SceneShot off = shot;
    off.lasers.clear();
    off.file = "off_" + shot.file;
    rendered.shots.push_back(off);
  }
  Result<SceneRenderer> renderer = SceneRenderer::Create(rendered);
  if (!renderer.ok()) return renderer.status();
  std::mt19937_64 rng(17);
  size_t off_index = scene.shots.size();
  for (size_t i = 0; i < scene.shots.size(); ++i) {
    Result<RenderedShot> shot = renderer->RenderShot(static_cast<int>(i));
    if (!shot.ok()) return shot.status();
    cv::Mat image = shot->image;
    if (scene.shots[i].camera == bad_camera) {
      Result<RenderedShot> off = renderer->RenderShot(static_cast<int>(off_index++));
      if (!off.ok()) return off.status();
      image = JitterSpots(*shot, off->image, sigma_px, rng);
    }
    Result<std::string> file = EncodeShotImage(image, scene.image);
    if (!file.ok()) return file.status();
    OPL_RETURN_IF_ERROR(WriteFileAtomically((dir / scene.shots[i].file).string(), *file));
  }
  FrontEndOptions options;
  options.num_threads = 2;
  return RunImageFrontEnd(scene, dir.string(), options);
}

std::vector<std::string> CameraWarnings(const FrontEndResult& result) {
  std::vector<std::string> out;
  for (const std::string& w : result.warnings) {
    std::printf("  warning: %s\n", w.c_str());
    if (w.rfind("camera ", 0) == 0) out.push_back(w);
  }
  return out;
}

void PrintRms(const FrontEndResult& result) {
  for (const ImageFindings& f : result.images) {
    std::printf("  %s: spot RMS %.3f px (model %.3f px), %d of %d spots matched\n", f.file.c_str(),
                f.spot_rms_px, f.spot_model_rms_px, f.spots_matched, f.spots_detected);
  }
}

TEST(CameraSpotRmsWarning, QuietWhenEveryCameraIsClean) {
  const Scene scene = QuietSmallScene();
  ASSERT_FALSE(scene.shots.empty());
  const std::filesystem::path dir = test::FreshTempDir("camera_rms_clean");
  Result<FrontEndResult> result = RunWithBadCamera(scene, "", 0.0, dir);
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  PrintRms(*result);
  EXPECT_TRUE(CameraWarnings(*result).empty());
  for (const ImageFindings& f : result->images) {
    EXPECT_LT(f.spot_rms_px, 0.2) << f.file;  // speckle: ~0.1 px
  }
}

TEST(CameraSpotRmsWarning, NamesTheOneCameraWhoseSpotsScatter) {
  const Scene scene = QuietSmallScene();
  ASSERT_FALSE(scene.shots.empty());
  const std::filesystem::path dir = test::FreshTempDir("camera_rms_bad");
  Result<FrontEndResult> result = RunWithBadCamera(scene, "cam2", 0.35, dir);
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  PrintRms(*result);
  const std::vector<std::string> warnings = CameraWarnings(*result);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].rfind("camera cam2: spot RMS ", 0), 0u) << warnings[0];
  EXPECT_NE(warnings[0].find("over its 2 image(s)"), std::string::npos) << warnings[0];
}

}  // namespace
}  // namespace opl
