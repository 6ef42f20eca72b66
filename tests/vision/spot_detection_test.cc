// DetectSpots on seeded simulations with known truth (lab/spot_image.h):
// centroid accuracy for clean, saturated and speckled spots, the reported
// covariance against the Monte-Carlo scatter, false detections, recall, bad
// input. SNR = peak amplitude A / background noise sigma (both DN).
#include "opl/vision/spot_detection.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "opl/core/format.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/spot_image.h"
#include "opl/sim/random.h"
#include "support/scene_images.h"

namespace opl {
namespace {

struct Scene {
  std::vector<SpotToRender> spots;
  SpotImageOptions options;
};

// Spots on a grid of `spacing` px cells, each at a random sub-pixel position
// within its cell's central +-2 px; round (elongation 1) or elliptical with a
// random angle.
Scene GridScene(int width, int height, int spacing, double diameter, double elongation,
                double peak_dn, uint64_t seed) {
  Scene s;
  s.options.width_px = width;
  s.options.height_px = height;
  std::mt19937_64 rng(seed);
  for (int y = spacing; y + spacing <= height; y += spacing) {
    for (int x = spacing; x + spacing <= width; x += spacing) {
      SpotToRender t;
      t.u_px = x + 4 * (Uniform01(rng) - 0.5);
      t.v_px = y + 4 * (Uniform01(rng) - 0.5);
      t.shape_covariance_px2 =
          EllipticalSpotShape(diameter, diameter / elongation, kPi * Uniform01(rng));
      t.peak_dn = peak_dn;
      s.spots.push_back(t);
    }
  }
  return s;
}

struct Errors {
  int matched = 0, missed = 0, extra = 0;
  double sum2_fit = 0, sum2_centroid = 0;  // sum of du^2 + dv^2
  double max_fit = 0;
  double sum_predicted = 0;  // sum of reported var(u) + var(v)
  double rms_predicted() const { return std::sqrt(sum_predicted / matched); }
  double rms_fit() const { return std::sqrt(sum2_fit / matched); }
  double rms_centroid() const { return std::sqrt(sum2_centroid / matched); }
};

// Matches each truth spot to the nearest detection within 2 px.
Errors Match(const std::vector<SpotToRender>& truth, const std::vector<DetectedSpot>& found,
             Errors e = Errors()) {
  std::vector<bool> used(found.size(), false);
  for (const SpotToRender& t : truth) {
    int best = -1;
    double best_d2 = 4.0;
    for (size_t k = 0; k < found.size(); ++k) {
      const double d2 = std::pow(found[k].u_px - t.u_px, 2) + std::pow(found[k].v_px - t.v_px, 2);
      if (d2 < best_d2) {
        best_d2 = d2;
        best = static_cast<int>(k);
      }
    }
    if (best < 0) {
      ++e.missed;
      continue;
    }
    used[static_cast<size_t>(best)] = true;
    ++e.matched;
    e.sum2_fit += best_d2;
    e.max_fit = std::max(e.max_fit, std::sqrt(best_d2));
    const DetectedSpot& f = found[static_cast<size_t>(best)];
    e.sum_predicted += f.covariance_px2.trace();
    e.sum2_centroid += std::pow(f.centroid_u_px - t.u_px, 2) + std::pow(f.centroid_v_px - t.v_px, 2);
  }
  for (bool u : used) e.extra += u ? 0 : 1;
  return e;
}

// Renders `images` scenes and detects each with every option set; returns
// the errors accumulated per option set.
std::vector<Errors> RunScenes(double diameter, double elongation, double peak_dn,
                              const SpotImageOptions& base,
                              const std::vector<SpotDetectionOptions>& detect, int images,
                              uint64_t seed) {
  std::vector<Errors> e(detect.size());
  for (int i = 0; i < images; ++i) {
    const int spacing = static_cast<int>(std::ceil(3.2 * diameter)) + 8;
    Scene s = GridScene(base.width_px, base.height_px, spacing, diameter, elongation, peak_dn,
                        seed + static_cast<uint64_t>(i));
    SpotImageOptions o = base;
    o.seed = seed * 1000 + static_cast<uint64_t>(i);
    auto img = RenderSpotImage(s.spots, o);
    EXPECT_TRUE(img.ok()) << img.status().ToString();
    if (!img.ok()) return e;
    for (size_t k = 0; k < detect.size(); ++k) {
      auto r = DetectSpots(img->image, detect[k]);
      EXPECT_TRUE(r.ok()) << r.status().ToString();
      if (!r.ok()) return e;
      e[k] = Match(s.spots, r->spots, e[k]);
    }
  }
  return e;
}

Errors RunScenes(double diameter, double elongation, double peak_dn, const SpotImageOptions& base,
                 const SpotDetectionOptions& detect, int images, uint64_t seed) {
  return RunScenes(diameter, elongation, peak_dn, base, std::vector<SpotDetectionOptions>{detect},
                   images, seed)[0];
}

SpotImageOptions Snr100() {
  SpotImageOptions o;
  o.width_px = 480;
  o.height_px = 360;
  o.background_dn = 500;
  o.read_noise_dn = 20;  // A = 2000 DN: SNR 100
  return o;
}

// The figure: RMS (radial: sqrt(mean(du^2 + dv^2))) <= 0.02 px for
// clean spots of 5-15 px diameter at SNR 100, round and elliptical.
TEST(SpotDetection, CleanSpotsAtSnr100MeetTwoHundredthsOfAPixel) {
  for (double elongation : {1.0, 1.6}) {
    for (double diameter : {5.0, 8.0, 11.0, 15.0}) {
      const Errors e = RunScenes(diameter, elongation, 2000.0, Snr100(), SpotDetectionOptions(),
                                 diameter >= 11 ? 2 : 1,
                                 static_cast<uint64_t>(diameter * 10 + elongation * 100));
      std::printf("clean SNR 100  D %4.1f px elong %.1f: %3d spots, RMS fit %.4f px, "
                  "centroid %.4f px, max %.4f\n",
                  diameter, elongation, e.matched, e.rms_fit(), e.rms_centroid(), e.max_fit);
      EXPECT_GE(e.matched, 30);
      EXPECT_EQ(e.missed, 0);
      EXPECT_EQ(e.extra, 0);
      EXPECT_LE(e.rms_fit(), 0.02) << "D " << diameter << " elongation " << elongation;
    }
  }
}

TEST(SpotDetection, SaturatedSpotsFitTheWings) {
  SpotImageOptions o;
  o.width_px = 480;
  o.height_px = 360;
  o.bit_depth = 8;
  o.background_dn = 20;
  o.read_noise_dn = 2.0;
  for (double diameter : {6.0, 10.0, 15.0}) {
    const Errors e = RunScenes(diameter, 1.0, 3.0 * 255.0, o, SpotDetectionOptions(), 2,
                         static_cast<uint64_t>(diameter * 7));
    std::printf("saturated 3x   D %4.1f px: %3d spots, RMS fit %.4f px, centroid %.4f px\n",
                diameter, e.matched, e.rms_fit(), e.rms_centroid());
    EXPECT_EQ(e.missed, 0);
    EXPECT_EQ(e.extra, 0);
    EXPECT_LE(e.rms_fit(), 0.02) << diameter;
  }
}

TEST(SpotDetection, SpeckleErrorIsMeasuredAndBounded) {
  SpotImageOptions o = Snr100();
  o.speckle_contrast = 0.5;
  o.speckle_grain_px = 1.5;
  for (double diameter : {6.0, 10.0, 15.0}) {
    // Default options, and the speckle known to the detector (weights and
    // covariance use it).
    SpotDetectionOptions known;
    known.speckle_contrast = 0.5;
    known.speckle_grain_px = 1.5;
    const std::vector<Errors> both =
        RunScenes(diameter, 1.0, 2000.0, o, {SpotDetectionOptions(), known}, 1,
                  static_cast<uint64_t>(diameter * 13));
    const Errors& e = both[0];
    const Errors& k = both[1];
    std::printf("speckle c 0.5 grain 1.5 px, SNR 100, D %4.1f px: %3d spots, RMS fit %.4f px, "
                "centroid %.4f px; reported sigma %.4f px\n",
                diameter, e.matched, e.rms_fit(), e.rms_centroid(), e.rms_predicted());
    EXPECT_EQ(e.missed, 0);
    EXPECT_EQ(e.extra, 0);
    // Measured 0.29-0.35 px (radial); the centroid of the same windows
    // 0.32-0.42 px. For comparison, the centroid of the whole speckled light
    // scatters by c grain / 2 = 0.375 px per axis (docs/spot_detection.md).
    EXPECT_LE(e.rms_fit(), 0.45) << diameter;
    EXPECT_LE(e.rms_fit(), e.rms_centroid()) << diameter;
    std::printf("  speckle known to the detector: RMS fit %.4f px, reported sigma %.4f px, "
                "ratio %.3f\n",
                k.rms_fit(), k.rms_predicted(), k.rms_fit() / k.rms_predicted());
    // Measured 0.21-0.33 px and ratios 0.72-0.88.
    EXPECT_LE(k.rms_fit(), 0.45) << diameter;
    EXPECT_GT(k.rms_fit() / k.rms_predicted(), 0.6) << diameter;
    EXPECT_LT(k.rms_fit() / k.rms_predicted(), 1.3) << diameter;
  }
}

// Scatter of one spot's centre over noise realisations against the mean
// reported standard deviation, per axis.
void CheckCovariance(const SpotImageOptions& base, const SpotDetectionOptions& detect,
                     double diameter, double peak_dn, const char* what) {
  SpotToRender t;
  t.u_px = 32.37;
  t.v_px = 31.81;
  t.shape_covariance_px2 = EllipticalSpotShape(diameter, 0.7 * diameter, 0.4);
  t.peak_dn = peak_dn;
  const int trials = 200;
  double su2 = 0, sv2 = 0, pu = 0, pv = 0;
  int n = 0;
  for (int i = 0; i < trials; ++i) {
    SpotImageOptions o = base;
    o.seed = static_cast<uint64_t>(i + 1);
    auto img = RenderSpotImage({t}, o);
    ASSERT_TRUE(img.ok());
    auto r = DetectSpots(img->image, detect);
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->spots.size(), 1u);
    const DetectedSpot& s = r->spots[0];
    su2 += std::pow(s.u_px - t.u_px, 2);
    sv2 += std::pow(s.v_px - t.v_px, 2);
    pu += s.covariance_px2(0, 0);
    pv += s.covariance_px2(1, 1);
    ++n;
  }
  const double ratio_u = std::sqrt(su2 / n) / std::sqrt(pu / n);
  const double ratio_v = std::sqrt(sv2 / n) / std::sqrt(pv / n);
  std::printf("%s: RMS u %.4f v %.4f px, predicted sigma u %.4f v %.4f px, ratio %.3f %.3f\n", what,
              std::sqrt(su2 / n), std::sqrt(sv2 / n), std::sqrt(pu / n), std::sqrt(pv / n), ratio_u,
              ratio_v);
  EXPECT_GT(ratio_u, 0.8) << what;
  EXPECT_LT(ratio_u, 1.25) << what;
  EXPECT_GT(ratio_v, 0.8) << what;
  EXPECT_LT(ratio_v, 1.25) << what;
}

TEST(SpotDetection, ReportedCovarianceMatchesMonteCarloScatter) {
  SpotImageOptions o;
  o.width_px = 64;
  o.height_px = 64;
  o.background_dn = 200;
  o.read_noise_dn = 10;
  SpotDetectionOptions d;
  d.background_block_px = 16;
  CheckCovariance(o, d, 8.0, 500.0, "read noise, SNR 50, D 8 px");
  // Shot noise dominated, gain known to the detector.
  o.read_noise_dn = 3;
  o.gain_e_per_dn = 0.5;
  d.gain_e_per_dn = 0.5;
  CheckCovariance(o, d, 10.0, 3000.0, "shot + read noise, gain 0.5 e/DN, D 10 px");
}

TEST(SpotDetection, NoFalseDetectionsOnNoise) {
  SpotImageOptions o;
  o.width_px = 1024;
  o.height_px = 768;
  o.background_dn = 300;
  o.background_gradient_u_dn_per_px = 0.2;
  o.background_gradient_v_dn_per_px = -0.1;
  o.read_noise_dn = 10;
  o.gain_e_per_dn = 1.0;
  for (uint64_t seed : {1u, 2u}) {
    o.seed = seed;
    auto img = RenderSpotImage({}, o);
    ASSERT_TRUE(img.ok());
    auto r = DetectSpots(img->image);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->spots.size(), 0u) << r->ToText();
    // The estimated noise: sqrt(read^2 + level / gain), level 300 at the
    // centre (the gradient changes it by +-100 DN across the image).
    EXPECT_NEAR(r->noise_dn, std::sqrt(100.0 + 300.0 + 1.0 / 12.0), 1.0) << r->ToText();
    EXPECT_NEAR(r->background_dn, 300.0, 5.0);
  }
}

