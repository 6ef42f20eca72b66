#include "opl/report/line_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "report/rgb.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// RGB colours the image promises (header and docs/report.md).
using test::PixelAt;
using test::Rgb;
// Okabe-Ito colours of series 0, 1, 2 (the header promises them).
const Rgb kBlue{0, 114, 178};
const Rgb kVermillion{213, 94, 0};
const Rgb kGreen{0, 158, 115};
const Rgb kWhiteRgb{255, 255, 255};

cv::Mat Decode(const LinePlot& plot) {
  Result<std::vector<unsigned char>> png = RenderLinePlotPng(plot);
  EXPECT_TRUE(png.ok()) << png.status().ToString();
  if (!png.ok()) return cv::Mat();
  return cv::imdecode(*png, cv::IMREAD_COLOR);
}

PlotSeries Series(std::string label, std::vector<double> x, std::vector<double> y,
                  PlotSeries::Style style = PlotSeries::Style::kLineMarkers) {
  PlotSeries s;
  s.label = std::move(label);
  s.x = std::move(x);
  s.y = std::move(y);
  s.style = style;
  return s;
}

PlotPanel Panel(std::string title, std::vector<PlotSeries> series) {
  PlotPanel p;
  p.title = std::move(title);
  p.x_label = "spot noise (mm)";
  p.y_label = "std of L (mm)";
  p.series = std::move(series);
  return p;
}

LinePlot OnePanel(PlotPanel p) {
  LinePlot plot;
  plot.title = "Design sweep";
  plot.panels.push_back(std::move(p));
  return plot;
}

// --- Ticks -------------------------------------------------------------------

TEST(NiceTicksTest, ExactDecimalValues) {
  EXPECT_EQ(NiceTicks(0, 1, 6), (std::vector<double>{0, 0.2, 0.4, 0.6, 0.8, 1}));
  EXPECT_EQ(NiceTicks(0, 1, 11),
            (std::vector<double>{0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1}));
  EXPECT_EQ(NiceTicks(-0.013, 0.048, 8), (std::vector<double>{-0.01, 0, 0.01, 0.02, 0.03, 0.04}));
  EXPECT_EQ(NiceTicks(0.27, 0.33, 7),
            (std::vector<double>{0.27, 0.28, 0.29, 0.3, 0.31, 0.32, 0.33}));
  EXPECT_EQ(NiceTicks(0.27, 0.33, 4), (std::vector<double>{0.28, 0.3, 0.32}));
  EXPECT_EQ(NiceTicks(3, 97, 5), (std::vector<double>{20, 40, 60, 80}));
  EXPECT_EQ(NiceTicks(3, 97, 10), (std::vector<double>{10, 20, 30, 40, 50, 60, 70, 80, 90}));
  EXPECT_EQ(NiceTicks(1200, 5600, 6), (std::vector<double>{2000, 3000, 4000, 5000}));
  EXPECT_EQ(NiceTicks(-2.5, 2.5, 6), (std::vector<double>{-2, -1, 0, 1, 2}));
  EXPECT_EQ(NiceTicks(1e-5, 5e-5, 5), (std::vector<double>{1e-5, 2e-5, 3e-5, 4e-5, 5e-5}));
  // 0.1 + 0.2 would be 0.30000000000000004; the third tick is exactly 0.3.
  EXPECT_EQ(NiceTicks(0.05, 0.45, 5)[2], 0.3);
}

TEST(NiceTicksTest, HugeOffsetsTerminate) {
  // lo / step beyond 2^53: k + 1 == k in doubles; still at most max_ticks.
  const std::vector<double> t = NiceTicks(1e17, 1e17 + 64, 5);
  EXPECT_GE(t.size(), 1u);
  EXPECT_LE(t.size(), 5u);
}

TEST(LinePlotTest, SeriesIsAnAggregateAsDocumented) {
  // docs/report.md builds series this way.
  const PlotSeries s{"Monte Carlo", {1, 2}, {3, 4}, {0.1, 0.2}, PlotSeries::Style::kMarkers};
  EXPECT_EQ(s.y_err.size(), 2u);
  EXPECT_TRUE(LayoutLinePlot(OnePanel(Panel("a", {s}))).ok());
}

TEST(NiceTicksTest, InvalidArgumentsGiveNoTicks) {
  EXPECT_TRUE(NiceTicks(1, 1, 5).empty());
  EXPECT_TRUE(NiceTicks(2, 1, 5).empty());
  EXPECT_TRUE(NiceTicks(0, kNaN, 5).empty());
  EXPECT_TRUE(NiceTicks(0, 1, 0).empty());
}

TEST(NiceLogTicksTest, DecadesForWideRanges) {
  const LogTicks t = NiceLogTicks(1, 1000, 10);
  EXPECT_EQ(t.major, (std::vector<double>{1, 10, 100, 1000}));
  EXPECT_EQ(t.minor.size(), 3u * 8u);  // 2..9 in each of 3 decades
  EXPECT_EQ(t.minor.front(), 2);
  EXPECT_EQ(t.minor.back(), 900);
  EXPECT_EQ(NiceLogTicks(0.003, 47, 10).major, (std::vector<double>{0.01, 0.1, 1, 10}));
}

