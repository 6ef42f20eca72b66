#include "opl/report/grid_heatmap.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "opl/core/format.h"
#include "report/rgb.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// RGB colours the image promises (header and docs/report.md).
using test::PixelAt;
using test::Rgb;
const Rgb kViridisTop{253, 231, 37};   // matplotlib viridis(1.0)
const Rgb kViridisBottom{68, 1, 84};   // matplotlib viridis(0.0)
const Rgb kNoData{217, 217, 217};

// The viridis colour of `value` on a scale 0..scale_max, straight from OpenCV.
Rgb ViridisOf(double value, double scale_max) {
  const double f = std::min(std::max(value / scale_max, 0.0), 1.0);
  cv::Mat level(1, 1, CV_8UC1, cv::Scalar(static_cast<int>(std::lround(255 * f))));
  cv::Mat colour;
  cv::applyColorMap(level, colour, cv::COLORMAP_VIRIDIS);
  return PixelAt(colour, 0, 0);
}

// The most frequent colour in `r` and the fraction of pixels that have it.
std::pair<Rgb, double> DominantColour(const cv::Mat& img, const PixelRect& r) {
  std::map<uint32_t, int> counts;
  for (int y = r.y; y < r.y + r.height; ++y) {
    for (int x = r.x; x < r.x + r.width; ++x) {
      const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
      ++counts[(uint32_t{c[2]} << 16) | (uint32_t{c[1]} << 8) | c[0]];
    }
  }
  auto best = counts.begin();
  for (auto it = counts.begin(); it != counts.end(); ++it) {
    if (it->second > best->second) best = it;
  }
  const Rgb colour{static_cast<int>(best->first >> 16), static_cast<int>((best->first >> 8) & 255),
                   static_cast<int>(best->first & 255)};
  return {colour, static_cast<double>(best->second) / (r.width * r.height)};
}

GridHeatmap MakeHeatmap(int n, std::vector<double> values) {
  GridHeatmap h;
  h.beams_per_side = n;
  h.values = std::move(values);
  h.title = "Source A: mean point-to-ray distance per beam";
  h.value_label = "mean point-to-ray distance [mm]";
  h.subtitle = "10 slices, 1203 samples, RMS 0.031 mm";
  return h;
}

// Value of beam id b: grows with the distance from the central cell.
std::vector<double> RadialValues(int n, double scale) {
  std::vector<double> v(static_cast<size_t>(n * n));
  const int c = n / 2;
  for (int id = 1; id <= n * n; ++id) {
    const int row = (id - 1) / n, col = (id - 1) % n;
    v[static_cast<size_t>(id - 1)] = scale * std::hypot(row - c, col - c);
  }
  return v;
}

cv::Mat Decode(const std::vector<unsigned char>& png) {
  return cv::imdecode(png, cv::IMREAD_UNCHANGED);
}

// Pixels that are not pure white within `border` px of the image's edges.
int CountNonWhiteInBorder(const cv::Mat& img, int border) {
  cv::Mat border_mask(img.size(), CV_8UC1, cv::Scalar(255));
  border_mask(cv::Rect(border, border, img.cols - 2 * border, img.rows - 2 * border)).setTo(0);
  cv::Mat white;
  cv::inRange(img, cv::Scalar(255, 255, 255), cv::Scalar(255, 255, 255), white);
  cv::Mat not_white;
  cv::bitwise_not(white, not_white);
  return cv::countNonZero(not_white & border_mask);
}

cv::Mat RenderOrDie(const GridHeatmap& h) {
  auto png = RenderGridHeatmap(h, PlotFormat::kPng);
  EXPECT_TRUE(png.ok()) << png.status().ToString();
  if (!png.ok()) return cv::Mat();
  return Decode(*png);
}

// ---------------------------------------------------------------------------
// Image and layout

void ExpectInvalidNoise(const GridHeatmap& h) {
  auto layout = LayoutGridHeatmap(h);
  ASSERT_FALSE(layout.ok());
  EXPECT_EQ(layout.status().message(),
            "GridHeatmap.noise_level: must be finite and >= 0 or NaN (none), got " +
                FormatNumber(h.noise_level));
}