TEST(SpotDetection, FindsEverySpotAboveSnr20) {
  SpotImageOptions o;
  o.width_px = 800;
  o.height_px = 600;
  o.background_dn = 400;
  o.background_gradient_u_dn_per_px = 0.3;
  o.read_noise_dn = 8;
  o.gain_e_per_dn = 2.0;
  o.seed = 5;
  std::mt19937_64 rng(99);
  std::vector<SpotToRender> spots;
  const double noise = std::sqrt(64.0 + 400.0 / 2.0);  // at the image centre
  for (int y = 40; y + 40 <= o.height_px; y += 60) {
    for (int x = 40; x + 40 <= o.width_px; x += 60) {
      SpotToRender t;
      t.u_px = x + 6 * (Uniform01(rng) - 0.5);
      t.v_px = y + 6 * (Uniform01(rng) - 0.5);
      const double d = 4.0 + 11.0 * Uniform01(rng);
      t.shape_covariance_px2 = EllipticalSpotShape(d, d * (0.6 + 0.4 * Uniform01(rng)),
                                                   kPi * Uniform01(rng));
      t.peak_dn = noise * (20.0 + 200.0 * Uniform01(rng));
      spots.push_back(t);
    }
  }
  auto img = RenderSpotImage(spots, o);
  ASSERT_TRUE(img.ok());
  auto r = DetectSpots(img->image);
  ASSERT_TRUE(r.ok());
  const Errors e = Match(spots, r->spots);
  EXPECT_EQ(e.missed, 0) << r->ToText();
  EXPECT_EQ(e.extra, 0) << r->ToText();
  EXPECT_EQ(static_cast<int>(r->spots.size()), static_cast<int>(spots.size()));
  EXPECT_LT(e.max_fit, 0.3);
}