TEST(NiceLogTicksTest, EveryOtherDecadeWhenTooMany) {
  const LogTicks t = NiceLogTicks(1e-6, 1e6, 6);
  EXPECT_EQ(t.major, (std::vector<double>{1e-6, 1e-3, 1, 1e3, 1e6}));
  // 13 decades: the unlabelled decades only, no 2..9 grid.
  EXPECT_EQ(t.minor.size(), 8u);
  EXPECT_EQ(NiceLogTicks(1e-6, 1e6, 7).major, (std::vector<double>{1e-6, 1e-4, 1e-2, 1, 1e2, 1e4,
                                                                    1e6}));
}

TEST(NiceLogTicksTest, TwoAndFiveForShortRanges) {
  EXPECT_EQ(NiceLogTicks(0.5, 30, 10).major, (std::vector<double>{0.5, 1, 2, 5, 10, 20}));
  EXPECT_EQ(NiceLogTicks(0.015, 0.3, 10).major, (std::vector<double>{0.02, 0.05, 0.1, 0.2}));
  // Too many for max_ticks: back to the decades.
  EXPECT_EQ(NiceLogTicks(0.5, 30, 4).major, (std::vector<double>{1, 10}));
  // Inside one decade: every 1..9, then linear.
  EXPECT_EQ(NiceLogTicks(3, 7, 5).major, (std::vector<double>{3, 4, 5, 6, 7}));
  EXPECT_EQ(NiceLogTicks(3, 7, 4).major, (std::vector<double>{4, 6}));
  EXPECT_EQ(NiceLogTicks(3, 7, 4).minor, (std::vector<double>{3, 5, 7}));
}

TEST(NiceLogTicksTest, AShortRangeGetsEnoughLabelsToRead) {
  // 10 to 45 (opl_simulate sweep --values 10:5:45 --log-x): 1, 2, 5 x 10^k
  // would label only 10 and 20; every 1..9 x 10^k labels four values.
  const LogTicks t = NiceLogTicks(10, 45, 10);
  EXPECT_EQ(t.major, (std::vector<double>{10, 20, 30, 40}));
  EXPECT_TRUE(t.minor.empty());
  // The axis of such a plot (range padded to 9.27 .. 48.6): the same labels.
  PlotPanel panel = Panel("angle", {Series("s", {10, 15, 20, 25, 30, 35, 40, 45},
                                           {1, 1.2, 1.5, 1.6, 2, 2.2, 2.5, 3})});
  panel.log_x = true;
  Result<LinePlotLayout> layout = LayoutLinePlot(OnePanel(panel));
  ASSERT_TRUE(layout.ok());
  EXPECT_EQ(layout->panels[0].x_tick_labels, (std::vector<std::string>{"10", "20", "30", "40"}));
  EXPECT_EQ(layout->panels[0].x_minor_ticks, (std::vector<double>{}));
  // Two or more 1-2-5 labels are kept when three do not fit max_ticks.
  EXPECT_EQ(NiceLogTicks(10, 45, 3).major, (std::vector<double>{10, 20}));
  // 1-2-5 already gives three: unchanged.
  EXPECT_EQ(NiceLogTicks(8, 60, 10).major, (std::vector<double>{10, 20, 50}));
}

TEST(NiceLogTicksTest, InvalidArgumentsGiveNoTicks) {
  EXPECT_TRUE(NiceLogTicks(0, 10, 5).major.empty());
  EXPECT_TRUE(NiceLogTicks(-1, 10, 5).major.empty());
  EXPECT_TRUE(NiceLogTicks(10, 10, 5).major.empty());
}

TEST(FormatTickLabelTest, ReadableNumbers) {
  EXPECT_EQ(FormatTickLabel(0.30000000000000004, 0.1), "0.3");
  EXPECT_EQ(FormatTickLabel(0, 0.1), "0");
  EXPECT_EQ(FormatTickLabel(-2.5, 0.5), "-2.5");
  EXPECT_EQ(FormatTickLabel(1500, 500), "1500");
  EXPECT_EQ(FormatTickLabel(0.0002, 0.0001), "0.0002");
  EXPECT_EQ(FormatTickLabel(2e-5, 1e-5), "2e-5");
  EXPECT_EQ(FormatTickLabel(2.5e-5, 5e-6), "2.5e-5");
  EXPECT_EQ(FormatTickLabel(3e6, 1e6), "3e6");
  // Log ticks (step 0): the value's own digits.
  EXPECT_EQ(FormatTickLabel(0.02, 0), "0.02");
  EXPECT_EQ(FormatTickLabel(1000, 0), "1000");
  EXPECT_EQ(FormatTickLabel(1e-6, 0), "1e-6");
  EXPECT_EQ(FormatTickLabel(1e6, 0), "1e6");
}

// --- Layout and pixels ---------------------------------------------------------