TEST(GridHeatmapTest, IsAnRgbPngOfTheLayoutSize) {
  for (int n : {3, 5, 11, 21}) {
    SCOPED_TRACE("n = " + std::to_string(n));
    const GridHeatmap h = MakeHeatmap(n, RadialValues(n, 0.01));
    auto png = RenderGridHeatmap(h, PlotFormat::kPng);
    ASSERT_TRUE(png.ok()) << png.status().ToString();
    ASSERT_GE(png->size(), 8u);
    EXPECT_EQ(std::string(png->begin(), png->begin() + 8), "\x89PNG\r\n\x1a\n");
    const cv::Mat img = Decode(*png);
    ASSERT_FALSE(img.empty());
    EXPECT_EQ(img.type(), CV_8UC3);
    auto layout = LayoutGridHeatmap(h);
    ASSERT_TRUE(layout.ok());
    EXPECT_EQ(img.cols, layout->image_width);
    EXPECT_EQ(img.rows, layout->image_height);
    EXPECT_EQ(layout->grid.width, n * layout->cell_size);
    EXPECT_EQ(layout->grid.height, n * layout->cell_size);
    EXPECT_EQ(layout->colour_bar.height, layout->grid.height);
    // Everything inside the image: the outer 8 px are untouched white.
    EXPECT_EQ(CountNonWhiteInBorder(img, 8), 0);
  }
}

TEST(GridHeatmapTest, CellSizeIs64PxForN11AndLargerForSmallGrids) {
  auto l11 = LayoutGridHeatmap(MakeHeatmap(11, RadialValues(11, 0.01)));
  auto l3 = LayoutGridHeatmap(MakeHeatmap(3, RadialValues(3, 0.01)));
  auto l21 = LayoutGridHeatmap(MakeHeatmap(21, RadialValues(21, 0.01)));
  ASSERT_TRUE(l11.ok() && l3.ok() && l21.ok());
  EXPECT_EQ(l11->cell_size, 64);
  EXPECT_EQ(l3->cell_size, 160);
  EXPECT_EQ(l21->cell_size, 64);
  EXPECT_LT(l21->image_width, 2000);
  EXPECT_LT(l21->image_height, 2000);
}

TEST(GridHeatmapTest, LayoutPutsBeamOneTopRightAndLastBeamBottomLeft) {
  const int n = 11;
  auto layout = LayoutGridHeatmap(MakeHeatmap(n, RadialValues(n, 0.01)));
  ASSERT_TRUE(layout.ok());
  const PixelRect g = layout->grid;
  const int c = layout->cell_size;
  const PixelRect b1 = layout->CellOfBeam(1);
  EXPECT_EQ(b1.x, g.x + g.width - c);  // rightmost column (col 0 = smallest Y)
  EXPECT_EQ(b1.y, g.y);                // top row (row 0 = largest Z)
  const PixelRect b11 = layout->CellOfBeam(11);
  EXPECT_EQ(b11.x, g.x);  // top left
  EXPECT_EQ(b11.y, g.y);
  const PixelRect b121 = layout->CellOfBeam(121);
  EXPECT_EQ(b121.x, g.x);  // bottom left
  EXPECT_EQ(b121.y, g.y + g.height - c);
  const PixelRect b61 = layout->CellOfBeam(61);  // central beam in the middle
  EXPECT_EQ(b61.x, g.x + 5 * c);
  EXPECT_EQ(b61.y, g.y + 5 * c);
  const PixelRect b12 = layout->CellOfBeam(12);  // row 1, col 0: right, second row
  EXPECT_EQ(b12.x, b1.x);
  EXPECT_EQ(b12.y, b1.y + c);
  EXPECT_EQ(layout->CellOfBeam(0).width, 0);
  EXPECT_EQ(layout->CellOfBeam(122).width, 0);
}