// Step 6: of two detections closer than min_spot_separation_px the one of
// lower peak goes. Two separate spots 30 px apart: both kept at the default
// (2 px), the fainter dropped when the separation is set to 35 px.
TEST(SpotDetection, DuplicatesKeepTheBrighter) {
  SpotImageOptions o;
  o.width_px = 120;
  o.height_px = 80;
  o.background_dn = 300;
  o.read_noise_dn = 3;
  SpotToRender bright, faint;
  bright.u_px = 50.3;
  bright.v_px = 40.2;
  bright.shape_covariance_px2 = RoundSpotShape(6.0);
  bright.peak_dn = 3000;
  faint = bright;
  faint.u_px = 80.3;
  faint.peak_dn = 1500;
  auto img = RenderSpotImage({bright, faint}, o);
  ASSERT_TRUE(img.ok());
  auto r = DetectSpots(img->image);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->spots.size(), 2u) << r->ToText();
  EXPECT_EQ(r->rejected_duplicate, 0);
  SpotDetectionOptions wide;
  wide.min_spot_separation_px = 35.0;
  r = DetectSpots(img->image, wide);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->spots.size(), 1u) << r->ToText();
  EXPECT_EQ(r->rejected_duplicate, 1);
  EXPECT_NEAR(r->spots[0].u_px, 50.3, 0.1);
  wide.min_spot_separation_px = -1.0;
  EXPECT_FALSE(DetectSpots(img->image, wide).ok());
}

