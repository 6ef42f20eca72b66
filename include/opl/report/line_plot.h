// Line plots for design sweeps (e.g. std of L against spot noise), as PNG,
// SVG or PDF (report/plot_format.h).
//
// A figure is 1..4 panels side by side under an optional figure title. Each
// panel has its own axes (linear or log), title, axis labels (with units) and
// series. The look follows the other report images (grid_heatmap.h): white
// background, DejaVu Sans text, anti-aliased drawing with cairo (the same
// drawing for every format), files written atomically. Per panel:
//
//   - a black frame around the plot area, ticks outward, tick values at 1, 2
//     or 5 times a power of ten (NiceTicks), light grey grid lines at them;
//     log axes: decades, plus 2 and 5 (or every 1..9, so that at least three
//     values are labelled: 10 to 45 reads 10, 20, 30, 40) when the range is
//     short (NiceLogTicks), with lighter unlabelled grid lines at 2..9 x 10^k;
//   - tick labels that never overlap (fewer ticks are used until they fit,
//     measured with the font's own glyph advances),
//     written as "0.3", "2.5", "1e-05"-free text (exact decimal forms such as
//     "0.00002" down to 1e-4, "2e-5" below);
//   - x label centred under the axis, y label rotated 90 degrees (reads
//     bottom-up), both shrunk and if need be cut with "..." to the axis length;
//   - the axis range is the data range (including error bars) widened by 5 %
//     of its span on each side (log axes: in log space), so no point sits on
//     the frame; a single x value or a constant y gets a range around it
//     (+-10 % of the value, +-1 for 0; factor 2 on log axes);
//   - series in the Okabe-Ito colour-blind-safe colours (blue, vermillion,
//     bluish green, reddish purple, orange, sky blue, black; then repeating)
//     and markers (filled circle, square, triangle up, diamond, triangle down,
//     plus, cross), 2 px anti-aliased lines; NaN in x or y is a gap (no marker,
//     the line is broken); error bars +-y_err with caps; everything is clipped
//     to the plot area;
//   - or a categorical x axis (PlotPanel::x_categories): ticks, grid lines
//     and names at the given positions only;
//   - a legend (white box, grey border; one row per series with a non-empty
//     label, its line/marker swatch and the label) in the corner of the plot
//     area that covers the fewest data points and line pixels (ties: top
//     left, top right, bottom right, bottom left).
//
// docs/report.md ("Line plots") shows the look.
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/report/grid_heatmap.h"  // PixelRect
#include "opl/report/plot_format.h"

namespace opl {

inline constexpr int kLinePlotMaxPanels = 4;
inline constexpr int kLinePlotMinPanelWidth = 320;
inline constexpr int kLinePlotMinPanelHeight = 240;
inline constexpr int kLinePlotMaxPanelSize = 4000;  // width and height, px

struct PlotSeries {
  std::string label;          // legend text; empty = not in the legend
  std::vector<double> x, y;   // same length; NaN in x or y = gap (no point, line broken)
  std::vector<double> y_err;  // empty, or same length: error bars y +- y_err (>= 0; NaN = none)
  enum class Style { kLineMarkers, kLine, kMarkers, kDashed } style = Style::kLineMarkers;
};

// A named position on a categorical x axis (PlotPanel::x_categories).
struct PlotCategory {
  double x = 0;       // where its tick (and its data) sit, e.g. 1, 2, ...
  std::string label;  // the tick's text, e.g. "side by side"
};

struct PlotPanel {
  std::string title;    // optional
  std::string x_label;  // with units, e.g. "spot noise sigma (mm)"
  std::string y_label;  // with units, e.g. "std of L (mm)"
  bool log_x = false, log_y = false;
  std::vector<PlotSeries> series;
  // A categorical x axis: when not empty, the x ticks are exactly these
  // positions, labelled with these names (each cut with "..." to fit the
  // space between it and its neighbours), with no numeric or minor ticks.
  // The x range spans the categories plus half their smallest spacing on
  // each side (0.5 for one category), widened to the data if a point lies
  // beyond. Needs a linear x axis; positions finite and increasing, labels
  // not empty.
  std::vector<PlotCategory> x_categories{};
};

struct LinePlot {
  std::string title;              // figure title (top), optional
  std::vector<PlotPanel> panels;  // laid out side by side, 1..4
  int panel_width_px = 640;       // each panel, [320, 4000]
  int panel_height_px = 480;      // each panel, [240, 4000] (the figure title is extra)
};

// Nice tick values in [lo, hi]: the multiples of the smallest step
// s = {1, 2, 5} x 10^k that give at most `max_ticks` of them. Values are exact
// decimals (0.3, not 0.30000000000000004). E.g. NiceTicks(0, 1, 6) =
// {0, 0.2, 0.4, 0.6, 0.8, 1}, NiceTicks(-0.013, 0.048, 8) = {-0.01, 0, 0.01,
// ..., 0.04}. Empty if lo, hi are not finite, lo >= hi or max_ticks < 1.
std::vector<double> NiceTicks(double lo, double hi, int max_ticks);

struct LogTicks {
  std::vector<double> major;  // labelled, ascending
  std::vector<double> minor;  // unlabelled grid lines, ascending, not in major
};

// Ticks for a log axis over [lo, hi] (0 < lo < hi), at most `max_ticks`
// labelled ones:
//   - spans of 2 decades or more: the decades 10^k, every m-th (m = 1, 2, 3,
//     ...) if there are more than max_ticks; minor: the other decades and, up
//     to 8 decades, 2..9 x 10^k;
//   - shorter spans: enough labels to read the axis: the first of
//       1, 2 and 5 x 10^k   with 3 .. max_ticks labels,
//       1 .. 9 x 10^k       with 3 .. max_ticks labels,
//       1, 2 and 5 x 10^k   with 2 .. max_ticks labels,
//       the decades         with 2 .. max_ticks labels,
//       1 .. 9 x 10^k       with 2 .. max_ticks labels,
//     else NiceTicks(lo, hi, max_ticks); minor: the rest of 1..9 x 10^k.
// E.g. (1, 1000, 10) -> major {1, 10, 100, 1000}; (0.5, 30, 10) -> major
// {0.5, 1, 2, 5, 10, 20}; (9.3, 48, 10) -> {10, 20, 30, 40} (1, 2, 5 would
// label only 10 and 20). Empty if the arguments are invalid.
LogTicks NiceLogTicks(double lo, double hi, int max_ticks);

// The text of a tick label: exact decimals ("0.3", "-2.5", "1500", "0.0002"),
// an exponent only for very large or small values ("2e-05" -> "2e-5",
// "1e+06" -> "1e6"). `step` is the distance between ticks (sets the number of
// decimals); for log ticks pass 0 (the value's own digits are used).
std::string FormatTickLabel(double value, double step);

// Where one panel's parts are in the image (pixels, x right, y down).
struct LinePlotPanelLayout {
  PixelRect panel;      // the panel's share of the image
  PixelRect plot_area;  // inside the frame: data are drawn (and clipped) here
  bool log_x = false, log_y = false;
  double x_min = 0, x_max = 0, y_min = 0, y_max = 0;  // axis ranges (data units)
  std::vector<double> x_ticks, y_ticks;               // labelled ticks
  std::vector<std::string> x_tick_labels, y_tick_labels;
  std::vector<double> x_minor_ticks, y_minor_ticks;   // log axes: unlabelled grid lines
  PixelRect legend;                    // width 0 when no series has a label
  std::vector<int> legend_series;      // series index of each legend row
  std::vector<PixelRect> legend_swatches;  // per row; the marker is at its centre

