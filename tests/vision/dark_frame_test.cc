// Dark-frame subtraction and the tag shift that decides whether a dark frame
// belongs to a lit image (vision/dark_frame.h), by hand-computed values.
#include "opl/vision/dark_frame.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace opl {
namespace {

TEST(SubtractDarkFrame, EightBitKeepsEveryDifferenceAndMarksSaturation) {
  cv::Mat lit = (cv::Mat_<uint8_t>(1, 6) << 100, 10, 255, 255, 255, 200);
  cv::Mat dark = (cv::Mat_<uint8_t>(1, 6) << 40, 250, 30, 255, 240, 200);
  Result<cv::Mat> d = SubtractDarkFrame(lit, dark);
  ASSERT_TRUE(d.ok()) << d.status().message();
  ASSERT_EQ(d->type(), CV_16UC1);
  EXPECT_EQ(d->at<uint16_t>(0, 0), 100 - 40 + 256);
  EXPECT_EQ(d->at<uint16_t>(0, 1), 10 - 250 + 256);  // negative differences are kept
  EXPECT_EQ(d->at<uint16_t>(0, 2), 65535);           // saturated with the lasers only
  EXPECT_EQ(d->at<uint16_t>(0, 3), 256);             // a lamp, saturated in both
  EXPECT_EQ(d->at<uint16_t>(0, 4), 256);             // its rim: 240 >= 0.9 * 255
  EXPECT_EQ(d->at<uint16_t>(0, 5), 256);
  // A 12-bit sensor in a 16-bit container: saturation given.
  cv::Mat lit16 = (cv::Mat_<uint16_t>(1, 3) << 4095, 4095, 70);
  cv::Mat dark16 = (cv::Mat_<uint16_t>(1, 3) << 100, 4000, 65);
  d = SubtractDarkFrame(lit16, dark16, 4095.0);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->at<uint16_t>(0, 0), 65535);
  EXPECT_EQ(d->at<uint16_t>(0, 1), 4096);
  EXPECT_EQ(d->at<uint16_t>(0, 2), 70 - 65 + 4096);
}

TEST(SubtractDarkFrame, MismatchedImagesAreRefused) {
  EXPECT_FALSE(SubtractDarkFrame(cv::Mat::zeros(4, 4, CV_8UC1), cv::Mat::zeros(4, 5, CV_8UC1)).ok());
  EXPECT_FALSE(SubtractDarkFrame(cv::Mat::zeros(4, 4, CV_8UC1), cv::Mat::zeros(4, 4, CV_16UC1)).ok());
  EXPECT_FALSE(SubtractDarkFrame(cv::Mat::zeros(4, 4, CV_32FC1), cv::Mat::zeros(4, 4, CV_32FC1)).ok());
}

TagDetection Tag(int id, double u, double v) {
  TagDetection t;
  t.id = id;
  t.corner_covariance_px2.fill(Eigen::Matrix2d::Identity());
  t.corners_px = {Eigen::Vector2d(u, v), Eigen::Vector2d(u + 10, v), Eigen::Vector2d(u + 10, v + 10),
                  Eigen::Vector2d(u, v + 10)};
  return t;
}

TEST(TagShiftPx, MedianOverTheCommonTagsCorners) {
  const std::vector<TagDetection> a = {Tag(1, 0, 0), Tag(2, 50, 50), Tag(3, 90, 0)};
  std::vector<TagDetection> b = {Tag(2, 50.3, 50.4), Tag(1, 0, 0.2), Tag(7, 5, 5)};
  int common = 0;
  // Corner shifts: 0.5 x 4 (tag 2) and 0.2 x 4 (tag 1): the median of
  // eight is the upper middle one, 0.5.
  EXPECT_NEAR(TagShiftPx(a, b, &common), 0.5, 1e-12);
  EXPECT_EQ(common, 2);
  b = {Tag(9, 0, 0)};
  EXPECT_EQ(TagShiftPx(a, b, &common), std::numeric_limits<double>::infinity());
  EXPECT_EQ(common, 0);
}