TEST(SpotDetection, RejectsMergedAndElongatedBlobs) {
  SpotImageOptions o;
  o.width_px = 200;
  o.height_px = 100;
  o.background_dn = 100;
  o.read_noise_dn = 5;
  SpotToRender a;
  a.u_px = 40;
  a.v_px = 50;
  a.shape_covariance_px2 = RoundSpotShape(8.0);
  a.peak_dn = 1000;
  SpotToRender b = a;
  b.u_px = 49.5;  // 4.75 sigma apart: one component with a dip
  SpotToRender streak = a;
  streak.u_px = 140;
  streak.shape_covariance_px2 = EllipticalSpotShape(50.0, 4.0, 0.3);
  auto img = RenderSpotImage({a, b, streak}, o);
  ASSERT_TRUE(img.ok());
  auto r = DetectSpots(img->image);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->spots.size(), 0u) << r->ToText();
  EXPECT_EQ(r->rejected_merged, 1) << r->ToText();
  EXPECT_EQ(r->rejected_elongated, 1) << r->ToText();
  // Apart, both are found.
  b.u_px = 80;
  img = RenderSpotImage({a, b}, o);
  ASSERT_TRUE(img.ok());
  r = DetectSpots(img->image);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->spots.size(), 2u) << r->ToText();
}