// Orientation from the pixels alone, without the layout: the largest blob of
// each of three distinct colours.
TEST(GridHeatmapTest, PixelsShowBeamOneTopRightWithoutUsingTheLayout) {
  const int n = 5;
  std::vector<double> v(n * n, kNaN);
  v[0] = 1.0;          // beam 1: top colour (yellow)
  v[n - 1] = 0.5;      // beam n: teal
  v[n * n - 1] = 0.0;  // beam n*n: bottom colour (dark purple)
  const cv::Mat img = RenderOrDie(MakeHeatmap(n, v));
  ASSERT_FALSE(img.empty());

  auto blob_centre = [&](const Rgb& c, cv::Point2d* centre, int* area) {
    cv::Mat mask, labels, stats, centroids;
    cv::inRange(img, cv::Scalar(c.b, c.g, c.r), cv::Scalar(c.b, c.g, c.r), mask);
    const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 4);
    int best = 0;
    for (int i = 1; i < count; ++i) {
      if (best == 0 || stats.at<int>(i, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA))
        best = i;
    }
    ASSERT_GT(best, 0) << "no pixel of " << c;
    *area = stats.at<int>(best, cv::CC_STAT_AREA);
    *centre = cv::Point2d(centroids.at<double>(best, 0), centroids.at<double>(best, 1));
  };
  cv::Point2d beam1, beam_n, beam_last;
  int a1 = 0, an = 0, alast = 0;
  blob_centre(kViridisTop, &beam1, &a1);
  blob_centre(ViridisOf(0.5, 1.0), &beam_n, &an);
  blob_centre(kViridisBottom, &beam_last, &alast);
  // Cells of n = 5 are 96 px: every blob is most of a cell.
  for (int a : {a1, an, alast}) EXPECT_GT(a, 96 * 96 / 2);
  EXPECT_GT(beam1.x, beam_n.x + 3.5 * 96);  // beam 1 right of beam n, same row
  EXPECT_NEAR(beam1.y, beam_n.y, 20);
  EXPECT_NEAR(beam_last.x, beam_n.x, 20);  // beam n*n below beam n
  EXPECT_GT(beam_last.y, beam_n.y + 3.5 * 96);
}

// ---------------------------------------------------------------------------
// Colours

TEST(GridHeatmapTest, EveryCellHasTheViridisColourOfItsValue) {
  const int n = 11;
  std::vector<double> v = RadialValues(n, 0.004);  // 0 .. ~0.0283 mm
  v[2] = kNaN;                                      // beam 3: no data
  v[100] = kNaN;
  const GridHeatmap h = MakeHeatmap(n, v);
  const cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  double max_value = 0;
  for (double x : v) {
    if (!std::isnan(x)) max_value = std::max(max_value, x);
  }
  EXPECT_DOUBLE_EQ(layout->scale_max, max_value);
  for (int id = 1; id <= n * n; ++id) {
    SCOPED_TRACE("beam " + std::to_string(id));
    const double value = v[static_cast<size_t>(id - 1)];
    const auto [colour, fraction] = DominantColour(img, layout->CellOfBeam(id));
    const Rgb expected = std::isnan(value) ? kNoData : ViridisOf(value, max_value);
    EXPECT_EQ(colour, expected);
    EXPECT_GT(fraction, 0.5);  // text and hatching cover less than half
  }
  // The corner beams are the largest values: the top colour. Beam 61 (centre)
  // is 0: the bottom colour.
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(1)).first, kViridisTop);
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(121)).first, kViridisTop);
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(61)).first, kViridisBottom);
}

