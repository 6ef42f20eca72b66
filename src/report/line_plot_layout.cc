#include "line_plot_layout.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "opl/core/format.h"

namespace opl {

double LinePlotPanelLayout::PixelX(double x) const {
  const double t = log_x ? std::log10(x) : x;
  const double t0 = log_x ? std::log10(x_min) : x_min;
  const double t1 = log_x ? std::log10(x_max) : x_max;
  return plot_area.x + (t - t0) / (t1 - t0) * (plot_area.width - 1);
}

double LinePlotPanelLayout::PixelY(double y) const {
  const double t = log_y ? std::log10(y) : y;
  const double t0 = log_y ? std::log10(y_min) : y_min;
  const double t1 = log_y ? std::log10(y_max) : y_max;
  return plot_area.y + (t1 - t) / (t1 - t0) * (plot_area.height - 1);
}

namespace plot_internal {
namespace {

std::string Quoted(const std::string& s) { return s.empty() ? "" : " \"" + s + "\""; }

std::string PanelName(const PlotPanel& p, size_t i) {
  return "LinePlot.panels[" + std::to_string(i) + "]" +
         Quoted(p.title.empty() ? p.y_label : p.title);
}

std::string SeriesName(const PlotSeries& s, size_t j) {
  return "series[" + std::to_string(j) + "]" + Quoted(s.label);
}

}  // namespace

bool PointUsable(const PlotSeries& s, size_t k) {
  return !std::isnan(s.x[k]) && !std::isnan(s.y[k]);
}

Status ValidateLinePlot(const LinePlot& plot) {
  const int n = static_cast<int>(plot.panels.size());
  if (n < 1 || n > kLinePlotMaxPanels) {
    return Status::InvalidArgument("LinePlot.panels: must have 1 to " +
                                   std::to_string(kLinePlotMaxPanels) + " panels, got " +
                                   std::to_string(n));
  }
  if (plot.panel_width_px < kLinePlotMinPanelWidth ||
      plot.panel_width_px > kLinePlotMaxPanelSize) {
    return Status::InvalidArgument("LinePlot.panel_width_px: must be in [" +
                                   std::to_string(kLinePlotMinPanelWidth) + ", " +
                                   std::to_string(kLinePlotMaxPanelSize) + "], got " +
                                   std::to_string(plot.panel_width_px));
  }
  if (plot.panel_height_px < kLinePlotMinPanelHeight ||
      plot.panel_height_px > kLinePlotMaxPanelSize) {
    return Status::InvalidArgument("LinePlot.panel_height_px: must be in [" +
                                   std::to_string(kLinePlotMinPanelHeight) + ", " +
                                   std::to_string(kLinePlotMaxPanelSize) + "], got " +
                                   std::to_string(plot.panel_height_px));
  }
  for (size_t i = 0; i < plot.panels.size(); ++i) {
    const PlotPanel& p = plot.panels[i];
    const std::string pname = PanelName(p, i);
    size_t usable = 0;
    for (size_t j = 0; j < p.series.size(); ++j) {
      const PlotSeries& s = p.series[j];
      const std::string sname = pname + ": " + SeriesName(s, j) + ": ";
      if (s.x.size() != s.y.size()) {
        return Status::InvalidArgument(sname + "x has " + std::to_string(s.x.size()) +
                                       " values but y has " + std::to_string(s.y.size()));
      }
      if (!s.y_err.empty() && s.y_err.size() != s.y.size()) {
        return Status::InvalidArgument(sname + "y_err has " + std::to_string(s.y_err.size()) +
                                       " values but y has " + std::to_string(s.y.size()));
      }
      for (size_t k = 0; k < s.x.size(); ++k) {
        const std::string idx = "[" + std::to_string(k) + "]";
        if (std::isinf(s.x[k])) {
          return Status::InvalidArgument(sname + "x" + idx + " is infinite (use NaN for a gap)");
        }
        if (std::isinf(s.y[k])) {
          return Status::InvalidArgument(sname + "y" + idx + " is infinite (use NaN for a gap)");
        }
        if (!s.y_err.empty() && !std::isnan(s.y_err[k]) &&
            !(std::isfinite(s.y_err[k]) && s.y_err[k] >= 0)) {
          return Status::InvalidArgument(sname + "y_err" + idx +
                                         " must be finite and >= 0 or NaN, got " +
                                         FormatNumber(s.y_err[k]));
        }
        if (p.log_x && !std::isnan(s.x[k]) && s.x[k] <= 0) {
          return Status::InvalidArgument(pname + ": log x axis needs x > 0: " +
                                         SeriesName(s, j) + " has x" + idx + " = " +
                                         FormatNumber(s.x[k]));
        }
        if (p.log_y && !std::isnan(s.y[k]) && s.y[k] <= 0) {
          return Status::InvalidArgument(pname + ": log y axis needs y > 0: " +
                                         SeriesName(s, j) + " has y" + idx + " = " +
                                         FormatNumber(s.y[k]));
        }
        if (PointUsable(s, k)) ++usable;
      }
    }
    if (!p.x_categories.empty() && p.log_x) {
      return Status::InvalidArgument(pname + ": x_categories need a linear x axis (log_x is set)");
    }
    for (size_t c = 0; c < p.x_categories.size(); ++c) {
      const PlotCategory& cat = p.x_categories[c];
      const std::string cname = pname + ": x_categories[" + std::to_string(c) + "]" + Quoted(cat.label);
      if (!std::isfinite(cat.x) || (c > 0 && !(cat.x > p.x_categories[c - 1].x))) {
        return Status::InvalidArgument(cname + ": x = " + FormatNumber(cat.x) +
                                       " must be finite and greater than the one before");
      }
      if (cat.label.empty()) return Status::InvalidArgument(cname + ": the label must not be empty");
    }
    if (usable == 0) {
      return Status::InvalidArgument(pname + ": no finite points to plot" +
                                     (p.series.empty() ? " (no series)" : ""));
    }
  }
  return Status::Ok();
}

// Runs of consecutive usable points (NaN breaks a run), as pixel positions.
std::vector<std::vector<Point>> PixelRuns(const PlotSeries& s, const LinePlotPanelLayout& L) {
  std::vector<std::vector<Point>> runs(1);
  for (size_t k = 0; k < s.x.size(); ++k) {
    if (!PointUsable(s, k)) {
      if (!runs.back().empty()) runs.emplace_back();
      continue;
    }
    runs.back().push_back(Point{L.PixelX(s.x[k]), L.PixelY(s.y[k])});
  }
  if (runs.back().empty()) runs.pop_back();
  return runs;
}

namespace {

constexpr int kPad = 10;  // panel edge -> outermost text

// Pixels from a text size: rounded up.
int Up(double px) { return static_cast<int>(std::ceil(px - 1e-9)); }

// Axis range: the data range, widened when it is a single value, plus 5 % of
// the span on each side (in log10 for log axes).
std::pair<double, double> AxisRange(double lo, double hi, bool log) {
  if (log) {
    double a = std::log10(lo), b = std::log10(hi);
    if (!(b - a > 1e-12)) {
      a -= std::log10(2.0);
      b += std::log10(2.0);
    }
    const double pad = 0.05 * (b - a);
    return {std::pow(10.0, a - pad), std::pow(10.0, b + pad)};
  }
  if (!(hi - lo > 1e-12 * std::max(std::fabs(lo), std::fabs(hi)))) {
    const double d = lo == 0 ? 1.0 : 0.1 * std::fabs(lo);
    const double mid = 0.5 * (lo + hi);
    lo = mid - d;
    hi = mid + d;
  }
  const double pad = 0.05 * (hi - lo);
  return {lo - pad, hi + pad};
}

struct AxisTicks {
  std::vector<double> major, minor;
  std::vector<std::string> labels;
};

AxisTicks MakeTicks(double lo, double hi, bool log, int max_ticks) {
  AxisTicks t;
  double step = 0;
  if (log) {
    LogTicks lt = NiceLogTicks(lo, hi, max_ticks);
    t.major = std::move(lt.major);
    t.minor = std::move(lt.minor);
  } else {
    t.major = NiceTicks(lo, hi, max_ticks);
    if (t.major.size() >= 2) step = t.major[1] - t.major[0];
    else step = std::fabs(t.major.empty() ? 1.0 : t.major[0]);
    // Step from the tick values is m * 10^e up to rounding; snap it.
    if (step > 0) {
      const double e = std::floor(std::log10(step) + 1e-9);
      step = std::round(step / std::pow(10.0, e)) * std::pow(10.0, e);
    }
  }
  for (double v : t.major) t.labels.push_back(FormatTickLabel(v, log ? 0.0 : step));
  return t;
}

// A categorical axis: the categories' positions, each name cut to the space
// between it and its neighbours (10 px apart), not shrunk.
AxisTicks CategoryTicks(const std::vector<PlotCategory>& categories, const LinePlotPanelLayout& L,
                        const TextMeter& meter) {
  AxisTicks t;
  for (size_t c = 0; c < categories.size(); ++c) {
    double room = L.plot_area.width;
    if (c > 0) room = std::min(room, L.PixelX(categories[c].x) - L.PixelX(categories[c - 1].x));
    if (c + 1 < categories.size()) {
      room = std::min(room, L.PixelX(categories[c + 1].x) - L.PixelX(categories[c].x));
    }
    t.major.push_back(categories[c].x);
    t.labels.push_back(meter.Fit(categories[c].label, kTickFont, room - 10, kTickFont.size_px).first);
  }
  return t;
}

// How much of the data the rectangle covers: markers count 10, line samples
// (every 3 px along segments) 1.
double Coverage(const LinePlot& plot, size_t panel, const LinePlotPanelLayout& L,
                const PixelRect& r) {
  const PixelRect box{r.x - 4, r.y - 4, r.width + 8, r.height + 8};
  const auto inside = [&](const Point& p) {
    return p.x >= box.x && p.x < box.x + box.width && p.y >= box.y && p.y < box.y + box.height;
  };
  double score = 0;
  for (const PlotSeries& s : plot.panels[panel].series) {
    for (const std::vector<Point>& run : PixelRuns(s, L)) {
      for (size_t i = 0; i < run.size(); ++i) {
        if (inside(run[i])) score += 10;
        if (i + 1 < run.size() && HasLine(s.style)) {
          const Point d{run[i + 1].x - run[i].x, run[i + 1].y - run[i].y};
          const int steps = std::max(1, static_cast<int>(std::hypot(d.x, d.y) / 3));
          for (int t = 1; t < steps; ++t) {
            const double f = static_cast<double>(t) / steps;
            if (inside(Point{run[i].x + d.x * f, run[i].y + d.y * f})) score += 1;
          }
        }
      }
    }
  }
  return score;
}

}  // namespace

Result<FullLinePlotLayout> ComputeLinePlotLayout(const LinePlot& plot, const TextMeter& meter) {
  FullLinePlotLayout F;
  const int n = static_cast<int>(plot.panels.size());
  const int W = plot.panel_width_px;
  const int H = plot.panel_height_px;
  F.pub.image_width = n * W;

  // Figure title row.
  int title_row = 0;
  if (!plot.title.empty()) {
    std::tie(F.title, F.title_font) =
        meter.Fit(plot.title, kFigureTitleFont, F.pub.image_width - 2 * kPad, kMinTextSize);
    const TextBox tb = meter.Measure(F.title, F.title_font);
    F.title_baseline = 14 + Up(tb.height);
    title_row = F.title_baseline + Up(tb.baseline) + 4;
  }
  F.pub.image_height = title_row + H;

  const TextBox digit = meter.Measure("0", kTickFont);
  const int digit_height = Up(digit.height), digit_depth = Up(digit.baseline);
  for (int i = 0; i < n; ++i) {
    const PlotPanel& p = plot.panels[static_cast<size_t>(i)];
    const std::string pname = PanelName(p, static_cast<size_t>(i));
    LinePlotPanelLayout L;
    PanelExtras X;
    L.panel = PixelRect{i * W, title_row, W, H};
    L.log_x = p.log_x;
    L.log_y = p.log_y;

    // Data ranges (error bars included; on a log y axis only positive ends).
    double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
    double y_lo = x_lo, y_hi = -x_lo;
    for (const PlotSeries& s : p.series) {
      for (size_t k = 0; k < s.x.size(); ++k) {
        if (!PointUsable(s, k)) continue;
        x_lo = std::min(x_lo, s.x[k]);
        x_hi = std::max(x_hi, s.x[k]);
        y_lo = std::min(y_lo, s.y[k]);
        y_hi = std::max(y_hi, s.y[k]);
        if (!s.y_err.empty() && std::isfinite(s.y_err[k])) {
          y_hi = std::max(y_hi, s.y[k] + s.y_err[k]);
          const double low = s.y[k] - s.y_err[k];
          if (!p.log_y || low > 0) y_lo = std::min(y_lo, low);
        }
      }
    }
    if (p.x_categories.empty()) {
      std::tie(L.x_min, L.x_max) = AxisRange(x_lo, x_hi, p.log_x);
    } else {
      // The categories with half their smallest spacing on each side.
      double half = 0.5;
      for (size_t c = 1; c < p.x_categories.size(); ++c) {
        const double spacing = p.x_categories[c].x - p.x_categories[c - 1].x;
        half = c == 1 ? 0.5 * spacing : std::min(half, 0.5 * spacing);
      }
      L.x_min = std::min(x_lo, p.x_categories.front().x - half);
      L.x_max = std::max(x_hi, p.x_categories.back().x + half);
    }
    std::tie(L.y_min, L.y_max) = AxisRange(y_lo, y_hi, p.log_y);

    // Vertical layout.
    int top = L.panel.y + kPad;
    if (!p.title.empty()) {
      std::tie(X.title, X.title_font) =
          meter.Fit(p.title, kPanelTitleFont, W - 2 * kPad, kMinTextSize);
      const TextBox tb = meter.Measure(X.title, X.title_font);
      X.title_baseline = top + Up(tb.height);
      top = X.title_baseline + Up(tb.baseline) + 10;
    } else {
      top += 4;
    }
    const TextBox xl_box = meter.Measure("0", kAxisLabelFont);
    int bottom = L.panel.y + H - kPad;
    if (!p.x_label.empty()) {
      X.x_label_baseline = bottom - Up(xl_box.baseline);
      bottom = X.x_label_baseline - Up(xl_box.height) - 8;
    }
    X.x_tick_baseline = bottom - digit_depth;
    bottom = X.x_tick_baseline - digit_height - 5 - kTickLength;  // frame row
    L.plot_area.y = top + 1;
    L.plot_area.height = bottom - L.plot_area.y;
    if (L.plot_area.height < 60) {
      return Status::InvalidArgument(pname + ": panel_height_px " + std::to_string(H) +
                                     " leaves only " + std::to_string(L.plot_area.height) +
                                     " px for the plot; make it larger");
    }

    // Y ticks: as many as fit with a line of space between labels.
    AxisTicks yt;
    for (int max_ticks = std::max(2, L.plot_area.height / 40); max_ticks >= 2; --max_ticks) {
      yt = MakeTicks(L.y_min, L.y_max, p.log_y, max_ticks);
      bool ok = true;
      for (size_t k = 1; k < yt.major.size() && ok; ++k) {
        const double gap = std::fabs(L.PixelY(yt.major[k]) - L.PixelY(yt.major[k - 1]));
        ok = gap >= digit_height + digit_depth + 8;
      }
      if (ok) break;
    }
    L.y_ticks = yt.major;
    L.y_tick_labels = yt.labels;
    L.y_minor_ticks = yt.minor;
    double y_label_width = 0;
    for (const std::string& s : L.y_tick_labels) {
      y_label_width = std::max(y_label_width, meter.Measure(s, kTickFont).width);
    }

    // Horizontal layout: [pad][y label][8][tick labels][4][tick][frame] plot [right margin].
    int left = L.panel.x + kPad;
    if (!p.y_label.empty()) {
      std::tie(X.y_label, X.y_label_font) =
          meter.Fit(p.y_label, kAxisLabelFont, L.plot_area.height, kMinTextSize);
      const TextBox yb = meter.Measure(X.y_label, X.y_label_font);
      X.y_label_left = left;
      left += Up(yb.height) + Up(yb.baseline) + 10;
    }
    X.y_tick_right = left + Up(y_label_width);
    L.plot_area.x = X.y_tick_right + 4 + kTickLength + 1;
    int right_margin = 24;
    AxisTicks xt;
    for (int attempt = 0; attempt < 2; ++attempt) {
      L.plot_area.width = L.panel.x + W - right_margin - L.plot_area.x;
      if (L.plot_area.width < 80) {
        return Status::InvalidArgument(pname + ": panel_width_px " + std::to_string(W) +
                                       " leaves only " + std::to_string(L.plot_area.width) +
                                       " px for the plot; make it larger");
      }
      if (!p.x_categories.empty()) xt = CategoryTicks(p.x_categories, L, meter);
      for (int max_ticks = std::max(2, L.plot_area.width / 60);
           p.x_categories.empty() && max_ticks >= 2; --max_ticks) {
        xt = MakeTicks(L.x_min, L.x_max, p.log_x, max_ticks);
        bool ok = true;
        for (size_t k = 1; k < xt.major.size() && ok; ++k) {
          const double gap = L.PixelX(xt.major[k]) - L.PixelX(xt.major[k - 1]);
          const double need = 0.5 * (meter.Measure(xt.labels[k], kTickFont).width +
                                     meter.Measure(xt.labels[k - 1], kTickFont).width) +
                              10;
          ok = gap >= need;
        }
        if (ok) break;
      }
      // The last label must not run off the panel.
      int overhang = 0;
      if (!xt.major.empty()) {
        const double end = L.PixelX(xt.major.back()) +
                           0.5 * meter.Measure(xt.labels.back(), kTickFont).width;
        overhang = static_cast<int>(std::ceil(end)) - (L.panel.x + W - 6);
      }
      if (overhang <= 0) break;
      right_margin += overhang;
    }
    L.x_ticks = xt.major;
    L.x_tick_labels = xt.labels;
    L.x_minor_ticks = xt.minor;
    if (!p.x_label.empty()) {
      std::tie(X.x_label, X.x_label_font) =
          meter.Fit(p.x_label, kAxisLabelFont, std::min(L.plot_area.width + 40, W - 2 * kPad),
                    kMinTextSize);
    }

    // Legend: rows for the labelled series, in the corner covering least data.
    std::vector<size_t> labelled;
    for (size_t j = 0; j < p.series.size(); ++j) {
      if (!p.series[j].label.empty()) labelled.push_back(j);
    }
    if (!labelled.empty()) {
      const TextBox lb = meter.Measure("Ag", kLegendFont);
      X.legend_row_height = std::max(Up(lb.height) + Up(lb.baseline), 12) + 8;
      const int max_text = std::max(40, L.plot_area.width * 3 / 5 - kSwatchWidth - 26);
      double text_width = 0;
      for (size_t j : labelled) {
        // One font for every row: cut, do not shrink.
        const std::string t =
            meter.Fit(p.series[j].label, kLegendFont, max_text, kLegendFont.size_px).first;
        X.legend_labels.push_back(t);
        text_width = std::max(text_width, meter.Measure(t, kLegendFont).width);
      }
      const int lw = 8 + kSwatchWidth + 8 + Up(text_width) + 10;
      const int lh = 6 + static_cast<int>(labelled.size()) * X.legend_row_height + 6;
      const PixelRect& a = L.plot_area;
      const std::array<PixelRect, 4> corners = {
          PixelRect{a.x + kLegendInset, a.y + kLegendInset, lw, lh},
          PixelRect{a.x + a.width - kLegendInset - lw, a.y + kLegendInset, lw, lh},
          PixelRect{a.x + a.width - kLegendInset - lw, a.y + a.height - kLegendInset - lh, lw,
                   lh},
          PixelRect{a.x + kLegendInset, a.y + a.height - kLegendInset - lh, lw, lh},
      };
      size_t best = 0;
      double best_score = std::numeric_limits<double>::infinity();
      for (size_t c = 0; c < corners.size(); ++c) {
        const double score = Coverage(plot, static_cast<size_t>(i), L, corners[c]);
        if (score < best_score) {
          best_score = score;
          best = c;
        }
      }
      const PixelRect r = corners[best];
      L.legend = r;
      for (size_t row = 0; row < labelled.size(); ++row) {
        L.legend_series.push_back(static_cast<int>(labelled[row]));
        L.legend_swatches.push_back(PixelRect{r.x + 8,
                                              r.y + 6 + static_cast<int>(row) * X.legend_row_height,
                                              kSwatchWidth, X.legend_row_height});
      }
    }
    F.pub.panels.push_back(std::move(L));
    F.extras.push_back(std::move(X));
  }
  return F;
}

}  // namespace plot_internal

Result<LinePlotLayout> LayoutLinePlot(const LinePlot& plot) {
  OPL_RETURN_IF_ERROR(plot_internal::ValidateLinePlot(plot));
  try {
    const plot_internal::TextMeter meter;
    Result<plot_internal::FullLinePlotLayout> layout =
        plot_internal::ComputeLinePlotLayout(plot, meter);
    if (!layout.ok()) return layout.status();
    return std::move(layout->pub);
  } catch (const std::exception& e) {  // std::bad_alloc
    return Status::IoError(std::string("line plot: cannot lay out the figure: ") + e.what());
  }
}

}  // namespace opl
