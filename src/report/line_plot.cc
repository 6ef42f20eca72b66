// Drawing a laid-out line plot (line_plot_layout.h) with cairo, and the
// public render and write functions.
#include "opl/report/line_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "line_plot_layout.h"
#include "opl/io/atomic_file.h"
#include "plot_canvas.h"

namespace opl {
namespace {

using plot_internal::Align;
using plot_internal::FullLinePlotLayout;
using plot_internal::PanelExtras;
using plot_internal::PlotCanvas;
using plot_internal::Point;
using plot_internal::Rgb;
using plot_internal::Rgb8;

const Rgb kWhite = Rgb8(255, 255, 255);
const Rgb kBlack = Rgb8(0, 0, 0);
const Rgb kTextGrey = Rgb8(40, 40, 40);
const Rgb kGridMajor = Rgb8(221, 221, 221);
const Rgb kGridMinor = Rgb8(240, 240, 240);
const Rgb kLegendBorder = Rgb8(160, 160, 160);

// Okabe-Ito, without yellow (too light on white).
const std::array<Rgb, 7> kPalette = {
    Rgb8(0, 114, 178),    // blue
    Rgb8(213, 94, 0),     // vermillion
    Rgb8(0, 158, 115),    // bluish green
    Rgb8(204, 121, 167),  // reddish purple
    Rgb8(230, 159, 0),    // orange
    Rgb8(86, 180, 233),   // sky blue
    Rgb8(0, 0, 0),        // black
};
enum class Marker { kCircle, kSquare, kTriangleUp, kDiamond, kTriangleDown, kPlus, kCross };
constexpr int kMarkerCount = 7;
constexpr double kMarkerRadius = 4.5;
constexpr double kLineWidth = 2;
constexpr double kDash[] = {9, 6};  // px on, px off; the pattern runs on across vertices

// Keeps far-off points (a log axis' 1e-300) within what cairo's fixed-point
// coordinates hold; such points are clipped away anyway.
double Clamp(double v) { return std::clamp(v, -1e5, 1e5); }

void DrawMarker(cairo_t* cr, Point c, Marker m, Rgb colour) {
  const double r = kMarkerRadius;
  cairo_set_source_rgb(cr, colour.r, colour.g, colour.b);
  const auto poly = [&](std::initializer_list<Point> pts) {
    bool first = true;
    for (const Point& p : pts) {
      if (first) cairo_move_to(cr, c.x + p.x, c.y + p.y);
      else cairo_line_to(cr, c.x + p.x, c.y + p.y);
      first = false;
    }
    cairo_close_path(cr);
    cairo_fill(cr);
  };
  const auto line = [&](double x0, double y0, double x1, double y1) {
    cairo_move_to(cr, c.x + x0, c.y + y0);
    cairo_line_to(cr, c.x + x1, c.y + y1);
  };
  switch (m) {
    case Marker::kCircle:
      cairo_new_sub_path(cr);
      cairo_arc(cr, c.x, c.y, r, 0, 2 * M_PI);
      cairo_fill(cr);
      break;
    case Marker::kSquare: {
      const double s = r * 0.85;
      poly({{-s, -s}, {s, -s}, {s, s}, {-s, s}});
      break;
    }
    case Marker::kTriangleUp:
      poly({{0, -r * 1.15}, {r * 1.05, r * 0.75}, {-r * 1.05, r * 0.75}});
      break;
    case Marker::kDiamond:
      poly({{0, -r * 1.2}, {r * 1.0, 0}, {0, r * 1.2}, {-r * 1.0, 0}});
      break;
    case Marker::kTriangleDown:
      poly({{0, r * 1.15}, {r * 1.05, -r * 0.75}, {-r * 1.05, -r * 0.75}});
      break;
    case Marker::kPlus:
      cairo_set_line_width(cr, 2);
      line(-r, 0, r, 0);
      line(0, -r, 0, r);
      cairo_stroke(cr);
      break;
    case Marker::kCross: {
      const double s = r * 0.8;
      cairo_set_line_width(cr, 2);
      line(-s, -s, s, s);
      line(-s, s, s, -s);
      cairo_stroke(cr);
      break;
    }
  }
}

// A polyline, solid or dashed; a single point is a small dot.
void DrawPolyline(cairo_t* cr, const std::vector<Point>& pts, bool dashed, Rgb colour) {
  if (pts.empty()) return;
  cairo_set_source_rgb(cr, colour.r, colour.g, colour.b);
  if (pts.size() == 1) {
    cairo_new_sub_path(cr);
    cairo_arc(cr, Clamp(pts[0].x), Clamp(pts[0].y), 1.5, 0, 2 * M_PI);
    cairo_fill(cr);
    return;
  }
  cairo_set_line_width(cr, kLineWidth);
  if (dashed) cairo_set_dash(cr, kDash, 2, 0);
  cairo_move_to(cr, Clamp(pts[0].x), Clamp(pts[0].y));
  for (size_t i = 1; i < pts.size(); ++i) cairo_line_to(cr, Clamp(pts[i].x), Clamp(pts[i].y));
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
}

// A vertical error bar from y_lo to y_hi at x, with caps (the low cap only
// when `low_cap`).
void DrawErrorBar(cairo_t* cr, double x, double y_lo, double y_hi, bool low_cap, Rgb colour) {
  cairo_set_source_rgb(cr, colour.r, colour.g, colour.b);
  cairo_set_line_width(cr, 1);
  cairo_move_to(cr, x, Clamp(y_lo));
  cairo_line_to(cr, x, Clamp(y_hi));
  cairo_move_to(cr, x - 3.5, Clamp(y_hi));
  cairo_line_to(cr, x + 3.5, Clamp(y_hi));
  if (low_cap) {
    cairo_move_to(cr, x - 3.5, Clamp(y_lo));
    cairo_line_to(cr, x + 3.5, Clamp(y_lo));
  }
  cairo_stroke(cr);
}

int Round(double v) { return static_cast<int>(std::lround(Clamp(v))); }

void DrawLegend(const PlotCanvas& canvas, const PlotPanel& p, const LinePlotPanelLayout& L,
                const PanelExtras& X, double cap_height) {
  cairo_t* cr = canvas.cr();
  const PixelRect& g = L.legend;
  canvas.FillPixels(g, kWhite);
  canvas.FrameAround(PixelRect{g.x + 1, g.y + 1, g.width - 2, g.height - 2}, kLegendBorder);
  for (size_t row = 0; row < L.legend_series.size(); ++row) {
    const size_t j = static_cast<size_t>(L.legend_series[row]);
    const PlotSeries& s = p.series[j];
    const Rgb colour = kPalette[j % kPalette.size()];
    const PixelRect& sw = L.legend_swatches[row];
    const double cx = sw.x + sw.width / 2;
    const double cy = sw.y + sw.height / 2;
    if (plot_internal::HasLine(s.style)) {
      DrawPolyline(cr, {{sw.x + 1.0, cy}, {sw.x + sw.width - 1.0, cy}},
                   s.style == PlotSeries::Style::kDashed, colour);
    }
    if (!s.y_err.empty() && !plot_internal::HasLine(s.style)) {  // a small bar behind the marker
      DrawErrorBar(cr, cx, cy + 7, cy - 7, true, colour);
    }
    if (plot_internal::HasMarkers(s.style)) {
      DrawMarker(cr, {cx, cy}, static_cast<Marker>(j % kMarkerCount), colour);
    }
    canvas.Text(X.legend_labels[row], sw.x + sw.width + 8, cy + 0.5 * cap_height,
                plot_internal::kLegendFont, kBlack);
  }
}

void DrawPanel(const PlotCanvas& canvas, const PlotPanel& p, const LinePlotPanelLayout& L,
               const PanelExtras& X, const plot_internal::TextMeter& meter) {
  const double tick_digit_height = meter.Measure("0", plot_internal::kTickFont).height;
  cairo_t* cr = canvas.cr();
  const PixelRect& a = L.plot_area;
  const int right = a.x + a.width;    // first column right of the area (frame)
  const int bottom = a.y + a.height;  // first row below the area (frame)
  const double plot_centre_x = a.x + 0.5 * (a.width - 1);

  if (!X.title.empty()) {
    canvas.Text(X.title, plot_centre_x, X.title_baseline, X.title_font, kBlack, Align::kCentre);
  }

  // Grid lines: minor (log axes) first, then major.
  const auto vline = [&](double x, Rgb c) {
    const int px = Round(L.PixelX(x));
    if (px >= a.x && px < right) canvas.PixelLine(px, a.y, px, bottom - 1, c);
  };
  const auto hline = [&](double y, Rgb c) {
    const int py = Round(L.PixelY(y));
    if (py >= a.y && py < bottom) canvas.PixelLine(a.x, py, right - 1, py, c);
  };
  for (double x : L.x_minor_ticks) vline(x, kGridMinor);
  for (double y : L.y_minor_ticks) hline(y, kGridMinor);
  for (double x : L.x_ticks) vline(x, kGridMajor);
  for (double y : L.y_ticks) hline(y, kGridMajor);

  // Data, clipped to the plot area: error bars and lines, then markers on top.
  canvas.ClipTo(a);
  for (size_t j = 0; j < p.series.size(); ++j) {
    const PlotSeries& s = p.series[j];
    const Rgb colour = kPalette[j % kPalette.size()];
    if (!s.y_err.empty()) {
      for (size_t k = 0; k < s.x.size(); ++k) {
        if (!plot_internal::PointUsable(s, k) || !std::isfinite(s.y_err[k]) || s.y_err[k] <= 0) {
          continue;
        }
        const double low_value = s.y[k] - s.y_err[k];
        const bool low_on_axis = !L.log_y || low_value > 0;
        const double lo = low_on_axis ? L.PixelY(low_value) : bottom + 10.0;
        DrawErrorBar(cr, L.PixelX(s.x[k]), lo, L.PixelY(s.y[k] + s.y_err[k]), low_on_axis, colour);
      }
    }
    if (plot_internal::HasLine(s.style)) {
      for (const std::vector<Point>& run : plot_internal::PixelRuns(s, L)) {
        DrawPolyline(cr, run, s.style == PlotSeries::Style::kDashed, colour);
      }
    }
  }
  for (size_t j = 0; j < p.series.size(); ++j) {
    const PlotSeries& s = p.series[j];
    if (!plot_internal::HasMarkers(s.style)) continue;
    const Marker m = static_cast<Marker>(j % kMarkerCount);
    for (const std::vector<Point>& run : plot_internal::PixelRuns(s, L)) {
      for (const Point& q : run) {
        DrawMarker(cr, {Clamp(q.x), Clamp(q.y)}, m, kPalette[j % kPalette.size()]);
      }
    }
  }
  // The legend over the data, clipped to the plot area too.
  if (L.legend.width > 0) {
    DrawLegend(canvas, p, L, X, meter.Measure("H", plot_internal::kLegendFont).height);
  }
  canvas.Unclip();

  // Frame, ticks and tick labels.
  canvas.FrameAround(a, kBlack);
  for (size_t k = 0; k < L.x_ticks.size(); ++k) {
    const int px = Round(L.PixelX(L.x_ticks[k]));
    canvas.PixelLine(px, bottom + 1, px, bottom + plot_internal::kTickLength, kBlack);
    canvas.Text(L.x_tick_labels[k], px, X.x_tick_baseline, plot_internal::kTickFont, kTextGrey,
                Align::kCentre);
  }
  for (double x : L.x_minor_ticks) {
    const int px = Round(L.PixelX(x));
    if (px < a.x || px >= right) continue;
    canvas.PixelLine(px, bottom + 1, px, bottom + plot_internal::kMinorTickLength, kBlack);
  }
  for (size_t k = 0; k < L.y_ticks.size(); ++k) {
    const int py = Round(L.PixelY(L.y_ticks[k]));
    canvas.PixelLine(a.x - 2, py, a.x - 1 - plot_internal::kTickLength, py, kBlack);
    canvas.Text(L.y_tick_labels[k], X.y_tick_right, py + 0.5 * tick_digit_height,
                plot_internal::kTickFont, kTextGrey, Align::kRight);
  }
  for (double y : L.y_minor_ticks) {
    const int py = Round(L.PixelY(y));
    if (py < a.y || py >= bottom) continue;
    canvas.PixelLine(a.x - 2, py, a.x - 1 - plot_internal::kMinorTickLength, py, kBlack);
  }

  // Axis labels.
  canvas.Text(X.x_label, plot_centre_x, X.x_label_baseline, X.x_label_font, kBlack,
              Align::kCentre);
  canvas.TextUp(X.y_label, X.y_label_left, a.y + 0.5 * (a.height - 1), X.y_label_font, kBlack);
}

Result<std::vector<unsigned char>> Render(const LinePlot& plot, PlotFormat format,
                                          const PlotMetadata& metadata) {
  OPL_RETURN_IF_ERROR(plot_internal::ValidateLinePlot(plot));
  const plot_internal::TextMeter meter;
  Result<FullLinePlotLayout> layout = plot_internal::ComputeLinePlotLayout(plot, meter);
  if (!layout.ok()) return layout.status();
  const FullLinePlotLayout& F = *layout;
  Result<std::unique_ptr<PlotCanvas>> canvas =
      PlotCanvas::Create(format, F.pub.image_width, F.pub.image_height, plot.title, metadata,
                         "line plot");
  if (!canvas.ok()) return canvas.status();
  const PlotCanvas& c = **canvas;
  c.Text(F.title, 0.5 * (F.pub.image_width - 1), F.title_baseline, F.title_font, kBlack,
         Align::kCentre);
  for (size_t i = 0; i < F.pub.panels.size(); ++i) {
    DrawPanel(c, plot.panels[i], F.pub.panels[i], F.extras[i], meter);
  }
  return (*canvas)->Finish();
}

}  // namespace

Result<std::vector<unsigned char>> RenderLinePlot(const LinePlot& plot, PlotFormat format,
                                                  const PlotMetadata& metadata) {
  try {
    return Render(plot, format, metadata);
  } catch (const std::exception& e) {  // std::bad_alloc
    return Status::IoError(std::string("line plot: cannot render the ") +
                           PlotFormatName(format) + ": " + e.what());
  }
}

Result<std::vector<unsigned char>> RenderLinePlotPng(const LinePlot& plot) {
  return RenderLinePlot(plot, PlotFormat::kPng);
}

Status WriteLinePlot(const LinePlot& plot, const std::string& path,
                     const PlotMetadata& metadata) {
  Result<PlotFormat> format = PlotFormatFromPath(path);
  if (!format.ok()) return format.status();
  Result<std::vector<unsigned char>> bytes = RenderLinePlot(plot, *format, metadata);
  if (!bytes.ok()) return bytes.status();
  return WriteFileAtomically(path, std::string(bytes->begin(), bytes->end()));
}

}  // namespace opl
