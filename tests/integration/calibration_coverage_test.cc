// Coverage of u(separation) of a calibration from noisy photographs.
//
// The session is examples/calibration_session_small.json (three 1024 x 768
// cameras, the prototype-like module of two 11 x 11 grids 55 mm apart, a
// screen at 0.9, 1.2, 1.5 m, 18 shots), rendered as a real camera would take
// it: 8 bit, read noise 0.004, shot noise at 20 e-/DN, speckle contrast 0.1.
// For every seed k = 1 .. N (scene.seed = k: new speckle and sensor noise,
// the same geometry) it is calibrated from the images (CalibrateFromImages)
// and
//   z_k = (L_k - 55 mm) / u(L_k)
// should be a standard normal draw when u(L) is right. Before the spots'
// shared errors (camera poses, datum tags) were propagated, u(A-B) was 36 um
// against a scatter of 63 um: RMS z 1.78 over seeds 1-10.
//
// Each session is calibrated twice: one camera pose per image (the default)
// and one per camera (FrontEndOptions::one_pose_per_camera; the cameras do
// not move in these renders), whose u is smaller; both must cover.
//
// N = 3 seeds by default (about 11 s each in Release on 2 cores); the test
// asserts sum z^2 below the 99.5% point of chi^2_N. OPL_CAL_COVERAGE_SEEDS=<N>
// and OPL_CAL_COVERAGE_FIRST_SEED=<k> run more by hand (docs/images.md,
// "Calibration sessions", has the figures of 40 seeds).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "opl/io/scene_json.h"
#include "opl/pipeline/calibrate_images.h"
#include "opl/sim/module_design.h"
#include "support/scene_images.h"

namespace opl {
namespace {

int EnvInt(const char* name, int fallback, int min) {
  const char* v = std::getenv(name);
  if (v == nullptr) return fallback;
  const int value = std::atoi(v);
  return value >= min ? value : fallback;
}

// chi^2_n quantile at p = 99.5% (Wilson-Hilferty; within 1% for n >= 2).
double ChiSquare995(int n) {
  const double a = 2.0 / (9.0 * n);
  const double c = 1.0 - a + 2.5758 * std::sqrt(a);
  return n * c * c * c;
}

TEST(CalibrationCoverage, NoisySessionsFallWithinTheirUncertainty) {
  Result<Scene> base = ReadSceneJson(test::SourceDir() + "/examples/calibration_session_small.json");
  ASSERT_TRUE(base.ok()) << base.status().ToString();
  base->image.bit_depth = 8;
  base->image.read_noise = 0.004;
  base->image.gain_e_per_dn = 20.0;
  base->spots.speckle_contrast = 0.1;
  ASSERT_TRUE(base->module.has_value());
  const ModuleDesign& design = *base->module;
  const double true_length = (design.sources[0].scene_from_source.translation -
                              design.sources[1].scene_from_source.translation)
                                 .norm();
  Result<ModuleCalibration> nominal = ExactCalibration(design);
  ASSERT_TRUE(nominal.ok());
  ImageCalibrationOptions options;
  options.front_end.num_threads = 2;
  ImageCalibrationOptions per_camera = options;
  per_camera.front_end.one_pose_per_camera = true;

  const int n = EnvInt("OPL_CAL_COVERAGE_SEEDS", 3, 1);
  const int first = EnvInt("OPL_CAL_COVERAGE_FIRST_SEED", 1, 0);
  double sum_z2 = 0.0, sum_z2_per_camera = 0.0;
  int within_2u = 0, within_2u_per_camera = 0;
  for (int seed = first; seed < first + n; ++seed) {
    Scene scene = *base;
    scene.seed = static_cast<uint64_t>(seed);
    const std::filesystem::path dir =
        test::FreshTempDir("calibration_coverage_" + std::to_string(seed));
    Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
    ASSERT_TRUE(truth.ok()) << truth.status().ToString();
    Result<ImageCalibrationReport> r = CalibrateFromImages(scene, dir.string(), *nominal, options);
    Result<ImageCalibrationReport> fixed =
        CalibrateFromImages(scene, dir.string(), *nominal, per_camera);
    std::filesystem::remove_all(dir);
    ASSERT_TRUE(r.ok()) << "seed " << seed << ": " << r.status().ToString();
    EXPECT_EQ(r->identification.unassigned, 0) << "seed " << seed;
    EXPECT_EQ(r->shared.components, 9 + 6 * static_cast<int>(scene.shots.size()));
    ASSERT_EQ(r->calibration.calibration.separations.size(), 1u);
    const Separation& sep = r->calibration.calibration.separations[0];
    const double z = (sep.length_mm - true_length) / sep.u_length_mm;
    sum_z2 += z * z;
    within_2u += std::abs(z) <= 2.0;
    std::printf("seed %d: A-B %.4f mm, error %+.1f um, u %.1f um (own %.1f, shared %.1f), z %+.2f\n",
                seed, sep.length_mm, 1e3 * (sep.length_mm - true_length), 1e3 * sep.u_length_mm,
                1e3 * r->shared.u_separation_own_mm[0], 1e3 * r->shared.u_separation_shared_mm[0], z);
    ASSERT_TRUE(fixed.ok()) << "seed " << seed << ", one pose per camera: " << fixed.status().ToString();
    EXPECT_EQ(fixed->shared.components, 9 + 6 * static_cast<int>(scene.cameras.size()));
    const Separation& f = fixed->calibration.calibration.separations.at(0);
    const double zf = (f.length_mm - true_length) / f.u_length_mm;
    sum_z2_per_camera += zf * zf;
    within_2u_per_camera += std::abs(zf) <= 2.0;
    std::printf("        one pose per camera: error %+.1f um, u %.1f um (own %.1f, shared %.1f), z %+.2f\n",
                1e3 * (f.length_mm - true_length), 1e3 * f.u_length_mm,
                1e3 * fixed->shared.u_separation_own_mm[0],
                1e3 * fixed->shared.u_separation_shared_mm[0], zf);
  }
  std::printf("%d sessions: RMS z %.2f, %d within 2 u; sum z^2 %.1f (chi^2_%d 99.5%%: %.1f)\n", n,
              std::sqrt(sum_z2 / n), within_2u, sum_z2, n, ChiSquare995(n));
  std::printf("one pose per camera: RMS z %.2f, %d within 2 u; sum z^2 %.1f\n",
              std::sqrt(sum_z2_per_camera / n), within_2u_per_camera, sum_z2_per_camera);
  EXPECT_LT(sum_z2, ChiSquare995(n));
  EXPECT_LT(sum_z2_per_camera, ChiSquare995(n));
}

}  // namespace
}  // namespace opl
