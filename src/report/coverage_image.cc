#include "opl/report/coverage_image.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "opl/core/format.h"
#include "plot_canvas.h"

namespace opl {
namespace {

using plot_internal::Align;
using plot_internal::Font;
using plot_internal::PlotCanvas;
using plot_internal::Rgb;
using plot_internal::Rgb8;
using plot_internal::TextBox;
using plot_internal::TextMeter;

const Rgb kBlack = Rgb8(0, 0, 0);
const Rgb kDarkGrey = Rgb8(60, 60, 60);
const Rgb kCovered = Rgb8(240, 240, 240);
const Rgb kEmpty = Rgb8(255, 205, 205);
const Rgb kGridLine = Rgb8(200, 200, 200);
const Rgb kOutline = Rgb8(40, 40, 40);

constexpr int kMargin = 24;
constexpr Font kTitleFont{16, true};
constexpr Font kCaptionFont{13, false};
constexpr Font kLegendFont{12, false};
constexpr double kMinTextSize = 9;
constexpr int kLegendGap = 24;       // sensor outline -> legend
constexpr int kLegendRow = 18;       // legend row height
constexpr int kLegendTextX = 16;     // legend dot column -> text
constexpr int kLegendMaxWidth = 300;
constexpr double kDotRadius = 2.5;

// Distinct colours: hue stepped by the golden angle (HSV, S = 220/255,
// V = 210/255).
Rgb ViewColour(size_t v) {
  const double hue = std::fmod(static_cast<double>(v) * 137.508, 360.0);
  const double value = 210.0 / 255.0, chroma = value * 220.0 / 255.0;
  const double h6 = hue / 60.0;
  const double x = chroma * (1.0 - std::fabs(std::fmod(h6, 2.0) - 1.0));
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h6)) {
    case 0: r = chroma, g = x; break;
    case 1: r = x, g = chroma; break;
    case 2: g = chroma, b = x; break;
    case 3: g = x, b = chroma; break;
    case 4: r = x, b = chroma; break;
    default: r = chroma, b = x; break;
  }
  const double m = value - chroma;
  return Rgb{r + m, g + m, b + m};
}

struct P2 {
  double x = 0, y = 0;
};