TEST(LinePlotTest, ImageSizeAndPngDecodes) {
  LinePlot plot = OnePanel(Panel("a", {Series("s", {0, 1, 2}, {1, 2, 3})}));
  plot.panels.push_back(plot.panels[0]);
  plot.panels.push_back(plot.panels[0]);
  plot.panel_width_px = 500;
  plot.panel_height_px = 400;
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok()) << layout.status().ToString();
  EXPECT_EQ(layout->image_width, 1500);
  EXPECT_GT(layout->image_height, 400);  // the figure title adds a row
  EXPECT_LT(layout->image_height, 460);
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 1500);
  EXPECT_EQ(img.rows, layout->image_height);
  EXPECT_EQ(img.type(), CV_8UC3);
  // Panels side by side, same plot area height.
  ASSERT_EQ(layout->panels.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const LinePlotPanelLayout& p = layout->panels[static_cast<size_t>(i)];
    EXPECT_EQ(p.panel.x, 500 * i);
    EXPECT_GE(p.plot_area.x, p.panel.x + 30);
    EXPECT_LE(p.plot_area.x + p.plot_area.width, p.panel.x + 500);
    EXPECT_EQ(p.plot_area.height, layout->panels[0].plot_area.height);
  }
  plot.title.clear();
  Result<LinePlotLayout> untitled = LayoutLinePlot(plot);
  ASSERT_TRUE(untitled.ok());
  EXPECT_EQ(untitled->image_height, 400);
}

TEST(LinePlotTest, AxisRangeHasMarginsAndTicksInside) {
  const LinePlot plot = OnePanel(Panel("a", {Series("s", {0, 10}, {2, 4})}));
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  EXPECT_DOUBLE_EQ(p.x_min, -0.5);
  EXPECT_DOUBLE_EQ(p.x_max, 10.5);
  EXPECT_DOUBLE_EQ(p.y_min, 1.9);
  EXPECT_DOUBLE_EQ(p.y_max, 4.1);
  EXPECT_EQ(p.x_ticks.front(), 0);
  EXPECT_EQ(p.x_ticks.back(), 10);
  EXPECT_EQ(p.y_ticks.front(), 2);
  EXPECT_EQ(p.y_ticks.back(), 4);
  ASSERT_EQ(p.y_ticks.size(), p.y_tick_labels.size());
  for (size_t k = 0; k < p.y_ticks.size(); ++k) {
    EXPECT_EQ(p.y_tick_labels[k], FormatTickLabel(p.y_ticks[k], p.y_ticks[1] - p.y_ticks[0]));
  }
  EXPECT_DOUBLE_EQ(p.PixelX(p.x_min), p.plot_area.x);
  EXPECT_DOUBLE_EQ(p.PixelX(p.x_max), p.plot_area.x + p.plot_area.width - 1);
  EXPECT_DOUBLE_EQ(p.PixelY(p.y_max), p.plot_area.y);
  EXPECT_DOUBLE_EQ(p.PixelY(p.y_min), p.plot_area.y + p.plot_area.height - 1);
}

TEST(LinePlotTest, ErrorBarsWidenTheYRange) {
  PlotSeries s = Series("s", {0, 1}, {1, 2});
  s.y_err = {0.5, kNaN};
  Result<LinePlotLayout> layout = LayoutLinePlot(OnePanel(Panel("a", {s})));
  ASSERT_TRUE(layout.ok());
  // Data 0.5 .. 2 (the NaN error has no bar), span 1.5, 5 % = 0.075.
  EXPECT_DOUBLE_EQ(layout->panels[0].y_min, 0.425);
  EXPECT_DOUBLE_EQ(layout->panels[0].y_max, 2.075);
}

TEST(LinePlotTest, SingleXAndConstantYGetARange) {
  Result<LinePlotLayout> layout =
      LayoutLinePlot(OnePanel(Panel("a", {Series("s", {5, 5, 5}, {0.2, 0.2, 0.2})})));
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  // +-10 % of the value, then 5 % of that span: 5 +- 0.55, 0.2 +- 0.022.
  EXPECT_NEAR(p.x_min, 4.45, 1e-12);
  EXPECT_NEAR(p.x_max, 5.55, 1e-12);
  EXPECT_NEAR(p.y_min, 0.178, 1e-12);
  EXPECT_NEAR(p.y_max, 0.222, 1e-12);
  EXPECT_GE(p.x_ticks.size(), 2u);
  EXPECT_GE(p.y_ticks.size(), 2u);
  // Zero: +-1.
  layout = LayoutLinePlot(OnePanel(Panel("a", {Series("s", {0}, {0})})));
  ASSERT_TRUE(layout.ok());
  EXPECT_NEAR(layout->panels[0].x_min, -1.1, 1e-12);
  EXPECT_NEAR(layout->panels[0].y_max, 1.1, 1e-12);
  // Log axis: a factor 2 each way, then 5 % of the log span.
  PlotPanel log = Panel("a", {Series("s", {10}, {3})});
  log.log_x = log.log_y = true;
  layout = LayoutLinePlot(OnePanel(log));
  ASSERT_TRUE(layout.ok());
  const double f = std::pow(2.0, 1.1);
  EXPECT_NEAR(layout->panels[0].x_min, 10 / f, 1e-9);
  EXPECT_NEAR(layout->panels[0].x_max, 10 * f, 1e-9);
  EXPECT_NEAR(layout->panels[0].y_min, 3 / f, 1e-9);
}

