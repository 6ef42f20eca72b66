// The printable board (report/board_print.h): the PNG's size in pixels is
// the page's size in mm times dpi / 25.4 and its pHYs chunk says the dpi;
// the tag detector finds every tag of the board in it, with the right id at
// the right place (to a small fraction of a pixel); the PDF has the page's
// size in points and, rasterised by poppler's pdftoppm (when installed),
// shows every tag at its place too.
#include "opl/report/board_print.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "opl/vision/tag_detection.h"

namespace opl {
namespace {

TagBoard TestBoard() {
  TagBoard b;
  b.columns = 5;
  b.rows = 3;
  b.tag_size = 24.0;
  b.tag_gap = 6.0;
  b.first_id = 100;
  return b;
}

// Every tag of `board` found in `image` (rendered at px_per_mm, the board's
// origin at (x0_mm, y0_mm) on the page) with its corners where the layout
// puts them; returns the largest corner error [px].
//
// The image is blurred first (Gaussian, sigma 1 px: symmetric, so it moves no
// edge), as any photograph of the print is: on a perfectly sharp edge the
// detector's edge fit locks to the pixel grid by up to 0.2 px.
double CheckTags(const cv::Mat& image, const TagBoard& board, double px_per_mm, double x0_mm, double y0_mm) {
  cv::Mat blurred;
  cv::GaussianBlur(image, blurred, cv::Size(0, 0), 1.0);
  Result<std::vector<TagDetection>> tags = DetectTags(blurred);
  EXPECT_TRUE(tags.ok());
  std::map<int, TagDetection> by_id;
  for (const TagDetection& t : *tags) by_id[t.id] = t;
  EXPECT_EQ(static_cast<int>(tags->size()), board.NumTags());
  double worst = 0.0;
  for (int id = board.first_id; id < board.first_id + board.NumTags(); ++id) {
    auto it = by_id.find(id);
    if (it == by_id.end()) {
      ADD_FAILURE() << "tag " << id << " not found";
      continue;
    }
    const Result<std::array<Eigen::Vector3d, 4>> corners = board.TagCorners(id);
    for (int c = 0; c < 4; ++c) {
      // Page mm -> pixel: pixel (0, 0) is the centre of the first pixel.
      const Eigen::Vector2d expected((x0_mm + (*corners)[c].x()) * px_per_mm - 0.5,
                                     (y0_mm + (*corners)[c].y()) * px_per_mm - 0.5);
      worst = std::max(worst, (it->second.corners_px[c] - expected).norm());
    }
  }
  return worst;
}

TEST(BoardPrint, PngHasTheSizeTheDpiAndEveryTagInPlace) {
  const TagBoard board = TestBoard();
  BoardPrintOptions options;
  options.dpi = 200.0;
  Result<BoardPrintLayout> layout = LayOutBoardPrint(board, options);
  ASSERT_TRUE(layout.ok()) << layout.status().ToString();
  EXPECT_EQ(layout->png_width_px, static_cast<int>(std::lround(layout->page_width_mm * 200.0 / 25.4)));
  EXPECT_EQ(layout->png_height_px, static_cast<int>(std::lround(layout->page_height_mm * 200.0 / 25.4)));
  // The page holds the grid (5 * 24 + 4 * 6 = 144 mm) and the 100 mm line with margins.
  EXPECT_GE(layout->page_width_mm, 144.0 + 2 * 15.0);
  Result<std::string> png = RenderBoardPng(board, options);
  ASSERT_TRUE(png.ok()) << png.status().ToString();
  const cv::Mat image = cv::imdecode(cv::Mat(1, static_cast<int>(png->size()), CV_8UC1, png->data()),
                                     cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.type(), CV_8UC1);
  EXPECT_EQ(image.cols, layout->png_width_px);
  EXPECT_EQ(image.rows, layout->png_height_px);
  // pHYs right after IHDR: 200 dpi = 7874 px per metre on both axes, unit metre.
  ASSERT_GT(png->size(), 50u);
  EXPECT_EQ(png->substr(37, 4), "pHYs");
  auto be32 = [&](size_t at) {
    return (static_cast<uint32_t>(static_cast<unsigned char>((*png)[at])) << 24) |
           (static_cast<uint32_t>(static_cast<unsigned char>((*png)[at + 1])) << 16) |
           (static_cast<uint32_t>(static_cast<unsigned char>((*png)[at + 2])) << 8) |
           static_cast<uint32_t>(static_cast<unsigned char>((*png)[at + 3]));
  };
  EXPECT_EQ(be32(41), 7874u);
  EXPECT_EQ(be32(45), 7874u);
  const double worst = CheckTags(image, board, 200.0 / 25.4, layout->board_x_mm, layout->board_y_mm);
  std::printf("PNG at 200 dpi: largest tag corner error %.3f px\n", worst);
  EXPECT_LT(worst, 0.05);
  // The scale line is drawn: black pixels along it, 100 mm long.
  const int row = static_cast<int>(std::lround(layout->scale_line_y_mm * 200.0 / 25.4 - 0.5));
  int first = -1, last = -1;
  const int end = static_cast<int>((layout->board_x_mm + 101.0) * 200.0 / 25.4);  // before the "100 mm" label
  for (int c = 0; c < end; ++c) {
    if (image.at<uint8_t>(row, c) < 128) {
      if (first < 0) first = c;
      last = c;
    }
  }
  EXPECT_NEAR((last - first + 1) / (200.0 / 25.4), 100.0, 0.5);
}

TEST(BoardPrint, PdfHasThePageSizeAndRasterisesToTheBoard) {
  const TagBoard board = TestBoard();
  BoardPrintOptions options;
  options.page = "a4";
  Result<BoardPrintLayout> layout = LayOutBoardPrint(board, options);
  ASSERT_TRUE(layout.ok());
  EXPECT_DOUBLE_EQ(layout->page_width_mm, 210.0);  // portrait holds it
  EXPECT_DOUBLE_EQ(layout->page_height_mm, 297.0);
  Result<std::string> pdf = RenderBoardPdf(board, options);
  ASSERT_TRUE(pdf.ok()) << pdf.status().ToString();
  EXPECT_EQ(pdf->rfind("%PDF-", 0), 0u);
  // A4 in points: 595.276 x 841.89.
  EXPECT_NE(pdf->find("/MediaBox [ 0 0 595.275591 841.889764 ]"), std::string::npos);
  if (std::system("pdftoppm -v >/dev/null 2>&1") != 0) GTEST_SKIP() << "pdftoppm (poppler-utils) not installed";
  testing_support::TempDir dir;
  const std::string path = dir.Write("board.pdf", *pdf);
  const std::string command = "pdftoppm -r 150 -gray -png -singlefile '" + path + "' '" + dir.File("page") + "'";
  ASSERT_EQ(std::system(command.c_str()), 0);
  const cv::Mat page = cv::imread(dir.File("page.png"), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(page.empty());
  // poppler rounds the page up to whole pixels (1240.2 -> 1241).
  EXPECT_NEAR(page.cols, 210.0 * 150 / 25.4, 1.0);
  EXPECT_NEAR(page.rows, 297.0 * 150 / 25.4, 1.0);
  const double worst = CheckTags(page, board, 150.0 / 25.4, layout->board_x_mm, layout->board_y_mm);
  std::printf("PDF rasterised by pdftoppm at 150 dpi: largest tag corner error %.3f px\n", worst);
  // poppler's rasteriser snaps the edges of axis-aligned fills to the pixel
  // grid (up to half a pixel, 0.085 mm here); the PDF's own coordinates are
  // exact (the MediaBox above, the tags drawn in mm).
  EXPECT_LT(worst, 0.5);
}

TEST(BoardPrint, RefusesWhatCannotBePrintedRight) {
  TagBoard board = TestBoard();
  board.tag_gap = 2.0;  // < a cell (3 mm): no quiet zone between tags
  Result<std::string> narrow = RenderBoardPng(board, BoardPrintOptions{});
  ASSERT_FALSE(narrow.ok());
  EXPECT_NE(narrow.status().message().find("must be at least one tag cell"), std::string::npos);
  board = TestBoard();
  board.columns = 10;  // 294 mm wide: not on A4 either way with its margins
  board.rows = 10;
  BoardPrintOptions a4;
  a4.page = "a4";
  Result<BoardPrintLayout> big = LayOutBoardPrint(board, a4);
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.status().message().find("does not fit on a4"), std::string::npos) << big.status().message();
  BoardPrintOptions dpi;
  dpi.dpi = 10.0;
  EXPECT_FALSE(LayOutBoardPrint(TestBoard(), dpi).ok());
}

}  // namespace
}  // namespace opl
