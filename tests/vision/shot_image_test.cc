// ReadShotImage (vision/shot_image.h): sensor pixels whatever the EXIF
// orientation says, tags in luma, spots in the laser's channel.
#include "opl/vision/shot_image.h"

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "opl/lab/shot_file.h"
#include "opl/vision/spot_detection.h"

namespace opl {
namespace {

// A JPEG of `image` carrying an EXIF APP1 segment whose only entry is
// Orientation (0x0112) = `orientation` (lab/shot_file.h).
std::string JpegWithExifOrientation(const cv::Mat& image, int orientation) {
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95});
  return *InsertExifOrientation(std::string(jpeg.begin(), jpeg.end()), orientation);
}

TEST(ShotImage, ExifOrientationIsNotApplied) {
  // A 96 x 48 gradient: rotated by a viewer it would be 48 x 96.
  cv::Mat image(48, 96, CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) image.at<uchar>(y, x) = static_cast<uchar>(2 * x + y);
  }
  testing_support::TempDir dir;
  const std::string path = dir.Write("portrait.jpg", JpegWithExifOrientation(image, 6));
  // The tag is real: OpenCV's default read honours it (90 deg clockwise).
  const cv::Mat rotated = cv::imread(path, cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(rotated.cols, 48);
  ASSERT_EQ(rotated.rows, 96);

  Result<ShotImage> shot = ReadShotImage(path, SpotChannel::kRed);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  ASSERT_EQ(shot->for_tags.cols, 96);
  ASSERT_EQ(shot->for_tags.rows, 48);
  EXPECT_EQ(shot->source_channels, 1);
  // The sensor's pixels, up to JPEG's loss.
  cv::Mat diff;
  cv::absdiff(shot->for_tags, image, diff);
  EXPECT_LT(cv::mean(diff)[0], 2.0);
}

TEST(ShotImage, RedLaserSpotKeepsItsContrastInTheRedChannel) {
  // A light grey wall with independent noise per channel and a red spot
  // (R only, 30 DN, sigma 2.5 px).
  const int w = 160, h = 120;
  const double u0 = 80.3, v0 = 60.7, sigma = 2.5, amplitude = 30.0;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 2.0);
  cv::Mat bgr(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double d2 = (x - u0) * (x - u0) + (y - v0) * (y - v0);
      const double spot = amplitude * std::exp(-0.5 * d2 / (sigma * sigma));
      const double level[3] = {150.0, 160.0, 170.0 + spot};  // B, G, R
      for (int c = 0; c < 3; ++c) {
        bgr.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>(level[c] + noise(rng));
      }
    }
  }
  testing_support::TempDir dir;
  const std::string path = dir.File("wall.png");
  ASSERT_TRUE(cv::imwrite(path, bgr));

  auto detect = [&](SpotChannel channel) {
    Result<ShotImage> shot = ReadShotImage(path, channel);
    EXPECT_TRUE(shot.ok());
    EXPECT_EQ(shot->source_channels, 3);
    Result<SpotDetectionResult> r = DetectSpots(shot->for_spots);
    EXPECT_TRUE(r.ok());
    return *r;
  };
  const SpotDetectionResult red = detect(SpotChannel::kRed);
  ASSERT_EQ(red.spots.size(), 1u);
  EXPECT_NEAR(red.spots[0].u_px, u0, 0.2);
  EXPECT_NEAR(red.spots[0].v_px, v0, 0.2);
  const SpotDetectionResult luma = detect(SpotChannel::kLuma);
  ASSERT_EQ(luma.spots.size(), 1u);
  // Luma keeps 0.299 of the amplitude and averages the noise down by
  // sqrt(0.299^2 + 0.587^2 + 0.114^2) = 0.668: SNR x 0.45 in expectation;
  // measured here (the noise estimated on this small image, luma rounded
  // to 8 bits): 13.8 against 8.6, x 0.62. The same channel would give 1.
  EXPECT_GT(red.spots[0].snr, 1.4 * luma.spots[0].snr)
      << red.spots[0].snr << " vs " << luma.spots[0].snr;
  EXPECT_TRUE(detect(SpotChannel::kGreen).spots.empty());
  EXPECT_TRUE(detect(SpotChannel::kBlue).spots.empty());

  // Tags are always read in luma.
  Result<ShotImage> shot = ReadShotImage(path, SpotChannel::kRed);
  cv::Mat grey, diff;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::absdiff(shot->for_tags, grey, diff);
  EXPECT_EQ(cv::countNonZero(diff), 0);
}

TEST(ShotImage, Errors) {
  testing_support::TempDir dir;
  Result<ShotImage> missing = ReadShotImage(dir.File("none.png"), SpotChannel::kRed);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_NE(missing.status().message().find("none.png: no such image"), std::string::npos);

  const std::string text = dir.Write("notes.png", "not an image");
  Result<ShotImage> garbage = ReadShotImage(text, SpotChannel::kRed);
  ASSERT_FALSE(garbage.ok());
  EXPECT_NE(garbage.status().message().find("cannot read the image"), std::string::npos);

  const std::string tiff = dir.File("float.tiff");
  ASSERT_TRUE(cv::imwrite(tiff, cv::Mat(8, 8, CV_32FC1, cv::Scalar(0.5))));
  Result<ShotImage> floating = ReadShotImage(tiff, SpotChannel::kRed);
  ASSERT_FALSE(floating.ok());
  EXPECT_NE(floating.status().message().find("CV_32FC1"), std::string::npos)
      << floating.status().message();

  EXPECT_EQ(*ParseSpotChannel("green"), SpotChannel::kGreen);
  EXPECT_FALSE(ParseSpotChannel("infrared").ok());
  for (SpotChannel c : {SpotChannel::kRed, SpotChannel::kGreen, SpotChannel::kBlue,
                        SpotChannel::kLuma}) {
    EXPECT_EQ(*ParseSpotChannel(SpotChannelName(c)), c);
  }
}

}  // namespace
}  // namespace opl
