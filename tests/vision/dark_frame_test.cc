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

}  // namespace
}  // namespace opl