TEST(GridHeatmapTest, CellCentreRowsAreFilledWithTheCellColour) {
  // The pixel at the horizontal centre line of a cell, near its left edge
  // (away from the labels), is the fill.
  const int n = 3;
  std::vector<double> v = {0.2, kNaN, 0.0, 0.1, 0.05, 0.15, 0.3, 0.25, 0.0};
  const GridHeatmap h = MakeHeatmap(n, v);
  const cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  for (int id = 1; id <= 9; ++id) {
    SCOPED_TRACE("beam " + std::to_string(id));
    const PixelRect r = layout->CellOfBeam(id);
    const double value = v[static_cast<size_t>(id - 1)];
    if (std::isnan(value)) continue;  // hatched
    EXPECT_EQ(PixelAt(img, r.x + 3, r.y + r.height / 2), ViridisOf(value, 0.3));
  }
  // Beam 7 (value 0.3 = max) is row 2, col 0: the bottom RIGHT cell.
  const PixelRect b7 = layout->CellOfBeam(7);
  EXPECT_EQ(b7.x, layout->grid.x + 2 * layout->cell_size);
  EXPECT_EQ(b7.y, layout->grid.y + 2 * layout->cell_size);
  EXPECT_EQ(PixelAt(img, b7.x + 3, b7.y + b7.height / 2), kViridisTop);
}

TEST(GridHeatmapTest, AllNaNRendersNoDataEverywhere) {
  const int n = 5;
  const GridHeatmap h = MakeHeatmap(n, std::vector<double>(n * n, kNaN));
  const cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  EXPECT_DOUBLE_EQ(layout->scale_max, 1.0);
  for (int id = 1; id <= n * n; ++id) {
    EXPECT_EQ(DominantColour(img, layout->CellOfBeam(id)).first, kNoData) << "beam " << id;
  }
}

TEST(GridHeatmapTest, NoDataCellsAreHatched) {
  const int n = 3;
  std::vector<double> v(9, 0.5);
  v[4] = kNaN;
  const GridHeatmap h = MakeHeatmap(n, v);
  const cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  // Some pixels darker than the grey fill: the hatch lines (and the label).
  const PixelRect r = layout->CellOfBeam(5);
  int darker = 0;
  for (int y = r.y; y < r.y + r.height - 1; ++y) {
    for (int x = r.x; x < r.x + r.width - 1; ++x) {
      const Rgb c = PixelAt(img, x, y);
      if (c.r < 200 && c.r == c.g && c.g == c.b) ++darker;
    }
  }
  EXPECT_GT(darker, 500);
}

TEST(GridHeatmapTest, ExplicitScaleMaxSetsTheTopColour) {
  const int n = 3;
  std::vector<double> v = {0.0, 0.05, 0.1, 0.2, 0.05, 0.05, 0.05, 0.05, 0.05};
  GridHeatmap h = MakeHeatmap(n, v);
  h.scale_max = 0.1;  // beam 4 (0.2) is above the scale: clamped to the top colour
  cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  EXPECT_DOUBLE_EQ(layout->scale_max, 0.1);
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(3)).first, kViridisTop);
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(4)).first, kViridisTop);
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(2)).first, ViridisOf(0.5, 1.0));
  // The overflow triangle sits above the colour bar.
  const PixelRect bar = layout->colour_bar;
  EXPECT_EQ(PixelAt(img, bar.x + bar.width / 2, bar.y - 8), kViridisTop);

  h.scale_max = 0.4;  // the largest value is now half way up the scale
  img = RenderOrDie(h);
  layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(4)).first, ViridisOf(0.5, 1.0));
  const PixelRect bar2 = layout->colour_bar;  // no triangle
  EXPECT_EQ(PixelAt(img, bar2.x + bar2.width / 2, bar2.y - 8), (Rgb{255, 255, 255}));
}

