// Issue 17: the calibration from photographs on the harder virtual lab
// (tests/support/harder_session.h: the example session in colour JPEG 90 on a
// photograph of fruit, ambient ramp, vignetting, defocus, 40 distractors per
// camera, one laser-off shot per camera and slice), judged against the
// renderer's truth:
//  - noise-free geometry: the separation against the true 55 mm and every
//    beam's direction against the fabricated pattern, JPEG 90 beside the
//    same session as lossless PNG; every lit shot's dark frame is the
//    laser-off shot of its own camera and slice; no identified spot off its
//    beam's true point; the JPEGs once more with the spots read in luma;
//  - noisy (speckle 0.1, read noise 0.004, shot noise at 20 e-/DN): for
//    seeds k = 1 .. N, the module moved about its centre per seed (JPEG's
//    error on a spot centre is a fixed function of where the spot falls on
//    the 8 x 8 blocks: one placement repeats it every seed, see
//    tests/integration/harder_lab_scene.h), z_k = (L_k - 55 mm) / u(L_k)
//    and the wrong identifications.
// N = 2 in the default suite (label no_sanitizer; about 20 s); the ctest entry
// studies/calibration_harder_study_20 (label "study") runs 20
// (OPL_STUDY_SCENES; OPL_STUDY_FIRST_SEED). Figures: docs/images.md,
// "Calibration sessions", "On the harder lab".
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "opl/pipeline/calibrate_images.h"
#include "opl/sim/module_design.h"
#include "opl/vision/shot_image.h"
#include "support/harder_session.h"
#include "support/scene_images.h"