// The convex hull (Andrew's monotone chain), without repeated or collinear
// points; fewer than 3 points are returned as they are (deduplicated).
std::vector<P2> ConvexHull(std::vector<P2> pts) {
  std::sort(pts.begin(), pts.end(), [](const P2& a, const P2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  pts.erase(std::unique(pts.begin(), pts.end(), [](const P2& a, const P2& b) { return a.x == b.x && a.y == b.y; }),
            pts.end());
  if (pts.size() < 3) return pts;
  const auto cross = [](const P2& o, const P2& a, const P2& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  std::vector<P2> hull(2 * pts.size());
  size_t k = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  for (size_t i = pts.size() - 1, lower = k + 1; i > 0; --i) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], pts[i - 1]) <= 0) --k;
    hull[k++] = pts[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

std::string ShortName(std::string name) {
  if (const size_t slash = name.find_last_of('/'); slash != std::string::npos) name = name.substr(slash + 1);
  return name;
}

// Everything CoverageImageLayout holds plus what the renderer needs.
struct FullLayout {
  CoverageImageLayout pub;
  std::string title;
  Font title_font = kTitleFont;
  int title_baseline = 0;
  std::vector<std::string> caption;  // the lines under the title
  std::vector<Font> caption_fonts;
  std::vector<int> caption_baselines;
  std::vector<std::string> legend_texts;  // per row; the last may be "... and N more"
  std::vector<int> legend_views;          // the view of each row, -1 for "... and N more"
  std::vector<int> legend_baselines;
};

Status ValidateArguments(int width_px, int height_px, const SensorCoverage& coverage,
                         const CoverageImageOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (width_px < 1 || height_px < 1) {
    return Status::InvalidArgument("coverage picture: image size " + std::to_string(width_px) + " x " +
                                   std::to_string(height_px) + " must be positive");
  }
  if (coverage.cells_across < 1 || coverage.cells_across > 100 || coverage.cells_down < 1 ||
      coverage.cells_down > 100) {
    return Status::InvalidArgument("coverage picture: SensorCoverage grid " + std::to_string(coverage.cells_across) +
                                   " x " + std::to_string(coverage.cells_down) + ": must be 1 to 100 cells each way");
  }
  const size_t cells = static_cast<size_t>(coverage.cells_across * coverage.cells_down);
  if (coverage.corners_per_cell.size() != cells) {
    return Status::InvalidArgument("coverage picture: SensorCoverage.corners_per_cell has " +
                                   std::to_string(coverage.corners_per_cell.size()) + " entries, expected " +
                                   std::to_string(coverage.cells_across) + " x " +
                                   std::to_string(coverage.cells_down) + " = " + std::to_string(cells));
  }
  return Status::Ok();
}

FullLayout ComputeLayout(int width_px, int height_px, const std::vector<BoardView>& views,
                         const SensorCoverage& coverage, const CoverageImageOptions& options,
                         const TextMeter& meter) {
  FullLayout L;
  CoverageImageLayout& P = L.pub;
  P.cells_across = coverage.cells_across;
  P.cells_down = coverage.cells_down;
  const double scale = static_cast<double>(options.max_side_px) / std::max(width_px, height_px);
  P.sensor.width = std::max(1, static_cast<int>(std::lround(width_px * scale)));
  P.sensor.height = std::max(1, static_cast<int>(std::lround(height_px * scale)));

  // Legend texts at their natural width, capped.
  std::vector<std::string> names;
  double legend_text_width = 0;
  for (const BoardView& v : views) {
    names.push_back(ShortName(v.name) + " (" + std::to_string(v.pixels.size()) + ")");
    legend_text_width = std::max(legend_text_width, meter.Measure(names.back(), kLegendFont).width);
  }
  legend_text_width = std::max(legend_text_width, meter.Measure("... and 9999 more", kLegendFont).width);
  P.legend.width = std::min(kLegendMaxWidth, kLegendTextX + static_cast<int>(std::ceil(legend_text_width)));

  // The caption: title, fraction, key.
  L.title = (options.title.empty() ? std::string("Sensor coverage") : options.title) + ": " +
            std::to_string(views.size()) + " views, " + std::to_string(coverage.num_corners) + " corners, image " +
            std::to_string(width_px) + " x " + std::to_string(height_px) + " px";
  int covered = 0;
  for (int n : coverage.corners_per_cell) covered += n > 0 ? 1 : 0;
  L.caption = {"corners in " + std::to_string(covered) + " of the " + std::to_string(coverage.cells_across) + " x " +
                   std::to_string(coverage.cells_down) + " cells (" +
                   FormatPrintf("%.0f", 100.0 * coverage.fraction_covered) + "%)",
               "empty cells tinted red; dots: the corners, lines: each view's outline (convex hull)"};
  // The picture is as wide as the sensor and the legend, or as the caption
  // (up to 1200 px; longer lines shrink, then are cut).
  const int base_width = kMargin + 2 + P.sensor.width + 2 + kLegendGap + P.legend.width + kMargin;
  double caption_width = meter.Measure(L.title, kTitleFont).width;
  for (const std::string& line : L.caption) caption_width = std::max(caption_width, meter.Measure(line, kCaptionFont).width);
  P.image_width = std::max(base_width, std::min(1200, static_cast<int>(std::ceil(caption_width)) + 2 * kMargin));
  const double text_width = P.image_width - 2.0 * kMargin;
  std::tie(L.title, L.title_font) = meter.Fit(L.title, kTitleFont, text_width, kMinTextSize);
  const TextBox title_box = meter.Measure(L.title, L.title_font);
  L.title_baseline = kMargin + static_cast<int>(std::ceil(title_box.height));
  int y = L.title_baseline + static_cast<int>(std::ceil(title_box.baseline));
  for (std::string& line : L.caption) {
    Font font = kCaptionFont;
    std::tie(line, font) = meter.Fit(line, kCaptionFont, text_width, kMinTextSize);
    const TextBox box = meter.Measure(line, font);
    y += 8 + static_cast<int>(std::ceil(box.height));
    L.caption_fonts.push_back(font);
    L.caption_baselines.push_back(y);
    y += static_cast<int>(std::ceil(box.baseline));
  }

  P.sensor.x = kMargin + 2;
  P.sensor.y = y + 18 + 2;
  P.legend.x = P.sensor.x + P.sensor.width + 2 + kLegendGap;
  P.legend.y = P.sensor.y;
  const int max_rows = std::max(1, (P.sensor.height + kMargin) / kLegendRow);
  const double legend_cap = meter.Measure("H", kLegendFont).height;
  for (size_t v = 0; v < views.size(); ++v) {
    const int row = static_cast<int>(v);
    const int baseline = P.legend.y + row * kLegendRow + static_cast<int>(std::lround(0.5 * (kLegendRow + legend_cap))) - 1;
    if (row == max_rows - 1 && views.size() > static_cast<size_t>(max_rows)) {
      L.legend_texts.push_back("... and " + std::to_string(views.size() - v) + " more");
      L.legend_views.push_back(-1);
      L.legend_baselines.push_back(baseline);
      break;
    }
    L.legend_texts.push_back(
        meter.Fit(names[v], kLegendFont, P.legend.width - kLegendTextX, kLegendFont.size_px).first);
    L.legend_views.push_back(row);
    L.legend_baselines.push_back(baseline);
  }
  P.legend.height = static_cast<int>(L.legend_texts.size()) * kLegendRow;
  P.image_height = std::max(P.sensor.y + P.sensor.height + 2, P.legend.y + P.legend.height) + kMargin;
  return L;
}

void Draw(const PlotCanvas& c, int width_px, int height_px, const std::vector<BoardView>& views,
          const SensorCoverage& coverage, const FullLayout& L) {
  const CoverageImageLayout& P = L.pub;
  c.Text(L.title, kMargin, L.title_baseline, L.title_font, kBlack);
  for (size_t i = 0; i < L.caption.size(); ++i) {
    c.Text(L.caption[i], kMargin, L.caption_baselines[i], L.caption_fonts[i], kDarkGrey);
  }

  // The sensor: covered cells grey, empty ones red, the grid, the outline.
  c.FillPixels(P.sensor, kCovered);
  for (int r = 0; r < P.cells_down; ++r) {
    for (int col = 0; col < P.cells_across; ++col) {
      if (coverage.corners_per_cell[static_cast<size_t>(r * P.cells_across + col)] == 0) {
        c.FillPixels(P.Cell(r, col), kEmpty);
      }
    }
  }
  for (int col = 1; col < P.cells_across; ++col) {
    const int x = P.Cell(0, col).x;
    c.PixelLine(x, P.sensor.y, x, P.sensor.y + P.sensor.height - 1, kGridLine);
  }
  for (int r = 1; r < P.cells_down; ++r) {
    const int y = P.Cell(r, 0).y;
    c.PixelLine(P.sensor.x, y, P.sensor.x + P.sensor.width - 1, y, kGridLine);
  }
  c.FrameAround(P.sensor, kOutline);
  c.FrameAround(PixelRect{P.sensor.x - 1, P.sensor.y - 1, P.sensor.width + 2, P.sensor.height + 2}, kOutline);

  // The views: outline and corners, clipped to the sensor.
  const double sx = static_cast<double>(P.sensor.width) / width_px;
  const double sy = static_cast<double>(P.sensor.height) / height_px;
  cairo_t* cr = c.cr();
  c.ClipTo(P.sensor);
  for (size_t v = 0; v < views.size(); ++v) {
    std::vector<P2> pts;
    for (const Eigen::Vector2d& p : views[v].pixels) {
      pts.push_back(P2{P.sensor.x - 0.5 + (p.x() + 0.5) * sx, P.sensor.y - 0.5 + (p.y() + 0.5) * sy});
    }
    c.SetColour(ViewColour(v));
    const std::vector<P2> hull = ConvexHull(pts);
    if (hull.size() >= 3) {
      cairo_set_line_width(cr, 1);
      cairo_move_to(cr, hull[0].x, hull[0].y);
      for (size_t k = 1; k < hull.size(); ++k) cairo_line_to(cr, hull[k].x, hull[k].y);
      cairo_close_path(cr);
      cairo_stroke(cr);
    }
    for (const P2& q : pts) {
      cairo_new_sub_path(cr);
      cairo_arc(cr, q.x, q.y, kDotRadius, 0, 2 * M_PI);
    }
    cairo_fill(cr);
  }
  c.Unclip();

  // The legend.
  const double legend_cap = 0.5 * kLegendRow;
  for (size_t i = 0; i < L.legend_texts.size(); ++i) {
    const int row_top = P.legend.y + static_cast<int>(i) * kLegendRow;
    if (L.legend_views[i] >= 0) {
      c.SetColour(ViewColour(static_cast<size_t>(L.legend_views[i])));
      cairo_new_sub_path(cr);
      cairo_arc(cr, P.legend.x + 5, row_top + legend_cap - 1, 5, 0, 2 * M_PI);
      cairo_fill(cr);
    }
    c.Text(L.legend_texts[i], P.legend.x + kLegendTextX, L.legend_baselines[i], kLegendFont, kBlack);
  }
}

Result<std::vector<unsigned char>> Render(int width_px, int height_px, const std::vector<BoardView>& views,
                                          const SensorCoverage& coverage, PlotFormat format,
                                          const CoverageImageOptions& options, const PlotMetadata& metadata) {
  OPL_RETURN_IF_ERROR(ValidateArguments(width_px, height_px, coverage, options));
  const TextMeter meter;
  const FullLayout layout = ComputeLayout(width_px, height_px, views, coverage, options, meter);
  Result<std::unique_ptr<PlotCanvas>> canvas = PlotCanvas::Create(
      format, layout.pub.image_width, layout.pub.image_height, layout.title, metadata, "coverage picture");
  if (!canvas.ok()) return canvas.status();
  Draw(**canvas, width_px, height_px, views, coverage, layout);
  return (*canvas)->Finish();
}

}  // namespace

std::string SensorCoverage::Summary() const {
  const int cells = cells_across * cells_down;
  int covered = 0;
  for (int n : corners_per_cell) covered += n > 0 ? 1 : 0;
  std::string out = "corners in " + std::to_string(covered) + " of " + std::to_string(cells) + " cells (" +
                    FormatPrintf("%.0f", 100.0 * fraction_covered) + "%) of a " + std::to_string(cells_across) +
                    " x " + std::to_string(cells_down) + " grid over the image";
  // Which regions (thirds of the image) hold empty cells.
  const char* names[3][3] = {{"top-left", "top", "top-right"},
                             {"left", "centre", "right"},
                             {"bottom-left", "bottom", "bottom-right"}};
  bool empty_region[3][3] = {};
  for (int r = 0; r < cells_down; ++r) {
    for (int c = 0; c < cells_across; ++c) {
      if (corners_per_cell[static_cast<size_t>(r * cells_across + c)] > 0) continue;
      empty_region[std::min(2, 3 * r / cells_down)][std::min(2, 3 * c / cells_across)] = true;
    }
  }
  std::string empty;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (empty_region[i][j]) empty += std::string(empty.empty() ? "" : ", ") + names[i][j];
    }
  }
  if (!empty.empty()) out += "; empty cells: " + empty;
  return out;
}