// A textured scene (smooth ramp plus a checker of 8 x 8 px cells, 20-200
// DN) seen twice with Gaussian noise of 2 DN: `exposure` scales the scene
// of the lit frame, which also shows 60 laser spots (peak 80 DN, sigma
// 2 px) on a 10 x 6 grid.
struct FramePair {
  cv::Mat lit, dark;
  cv::Mat spot_free;  // 255 where no spot is within 8 px
};

FramePair MakeFrames(double exposure, int depth, uint64_t seed) {
  const int W = 640, H = 400;
  const double scale = depth == CV_8U ? 1.0 : 257.0;
  cv::Mat scene(H, W, CV_64FC1), spots = cv::Mat::zeros(H, W, CV_64FC1);
  for (int y = 0; y < H; ++y) {
    for (int x = 0; x < W; ++x) {
      const bool cell = ((x / 8) + (y / 8)) % 2 == 0;
      scene.at<double>(y, x) = 20.0 + 100.0 * x / W + (cell ? 80.0 : 0.0);
    }
  }
  FramePair f;
  f.spot_free = cv::Mat(H, W, CV_8UC1, cv::Scalar(255));
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 6; ++j) {
      const double cu = 40.0 + 62.0 * i + 0.3 * j, cv_ = 40.0 + 62.0 * j + 0.2 * i;
      for (int y = static_cast<int>(cv_) - 8; y <= static_cast<int>(cv_) + 8; ++y) {
        for (int x = static_cast<int>(cu) - 8; x <= static_cast<int>(cu) + 8; ++x) {
          const double r2 = (x - cu) * (x - cu) + (y - cv_) * (y - cv_);
          spots.at<double>(y, x) += 80.0 * std::exp(-0.5 * r2 / 4.0);
          f.spot_free.at<uint8_t>(y, x) = 0;
        }
      }
    }
  }
  cv::RNG rng(seed);
  cv::Mat noise_lit(H, W, CV_64FC1), noise_dark(H, W, CV_64FC1);
  rng.fill(noise_lit, cv::RNG::NORMAL, 0.0, 2.0);
  rng.fill(noise_dark, cv::RNG::NORMAL, 0.0, 2.0);
  const cv::Mat lit = (exposure * scene + spots + noise_lit) * scale;
  const cv::Mat dark = (scene + noise_dark) * scale;
  lit.convertTo(f.lit, depth == CV_8U ? CV_8UC1 : CV_16UC1);  // rounds and saturates
  dark.convertTo(f.dark, depth == CV_8U ? CV_8UC1 : CV_16UC1);
  return f;
}

// The spread of a difference image where there is no spot [DN].
double SpotFreeSigma(const cv::Mat& difference, const cv::Mat& spot_free) {
  cv::Scalar mean, sd;
  cv::meanStdDev(difference, mean, sd, spot_free);
  return sd[0];
}

TEST(EstimateDarkFrameGain, FindsTheExposureChangeAndItsSubtractionRemovesTheScene) {
  for (const double exposure : {0.94, 1.06}) {
    const FramePair f = MakeFrames(exposure, CV_8U, 7);
    Result<DarkFrameGain> g = EstimateDarkFrameGain(f.lit, f.dark);
    ASSERT_TRUE(g.ok()) << g.status().message();
    // The truth is the exposure itself; sums over ~256k pixels with 2 DN
    // noise leave about 1e-4, the spots' tails below 5 sigma about 8e-4.
    EXPECT_NEAR(g->gain, exposure, 2e-3);
    // Noise of lit - gain dark: 2 sqrt(1 + gain^2) ~ 2.8 DN (plus rounding).
    EXPECT_NEAR(g->residual_sigma_dn, 2.0 * std::sqrt(1.0 + exposure * exposure), 0.4);
    // 6% of the dark's 95th percentile (~200 DN).
    EXPECT_NEAR(g->mismatch_dn, 0.06 * 200.0, 1.5);
    EXPECT_TRUE(DarkFrameGainMatters(*g, CV_8U));
    Result<cv::Mat> plain = SubtractDarkFrame(f.lit, f.dark);
    Result<cv::Mat> matched = SubtractDarkFrame(f.lit, f.dark, 0.0, g->gain);
    ASSERT_TRUE(plain.ok() && matched.ok());
    // As they are, the checker is left at 6% of its 80 DN step and more;
    // matched, only the noise.
    EXPECT_GT(SpotFreeSigma(*plain, f.spot_free), 4.0);
    EXPECT_LT(SpotFreeSigma(*matched, f.spot_free), 3.0);
    // The spots keep their peaks (80 DN over the offset 256 x ceil(gain))
    // where the lit frame is not saturated (65535 marks those).
    const int offset = 256 * static_cast<int>(std::ceil(exposure));
    cv::Mat unsaturated;
    cv::compare(*matched, cv::Scalar(65535), unsaturated, cv::CMP_LT);
    const cv::Mat dark_cells = f.dark < 100;  // spots on the checker's dark cells
    double peak = 0.0;
    cv::minMaxLoc(*matched, nullptr, &peak, nullptr, nullptr, unsaturated & dark_cells);
    EXPECT_NEAR(peak - offset, 80.0, 10.0);
  }
}

