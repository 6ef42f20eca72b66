// Sensor coverage of a calibration's corners (report/coverage_image.h):
// the counts per cell, the covered fraction and the picture's size.
#include "opl/report/coverage_image.h"

#include <gtest/gtest.h>

namespace opl {
namespace {

TEST(CoverageImage, CountsCornersPerCell) {
  // 100 x 50 image, 4 cells across -> 2 down (25 x 25 px cells).
  BoardView a, b;
  a.name = "a.png";
  a.pixels = {{0, 0}, {10, 10}, {30, 5}, {99, 49}};  // cells (0,0) x2, (0,1), (1,3)
  b.name = "b.png";
  b.pixels = {{-0.5, 20}, {60, 30}, {200, 10}};  // (0,0), (1,2); the last is outside
  Result<SensorCoverage> cov = ComputeSensorCoverage(100, 50, {a, b}, 4);
  ASSERT_TRUE(cov.ok());
  EXPECT_EQ(cov->cells_across, 4);
  EXPECT_EQ(cov->cells_down, 2);
  EXPECT_EQ(cov->corners_per_cell, (std::vector<int>{3, 1, 0, 0, 0, 0, 1, 1}));
  EXPECT_EQ(cov->num_corners, 6);
  EXPECT_DOUBLE_EQ(cov->fraction_covered, 4.0 / 8.0);
  EXPECT_EQ(cov->Summary().rfind("corners in 4 of 8 cells (50%) of a 4 x 2 grid", 0), 0u) << cov->Summary();
  CoverageImageOptions options;
  options.max_side_px = 400;
  Result<cv::Mat> image = DrawCoverageImage(100, 50, {a, b}, *cov, options);
  ASSERT_TRUE(image.ok());
  EXPECT_EQ(image->type(), CV_8UC3);
  EXPECT_GT(image->cols, 400);  // the sensor at 400 px, plus margins and legend
  EXPECT_FALSE(ComputeSensorCoverage(0, 50, {a}, 4).ok());
  EXPECT_FALSE(ComputeSensorCoverage(100, 50, {a}, 0).ok());
}

}  // namespace
}  // namespace opl