Result<SensorCoverage> ComputeSensorCoverage(int width_px, int height_px, const std::vector<BoardView>& views,
                                             int cells_across) {
  if (width_px < 1 || height_px < 1) {
    return Status::InvalidArgument("ComputeSensorCoverage: image size " + std::to_string(width_px) + " x " +
                                   std::to_string(height_px) + " must be positive");
  }
  if (cells_across < 1 || cells_across > 100) {
    return Status::InvalidArgument("ComputeSensorCoverage: cells_across = " + std::to_string(cells_across) +
                                   ": must be in [1, 100]");
  }
  SensorCoverage cov;
  cov.cells_across = cells_across;
  cov.cells_down = std::max(1, static_cast<int>(std::lround(cells_across * static_cast<double>(height_px) / width_px)));
  cov.corners_per_cell.assign(static_cast<size_t>(cov.cells_across * cov.cells_down), 0);
  for (const BoardView& view : views) {
    for (const Eigen::Vector2d& p : view.pixels) {
      // Pixel (u, v) covers [u - 0.5, u + 0.5): the image spans [-0.5, W - 0.5).
      const double x = (p.x() + 0.5) / width_px, y = (p.y() + 0.5) / height_px;
      if (!(x >= 0.0 && x < 1.0 && y >= 0.0 && y < 1.0)) continue;
      const int c = std::min(cov.cells_across - 1, static_cast<int>(x * cov.cells_across));
      const int r = std::min(cov.cells_down - 1, static_cast<int>(y * cov.cells_down));
      ++cov.corners_per_cell[static_cast<size_t>(r * cov.cells_across + c)];
      ++cov.num_corners;
    }
  }
  int covered = 0;
  for (int n : cov.corners_per_cell) covered += n > 0 ? 1 : 0;
  cov.fraction_covered = static_cast<double>(covered) / static_cast<double>(cov.corners_per_cell.size());
  return cov;
}