TEST(GridHeatmapTest, ASharedScaleMakesEqualColoursEqualValues) {
  // Source A's largest mean is 0.1 mm, source B's 0.4 mm. Alone, A's 0.1
  // cell is yellow (the top); on the shared scale 0..0.4 it is a quarter of
  // the way up, and B's 0.1 cell has the very same colour.
  GridHeatmap a = MakeHeatmap(3, {0.1, 0.05, 0.05, 0.05, 0.02, 0.05, 0.05, 0.05, 0.05});
  GridHeatmap b = MakeHeatmap(3, {0.4, 0.1, 0.2, 0.2, kNaN, 0.2, 0.2, 0.2, 0.2});
  cv::Mat img = RenderOrDie(a);
  auto layout = LayoutGridHeatmap(a);
  ASSERT_TRUE(layout.ok());
  EXPECT_EQ(DominantColour(img, layout->CellOfBeam(1)).first, kViridisTop);

  EXPECT_DOUBLE_EQ(SharedScaleMax({a, b}), 0.4);
  EXPECT_DOUBLE_EQ(SharedScaleMax({MakeHeatmap(3, std::vector<double>(9, kNaN))}), 1.0);
  a.scale_max = b.scale_max = SharedScaleMax({a, b});
  a.scale_note = b.scale_note = "one scale for sources A, B";
  img = RenderOrDie(a);
  layout = LayoutGridHeatmap(a);
  ASSERT_TRUE(layout.ok());
  const Rgb a_cell = DominantColour(img, layout->CellOfBeam(1)).first;
  EXPECT_EQ(a_cell, ViridisOf(0.1, 0.4));
  EXPECT_NE(a_cell, kViridisTop);
  const cv::Mat img_b = RenderOrDie(b);
  auto layout_b = LayoutGridHeatmap(b);
  ASSERT_TRUE(layout_b.ok());
  EXPECT_EQ(DominantColour(img_b, layout_b->CellOfBeam(2)).first, a_cell);
  EXPECT_EQ(DominantColour(img_b, layout_b->CellOfBeam(1)).first, kViridisTop);
}

// Pixels of the noise mark's colour (RGB 0,110,70, anti-aliased text) in the
// rows above the grid.
int NoiseMarkPixels(const cv::Mat& img, const GridHeatmapLayout& layout) {
  int count = 0;
  for (int y = 0; y < layout.grid.y; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const Rgb c = PixelAt(img, x, y);
      if (c.g > c.r + 40 && c.g > c.b + 15) ++count;  // green, not grey or black
    }
  }
  return count;
}

TEST(GridHeatmapTest, AMapOfNoiseSaysSo) {
  GridHeatmap h = MakeHeatmap(3, {0.011, 0.012, 0.009, kNaN, 0.015, 0.01, 0.012, 0.013, 0.014});
  h.value_unit = "mm";
  auto plain = LayoutGridHeatmap(h);
  ASSERT_TRUE(plain.ok());
  EXPECT_FALSE(plain->all_at_noise_level);  // no noise level given
  h.noise_level = 0.02;
  auto noisy = LayoutGridHeatmap(h);
  ASSERT_TRUE(noisy.ok());
  EXPECT_TRUE(noisy->all_at_noise_level);
  EXPECT_GT(noisy->grid.y, plain->grid.y + 10);  // a header line more
  const cv::Mat img = RenderOrDie(h);
  EXPECT_GT(NoiseMarkPixels(img, *noisy), 100);
  // One beam above the noise level: no mark.
  h.values[4] = 0.021;
  auto signal = LayoutGridHeatmap(h);
  ASSERT_TRUE(signal.ok());
  EXPECT_FALSE(signal->all_at_noise_level);
  EXPECT_EQ(NoiseMarkPixels(RenderOrDie(h), *signal), 0);
  // Exactly at the level counts as noise; so does a map of zeros.
  h.values[4] = 0.02;
  EXPECT_TRUE(LayoutGridHeatmap(h)->all_at_noise_level);
  h.noise_level = -1;
  ExpectInvalidNoise(h);
}

TEST(GridHeatmapTest, ColourBarRunsFromBottomToTopColour) {
  const GridHeatmap h = MakeHeatmap(11, RadialValues(11, 0.01));
  const cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  const PixelRect b = layout->colour_bar;
  const int cx = b.x + b.width / 2;
  EXPECT_EQ(PixelAt(img, cx, b.y), kViridisTop);
  EXPECT_EQ(PixelAt(img, cx, b.y + b.height - 1), kViridisBottom);
  EXPECT_EQ(PixelAt(img, cx, b.y + (b.height - 1) / 2), ViridisOf(0.5, 1.0));
  // Black frame around the bar; tick marks at its right for 0 (bottom).
  EXPECT_EQ(PixelAt(img, cx, b.y - 1), (Rgb{0, 0, 0}));
  EXPECT_EQ(PixelAt(img, b.x + b.width + 2, b.y + b.height - 1), (Rgb{0, 0, 0}));
}

