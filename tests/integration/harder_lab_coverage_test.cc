// Coverage of u(s) in the harder virtual lab (issue 17, "Figures"): the
// small scene of examples/scene_clutter.json (colour JPEG 90 through an RGB
// sensor, a photograph of fruit as the wall, an ambient ramp, vignetting,
// defocus, 40 distractors per camera, speckle, shot and read noise, and one
// laser-off shot per camera). For every seed k the scene is rendered anew
// (new speckle, noise and distractors, and the module placed anew: see
// PlaceModuleForSeed), measured from its images with the exact calibration
// (dark frames subtracted, the default), and judged
// against the renderer's truth, independently of the pipeline:
//   - z_k = (s_k - s_true,k) / u(s_k), s_true the scale of the similarity
//     (Umeyama) from the identified 3D spots to their true points;
//   - wrong assignments: identified spots farther than 5 mm from their
//     beam's true point after that similarity;
//   - spot recall and false spots per image against the truth's pixels.
// A second, noise-free geometry run (no speckle, no sensor noise; JPEG 90
// and the rest kept) checks s against the truth to 1e-4.
//
// N = 8 scenes in ctest (about 9 s each on 2 cores; label no_sanitizer);
// OPL_HARDER_LAB_SCENES=<N> (and OPL_HARDER_LAB_FIRST_SEED) by hand, e.g.
// the 200 of docs/images.md ("Measured: the harder lab").
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "integration/harder_lab_scene.h"
#include "support/lab_truth.h"
#include "support/scene_images.h"