Status CoverageImageOptions::Validate() const {
  if (max_side_px < 200 || max_side_px > 4000) {
    return Status::InvalidArgument("CoverageImageOptions.max_side_px = " + std::to_string(max_side_px) +
                                   ": must be in [200, 4000]");
  }
  return Status::Ok();
}

PixelRect CoverageImageLayout::Cell(int row, int col) const {
  if (row < 0 || row >= cells_down || col < 0 || col >= cells_across) return PixelRect{};
  const int x0 = sensor.x + sensor.width * col / cells_across;
  const int x1 = sensor.x + sensor.width * (col + 1) / cells_across;
  const int y0 = sensor.y + sensor.height * row / cells_down;
  const int y1 = sensor.y + sensor.height * (row + 1) / cells_down;
  return PixelRect{x0, y0, x1 - x0, y1 - y0};
}

Result<CoverageImageLayout> LayoutCoverageImage(int width_px, int height_px, const std::vector<BoardView>& views,
                                                const SensorCoverage& coverage,
                                                const CoverageImageOptions& options) {
  OPL_RETURN_IF_ERROR(ValidateArguments(width_px, height_px, coverage, options));
  try {
    const TextMeter meter;
    return ComputeLayout(width_px, height_px, views, coverage, options, meter).pub;
  } catch (const std::exception& e) {  // std::bad_alloc
    return Status::IoError(std::string("coverage picture: cannot lay out the figure: ") + e.what());
  }
}

Result<std::vector<unsigned char>> RenderCoverageImage(int width_px, int height_px,
                                                       const std::vector<BoardView>& views,
                                                       const SensorCoverage& coverage, PlotFormat format,
                                                       const CoverageImageOptions& options,
                                                       const PlotMetadata& metadata) {
  try {
    return Render(width_px, height_px, views, coverage, format, options, metadata);
  } catch (const std::exception& e) {  // std::bad_alloc
    return Status::IoError(std::string("coverage picture: cannot render the ") + PlotFormatName(format) + ": " +
                           e.what());
  }
}

}  // namespace opl