TEST(GridHeatmapTest, CellTextContrastsWithItsFill) {
  const int n = 3;
  std::vector<double> v = {1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0};
  const GridHeatmap h = MakeHeatmap(n, v);
  const cv::Mat img = RenderOrDie(h);
  ASSERT_FALSE(img.empty());
  auto layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  auto count = [&](int id, bool bright) {
    const PixelRect r = layout->CellOfBeam(id);
    int k = 0;
    for (int y = r.y; y < r.y + r.height - 1; ++y) {
      for (int x = r.x; x < r.x + r.width - 1; ++x) {
        const Rgb c = PixelAt(img, x, y);
        const int lum = (2 * c.r + 7 * c.g + c.b) / 10;
        if (bright ? lum > 230 : lum < 10) ++k;
      }
    }
    return k;
  };
  EXPECT_GT(count(2, /*bright=*/true), 100);   // white text on dark purple
  EXPECT_GT(count(1, /*bright=*/false), 100);  // black text on yellow
  EXPECT_EQ(count(2, /*bright=*/false), 0);    // no black text on dark purple
}

TEST(GridHeatmapTest, RenderingIsDeterministic) {
  const GridHeatmap h = MakeHeatmap(11, RadialValues(11, 0.003));
  auto a = RenderGridHeatmap(h, PlotFormat::kPng);
  auto b = RenderGridHeatmap(h, PlotFormat::kPng);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(*a, *b);
}

TEST(GridHeatmapTest, ExtremeValuesAndLongTextsStayInsideABoundedImage) {
  const int n = 3;
  GridHeatmap huge = MakeHeatmap(n, {1e12, 0, 1e-12, 5, kNaN, 123456.789, 0, 0, 0});
  huge.subtitle.clear();
  huge.title = std::string(400, 'W');
  GridHeatmap tiny = MakeHeatmap(n, std::vector<double>(9, 1e-200));
  tiny.subtitle = std::string(400, 'M');
  tiny.value_label = std::string(200, 'x') + " [mm]";
  for (const GridHeatmap& h : {huge, tiny}) {
    const cv::Mat img = RenderOrDie(h);
    ASSERT_FALSE(img.empty());
    EXPECT_LT(img.cols, 2000);
    EXPECT_EQ(CountNonWhiteInBorder(img, 8), 0);
  }
}

// ---------------------------------------------------------------------------
// Errors