TEST(LinePlotTest, MarkersAtThePredictedPixelsAndWhiteBackground) {
  // Series 0 (blue circles) and 1 (vermillion squares), markers only.
  const std::vector<double> x = {0.1, 0.2, 0.3, 0.4};
  const std::vector<double> y0 = {1.0, 1.5, 1.2, 2.0};
  const std::vector<double> y1 = {3.0, 2.6, 2.9, 2.7};
  LinePlot plot = OnePanel(Panel("a", {Series("", x, y0, PlotSeries::Style::kMarkers),
                                       Series("", x, y1, PlotSeries::Style::kMarkers)}));
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  EXPECT_EQ(p.legend.width, 0);  // no labels, no legend
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  for (size_t k = 0; k < x.size(); ++k) {
    const int px = static_cast<int>(std::lround(p.PixelX(x[k])));
    EXPECT_EQ(PixelAt(img, px, static_cast<int>(std::lround(p.PixelY(y0[k])))), kBlue) << k;
    EXPECT_EQ(PixelAt(img, px, static_cast<int>(std::lround(p.PixelY(y1[k])))), kVermillion)
        << k;
  }
  // Far from the data (away from grid lines): white. Between the two groups
  // at y = 2.3, and halfway between x ticks.
  const int mid_y = static_cast<int>(std::lround(p.PixelY(2.33)));
  const int between_x = static_cast<int>(
      std::lround(0.5 * (p.PixelX(p.x_ticks[0]) + p.PixelX(p.x_ticks[1]))));
  EXPECT_EQ(PixelAt(img, between_x, mid_y), kWhiteRgb);
  // Outside the panel's frame, right of the plot area: white.
  EXPECT_EQ(PixelAt(img, p.plot_area.x + p.plot_area.width + 8, p.plot_area.y + 20), kWhiteRgb);
  // The frame is black.
  EXPECT_EQ(PixelAt(img, p.plot_area.x - 1, p.plot_area.y + 17), (Rgb{0, 0, 0}));
  EXPECT_EQ(PixelAt(img, p.plot_area.x + 17, p.plot_area.y + p.plot_area.height), (Rgb{0, 0, 0}));
}

TEST(LinePlotTest, LogAxesMapDecadesEvenly) {
  PlotPanel panel = Panel("log", {Series("", {1, 10, 100}, {1e-3, 1e-2, 1e-1},
                                         PlotSeries::Style::kMarkers)});
  panel.log_x = panel.log_y = true;
  const LinePlot plot = OnePanel(panel);
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  EXPECT_NEAR(p.PixelX(10) - p.PixelX(1), p.PixelX(100) - p.PixelX(10), 1e-9);
  EXPECT_NEAR(p.PixelX(10), p.plot_area.x + 0.5 * (p.plot_area.width - 1), 1e-9);
  EXPECT_NEAR(p.PixelY(1e-2), p.plot_area.y + 0.5 * (p.plot_area.height - 1), 1e-9);
  EXPECT_EQ(p.x_ticks, (std::vector<double>{1, 10, 100}));
  EXPECT_EQ(p.y_tick_labels, (std::vector<std::string>{"0.001", "0.01", "0.1"}));
  EXPECT_FALSE(p.x_minor_ticks.empty());
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(PixelAt(img, static_cast<int>(std::lround(p.PixelX(10))),
                    static_cast<int>(std::lround(p.PixelY(1e-2)))),
            kBlue);
}

TEST(LinePlotTest, NaNIsAGapInTheLine) {
  // A horizontal line y = 1 from x = 0 to 4 with y[2] = NaN: drawn from 0 to
  // 1 and from 3 to 4, nothing between 1 and 3.
  LinePlot plot = OnePanel(
      Panel("gap", {Series("", {0, 1, 2, 3, 4}, {1, 1, kNaN, 1, 1}, PlotSeries::Style::kLine),
                    Series("", {0, 4}, {0, 2}, PlotSeries::Style::kMarkers)}));
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  const int row = static_cast<int>(std::lround(p.PixelY(1)));
  const auto coloured = [&](double x) {
    const Rgb c = PixelAt(img, static_cast<int>(std::lround(p.PixelX(x))), row);
    return c.r < 128 && c.b > 100;  // blue-ish
  };
  EXPECT_TRUE(coloured(0.5));
  EXPECT_TRUE(coloured(3.5));
  EXPECT_FALSE(coloured(1.6));
  EXPECT_FALSE(coloured(2.3));
}

TEST(LinePlotTest, EverythingIsClippedToThePlotArea) {
  // An error bar far below the axis on a log y axis (y - err < 0) must not
  // draw below the frame.
  PlotSeries s = Series("", {1, 2, 3}, {1, 2, 3}, PlotSeries::Style::kMarkers);
  s.y_err = {5, 0, 0};
  PlotPanel panel = Panel("clip", {s});
  panel.log_y = true;
  const LinePlot plot = OnePanel(panel);
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  const int px = static_cast<int>(std::lround(p.PixelX(1)));
  const int frame = p.plot_area.y + p.plot_area.height;
  EXPECT_EQ(PixelAt(img, px, frame), (Rgb{0, 0, 0}));
  EXPECT_EQ(PixelAt(img, px, frame + 7), kWhiteRgb);  // between tick and label? no tick here
  // The bar itself is drawn inside (blue-ish just above the frame).
  const Rgb inside = PixelAt(img, px, frame - 2);
  EXPECT_GT(inside.b, inside.r + 60) << inside;
}