TEST(SpotDetection, EightBitImagesAndSpotProperties) {
  SpotImageOptions o;
  o.width_px = 160;
  o.height_px = 120;
  o.bit_depth = 8;
  o.background_dn = 30;
  o.read_noise_dn = 1.5;
  SpotToRender t;
  t.u_px = 70.3;
  t.v_px = 55.6;
  t.shape_covariance_px2 = EllipticalSpotShape(12.0, 8.0, 0.3);
  t.peak_dn = 150;
  auto img = RenderSpotImage({t}, o);
  ASSERT_TRUE(img.ok());
  auto r = DetectSpots(img->image);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->spots.size(), 1u);
  const DetectedSpot& s = r->spots[0];
  EXPECT_NEAR(s.u_px, t.u_px, 0.05);
  EXPECT_NEAR(s.v_px, t.v_px, 0.05);
  EXPECT_NEAR(s.peak_dn, 150.0, 6.0);
  EXPECT_NEAR(s.background_dn, 30.0, 0.5);
  const double flux = 2 * kPi * std::sqrt(t.shape_covariance_px2.determinant()) * t.peak_dn;
  EXPECT_NEAR(s.flux_dn / flux, 1.0, 0.05);
  // Point-sampled fit of a pixel-integrated spot: C + I/12.
  const Eigen::Matrix2d expected = t.shape_covariance_px2 + Eigen::Matrix2d::Identity() / 12.0;
  EXPECT_LT((s.shape_px2 - expected).cwiseAbs().maxCoeff(), 0.15) << s.shape_px2;
  EXPECT_EQ(s.flags, 0u);
  EXPECT_EQ(s.saturated_px, 0);
  EXPECT_NEAR(s.snr, 100.0, 10.0);
  EXPECT_GT(s.reduced_chi2, 0.7);
  EXPECT_LT(s.reduced_chi2, 1.4);
}