void ExpectInvalid(const GridHeatmap& h, const std::string& message) {
  auto png = RenderGridHeatmap(h, PlotFormat::kPng);
  ASSERT_FALSE(png.ok());
  EXPECT_EQ(png.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(png.status().message(), message);
  auto layout = LayoutGridHeatmap(h);
  ASSERT_FALSE(layout.ok());
  EXPECT_EQ(layout.status().message(), message);
}

TEST(GridHeatmapTest, RejectsInvalidInputNamingTheField) {
  const GridHeatmap good = MakeHeatmap(3, std::vector<double>(9, 0.1));
  GridHeatmap h = good;
  h.beams_per_side = 4;
  h.values.assign(16, 0.1);
  ExpectInvalid(h, "GridHeatmap.beams_per_side: must be odd and in [3, 51], got 4");
  h.beams_per_side = 1;
  h.values.assign(1, 0.1);
  ExpectInvalid(h, "GridHeatmap.beams_per_side: must be odd and in [3, 51], got 1");
  h.beams_per_side = 53;
  ExpectInvalid(h, "GridHeatmap.beams_per_side: must be odd and in [3, 51], got 53");

  h = good;
  h.values.pop_back();
  ExpectInvalid(h, "GridHeatmap.values: has 8 entries, expected beams_per_side^2 = 9");

  h = good;
  h.values[4] = -0.1;
  ExpectInvalid(h, "GridHeatmap.values[4] (beam 5): must be >= 0 or NaN (no data), got -0.1");
  h.values[4] = std::numeric_limits<double>::infinity();
  ExpectInvalid(h, "GridHeatmap.values[4] (beam 5): must be finite or NaN (no data), got inf");
  h.values[4] = -std::numeric_limits<double>::infinity();
  ExpectInvalid(h, "GridHeatmap.values[4] (beam 5): must be finite or NaN (no data), got -inf");

  h = good;
  h.title.clear();
  ExpectInvalid(h, "GridHeatmap.title: must not be empty");
  h = good;
  h.value_label.clear();
  ExpectInvalid(h, "GridHeatmap.value_label: must not be empty (it names the value and its unit)");

  h = good;
  h.scale_max = 0.0;
  ExpectInvalid(h, "GridHeatmap.scale_max: must be finite and > 0, got 0");
  h.scale_max = kNaN;
  ExpectInvalid(h, "GridHeatmap.scale_max: must be finite and > 0, got nan");
  h.scale_max = std::numeric_limits<double>::infinity();
  ExpectInvalid(h, "GridHeatmap.scale_max: must be finite and > 0, got inf");
}

// ---------------------------------------------------------------------------
// Writing

TEST(GridHeatmapTest, WritesThePngBytes) {
  TempDir dir;
  const GridHeatmap h = MakeHeatmap(11, RadialValues(11, 0.003));
  const std::string path = dir.File("source_a_heatmap.png");
  ASSERT_TRUE(WriteGridHeatmap(h, path).ok());
  auto png = RenderGridHeatmap(h, PlotFormat::kPng);
  ASSERT_TRUE(png.ok());
  EXPECT_EQ(ReadAll(path), std::string(png->begin(), png->end()));
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"source_a_heatmap.png"});  // no temp left
  EXPECT_FALSE(cv::imread(path).empty());
}

TEST(GridHeatmapTest, InvalidInputWritesNothingAndKeepsAnOldFile) {
  TempDir dir;
  GridHeatmap h = MakeHeatmap(11, RadialValues(11, 0.003));
  h.values[7] = -1;
  const std::string path = dir.File("heatmap.png");
  Status s = WriteGridHeatmap(h, path);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(dir.Entries().empty());

  dir.Write("heatmap.png", "old");
  s = WriteGridHeatmap(h, path);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadAll(path), "old");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"heatmap.png"});
}

TEST(GridHeatmapTest, UnwritablePathIsAnIoError) {
  TempDir dir;
  const Status s =
      WriteGridHeatmap(MakeHeatmap(3, std::vector<double>(9, 0.1)), dir.File("no/such/x.png"));
  EXPECT_EQ(s.code(), StatusCode::kIoError);
  EXPECT_NE(s.message().find("no/such/x.png"), std::string::npos) << s.message();
  EXPECT_TRUE(dir.Entries().empty());
}

// Samples for looking at (only with OPL_GRID_HEATMAP_SAMPLES=<dir>): a 3 x 3
// map with a no-data beam and the noise-level line, and an 11 x 11 map on a
// fixed scale, in all three formats.
TEST(GridHeatmapSamples, WriteWhenAsked) {
  const char* dir = std::getenv("OPL_GRID_HEATMAP_SAMPLES");
  if (dir == nullptr) GTEST_SKIP() << "set OPL_GRID_HEATMAP_SAMPLES=<dir> to write samples";
  GridHeatmap noise = MakeHeatmap(3, {0.011, 0.012, 0.009, kNaN, 0.015, 0.01, 0.012, 0.013, 0.014});
  noise.noise_level = 0.02;
  noise.value_unit = "mm";
  GridHeatmap fixed = MakeHeatmap(11, RadialValues(11, 0.006));
  fixed.values[16] = kNaN;
  fixed.scale_max = 0.04;
  fixed.scale_note = "one scale for sources A, B";
  for (const char* ext : {"png", "svg", "pdf"}) {
    ASSERT_TRUE(WriteGridHeatmap(noise, std::string(dir) + "/noise_3x3." + ext).ok());
    ASSERT_TRUE(WriteGridHeatmap(fixed, std::string(dir) + "/fixed_11x11." + ext).ok());
  }
}

}  // namespace
}  // namespace opl
