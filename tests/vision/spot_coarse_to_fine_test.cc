// SpotDetectionOptions::coarse_to_fine (vision/spot_threshold_mask.h): the
// coarse-to-fine threshold must give the very result of the full one, every
// spot field to the bit and every counter, on images chosen to trip it:
// spots straddling the 8 px cells and the 64 px background blocks, faint
// spots at the threshold, saturated spots, a background gradient, 8 and 16
// bit; and the harder lab's shots (examples/scene_clutter.json: colour JPEG
// 90 through an RGB sensor, a photograph of fruit as the wall, distractors,
// speckle), as the front end reads them and after the dark-frame
// subtraction. The coarse pass must also leave most of the image out.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "integration/harder_lab_scene.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/spot_image.h"
#include "opl/sim/random.h"
#include "opl/vision/dark_frame.h"
#include "opl/vision/shot_image.h"
#include "opl/vision/spot_detection.h"
#include "support/scene_images.h"

namespace opl {
namespace {

// Detects with both paths and expects the same result; returns the coarse
// path's fraction of cells thresholded pixel by pixel.
double ExpectSameSpots(const cv::Mat& image, const std::string& what,
                       SpotDetectionOptions options = SpotDetectionOptions()) {
  options.coarse_to_fine = false;
  Result<SpotDetectionResult> full = DetectSpots(image, options);
  options.coarse_to_fine = true;
  Result<SpotDetectionResult> coarse = DetectSpots(image, options);
  EXPECT_TRUE(full.ok() && coarse.ok()) << what;
  if (!full.ok() || !coarse.ok()) return 1.0;
  EXPECT_EQ(full->fine_fraction, 1.0) << what;
  EXPECT_EQ(full->components, coarse->components) << what;
  EXPECT_EQ(full->rejected_small, coarse->rejected_small) << what;
  EXPECT_EQ(full->rejected_large, coarse->rejected_large) << what;
  EXPECT_EQ(full->rejected_border, coarse->rejected_border) << what;
  EXPECT_EQ(full->rejected_elongated, coarse->rejected_elongated) << what;
  EXPECT_EQ(full->rejected_merged, coarse->rejected_merged) << what;
  EXPECT_EQ(full->rejected_duplicate, coarse->rejected_duplicate) << what;
  EXPECT_EQ(full->threshold_dn, coarse->threshold_dn) << what;
  EXPECT_EQ(full->spots.size(), coarse->spots.size()) << what;
  for (size_t i = 0; i < std::min(full->spots.size(), coarse->spots.size()); ++i) {
    const DetectedSpot& a = full->spots[i];
    const DetectedSpot& b = coarse->spots[i];
    EXPECT_EQ(a.u_px, b.u_px) << what << " spot " << i;
    EXPECT_EQ(a.v_px, b.v_px) << what << " spot " << i;
    EXPECT_EQ(a.covariance_px2, b.covariance_px2) << what << " spot " << i;
    EXPECT_EQ(a.centroid_u_px, b.centroid_u_px) << what << " spot " << i;
    EXPECT_EQ(a.centroid_v_px, b.centroid_v_px) << what << " spot " << i;
    EXPECT_EQ(a.peak_dn, b.peak_dn) << what << " spot " << i;
    EXPECT_EQ(a.background_dn, b.background_dn) << what << " spot " << i;
    EXPECT_EQ(a.flux_dn, b.flux_dn) << what << " spot " << i;
    EXPECT_EQ(a.shape_px2, b.shape_px2) << what << " spot " << i;
    EXPECT_EQ(a.area_px, b.area_px) << what << " spot " << i;
    EXPECT_EQ(a.saturated_px, b.saturated_px) << what << " spot " << i;
    EXPECT_EQ(a.reduced_chi2, b.reduced_chi2) << what << " spot " << i;
    EXPECT_EQ(a.snr, b.snr) << what << " spot " << i;
    EXPECT_EQ(a.speckle_contrast, b.speckle_contrast) << what << " spot " << i;
    EXPECT_EQ(a.flags, b.flags) << what << " spot " << i;
  }
  std::printf("%s: %zu spots, %d components, %.4f of the cells thresholded\n", what.c_str(),
              coarse->spots.size(), coarse->components, coarse->fine_fraction);
  return coarse->fine_fraction;
}

// Spots on a grid whose centres sit on cell and block edges (u, v = 64 k -
// 0.5 and 8 k - 0.5 are the borders between pixels), faint ones near the
// threshold, saturated ones, on a sloped background with shot and read noise.
TEST(SpotCoarseToFine, SameSpotsOnBordersFaintAndSaturated) {
  for (const int bit_depth : {8, 16}) {
    SpotImageOptions o;
    o.width_px = 1000;
    o.height_px = 700;
    o.bit_depth = bit_depth;
    const double full_scale = bit_depth == 8 ? 255.0 : 65535.0;
    o.background_dn = 0.25 * full_scale;
    o.background_gradient_u_dn_per_px = 0.0001 * full_scale;
    o.background_gradient_v_dn_per_px = -0.00005 * full_scale;
    o.read_noise_dn = 0.008 * full_scale;
    o.gain_e_per_dn = bit_depth == 8 ? 20.0 : 0.5;
    o.seed = 17;
    std::vector<SpotToRender> spots;
    std::mt19937_64 rng(5);
    for (int row = 0; row < 9; ++row) {
      for (int col = 0; col < 13; ++col) {
        SpotToRender s;
        // Every third spot on a block edge, every third on a cell edge.
        const double edge_u = (col % 3 == 0) ? 64.0 * (col + 1) - 0.5 : 8.0 * (8 * col + 5) - 0.5;
        const double edge_v = (row % 3 == 0) ? 64.0 * (row + 1) - 0.5 : 8.0 * (8 * row + 3) - 0.5;
        s.u_px = std::min(edge_u, o.width_px - 20.0) + (col % 3 == 2 ? Uniform01(rng) : 0.0);
        s.v_px = std::min(edge_v, o.height_px - 20.0) + (row % 3 == 2 ? Uniform01(rng) : 0.0);
        s.shape_covariance_px2 = RoundSpotShape(4.0 + 8.0 * Uniform01(rng));
        // Peaks from ~3 noise sigmas (below the threshold) to 3 x full scale.
        const int k = row * 13 + col;
        s.peak_dn = (k % 4 == 0)   ? 3.0 * full_scale
                    : (k % 4 == 1) ? (0.03 + 0.05 * Uniform01(rng)) * full_scale
                                   : (0.1 + 0.5 * Uniform01(rng)) * full_scale;
        spots.push_back(s);
      }
    }
    Result<SpotImage> image = RenderSpotImage(spots, o);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    const double fraction = ExpectSameSpots(image->image, std::to_string(bit_depth) + " bit");
    // 117 spots of up to ~30 x 30 px (the saturated ones wider) on 0.7 MP:
    // measured 0.30 of the cells at 16 bit.
    EXPECT_LT(fraction, 0.4) << bit_depth << " bit";
    // A lower threshold (more faint blobs at the edge) and a smaller block.
    SpotDetectionOptions low;
    low.threshold_sigma = 3.0;
    low.background_block_px = 24;
    ExpectSameSpots(image->image, std::to_string(bit_depth) + " bit, threshold 3", low);
  }
}

// The harder lab: every shot of examples/scene_clutter.json's first camera
// as the front end reads it (red channel of the colour JPEG 90), and each
// lit shot minus the laser-off shot (16-bit difference).
TEST(SpotCoarseToFine, SameSpotsOnTheHarderLab) {
  const Scene scene = test::ClutterScene();
  ASSERT_FALSE(scene.shots.empty());
  const std::filesystem::path dir = test::FreshTempDir("spot_coarse_to_fine");
  Scene one_camera = scene;
  one_camera.shots.clear();
  for (const SceneShot& shot : scene.shots) {
    if (shot.camera == scene.shots.front().camera) one_camera.shots.push_back(shot);
  }
  ASSERT_GE(one_camera.shots.size(), 2u);
  Result<SceneRenderer> renderer = test::RenderShotsTo(one_camera, dir, 2);
  ASSERT_TRUE(renderer.ok()) << renderer.status().ToString();
  cv::Mat dark;
  std::vector<cv::Mat> lit;
  for (const SceneShot& shot : one_camera.shots) {
    Result<ShotImage> image = ReadShotImage((dir / shot.file).string(), SpotChannel::kRed);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    const double fraction = ExpectSameSpots(image->for_spots, shot.file);
    EXPECT_LT(fraction, 0.5) << shot.file;
    (shot.lasers.empty() ? dark : lit.emplace_back()) = image->for_spots;
  }
  ASSERT_FALSE(dark.empty());
  ASSERT_FALSE(lit.empty());
  for (size_t i = 0; i < lit.size(); ++i) {
    Result<cv::Mat> difference = SubtractDarkFrame(lit[i], dark);
    ASSERT_TRUE(difference.ok()) << difference.status().ToString();
    ExpectSameSpots(*difference, "lit shot " + std::to_string(i) + " minus the dark frame");
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace opl