TEST(LinePlotTest, LegendSwatchesShowTheSeriesColours) {
  LinePlot plot =
      OnePanel(Panel("legend", {Series("Monte Carlo", {1, 2, 3}, {1, 2, 3}),
                                Series("first order", {1, 2, 3}, {1.1, 2.1, 3.1}),
                                Series("", {1, 2, 3}, {0.5, 1, 1.5}),  // not in the legend
                                Series("Cramer-Rao bound", {1, 2, 3}, {0.9, 1.9, 2.9},
                                       PlotSeries::Style::kMarkers)}));
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  ASSERT_EQ(p.legend_series, (std::vector<int>{0, 1, 3}));
  ASSERT_EQ(p.legend_swatches.size(), 3u);
  // Rising data: bottom-left and top-right are covered; the legend goes top left.
  EXPECT_EQ(p.legend.x, p.plot_area.x + 8);
  EXPECT_EQ(p.legend.y, p.plot_area.y + 8);
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  const Rgb kPurple{204, 121, 167};  // series 3
  const std::vector<Rgb> expected = {kBlue, kVermillion, kPurple};
  for (size_t row = 0; row < 3; ++row) {
    const PixelRect& sw = p.legend_swatches[row];
    EXPECT_EQ(PixelAt(img, sw.x + sw.width / 2, sw.y + sw.height / 2), expected[row]) << row;
    // The legend box is white between swatch and text rows' edges.
    EXPECT_EQ(PixelAt(img, p.legend.x + 3, sw.y + sw.height / 2), kWhiteRgb);
  }
  // Lines in the swatches of line series (row 0 and 1) reach the swatch ends.
  const PixelRect& sw0 = p.legend_swatches[0];
  EXPECT_EQ(PixelAt(img, sw0.x + 4, sw0.y + sw0.height / 2).r, 0);
  const PixelRect& sw2 = p.legend_swatches[2];  // markers only: no line
  EXPECT_EQ(PixelAt(img, sw2.x + 3, sw2.y + sw2.height / 2), kWhiteRgb);
}

TEST(LinePlotTest, ALegendTallerThanThePlotIsClippedToIt) {
  PlotPanel panel = Panel("many", {});
  for (int j = 0; j < 15; ++j) {
    panel.series.push_back(Series("series " + std::to_string(j), {0, 1}, {1.0 * j, j + 0.5}));
  }
  LinePlot plot = OnePanel(panel);
  plot.panel_height_px = 240;
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  ASSERT_GT(p.legend.y + p.legend.height, p.plot_area.y + p.plot_area.height);  // too tall
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  // The bottom frame under the legend is still black, the tick area below white.
  const int x = p.legend.x + p.legend.width - 3;
  EXPECT_EQ(PixelAt(img, x, p.plot_area.y + p.plot_area.height), (Rgb{0, 0, 0}));
  EXPECT_EQ(PixelAt(img, p.legend.x + 2, p.plot_area.y + p.plot_area.height + 3), kWhiteRgb);
}

TEST(LinePlotTest, LegendAvoidsTheData) {
  // Falling data covers top left and bottom right: the legend goes top right.
  Result<LinePlotLayout> layout = LayoutLinePlot(
      OnePanel(Panel("fall", {Series("falling", {0, 1, 2, 3, 4, 5}, {5, 4, 3, 2, 1, 0})})));
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  EXPECT_EQ(p.legend.x + p.legend.width, p.plot_area.x + p.plot_area.width - 8);
  EXPECT_EQ(p.legend.y, p.plot_area.y + 8);
  // Data only along the top: the legend goes to a bottom corner.
  layout = LayoutLinePlot(OnePanel(Panel(
      "top", {Series("top", {0, 1, 2, 3, 4, 5}, {5, 5.1, 5, 5.1, 5, 5.1}),
              Series("low", {2.5}, {0}, PlotSeries::Style::kMarkers)})));
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& q = layout->panels[0];
  EXPECT_EQ(q.legend.y + q.legend.height, q.plot_area.y + q.plot_area.height - 8);
}