  // Pixel coordinates (fractional; pixel centres are integers) of a data
  // value: x_min maps to plot_area.x, x_max to plot_area.x + width - 1,
  // y_max to plot_area.y, y_min to plot_area.y + height - 1; log axes map
  // log10 linearly.
  double PixelX(double x) const;
  double PixelY(double y) const;
};

struct LinePlotLayout {
  int image_width = 0;   // panels * panel_width_px
  int image_height = 0;  // panel_height_px + the figure title's row
  std::vector<LinePlotPanelLayout> panels;
};

// Checks the plot and computes the layout. InvalidArgument with one line
// naming the panel/series and the problem, e.g.
//   "LinePlot.panels: must have 1 to 4 panels, got 0"
//   "LinePlot.panel_width_px: must be in [320, 4000], got 100"
//   "LinePlot.panels[1] \"u(L)/L\": series[0] \"Monte Carlo\": x has 5 values but y has 4"
//   "LinePlot.panels[0] \"std of L\": series[2] \"CRB\": y_err has 3 values but y has 4"
//   "LinePlot.panels[0] \"std of L\": series[0] \"MC\": y_err[2] must be >= 0 or NaN, got -1"
//   "LinePlot.panels[0] \"std of L\": series[0] \"MC\": y[3] is infinite (use NaN for a gap)"
//   "LinePlot.panels[0] \"std of L\": log x axis needs x > 0: series[1] \"MC\" has x[0] = 0"
//   "LinePlot.panels[0] \"std of L\": no finite points to plot"
//   "LinePlot.panels[0] \"std of L\": x_categories need a linear x axis (log_x is set)"
//   "LinePlot.panels[0] \"std of L\": x_categories[1] \"b\": x = 1 must be finite and greater than the one before"
//   "LinePlot.panels[0] \"std of L\": x_categories[0]: the label must not be empty"
Result<LinePlotLayout> LayoutLinePlot(const LinePlot& plot);

// Renders the figure in `format` (the file's bytes): PNG 8-bit RGB, one
// pixel per layout pixel; SVG and PDF the same drawing as vectors
// (report/plot_format.h; `metadata` goes into the PDF's information
// dictionary). Errors as LayoutLinePlot; IoError "line plot: cannot render
// the png: ..." if cairo fails (out of memory). Never throws.
Result<std::vector<unsigned char>> RenderLinePlot(const LinePlot& plot, PlotFormat format,
                                                  const PlotMetadata& metadata = {});
// RenderLinePlot(plot, PlotFormat::kPng).
Result<std::vector<unsigned char>> RenderLinePlotPng(const LinePlot& plot);

// Renders in the format `path`'s extension names (.png, .svg, .pdf, any
// case; another is InvalidArgument naming the path) and writes the file
// atomically (opl/io/atomic_file.h): on any error no file is created and an
// existing `path` is left as it was.
Status WriteLinePlot(const LinePlot& plot, const std::string& path,
                     const PlotMetadata& metadata = {});

}  // namespace opl
