// The overlay of a shot (report/shot_overlay.h): every kind of finding is
// drawn in its documented colour at its place, over a dimmed grey copy of
// the image, whatever the image's depth and channels.
#include "opl/report/shot_overlay.h"

#include <gtest/gtest.h>

namespace opl {
namespace {

// Is the BGR pixel near `bgr` (each channel within 60)?
bool Near(const cv::Vec3b& px, int b, int g, int r) {
  return std::abs(px[0] - b) < 60 && std::abs(px[1] - g) < 60 && std::abs(px[2] - r) < 60;
}

ShotOverlay Example() {
  ShotOverlay o;
  o.title = "cam0_A.png";
  o.tags.push_back({7, {Eigen::Vector2d(100, 300), Eigen::Vector2d(200, 300),
                        Eigen::Vector2d(200, 400), Eigen::Vector2d(100, 400)}});
  o.spots.push_back({Eigen::Vector2d(400, 200), ShotOverlay::SpotState::kIdentified, "A61"});
  o.spots.push_back({Eigen::Vector2d(500, 200), ShotOverlay::SpotState::kMatched, ""});
  o.spots.push_back({Eigen::Vector2d(600, 200), ShotOverlay::SpotState::kDetected, ""});
  o.rejected_px.push_back(Eigen::Vector2d(700, 300));
  return o;
}

TEST(ShotOverlay, EveryFindingInItsColour) {
  const cv::Mat image(480, 800, CV_8UC1, cv::Scalar(200));
  Result<cv::Mat> drawn = DrawShotOverlay(image, Example());
  ASSERT_TRUE(drawn.ok()) << drawn.status().message();
  ASSERT_EQ(drawn->type(), CV_8UC3);
  ASSERT_EQ(drawn->size(), image.size());
  // Radius: max(6, 800 / 250) = 6 px; the ring passes 6 px right of each centre.
  EXPECT_TRUE(Near(drawn->at<cv::Vec3b>(200, 406), 0, 220, 0));    // identified: green
  EXPECT_TRUE(Near(drawn->at<cv::Vec3b>(200, 506), 0, 230, 255));  // matched: yellow
  EXPECT_TRUE(Near(drawn->at<cv::Vec3b>(200, 606), 0, 140, 255));  // unmatched: orange
  EXPECT_TRUE(Near(drawn->at<cv::Vec3b>(300, 700), 40, 40, 255));  // rejected: red cross
  EXPECT_TRUE(Near(drawn->at<cv::Vec3b>(350, 200), 255, 255, 0));  // tag edge: cyan
  // Away from every marker: the grey image dimmed to 60%.
  EXPECT_EQ(drawn->at<cv::Vec3b>(450, 450), cv::Vec3b(120, 120, 120));
  // The caption band at the top is black with white text.
  EXPECT_EQ(drawn->at<cv::Vec3b>(1, 790), cv::Vec3b(0, 0, 0));
}

TEST(ShotOverlay, SixteenBitAndColourImages) {
  const cv::Mat grey16(480, 800, CV_16UC1, cv::Scalar(257 * 100));
  Result<cv::Mat> drawn = DrawShotOverlay(grey16, Example());
  ASSERT_TRUE(drawn.ok());
  EXPECT_EQ(drawn->at<cv::Vec3b>(450, 450), cv::Vec3b(60, 60, 60));
  const cv::Mat colour(480, 800, CV_8UC3, cv::Scalar(100, 100, 100));
  drawn = DrawShotOverlay(colour, Example());
  ASSERT_TRUE(drawn.ok());
  EXPECT_EQ(drawn->at<cv::Vec3b>(450, 450), cv::Vec3b(60, 60, 60));
  EXPECT_FALSE(DrawShotOverlay(cv::Mat(), Example()).ok());
  EXPECT_FALSE(DrawShotOverlay(cv::Mat(4, 4, CV_32FC1), Example()).ok());
}

}  // namespace
}  // namespace opl