TEST(SpotDetection, SaturatedSpotIsFlagged) {
  SpotImageOptions o;
  o.width_px = 100;
  o.height_px = 100;
  o.bit_depth = 8;
  o.background_dn = 10;
  o.read_noise_dn = 1;
  SpotToRender t;
  t.u_px = 50.25;
  t.v_px = 49.6;
  t.shape_covariance_px2 = RoundSpotShape(10.0);
  t.peak_dn = 765;
  auto img = RenderSpotImage({t}, o);
  ASSERT_TRUE(img.ok());
  auto r = DetectSpots(img->image);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->spots.size(), 1u);
  EXPECT_TRUE(r->spots[0].has(kSpotSaturated));
  EXPECT_EQ(r->spots[0].saturated_px, img->spots[0].saturated_pixels);
  EXPECT_NEAR(r->spots[0].peak_dn, 765.0, 40.0);  // the fitted amplitude above full scale
}

// Every reported covariance is symmetric to the bit and positive definite:
// MatchSpots and the bundle adjustment refuse any other. The fit's
// covariance is a block of a solve against the identity, symmetric only to
// rounding; on a faint, elongated non-spot blob (SNR 5, 983 px: the
// off-diagonal terms -2.92429898427 and -2.92429898426) that rounding
// exceeded MatchSpots' 1e-12 and failed a whole measurement (4 of 1000
// seeded scene_small renders). This image is one of them: seed 423, shot
// cam3_B.
TEST(SpotDetection, CovariancesAreSymmetricPositiveDefinite) {
  Result<::opl::Scene> scene = ReadSceneJson(test::SourceDir() + "/examples/scene_small.json");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  scene->seed = 423;
  int shot = -1;
  for (size_t i = 0; i < scene->shots.size(); ++i) {
    if (scene->shots[i].file == "cam3_B.png") shot = static_cast<int>(i);
  }
  ASSERT_GE(shot, 0);
  Result<RenderedShot> rendered = RenderShot(*scene, shot);
  ASSERT_TRUE(rendered.ok()) << rendered.status().ToString();
  Result<SpotDetectionResult> r = DetectSpots(rendered->image);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_GE(r->spots.size(), 110u) << r->ToText();
  int faint_blobs = 0;
  for (const DetectedSpot& s : r->spots) {
    const Eigen::Matrix2d& c = s.covariance_px2;
    const std::string where =
        "spot at (" + FormatNumber(s.u_px, 6) + ", " + FormatNumber(s.v_px, 6) + ")";
    EXPECT_EQ(c(0, 1), c(1, 0)) << where;
    EXPECT_TRUE(c.allFinite() && c(0, 0) > 0 && c(1, 1) > 0 && c.determinant() > 0)
        << where << ": " << c;
    if (s.snr < 10 && s.area_px > 500) ++faint_blobs;
  }
  // The case this guards: the faint elongated blob is still reported.
  EXPECT_GE(faint_blobs, 1);
}

TEST(SpotDetection, BadInputGivesClearStatus) {
  auto r = DetectSpots(cv::Mat());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("empty"), std::string::npos);
  r = DetectSpots(cv::Mat(10, 10, CV_8UC3, cv::Scalar::all(0)));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("CV_8UC3"), std::string::npos) << r.status().message();
  r = DetectSpots(cv::Mat(10, 10, CV_32FC1, cv::Scalar::all(0)));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("CV_32FC1"), std::string::npos) << r.status().message();
  SpotDetectionOptions d;
  d.threshold_sigma = 0;
  r = DetectSpots(cv::Mat(10, 10, CV_8UC1, cv::Scalar::all(0)), d);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("threshold_sigma = 0"), std::string::npos)
      << r.status().message();
  d = SpotDetectionOptions();
  d.max_area_px = 1;
  d.min_area_px = 4;
  EXPECT_FALSE(d.Validate().ok());
  EXPECT_TRUE(SpotDetectionOptions().Validate().ok());
  // A flat image is valid and has no spots.
  r = DetectSpots(cv::Mat(50, 50, CV_16UC1, cv::Scalar::all(1000)));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->spots.size(), 0u);
}

}  // namespace
}  // namespace opl
