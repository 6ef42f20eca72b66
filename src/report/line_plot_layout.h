// Internal to src/report: the line plot's full layout (what LayoutLinePlot
// returns plus what the renderer needs: fitted texts, baselines) and the
// helpers the layout and the renderer share.
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/report/line_plot.h"
#include "plot_canvas.h"

namespace opl::plot_internal {

// Fonts (em sizes in px) of the parts of a line plot.
inline constexpr Font kFigureTitleFont{17, true};
inline constexpr Font kPanelTitleFont{15, true};
inline constexpr Font kAxisLabelFont{13.5, false};
inline constexpr Font kTickFont{12, false};
inline constexpr Font kLegendFont{12.5, false};
inline constexpr double kMinTextSize = 9;  // long texts shrink to this, then are cut

inline constexpr int kTickLength = 5;
inline constexpr int kMinorTickLength = 3;
inline constexpr int kSwatchWidth = 36;
inline constexpr int kLegendInset = 8;  // legend <-> plot-area edge

struct Point {
  double x = 0, y = 0;
};

struct PanelExtras {
  std::string title;
  Font title_font = kPanelTitleFont;
  int title_baseline = 0;
  std::string x_label;
  Font x_label_font = kAxisLabelFont;
  int x_label_baseline = 0;
  std::string y_label;
  Font y_label_font = kAxisLabelFont;
  int y_label_left = 0;
  int x_tick_baseline = 0;
  int y_tick_right = 0;
  std::vector<std::string> legend_labels;
  int legend_row_height = 0;
};

struct FullLinePlotLayout {
  LinePlotLayout pub;
  std::string title;
  Font title_font = kFigureTitleFont;
  int title_baseline = 0;
  std::vector<PanelExtras> extras;
};

// Checks the plot (the messages of LayoutLinePlot).
Status ValidateLinePlot(const LinePlot& plot);
// The layout of a valid plot; InvalidArgument when a panel is too small for
// its texts.
Result<FullLinePlotLayout> ComputeLinePlotLayout(const LinePlot& plot, const TextMeter& meter);

bool PointUsable(const PlotSeries& s, size_t k);
inline bool HasLine(PlotSeries::Style s) { return s != PlotSeries::Style::kMarkers; }
inline bool HasMarkers(PlotSeries::Style s) {
  return s == PlotSeries::Style::kMarkers || s == PlotSeries::Style::kLineMarkers;
}
// Runs of consecutive usable points (NaN breaks a run), in pixels.
std::vector<std::vector<Point>> PixelRuns(const PlotSeries& s, const LinePlotPanelLayout& L);

}  // namespace opl::plot_internal
