// SpotChannel (vision/shot_image.h): names, and the red-minus-green image
// of 8- and 16-bit colour photographs, with its saturation rule.
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "opl/vision/shot_image.h"

namespace opl {
namespace {

TEST(SpotChannel, NamesRoundTrip) {
  for (SpotChannel c : {SpotChannel::kRed, SpotChannel::kGreen, SpotChannel::kBlue,
                        SpotChannel::kLuma, SpotChannel::kRedMinusGreen}) {
    Result<SpotChannel> parsed = ParseSpotChannel(SpotChannelName(c));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, c);
  }
  EXPECT_STREQ(SpotChannelName(SpotChannel::kRedMinusGreen), "red-minus-green");
  Result<SpotChannel> bad = ParseSpotChannel("magenta");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message(),
            "spot channel 'magenta' is not one of red, green, blue, luma, red-minus-green");
}

// BGR pixels (b, g, r) -> R - G, saturated at 0; R clipped and G not: full scale.
template <typename T>
void CheckRedMinusGreen(double full) {
  const int type = cv::DataType<T>::depth;
  cv::Mat bgr(1, 5, CV_MAKETYPE(type, 3));
  const auto px = [&](int i, double b, double g, double r) {
    bgr.at<cv::Vec<T, 3>>(0, i) = cv::Vec<T, 3>(static_cast<T>(b), static_cast<T>(g), static_cast<T>(r));
  };
  px(0, 10, 0.2 * full, 0.8 * full);  // a red spot: 0.6
  px(1, 10, 0.7 * full, 0.3 * full);  // green wall: 0
  px(2, 0.5 * full, full, full);      // a white lamp, clipped: 0
  px(3, 10, 0.4 * full, full);        // a saturated red spot: full scale
  px(4, 0.9 * full, 0.9 * full, 0.9 * full);  // white: 0
  const cv::Mat out = RedMinusGreen(bgr);
  ASSERT_EQ(out.type(), CV_MAKETYPE(type, 1));
  EXPECT_EQ(out.at<T>(0, 0), static_cast<T>(static_cast<T>(0.8 * full) - static_cast<T>(0.2 * full)));
  EXPECT_EQ(out.at<T>(0, 1), 0);
  EXPECT_EQ(out.at<T>(0, 2), 0);
  EXPECT_EQ(out.at<T>(0, 3), static_cast<T>(full));
  EXPECT_EQ(out.at<T>(0, 4), 0);
}

TEST(SpotChannel, RedMinusGreen8And16Bit) {
  CheckRedMinusGreen<uint8_t>(255.0);
  CheckRedMinusGreen<uint16_t>(65535.0);
  // BGRA too.
  cv::Mat bgra(1, 1, CV_8UC4, cv::Scalar(0, 40, 240, 255));
  EXPECT_EQ(RedMinusGreen(bgra).at<uint8_t>(0, 0), 200);
}

TEST(SpotChannel, ReadShotImageGivesRedMinusGreenForSpotsAndLumaForTags) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("opl_spot_channel_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + ".png");
  cv::Mat bgr(4, 4, CV_16UC3, cv::Scalar(1000, 3000, 50000));
  ASSERT_TRUE(cv::imwrite(path.string(), bgr));
  Result<ShotImage> shot = ReadShotImage(path.string(), SpotChannel::kRedMinusGreen);
  std::filesystem::remove(path);
  ASSERT_TRUE(shot.ok()) << shot.status().ToString();
  EXPECT_EQ(shot->for_spots.type(), CV_16UC1);
  EXPECT_EQ(shot->for_spots.at<uint16_t>(2, 2), 47000);
  // Tags in luma: 0.299 R + 0.587 G + 0.114 B.
  EXPECT_NEAR(shot->for_tags.at<uint16_t>(2, 2), 0.299 * 50000 + 0.587 * 3000 + 0.114 * 1000, 1.0);
}

}  // namespace
}  // namespace opl