TEST(EstimateDarkFrameGain, OneExposureIsLeftAsItIs) {
  const FramePair f = MakeFrames(1.0, CV_8U, 11);
  Result<DarkFrameGain> g = EstimateDarkFrameGain(f.lit, f.dark);
  ASSERT_TRUE(g.ok());
  // The spots' tails below 5 sigma stay in the sums: about 8e-4 here (their
  // share of the light), a residue of 0.16 DN, far below what matters.
  EXPECT_NEAR(g->gain, 1.0, 2e-3);
  EXPECT_LT(g->mismatch_dn, 0.5);
  EXPECT_FALSE(DarkFrameGainMatters(*g, CV_8U));
  // Noise-free frames of one exposure: the same pixels but the spots.
  cv::Mat lit = f.dark.clone();
  lit(cv::Rect(100, 100, 5, 5)).setTo(cv::Scalar(250));
  g = EstimateDarkFrameGain(lit, f.dark);
  ASSERT_TRUE(g.ok());
  EXPECT_EQ(g->gain, 1.0);
  EXPECT_FALSE(DarkFrameGainMatters(*g, CV_8U));
}

TEST(EstimateDarkFrameGain, SixteenBitFrames) {
  const FramePair f = MakeFrames(0.9, CV_16U, 3);
  Result<DarkFrameGain> g = EstimateDarkFrameGain(f.lit, f.dark);
  ASSERT_TRUE(g.ok());
  EXPECT_NEAR(g->gain, 0.9, 1e-3);
  EXPECT_TRUE(DarkFrameGainMatters(*g, CV_16U));
  Result<cv::Mat> matched = SubtractDarkFrame(f.lit, f.dark, 0.0, g->gain);
  ASSERT_TRUE(matched.ok());
  EXPECT_LT(SpotFreeSigma(*matched, f.spot_free), 3.0 * 257.0);
}

TEST(EstimateDarkFrameGain, SaturatedFramesAndBadGainsAreRefused) {
  const cv::Mat white(100, 100, CV_8UC1, cv::Scalar(255));
  Result<DarkFrameGain> g = EstimateDarkFrameGain(white, white);
  ASSERT_FALSE(g.ok());
  EXPECT_EQ(g.status().code(), StatusCode::kNoSolution);
  EXPECT_FALSE(EstimateDarkFrameGain(white, cv::Mat(100, 101, CV_8UC1)).ok());
  const cv::Mat black = cv::Mat::zeros(100, 100, CV_8UC1);
  EXPECT_FALSE(EstimateDarkFrameGain(black, black).ok());
  EXPECT_FALSE(SubtractDarkFrame(black, black, 0.0, 0.0).ok());
  EXPECT_FALSE(SubtractDarkFrame(black, black, 0.0, 17.0).ok());
  // By hand: 100 - 1.5 x 40 + 512 (the offset for a gain in (1, 2]).
  const cv::Mat lit = (cv::Mat_<uint8_t>(1, 2) << 100, 10);
  const cv::Mat dark = (cv::Mat_<uint8_t>(1, 2) << 40, 250);
  Result<cv::Mat> d = SubtractDarkFrame(lit, dark, 0.0, 1.5);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->at<uint16_t>(0, 0), 100 - 60 + 512);
  EXPECT_EQ(d->at<uint16_t>(0, 1), 10 - 375 + 512);
}

}  // namespace
}  // namespace opl
