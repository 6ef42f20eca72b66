// Issue 17: the spot channel of a red laser, red against red-minus-green
// (vision/shot_image.h, SpotChannel), on the harder lab with its white and
// warm distractors (specular highlights, lamps, retro-reflective dots; 40
// per camera), a photograph of fruit as the wall, colour JPEG 90, speckle
// and sensor noise (examples/scene_clutter.json; the module placed per seed,
// tests/integration/harder_lab_scene.h).
//
// Luma is measured too (the JPEG study: in 4:2:0 JPEG the red channel's
// detail is mostly chroma, stored at half resolution).
//
// Per seed and channel, with and without the laser-off frames (without
// them the distractors reach the spot detector): recall of the true spots
// (a kept detection within 1 px), false spots kept, spots identified and
// wrongly so, and z of the reported s against the truth
// (tests/support/lab_truth.h). Seed 1 without laser-off frames in the
// default suite (red and red-minus-green); OPL_STUDY_SCENES seeds of both (`ctest -L study`: 10).
// docs/images.md, "Red or red minus green", has the figures.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "integration/harder_lab_scene.h"
#include "opl/lab/render_scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "opl/vision/shot_image.h"
#include "support/lab_truth.h"
#include "support/scene_images.h"

namespace opl {
namespace {

const SpotChannel kChannels[3] = {SpotChannel::kRed, SpotChannel::kRedMinusGreen,
                                  SpotChannel::kLuma};

struct Tally {
  int scenes = 0, measured = 0;
  int visible = 0, found = 0, false_spots = 0, identified = 0, wrong = 0, rejected = 0;
  double sum_z2 = 0.0;
  int within = 0;
  // The reported s against the truth: sum of (s / s_true - 1)^2 and of
  // u(s) / s_true, over the measured scenes with a truth fit.
  double sum_e2 = 0.0, sum_u = 0.0;
  int with_truth = 0;
};

// Renders seed k once, then measures it per (dark frames, channel).
void MeasureSeed(uint64_t seed, const std::vector<bool>& dark_frames,
                 const std::vector<int>& channels, Tally tallies[2][3]) {
  Scene scene = test::ClutterScene();
  ASSERT_FALSE(scene.shots.empty());
  scene.seed = seed;
  test::PlaceModuleForSeed(scene, seed);
  const std::filesystem::path dir = test::FreshTempDir("spot_channel_" + std::to_string(seed));
  Result<SceneRenderer> truth = test::RenderShotsTo(scene, dir, 2);
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ASSERT_TRUE(calibration.ok());
  for (bool dark : dark_frames) {
    for (int c : channels) {
      const SpotChannel channel = kChannels[c];
      Tally& t = tallies[dark ? 1 : 0][c];
      ++t.scenes;
      ImageMeasureOptions options;
      options.front_end.num_threads = 2;
      options.front_end.use_dark_frames = dark;
      options.front_end.spot_channel = channel;
      Result<ImageMeasureReport> report =
          MeasureScaleFromImages(scene, dir.string(), *calibration, options);
      if (!report.ok()) {
        std::printf("seed %d, %s, %s: not measured: %s\n", static_cast<int>(seed),
                    dark ? "laser-off frames" : "no laser-off frames", SpotChannelName(channel),
                    report.status().ToString().c_str());
        continue;
      }
      ++t.measured;
      const test::SpotCounts counts = test::CountSpots(*truth, *report);
      const test::TruthFit fit = test::FitToTruth(*report, *truth);
      int rejected = 0;
      for (const ImageFindings& f : report->front_end.images) rejected += f.blobs_rejected;
      const double z =
          fit.points >= 4 ? (report->scale_factor - fit.scale) / report->u_scale_factor : 0.0;
      std::printf("seed %d, %-19s %-16s recall %d/%d, false spots %d, blobs rejected %d, "
                  "identified %d (wrong %d), z %+.2f, s / s_true - 1 %+.3e, u(s) %.3e\n",
                  static_cast<int>(seed), dark ? "laser-off frames," : "no laser-off frames,",
                  SpotChannelName(channel), counts.found, counts.visible, counts.false_spots,
                  rejected, fit.points, fit.wrong, z,
                  fit.points >= 4 ? report->scale_factor / fit.scale - 1.0 : 0.0,
                  report->u_scale_factor);
      t.visible += counts.visible;
      t.found += counts.found;
      t.false_spots += counts.false_spots;
      t.identified += fit.points;
      t.wrong += fit.wrong;
      t.rejected += rejected;
      t.sum_z2 += z * z;
      t.within += std::abs(z) <= 2.0 ? 1 : 0;
      if (fit.points >= 4) {
        const double e = report->scale_factor / fit.scale - 1.0;
        t.sum_e2 += e * e;
        t.sum_u += report->u_scale_factor / fit.scale;
        ++t.with_truth;
      }
    }
  }
  std::filesystem::remove_all(dir);
}

void PrintTallies(Tally tallies[2][3], bool with_dark) {
  for (int d = 0; d < (with_dark ? 2 : 1); ++d) {
    for (int c = 0; c < 3; ++c) {
      const Tally& t = tallies[d][c];
      if (t.measured == 0) continue;
      std::printf("%-20s %-16s %d of %d measured: recall %d/%d (%.2f%%), false spots %d (%.1f per "
                  "lit image), blobs rejected %d, identified %d (wrong %d), |z| <= 2 in %d, RMS z "
                  "%.2f; s / s_true - 1: RMS %.2e, mean u(s) %.2e\n",
                  d ? "laser-off frames" : "no laser-off frames",
                  SpotChannelName(kChannels[c]), t.measured, t.scenes, t.found, t.visible,
                  100.0 * t.found / std::max(1, t.visible), t.false_spots,
                  t.false_spots / (8.0 * t.measured), t.rejected, t.identified, t.wrong, t.within,
                  std::sqrt(t.sum_z2 / t.measured),
                  std::sqrt(t.sum_e2 / std::max(1, t.with_truth)),
                  t.sum_u / std::max(1, t.with_truth));
    }
  }
}

TEST(SpotChannelStudy, RedMinusGreenAgainstRedWithoutLaserOffFrames) {
  Tally tallies[2][3];
  MeasureSeed(1, {false}, {0, 1}, tallies);
  PrintTallies(tallies, false);
  const Tally& red = tallies[0][0];
  const Tally& rmg = tallies[0][1];
  ASSERT_EQ(red.measured, 1);
  ASSERT_EQ(rmg.measured, 1);
  // Measured (seed 1): red recall 654 of 968, 1485 false spots, 149
  // identified, 1 of them wrong; red-minus-green 728 of 968, 895 false
  // spots, 159 identified, none wrong.
  EXPECT_GE(rmg.found, red.found + 50);
  EXPECT_LE(rmg.false_spots, 0.7 * red.false_spots);
  EXPECT_GE(rmg.identified, red.identified);
  EXPECT_EQ(rmg.wrong, 0);
}

TEST(SpotChannelStudy, StudyOverSeeds) {
  const char* env = std::getenv("OPL_STUDY_SCENES");
  const int n = env != nullptr ? std::atoi(env) : 0;
  if (n <= 0) GTEST_SKIP() << "OPL_STUDY_SCENES=<N> (ctest -L study: 10)";
  Tally tallies[2][3];
  for (int k = 1; k <= n; ++k) {
    MeasureSeed(static_cast<uint64_t>(k), {false, true}, {0, 1, 2}, tallies);
  }
  PrintTallies(tallies, true);
  // With laser-off frames (the default) no spot is wrongly identified;
  // without them clutter can be (seeds 1-2: 1 with red, 3 with
  // red-minus-green), which is why they are the default.
  for (int c = 0; c < 3; ++c) EXPECT_EQ(tallies[1][c].wrong, 0);
  EXPECT_EQ(tallies[1][0].measured, n);
}

// Red against luma with the laser-off frames (the case where luma could be
// chosen for 4:2:0 JPEG, docs/images.md "The JPEG bias"): the error of the
// reported s against the truth, not only its z. By hand:
// OPL_STUDY_LUMA_SCENES=<N> (first seed OPL_STUDY_FIRST_SEED, default 1).
TEST(SpotChannelStudy, RedAgainstLumaWithLaserOffFrames) {
  const char* env = std::getenv("OPL_STUDY_LUMA_SCENES");
  const int n = env != nullptr ? std::atoi(env) : 0;
  if (n <= 0) GTEST_SKIP() << "OPL_STUDY_LUMA_SCENES=<N>";
  const char* first_env = std::getenv("OPL_STUDY_FIRST_SEED");
  const int first = first_env != nullptr ? std::max(1, std::atoi(first_env)) : 1;
  Tally tallies[2][3];
  for (int k = first; k < first + n; ++k) {
    MeasureSeed(static_cast<uint64_t>(k), {true}, {0, 2}, tallies);
  }
  PrintTallies(tallies, true);
  EXPECT_EQ(tallies[1][0].wrong, 0);
  EXPECT_EQ(tallies[1][2].wrong, 0);
}

}  // namespace
}  // namespace opl