TEST(LinePlotTest, TickLabelsDoNotOverlap) {
  // Long labels (large numbers with decimals) on a narrow panel: between
  // every two x tick labels the rendered PNG has a white column in the label
  // band, and the last label ends inside the image.
  LinePlot plot =
      OnePanel(Panel("narrow", {Series("", {123456.25, 123459.75}, {0.0012345, 0.0012399})}));
  plot.panel_width_px = 400;
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok()) << layout.status().ToString();
  const LinePlotPanelLayout& p = layout->panels[0];
  ASSERT_GE(p.x_ticks.size(), 2u);
  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  // The label band: below the ticks, above the x label.
  const int band_top = p.plot_area.y + p.plot_area.height + 7;
  const int band_bottom = band_top + 14;
  const auto column_white = [&](int x) {
    for (int y = band_top; y <= band_bottom; ++y) {
      if (PixelAt(img, x, y) != kWhiteRgb) return false;
    }
    return true;
  };
  const auto column_inked = [&](int x) { return !column_white(x); };
  for (size_t k = 0; k < p.x_ticks.size(); ++k) {
    const int px = static_cast<int>(std::lround(p.PixelX(p.x_ticks[k])));
    EXPECT_TRUE(column_inked(px) || column_inked(px - 2) || column_inked(px + 2)) << k;
    if (k == 0) continue;
    const int prev = static_cast<int>(std::lround(p.PixelX(p.x_ticks[k - 1])));
    bool gap = false;
    for (int x = prev + 1; x < px && !gap; ++x) gap = column_white(x);
    EXPECT_TRUE(gap) << "labels " << p.x_tick_labels[k - 1] << " and " << p.x_tick_labels[k];
    EXPECT_NE(p.x_tick_labels[k], p.x_tick_labels[k - 1]);
  }
  // Nothing inked in the last 5 columns of the image (the last label fits).
  for (int x = img.cols - 5; x < img.cols; ++x) EXPECT_TRUE(column_white(x)) << x;
}

// A categorical x axis: ticks exactly at the categories with their names,
// the range half a spacing beyond them, no numeric or minor ticks; in the
// PNG a tick mark under each category and none between them.
TEST(LinePlotTest, CategoricalAxisHasNamedTicksOnly) {
  PlotPanel panel = Panel("layouts", {Series("MC", {1, 2, 3}, {0.5, 0.7, 0.6}, PlotSeries::Style::kMarkers),
                                      Series("FO", {0.88, 1.88, 2.88}, {0.5, 0.7, 0.6},
                                             PlotSeries::Style::kMarkers)});
  panel.x_label = "layout";
  panel.x_categories = {{1, "side by side"}, {2, "staggered"}, {3, "a very long layout name to be cut"}};
  LinePlot plot = OnePanel(panel);
  plot.panel_width_px = 480;
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok()) << layout.status().ToString();
  const LinePlotPanelLayout& p = layout->panels[0];
  EXPECT_EQ(p.x_ticks, (std::vector<double>{1, 2, 3}));
  ASSERT_EQ(p.x_tick_labels.size(), 3u);
  EXPECT_EQ(p.x_tick_labels[0], "side by side");
  EXPECT_EQ(p.x_tick_labels[1], "staggered");
  // Cut with "..." to the space between categories (one third of the plot).
  EXPECT_EQ(p.x_tick_labels[2].substr(p.x_tick_labels[2].size() - 3), "...");
  EXPECT_LT(p.x_tick_labels[2].size(), 25u) << p.x_tick_labels[2];
  EXPECT_TRUE(p.x_minor_ticks.empty());
  EXPECT_DOUBLE_EQ(p.x_min, 0.5);
  EXPECT_DOUBLE_EQ(p.x_max, 3.5);

  const cv::Mat img = Decode(plot);
  ASSERT_FALSE(img.empty());
  const int tick_row = p.plot_area.y + p.plot_area.height + 2;  // inside the tick marks
  const Rgb black{0, 0, 0};
  for (double x : {1.0, 2.0, 3.0}) {
    EXPECT_EQ(PixelAt(img, static_cast<int>(std::lround(p.PixelX(x))), tick_row), black) << x;
  }
  // Between categories (where numeric ticks at 0.5 steps would be): no
  // tick, and a white column through the label band (the names do not meet).
  const int band_top = p.plot_area.y + p.plot_area.height + 7;
  for (double x : {1.5, 2.5}) {
    const int px = static_cast<int>(std::lround(p.PixelX(x)));
    EXPECT_EQ(PixelAt(img, px, tick_row), kWhiteRgb) << x;
    for (int y = band_top; y <= band_top + 14; ++y) EXPECT_EQ(PixelAt(img, px, y), kWhiteRgb) << x << " " << y;
  }
  // A single category: the range 0.5 around it.
  panel.x_categories = {{1, "one"}};
  panel.series = {Series("MC", {1}, {2}, PlotSeries::Style::kMarkers)};
  Result<LinePlotLayout> one = LayoutLinePlot(OnePanel(panel));
  ASSERT_TRUE(one.ok());
  EXPECT_DOUBLE_EQ(one->panels[0].x_min, 0.5);
  EXPECT_DOUBLE_EQ(one->panels[0].x_max, 1.5);
  EXPECT_EQ(one->panels[0].x_tick_labels, (std::vector<std::string>{"one"}));
}

// --- Errors ------------------------------------------------------------------------

