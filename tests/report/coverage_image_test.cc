// Sensor coverage of a calibration's corners (report/coverage_image.h): the
// counts per cell, the covered fraction, and the picture in PNG (the colours
// of a covered cell, an empty cell, a corner and the outline at the layout's
// pixels), SVG (well-formed, its title) and PDF (%PDF, the metadata).
#include "opl/report/coverage_image.h"

#include <expat.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "report/rgb.h"

namespace opl {
namespace {

using test::PixelAt;
using test::Rgb;

// The colours the header promises.
const Rgb kCovered{240, 240, 240};
const Rgb kEmpty{255, 205, 205};
const Rgb kOutline{40, 40, 40};
const Rgb kFirstView{210, 29, 29};  // hue 0, S = 220/255, V = 210/255 (cairo rounds to +-1)

bool Near(const Rgb& a, const Rgb& b, int tolerance) {
  return std::abs(a.r - b.r) <= tolerance && std::abs(a.g - b.g) <= tolerance &&
         std::abs(a.b - b.b) <= tolerance;
}

// 100 x 50 image, 4 cells across -> 2 down (25 x 25 px cells).
std::vector<BoardView> Views() {
  BoardView a, b;
  a.name = "shots/a.png";
  a.pixels = {{0, 0}, {10, 10}, {30, 5}, {99, 49}};  // cells (0,0) x2, (0,1), (1,3)
  b.name = "b.png";
  b.pixels = {{-0.5, 20}, {60, 30}, {200, 10}};  // (0,0), (1,2); the last is outside
  return {a, b};
}

TEST(CoverageImage, CountsCornersPerCell) {
  Result<SensorCoverage> cov = ComputeSensorCoverage(100, 50, Views(), 4);
  ASSERT_TRUE(cov.ok());
  EXPECT_EQ(cov->cells_across, 4);
  EXPECT_EQ(cov->cells_down, 2);
  EXPECT_EQ(cov->corners_per_cell, (std::vector<int>{3, 1, 0, 0, 0, 0, 1, 1}));
  EXPECT_EQ(cov->num_corners, 6);
  EXPECT_DOUBLE_EQ(cov->fraction_covered, 4.0 / 8.0);
  EXPECT_EQ(cov->Summary().rfind("corners in 4 of 8 cells (50%) of a 4 x 2 grid", 0), 0u) << cov->Summary();
  EXPECT_FALSE(ComputeSensorCoverage(0, 50, Views(), 4).ok());
  EXPECT_FALSE(ComputeSensorCoverage(100, 50, Views(), 0).ok());
}

TEST(CoverageImage, LayoutPlacesTheSensorAndItsCells) {
  const SensorCoverage cov = *ComputeSensorCoverage(100, 50, Views(), 4);
  CoverageImageOptions options;
  options.max_side_px = 400;
  Result<CoverageImageLayout> layout = LayoutCoverageImage(100, 50, Views(), cov, options);
  ASSERT_TRUE(layout.ok()) << layout.status().ToString();
  const PixelRect s = layout->sensor;
  EXPECT_EQ(s.width, 400);
  EXPECT_EQ(s.height, 200);
  const PixelRect c = layout->Cell(1, 3);
  EXPECT_EQ(c.x, s.x + 300);
  EXPECT_EQ(c.y, s.y + 100);
  EXPECT_EQ(c.width, 100);
  EXPECT_EQ(c.height, 100);
  EXPECT_EQ(layout->Cell(2, 0).width, 0);  // outside the grid
  EXPECT_GE(layout->legend.x, s.x + s.width + 2);
  EXPECT_LE(layout->legend.x + layout->legend.width, layout->image_width);
  EXPECT_GT(layout->image_height, s.y + s.height);

  options.max_side_px = 100;
  EXPECT_EQ(LayoutCoverageImage(100, 50, Views(), cov, options).status().message(),
            "CoverageImageOptions.max_side_px = 100: must be in [200, 4000]");
  SensorCoverage short_grid = cov;
  short_grid.corners_per_cell.pop_back();
  EXPECT_EQ(LayoutCoverageImage(100, 50, Views(), short_grid).status().message(),
            "coverage picture: SensorCoverage.corners_per_cell has 7 entries, expected 4 x 2 = 8");
  EXPECT_EQ(RenderCoverageImage(0, 50, Views(), cov, PlotFormat::kPng).status().message(),
            "coverage picture: image size 0 x 50 must be positive");
}

// Image pixel (u, v) in the picture (header: centred at sensor.x - 0.5 +
// (u + 0.5) * scale).
int PictureX(const CoverageImageLayout& L, double u) {
  return static_cast<int>(std::lround(L.sensor.x - 0.5 + (u + 0.5) * L.sensor.width / 100.0));
}
int PictureY(const CoverageImageLayout& L, double v) {
  return static_cast<int>(std::lround(L.sensor.y - 0.5 + (v + 0.5) * L.sensor.height / 50.0));
}

TEST(CoverageImage, PngShowsCoveredAndEmptyCellsAndTheCorners) {
  const SensorCoverage cov = *ComputeSensorCoverage(100, 50, Views(), 4);
  CoverageImageOptions options;
  options.max_side_px = 400;
  const CoverageImageLayout L = *LayoutCoverageImage(100, 50, Views(), cov, options);
  Result<std::vector<unsigned char>> png = RenderCoverageImage(100, 50, Views(), cov, PlotFormat::kPng, options);
  ASSERT_TRUE(png.ok()) << png.status().ToString();
  const cv::Mat img = cv::imdecode(*png, cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, L.image_width);
  EXPECT_EQ(img.rows, L.image_height);
  // Cell (0, 0) holds corners: grey near its top-right corner (away from the
  // dots and the views' outlines). Cell (0, 3) is empty: red.
  const PixelRect covered = L.Cell(0, 0), empty = L.Cell(0, 3), empty_below = L.Cell(1, 0);
  EXPECT_EQ(PixelAt(img, covered.x + covered.width - 6, covered.y + 5), kCovered);
  EXPECT_EQ(PixelAt(img, empty.x + 50, empty.y + 20), kEmpty);
  EXPECT_EQ(PixelAt(img, empty_below.x + 50, empty_below.y + 80), kEmpty);
  // The corner (10, 10) of the first view: a dot in its colour.
  EXPECT_TRUE(Near(PixelAt(img, PictureX(L, 10), PictureY(L, 10)), kFirstView, 1))
      << PixelAt(img, PictureX(L, 10), PictureY(L, 10));
  // The grid line between cells (0, 2) and (0, 3), and the outline.
  EXPECT_EQ(PixelAt(img, empty.x, empty.y + 20), (Rgb{200, 200, 200}));
  EXPECT_EQ(PixelAt(img, L.sensor.x - 1, L.sensor.y + 50), kOutline);
  EXPECT_EQ(PixelAt(img, L.sensor.x - 2, L.sensor.y + 50), kOutline);
  EXPECT_EQ(PixelAt(img, L.sensor.x - 3, L.sensor.y + 50), (Rgb{255, 255, 255}));
}

// The SVG's root element and the text of its <title>.
std::pair<bool, std::string> ParseSvgTitle(const std::string& svg) {
  struct State {
    int depth = 0;
    bool in_title = false;
    std::string title;
  } state;
  XML_Parser parser = XML_ParserCreate(nullptr);
  XML_SetUserData(parser, &state);
  XML_SetElementHandler(
      parser,
      [](void* data, const XML_Char* name, const XML_Char**) {
        State& s = *static_cast<State*>(data);
        s.in_title = s.depth == 1 && std::string(name) == "title";
        ++s.depth;
      },
      [](void* data, const XML_Char*) {
        State& s = *static_cast<State*>(data);
        --s.depth;
        s.in_title = false;
      });
  XML_SetCharacterDataHandler(parser, [](void* data, const XML_Char* text, int length) {
    State& s = *static_cast<State*>(data);
    if (s.in_title) s.title.append(text, static_cast<size_t>(length));
  });
  const bool ok = XML_Parse(parser, svg.data(), static_cast<int>(svg.size()), 1) == XML_STATUS_OK;
  XML_ParserFree(parser);
  return {ok, state.title};
}

TEST(CoverageImage, SvgAndPdfAreTheSameFigure) {
  const SensorCoverage cov = *ComputeSensorCoverage(100, 50, Views(), 4);
  CoverageImageOptions options;
  options.title = "Camera 'cam0'";
  Result<std::vector<unsigned char>> svg = RenderCoverageImage(100, 50, Views(), cov, PlotFormat::kSvg, options);
  ASSERT_TRUE(svg.ok());
  const auto [well_formed, title] = ParseSvgTitle(std::string(svg->begin(), svg->end()));
  EXPECT_TRUE(well_formed);
  EXPECT_EQ(title, "Camera 'cam0': 2 views, 6 corners, image 100 x 50 px");
  PlotMetadata metadata;
  metadata.creator = "OPL opl_test 1.0";
  Result<std::vector<unsigned char>> pdf =
      RenderCoverageImage(100, 50, Views(), cov, PlotFormat::kPdf, options, metadata);
  ASSERT_TRUE(pdf.ok());
  const std::string text(pdf->begin(), pdf->end());
  EXPECT_EQ(text.compare(0, 5, "%PDF-"), 0);
  EXPECT_NE(text.find("/Creator (OPL opl_test 1.0)"), std::string::npos);
  EXPECT_NE(text.find("/Title (Camera 'cam0': 2 views, 6 corners, image 100 x 50 px)"), std::string::npos);
}

}  // namespace
}  // namespace opl