namespace opl {
namespace {

int EnvInt(const char* name, int fallback, int min) {
  const char* v = std::getenv(name);
  return v != nullptr && std::atoi(v) >= min ? std::atoi(v) : fallback;
}

// chi^2_n quantile at p = 99.5% (Wilson-Hilferty; within 1% for n >= 2).
double ChiSquare995(int n) {
  const double a = 2.0 / (9.0 * n);
  const double c = 1.0 - a + 2.5758 * std::sqrt(a);
  return n * c * c * c;
}

// The module moved rigidly about the midpoint of its origins for seed k: up
// to +-20 mm across the beams (y, z), +-1 deg of yaw and pitch, +-5 deg of
// roll. The separation stays 55 mm; the grids stay on the screen.
void PlaceSessionModuleForSeed(Scene& scene, uint64_t seed) {
  std::mt19937_64 rng(0x5851f42d4c957f2dULL ^ seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const double deg = M_PI / 180.0;
  const Eigen::Matrix3d r =
      (Eigen::AngleAxisd(1.0 * deg * uniform(rng), Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(1.0 * deg * uniform(rng), Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(5.0 * deg * uniform(rng), Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const double dy = 20.0 * uniform(rng), dz = 20.0 * uniform(rng);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const SourceDesign& s : scene.module->sources) centre += s.scene_from_source.translation;
  centre /= static_cast<double>(scene.module->sources.size());
  // x -> r (x - centre) + centre + (0, dy, dz)
  const Rigid3d moved(r, centre - r * centre + Eigen::Vector3d(0.0, dy, dz));
  for (SourceDesign& source : scene.module->sources) {
    source.scene_from_source = moved * source.scene_from_source;
  }
}

double TrueSeparation(const ModuleDesign& design) {
  return (design.sources[0].scene_from_source.translation -
          design.sources[1].scene_from_source.translation)
      .norm();
}

struct Outcome {
  bool calibrated = false;
  std::string error;
  double length_mm = 0.0, u_mm = 0.0, own_mm = 0.0, shared_mm = 0.0, z = 0.0;
  double beam_rms_urad = 0.0, beam_max_urad = 0.0;  // over both sources
  double origin_max_mm = 0.0;
  int identified = 0, wrong = 0, unassigned = 0;
  int wrong_dark_frames = 0;  // lit shots not paired with their own camera's and slice's
  double seconds = 0.0;
};

Outcome CalibrateSession(const Scene& scene, const std::string& tag,
                         SpotChannel channel = SpotChannel::kRed) {
  const auto start = std::chrono::steady_clock::now();
  Outcome o;
  const ModuleDesign& design = *scene.module;
  const std::filesystem::path dir = test::FreshTempDir("calibration_harder_" + tag);
  Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
  if (!truth.ok()) {
    o.error = truth.status().ToString();
    return o;
  }
  Result<ModuleCalibration> nominal = ExactCalibration(design);
  if (!nominal.ok()) {
    o.error = nominal.status().ToString();
    return o;
  }
  ImageCalibrationOptions options;
  options.front_end.num_threads = 2;
  options.front_end.spot_channel = channel;
  Result<ImageCalibrationReport> r = CalibrateFromImages(scene, dir.string(), *nominal, options);
  std::filesystem::remove_all(dir);
  if (!r.ok()) {
    o.error = r.status().ToString();
    return o;
  }
  o.calibrated = true;
  const test::SessionTruthCheck check = test::CheckAgainstTruth(*r, *truth);
  o.identified = check.identified;
  o.wrong = check.wrong;
  o.unassigned = r->identification.unassigned;
  for (size_t i = 0; i < scene.shots.size(); ++i) {
    const SceneShot& shot = scene.shots[i];
    if (shot.lasers.empty()) continue;
    const std::string& dark = r->front_end.images[i].dark_frame;
    const std::string expected = test::LaserOffFile(shot.slice, shot.camera);
    o.wrong_dark_frames += dark.substr(0, dark.rfind('.')) !=
                                   expected.substr(0, expected.rfind('.'))
                               ? 1
                               : 0;
  }
  const Separation& sep = r->calibration.calibration.separations.at(0);
  o.length_mm = sep.length_mm;
  o.u_mm = sep.u_length_mm;
  o.own_mm = r->shared.u_separation_own_mm.at(0);
  o.shared_mm = r->shared.u_separation_shared_mm.at(0);
  o.z = (sep.length_mm - TrueSeparation(design)) / sep.u_length_mm;
  double sum2 = 0.0;
  int beams = 0;
  for (const SourceDesign& source : design.sources) {
    Result<BeamPattern> fabricated = MakePattern(source);
    const SourceCalibration* calibrated = r->calibration.calibration.FindSource(source.name);
    if (!fabricated.ok() || calibrated == nullptr) {
      o.beam_max_urad = INFINITY;
      continue;
    }
    for (const Beam& beam : calibrated->pattern.beams()) {
      const double a = 1e6 * std::acos(std::min(1.0, calibrated->pattern.DirectionInSource(beam.id).dot(
                                                         fabricated->DirectionInSource(beam.id))));
      sum2 += a * a;
      ++beams;
      o.beam_max_urad = std::max(o.beam_max_urad, a);
    }
    o.origin_max_mm = std::max(o.origin_max_mm, (calibrated->calibration_from_source.translation -
                                                 source.scene_from_source.translation)
                                                    .norm());
  }
  o.beam_rms_urad = beams > 0 ? std::sqrt(sum2 / beams) : INFINITY;
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return o;
}

void Print(const char* what, const Outcome& o) {
  std::printf("%s: A-B %.5f mm, error %+.1f um, u %.1f um (own %.1f, shared %.1f), z %+.2f; beams "
              "RMS %.1f urad, max %.1f urad; origins within %.3f mm; %d identified, %d wrong, %d "
              "unassigned; %d wrong dark frames; %.1f s\n",
              what, o.length_mm, 1e3 * (o.length_mm - 55.0), 1e3 * o.u_mm, 1e3 * o.own_mm,
              1e3 * o.shared_mm, o.z, o.beam_rms_urad, o.beam_max_urad, o.origin_max_mm,
              o.identified, o.wrong, o.unassigned, o.wrong_dark_frames, o.seconds);
}

TEST(CalibrationHarderStudy, NoiseFreeGeometryJpegAndPng) {
  const Scene jpeg_scene = test::HarderSession(/*noisy=*/false);
  ASSERT_EQ(jpeg_scene.shots.size(), 18u + 9u);
  ASSERT_NEAR(TrueSeparation(*jpeg_scene.module), 55.0, 1e-12);
  const Outcome jpeg = CalibrateSession(jpeg_scene, "jpeg");
  ASSERT_TRUE(jpeg.calibrated) << jpeg.error;
  const Outcome png = CalibrateSession(test::AsPng(jpeg_scene), "png");
  ASSERT_TRUE(png.calibrated) << png.error;
  const Outcome luma = CalibrateSession(jpeg_scene, "jpeg_luma", SpotChannel::kLuma);
  ASSERT_TRUE(luma.calibrated) << luma.error;
  Print("noise-free harder session, JPEG 90", jpeg);
  Print("noise-free harder session, JPEG 90, spots in luma", luma);
  Print("noise-free harder session, PNG 16 bit", png);
  for (const Outcome* o : {&jpeg, &png, &luma}) {
    // Each lit shot minus the laser-off shot of its own slice: the screen
    // moved between slices (every laser-off shot of a camera shows the same
    // tags, so the tags alone cannot tell them apart; before the front end
    // matched the slice, 12 of the 18 lit shots got slice 0's).
    EXPECT_EQ(o->wrong_dark_frames, 0);
    EXPECT_EQ(o->wrong, 0);
    EXPECT_LT(std::abs(o->z), 2.0);
  }
  // Lossless: as the clean renders (docs/images.md: error -2.0 um, beams
  // within 2.8 urad).
  EXPECT_GE(png.identified, 715);
  EXPECT_LT(std::abs(png.length_mm - 55.0), 0.01);
  EXPECT_LT(png.beam_rms_urad, 6.0);
  EXPECT_LT(png.beam_max_urad, 30.0);
  EXPECT_LT(png.origin_max_mm, 0.2);
  // JPEG 90 without any noise is the front end's worst case, not its best:
  // the dark-frame difference is exactly 0 but in the 8 x 8 blocks of the
  // spots, the detector's noise is its 0.5 DN floor, and the compression's
  // ripple (4:2:0 chroma on spots of 2-3 px) breaks the spots of the nearest
  // slice into several peaks and pieces. Recorded, not endorsed (docs/
  // images.md, "On the harder lab"): 404 of 726 identified, u(A-B) 252 um
  // covering an error of -242 um. Never a wrong spot.
  EXPECT_GE(jpeg.identified, 350);
  EXPECT_LT(jpeg.u_mm, 0.4);
  // The same JPEGs with the spots read in luma (full resolution in 4:2:0):
  // whole again, and the beams 7 times closer (-6.6 um, RMS 56 urad).
  EXPECT_GE(luma.identified, 715);
  EXPECT_LT(std::abs(luma.length_mm - 55.0), 0.03);
  EXPECT_LT(luma.beam_rms_urad, 100.0);
  EXPECT_LT(luma.origin_max_mm, 0.3);
}

TEST(CalibrationHarderStudy, NoisySessionsWithinTheirUncertainty) {
  const Scene base = test::HarderSession(/*noisy=*/true);
  ASSERT_FALSE(base.shots.empty());
  const int n = EnvInt("OPL_STUDY_SCENES", 2, 1);
  const int first = EnvInt("OPL_STUDY_FIRST_SEED", 1, 0);
  // OPL_STUDY_SPOT_CHANNEL=luma (or red, the default) by hand.
  const char* channel_name = std::getenv("OPL_STUDY_SPOT_CHANNEL");
  Result<SpotChannel> parsed = ParseSpotChannel(channel_name != nullptr ? channel_name : "red");
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  const SpotChannel channel = *parsed;
  std::printf("spot channel %s\n", SpotChannelName(channel));
  int calibrated = 0, refused = 0, within_2u = 0, wrong = 0, wrong_dark = 0;
  double sum_z = 0.0, sum_z2 = 0.0, sum_error = 0.0, sum_error2 = 0.0, sum_u = 0.0;
  for (int seed = first; seed < first + n; ++seed) {
    Scene scene = base;
    scene.seed = static_cast<uint64_t>(seed);
    PlaceSessionModuleForSeed(scene, scene.seed);
    const Outcome o = CalibrateSession(scene, std::to_string(seed), channel);
    if (!o.calibrated) {
      // In this session the frame tags 0 and 3 and the artifact tag 8 are
      // each in the view of two of the three cameras only; a distractor
      // over one of them in one of those cameras leaves it in one view, and
      // the front end refuses (seeds 3, 9, 11, 20: "frame origin tag 0 is
      // not seen from two camera positions", seed 15: "artifact tag 8 was
      // not found in two placed images"; 5 of 20). The scene's refusal,
      // counted; any other is a failure.
      std::printf("seed %d: refused: %s\n", seed, o.error.c_str());
      EXPECT_EQ(o.error.find('\n'), std::string::npos) << o.error;
      EXPECT_TRUE(o.error.find("is not seen from two camera positions") != std::string::npos ||
                  o.error.find("was not found in two placed images") != std::string::npos)
          << "seed " << seed << ": " << o.error;
      ++refused;
      continue;
    }
    Print(("seed " + std::to_string(seed)).c_str(), o);
    ++calibrated;
    within_2u += std::abs(o.z) <= 2.0 ? 1 : 0;
    wrong += o.wrong;
    wrong_dark += o.wrong_dark_frames;
    sum_z += o.z;
    sum_z2 += o.z * o.z;
    const double error_um = 1e3 * (o.length_mm - TrueSeparation(*scene.module));
    sum_error += error_um;
    sum_error2 += error_um * error_um;
    sum_u += 1e3 * o.u_mm;
    EXPECT_GE(o.identified, 700) << "seed " << seed;
  }
  ASSERT_GE(calibrated, 1);
  const double mean_error = sum_error / calibrated;
  const double sd_error =
      calibrated > 1 ? std::sqrt((sum_error2 - calibrated * mean_error * mean_error) / (calibrated - 1))
                     : 0.0;
  std::printf("harder calibration sessions, %d of %d calibrated (%d refused): mean error %+.1f um, SD %.1f um, "
              "mean u %.1f um; mean z %+.2f, RMS z %.2f, %d within 2 u; sum z^2 %.1f (chi^2_%d "
              "99.5%%: %.1f); %d wrong identifications, %d wrong dark frames\n",
              calibrated, n, refused, mean_error, sd_error, sum_u / calibrated, sum_z / calibrated,
              std::sqrt(sum_z2 / calibrated), within_2u, sum_z2, calibrated,
              ChiSquare995(calibrated), wrong, wrong_dark);
  EXPECT_LE(refused, n / 3) << "seeds refused";
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(wrong_dark, 0);
  EXPECT_LT(sum_z2, ChiSquare995(calibrated));
}

}  // namespace
}  // namespace opl