void ExpectInvalid(const LinePlot& plot, const std::string& message) {
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_FALSE(layout.ok());
  EXPECT_EQ(layout.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(layout.status().message(), message);
  Result<std::vector<unsigned char>> png = RenderLinePlotPng(plot);
  ASSERT_FALSE(png.ok());
  EXPECT_EQ(png.status().message(), message);
}

TEST(LinePlotErrorsTest, Messages) {
  LinePlot none;
  ExpectInvalid(none, "LinePlot.panels: must have 1 to 4 panels, got 0");
  LinePlot five = OnePanel(Panel("a", {Series("s", {1}, {1})}));
  for (int i = 0; i < 4; ++i) five.panels.push_back(five.panels[0]);
  ExpectInvalid(five, "LinePlot.panels: must have 1 to 4 panels, got 5");

  LinePlot small = OnePanel(Panel("a", {Series("s", {1}, {1})}));
  small.panel_width_px = 100;
  ExpectInvalid(small, "LinePlot.panel_width_px: must be in [320, 4000], got 100");
  small.panel_width_px = 640;
  small.panel_height_px = 5000;
  ExpectInvalid(small, "LinePlot.panel_height_px: must be in [240, 4000], got 5000");

  LinePlot two = OnePanel(Panel("std of L", {Series("s", {1}, {1})}));
  two.panels.push_back(Panel("u(L)/L", {Series("s", {1}, {1}),
                                        Series("Monte Carlo", {1, 2, 3, 4, 5}, {1, 2, 3, 4})}));
  ExpectInvalid(two,
                "LinePlot.panels[1] \"u(L)/L\": series[1] \"Monte Carlo\": x has 5 values but y "
                "has 4");

  PlotSeries err = Series("MC", {1, 2, 3}, {1, 2, 3});
  err.y_err = {0.1, 0.1};
  ExpectInvalid(OnePanel(Panel("p", {err})),
                "LinePlot.panels[0] \"p\": series[0] \"MC\": y_err has 2 values but y has 3");
  err.y_err = {0.1, -1, 0.1};
  ExpectInvalid(OnePanel(Panel("p", {err})),
                "LinePlot.panels[0] \"p\": series[0] \"MC\": y_err[1] must be finite and >= 0 "
                "or NaN, got -1");

  const double inf = std::numeric_limits<double>::infinity();
  ExpectInvalid(OnePanel(Panel("p", {Series("", {1, 2}, {1, inf})})),
                "LinePlot.panels[0] \"p\": series[0]: y[1] is infinite (use NaN for a gap)");
  ExpectInvalid(OnePanel(Panel("p", {Series("", {-inf, 2}, {1, 1})})),
                "LinePlot.panels[0] \"p\": series[0]: x[0] is infinite (use NaN for a gap)");

  PlotPanel log = Panel("p", {Series("a", {1, 2}, {1, 1}), Series("MC", {0, 2}, {1, 1})});
  log.log_x = true;
  ExpectInvalid(OnePanel(log),
                "LinePlot.panels[0] \"p\": log x axis needs x > 0: series[1] \"MC\" has x[0] = 0");
  log = Panel("p", {Series("a", {1, 2}, {1, -0.5})});
  log.log_y = true;
  ExpectInvalid(OnePanel(log),
                "LinePlot.panels[0] \"p\": log y axis needs y > 0: series[0] \"a\" has y[1] = "
                "-0.5");

  ExpectInvalid(OnePanel(Panel("p", {Series("a", {1, kNaN}, {kNaN, 2}), Series("b", {}, {})})),
                "LinePlot.panels[0] \"p\": no finite points to plot");
  ExpectInvalid(OnePanel(Panel("p", {})),
                "LinePlot.panels[0] \"p\": no finite points to plot (no series)");
  PlotPanel categories = Panel("p", {Series("a", {1, 2}, {1, 1})});
  categories.x_categories = {{1, "a"}, {1, "b"}};
  ExpectInvalid(OnePanel(categories),
                "LinePlot.panels[0] \"p\": x_categories[1] \"b\": x = 1 must be finite and greater than "
                "the one before");
  categories.x_categories = {{1, ""}};
  ExpectInvalid(OnePanel(categories), "LinePlot.panels[0] \"p\": x_categories[0]: the label must not be empty");
  categories.x_categories = {{1, "a"}};
  categories.log_x = true;
  ExpectInvalid(OnePanel(categories),
                "LinePlot.panels[0] \"p\": x_categories need a linear x axis (log_x is set)");
  // An untitled panel is named by its y label.
  PlotPanel untitled = Panel("", {});
  ExpectInvalid(OnePanel(untitled),
                "LinePlot.panels[0] \"std of L (mm)\": no finite points to plot (no series)");
}

// --- Files ------------------------------------------------------------------------

TEST(LinePlotTest, WritesThePngAtomically) {
  TempDir dir;
  const std::string path = dir.File("plot.png");
  const LinePlot plot = OnePanel(Panel("a", {Series("s", {1, 2}, {3, 4})}));
  ASSERT_TRUE(WriteLinePlot(plot, path).ok());
  Result<std::vector<unsigned char>> png = RenderLinePlotPng(plot);
  ASSERT_TRUE(png.ok());
  EXPECT_EQ(ReadAll(path), std::string(png->begin(), png->end()));
  // An invalid plot leaves the file as it was.
  LinePlot bad = plot;
  bad.panels.clear();
  EXPECT_FALSE(WriteLinePlot(bad, path).ok());
  EXPECT_EQ(ReadAll(path), std::string(png->begin(), png->end()));
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"plot.png"}));
  // A missing directory is an IoError.
  EXPECT_EQ(WriteLinePlot(plot, dir.File("no/such/x.png")).code(), StatusCode::kIoError);
}