namespace opl {
namespace {

using test::SourceDir;

int EnvInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && std::atoi(v) >= 1 ? std::atoi(v) : fallback;
}

using test::ClutterScene;
using test::PlaceModuleForSeed;

struct Outcome {
  uint64_t seed = 0;
  bool measured = false;
  std::string error;
  double s = 0.0, u = 0.0, s_true = 0.0, z = 0.0;
  // The scale inside the adjustment (FrontEndOptions::scale_in_adjustment),
  // judged against the same truth.
  bool projector = false;
  double s_projector = 0.0, u_projector = 0.0, z_projector = 0.0;
  int identified = 0, wrong = 0;
  int visible = 0, found = 0, false_spots = 0;
  int warnings = 0;
  int sources = 0, lengths = 0;  // located sources, lengths of s
  bool lossy_jpeg_warning = false;
  double seconds = 0.0;
};

Outcome MeasureSeed(const Scene& base, uint64_t seed) {
  const auto start = std::chrono::steady_clock::now();
  Outcome out;
  out.seed = seed;
  Scene scene = base;
  scene.seed = seed;
  PlaceModuleForSeed(scene, seed);
  const std::filesystem::path dir = test::FreshTempDir("harder_lab_" + std::to_string(seed));
  Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
  if (!truth.ok()) {
    out.error = truth.status().ToString();
    return out;
  }
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;  // the scale inside the adjustment: the default
  Result<ImageMeasureReport> report =
      MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  std::filesystem::remove_all(dir);
  if (!report.ok()) {
    out.error = report.status().ToString();
    return out;
  }
  out.measured = true;
  out.warnings = static_cast<int>(report->front_end.warnings.size());
  for (const std::string& w : report->front_end.warnings) {
    out.lossy_jpeg_warning = out.lossy_jpeg_warning || w.find("lossy JPEG") != std::string::npos;
  }
  const test::TruthFit fit = test::FitToTruth(*report, *truth);
  out.identified = fit.points;
  out.wrong = fit.wrong;
  out.s_true = fit.scale;
  out.sources = static_cast<int>(report->measure.sources.size());
  out.lengths = static_cast<int>(report->measure.scale.lengths.size());
  out.s = report->measure.scale.scale_factor;
  out.u = report->measure.scale.u_scale_factor;
  out.z = out.u > 0.0 && fit.points >= 4 ? (out.s - out.s_true) / out.u : 0.0;
  if (report->projector && report->projector->u_scale_factor > 0.0 && fit.points >= 4) {
    out.projector = true;
    out.s_projector = report->projector->scale_factor;
    out.u_projector = report->projector->u_scale_factor;
    out.z_projector = (out.s_projector - out.s_true) / out.u_projector;
  }
  const test::SpotCounts counts = test::CountSpots(*truth, *report);
  out.visible = counts.visible;
  out.found = counts.found;
  out.false_spots = counts.false_spots;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

TEST(HarderLabCoverage, ScaleWithinItsUncertaintyAndNoWrongSpot) {
  const Scene scene = ClutterScene();
  ASSERT_FALSE(scene.shots.empty());
  const int n = EnvInt("OPL_HARDER_LAB_SCENES", 8);
  const int first = EnvInt("OPL_HARDER_LAB_FIRST_SEED", 1);
  int measured = 0, within = 0, wrong = 0, visible = 0, found = 0, false_spots = 0;
  int projector = 0, projector_within = 0;
  double sum_z2 = 0.0, seconds = 0.0, sum_zp2 = 0.0;
  for (int k = first; k < first + n; ++k) {
    const Outcome o = MeasureSeed(scene, static_cast<uint64_t>(k));
    if (!o.measured) {
      std::printf("seed %d: not measured: %s\n", k, o.error.c_str());
      ADD_FAILURE() << "seed " << k << ": " << o.error;
      continue;
    }
    ++measured;
    within += std::abs(o.z) <= 2.0 ? 1 : 0;
    sum_z2 += o.z * o.z;
    wrong += o.wrong;
    visible += o.visible;
    found += o.found;
    false_spots += o.false_spots;
    seconds += o.seconds;
    if (o.projector) {
      ++projector;
      projector_within += std::abs(o.z_projector) <= 2.0 ? 1 : 0;
      sum_zp2 += o.z_projector * o.z_projector;
    }
    std::printf("seed %d: s %.6f +- %.4f, s_true %.6f, z %+.2f; projector s %.6f +- %.5f, z %+.2f; "
                "%d identified, %d wrong; recall %d/%d, false spots %d; %d warnings; %.1f s\n",
                k, o.s, o.u, o.s_true, o.z, o.s_projector, o.u_projector, o.z_projector,
                o.identified, o.wrong, o.found, o.visible, o.false_spots, o.warnings, o.seconds);
  }
  ASSERT_GE(measured, 2);
  const double rms_z = std::sqrt(sum_z2 / measured);
  std::printf("harder lab, %d of %d scenes measured: |z| <= 2 in %d (%.1f%%), RMS z %.3f; "
              "%d wrong assignments; recall %d/%d (%.2f%%), %d false spots; %.1f s per scene\n",
              measured, n, within, 100.0 * within / measured, rms_z, wrong, found, visible,
              100.0 * found / visible, false_spots, seconds / measured);
  const double rms_zp = projector > 0 ? std::sqrt(sum_zp2 / projector) : 0.0;
  std::printf("  the scale inside the adjustment: %d scenes, |z| <= 2 in %d (%.1f%%), RMS z %.3f\n",
              projector, projector_within, projector > 0 ? 100.0 * projector_within / projector : 0.0,
              rms_zp);
  EXPECT_EQ(measured, n);
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(found, 0.98 * visible);
  EXPECT_LE(false_spots, 2 * 8 * measured);  // 2 per lit image
  // Coverage bounds as tests/integration/images_coverage_test.cc: at least
  // floor(0.75 N) inside 2 u (N = 8: 6; a correct u(s) fails with p = 0.004),
  // and RMS z within [0.5, 1.8].
  EXPECT_GE(within, static_cast<int>(std::floor(0.75 * measured)));
  EXPECT_GE(rms_z, 0.5);
  EXPECT_LE(rms_z, 1.8);
  // The scale inside the adjustment (the reported s) ran on every scene,
  // and is judged by the same bounds: over seeds 131-230 its |z| <= 2 in
  // 95 of 100, RMS z 0.98 (two-step: 94, 1.04; docs/multiview.md).
  EXPECT_EQ(projector, measured);
  EXPECT_GE(projector_within, static_cast<int>(std::floor(0.75 * projector)));
  EXPECT_GE(rms_zp, 0.5);
  EXPECT_LE(rms_zp, 1.8);
}

// The module at two placements (issue 20 item 2) in the harder lab: the
// placements of examples/scene_small_placements.json ('aside': 160 mm left,
// 100 mm up, turned 4 deg) on top of the seed's own placement, every lit
// shot taken at each, the laser-off shots once. Both paths judged against
// the truth as above; each seed's four sources located and its two
// lengths used. N = 2 in ctest; OPL_HARDER_LAB_PLACEMENT_SCENES=<N> by
// hand (docs/multiview.md, "Several placements").
Scene WithTwoPlacements(Scene scene) {
  SceneModulePlacement centre, aside;
  centre.name = "centre";
  aside.name = "aside";
  aside.rotation_deg = Eigen::Vector3d(0.0, 0.0, -4.0);
  aside.translation_mm = Eigen::Vector3d(0.0, 160.0, 100.0);
  scene.module_placements = {centre, aside};
  std::vector<SceneShot> shots;
  for (const SceneModulePlacement& placement : scene.module_placements) {
    for (const SceneShot& shot : scene.shots) {
      if (shot.lasers.empty()) continue;
      SceneShot lit = shot;
      const size_t dot = lit.file.rfind('.');
      lit.file = lit.file.substr(0, dot) + "_" + placement.name + lit.file.substr(dot);
      lit.placement = placement.name;
      shots.push_back(lit);
    }
  }
  for (const SceneShot& shot : scene.shots) {
    if (shot.lasers.empty()) shots.push_back(shot);
  }
  scene.shots = shots;
  return scene;
}

TEST(HarderLabCoverage, ModuleAtTwoPlacements) {
  const Scene scene = WithTwoPlacements(ClutterScene());
  ASSERT_EQ(scene.shots.size(), 20u);
  ASSERT_TRUE(scene.Validate().ok()) << scene.Validate().ToString();
  const int n = EnvInt("OPL_HARDER_LAB_PLACEMENT_SCENES", 2);
  const int first = EnvInt("OPL_HARDER_LAB_FIRST_SEED", 1);
  int measured = 0, within = 0, projector_within = 0, wrong = 0;
  double sum_z2 = 0.0, sum_zp2 = 0.0, sum_u_ratio = 0.0;
  for (int k = first; k < first + n; ++k) {
    const Outcome o = MeasureSeed(scene, static_cast<uint64_t>(k));
    if (!o.measured) {
      ADD_FAILURE() << "seed " << k << ": " << o.error;
      continue;
    }
    ++measured;
    std::printf("two placements, seed %d: s %.6f +- %.4f, z %+.2f; projector s %.6f +- %.5f, z %+.2f; "
                "%d sources, %d lengths; %d identified, %d wrong; recall %d/%d; %.1f s\n",
                k, o.s, o.u, o.z, o.s_projector, o.u_projector, o.z_projector, o.sources, o.lengths,
                o.identified, o.wrong, o.found, o.visible, o.seconds);
    EXPECT_EQ(o.sources, 4) << "seed " << k;
    EXPECT_EQ(o.lengths, 2) << "seed " << k;
    EXPECT_TRUE(o.projector) << "seed " << k;
    EXPECT_GE(o.identified, 2 * 200) << "seed " << k;
    wrong += o.wrong;
    within += std::abs(o.z) <= 2.0 ? 1 : 0;
    projector_within += std::abs(o.z_projector) <= 2.0 ? 1 : 0;
    sum_z2 += o.z * o.z;
    sum_zp2 += o.z_projector * o.z_projector;
    sum_u_ratio += o.u / o.u_projector;
    // Each seed on its own: a correct u passes |z| <= 3 with p = 0.997.
    EXPECT_LE(std::abs(o.z), 3.0) << "seed " << k;
    EXPECT_LE(std::abs(o.z_projector), 3.0) << "seed " << k;
  }
  ASSERT_GE(measured, 1);
  std::printf("two placements in the harder lab, %d of %d scenes: two-step |z| <= 2 in %d, RMS z %.3f; "
              "projector |z| <= 2 in %d, RMS z %.3f; mean u ratio (two-step / projector) %.1f; %d "
              "wrong assignments\n",
              measured, n, within, std::sqrt(sum_z2 / measured), projector_within,
              std::sqrt(sum_zp2 / measured), sum_u_ratio / measured, wrong);
  EXPECT_EQ(measured, n);
  EXPECT_EQ(wrong, 0);
}

// Noise-free geometry (no speckle, no sensor noise), everything else of the
// harder lab kept. Lossless (PNG): s to 1e-4 of the truth. JPEG 90 is not
// noise-free: compression moves each spot centre by ~0.07 px RMS, and s
// follows it within its (then honest) uncertainty.
TEST(HarderLabCoverage, NoiseFreeGeometryGivesTheTrueScale) {
  Scene scene = ClutterScene();
  ASSERT_FALSE(scene.shots.empty());
  scene.spots.speckle_contrast = 0.0;
  scene.image.read_noise = 0.0;
  scene.image.gain_e_per_dn = 0.0;
  const Outcome jpeg = MeasureSeed(scene, 1);
  ASSERT_TRUE(jpeg.measured) << jpeg.error;
  scene.image.format = "png";
  for (SceneShot& shot : scene.shots) shot.file = shot.file.substr(0, shot.file.rfind('.')) + ".png";
  const Outcome png = MeasureSeed(scene, 1);
  ASSERT_TRUE(png.measured) << png.error;
  for (const Outcome* o : {&png, &jpeg}) {
    std::printf("noise-free harder lab, %s: s/s_true - 1 = %.2e (u(s) %.2e, z %+.2f); %d "
                "identified, %d wrong; recall %d/%d, false spots %d\n",
                o == &png ? "PNG" : "JPEG 90", o->s / o->s_true - 1.0, o->u, o->z, o->identified,
                o->wrong, o->found, o->visible, o->false_spots);
    EXPECT_EQ(o->wrong, 0);
    EXPECT_GE(o->identified, 220);
  }
  EXPECT_LT(std::abs(png.s / png.s_true - 1.0), 1e-4);
  EXPECT_LT(std::abs(jpeg.z), 2.0);
}

// JPEG 75: measured with the lossy-JPEG warning and s within its
// uncertainty, or refused with a clear message; never a silent wrong s.
TEST(HarderLabCoverage, Jpeg75WarnsOrIsRefused) {
  Scene scene = ClutterScene();
  ASSERT_FALSE(scene.shots.empty());
  scene.image.jpeg_quality = 75;
  const Outcome o = MeasureSeed(scene, 3);
  if (!o.measured) {
    std::printf("JPEG 75: refused: %s\n", o.error.c_str());
    EXPECT_EQ(o.error.find('\n'), std::string::npos);
    return;
  }
  std::printf("JPEG 75: s/s_true - 1 = %.2e (u(s) %.2e, z %+.2f); %d identified, %d wrong; recall "
              "%d/%d, false spots %d; %d warnings\n",
              o.s / o.s_true - 1.0, o.u, o.z, o.identified, o.wrong, o.found, o.visible,
              o.false_spots, o.warnings);
  EXPECT_TRUE(o.lossy_jpeg_warning);
  EXPECT_EQ(o.wrong, 0);
  EXPECT_LT(std::abs(o.z), 3.0);
}

}  // namespace
}  // namespace opl