// --- Samples for looking at (only with OPL_LINE_PLOT_SAMPLES=<dir>) ----------------

TEST(LinePlotSamples, WriteWhenAsked) {
  const char* dir = std::getenv("OPL_LINE_PLOT_SAMPLES");
  if (dir == nullptr) GTEST_SKIP() << "set OPL_LINE_PLOT_SAMPLES=<dir> to write sample PNGs";
  const std::vector<double> sigma = {0.005, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1};
  PlotSeries mc = Series("Monte Carlo", sigma, {}, PlotSeries::Style::kMarkers);
  PlotSeries fo = Series("first order", sigma, {}, PlotSeries::Style::kLine);
  PlotSeries crb = Series("Cramer-Rao bound", sigma, {}, PlotSeries::Style::kDashed);
  PlotSeries mc2 = mc, fo2 = fo, crb2 = crb;
  for (size_t k = 0; k < sigma.size(); ++k) {
    const double s = sigma[k];
    fo.y.push_back(0.41 * s);
    crb.y.push_back(0.38 * s);
    mc.y.push_back(0.41 * s * (1 + 0.04 * std::sin(7.0 * k)));
    mc.y_err.push_back(0.41 * s * 0.06);
    fo2.y.push_back(0.41 * s / 1500 * 1e6);
    crb2.y.push_back(0.38 * s / 1500 * 1e6);
    mc2.y.push_back(mc.y.back() / 1500 * 1e6);
    mc2.y_err.push_back(mc.y_err.back() / 1500 * 1e6);
  }
  mc.y[4] = kNaN;  // a failed run: a gap
  LinePlot plot;
  plot.title = "Length scale: spot noise sweep (L = 1500 mm, 9 x 9 beams)";
  PlotPanel a = Panel("std of L", {mc, fo, crb});
  PlotPanel b = Panel("u(L)/L", {mc2, fo2, crb2});
  b.y_label = "u(L)/L (ppm)";
  plot.panels = {a, b};
  ASSERT_TRUE(WriteLinePlot(plot, std::string(dir) + "/sweep_two_panels.png").ok());

  LinePlot loglog;
  loglog.title = "Log-log sweep";
  PlotPanel l = b;
  l.title = "u(L)/L against spot noise";
  l.log_x = l.log_y = true;
  PlotPanel l2 = l;
  l2.title = "wide range";
  for (PlotSeries& s : l2.series) {
    for (double& x : s.x) x = x * x * 1e3;
  }
  loglog.panels = {l, l2};
  ASSERT_TRUE(WriteLinePlot(loglog, std::string(dir) + "/sweep_loglog.png").ok());

  LinePlot edge;
  edge.title = "Edge cases";
  edge.panel_width_px = 420;
  edge.panel_height_px = 320;
  edge.panels = {Panel("single x", {Series("one x", {0.3, 0.3}, {1, 2})}),
                 Panel("constant y", {Series("flat", {1, 2, 3}, {0.1, 0.1, 0.1})}),
                 Panel("tiny range", {Series("big numbers", {123456.25, 123459.75},
                                             {0.0012345, 0.0012399})}),
                 Panel("seven series", {})};
  for (int j = 0; j < 7; ++j) {
    edge.panels[3].series.push_back(Series("series " + std::to_string(j), {0, 1, 2, 3},
                                           {1.0 * j, j + 0.5, j + 0.2, j + 0.9}));
  }
  ASSERT_TRUE(WriteLinePlot(edge, std::string(dir) + "/edge_cases.png").ok());

  LinePlot angle;
  angle.title = "Log axis from 10 to 45";
  PlotPanel ap = Panel("u(L)/L against angle", {Series("Monte Carlo", {10, 15, 20, 25, 30, 35, 40, 45},
                                                         {9, 6, 4.4, 3.7, 3.1, 2.6, 2.3, 2.1})});
  ap.x_label = "half angle (deg)";
  ap.log_x = ap.log_y = true;
  angle.panels = {ap};
  for (const char* ext : {"png", "svg", "pdf"}) {
    ASSERT_TRUE(WriteLinePlot(angle, std::string(dir) + "/log_10_45." + ext).ok());
  }

  LinePlot categorical;
  categorical.title = "Categorical x axis";
  PlotPanel cp = Panel("std of L", {Series("first order", {0.88, 1.88, 2.88}, {0.020, 0.031, 0.026},
                                           PlotSeries::Style::kMarkers),
                                    Series("Monte Carlo", {1, 2, 3}, {0.021, 0.030, 0.027},
                                           PlotSeries::Style::kMarkers)});
  cp.x_label = "layout";
  cp.x_categories = {{1, "side by side"}, {2, "staggered"}, {3, "a very long layout name to be cut"}};
  categorical.panels = {cp};
  ASSERT_TRUE(WriteLinePlot(categorical, std::string(dir) + "/categorical.png").ok());
}

}  // namespace
}  // namespace opl
