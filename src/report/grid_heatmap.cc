#include "opl/report/grid_heatmap.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "opl/io/atomic_file.h"
#include "plot_canvas.h"

namespace opl {

PixelRect GridHeatmapLayout::CellOfBeam(int beam_id) const {
  const int n = beams_per_side;
  if (n <= 0 || beam_id < 1 || beam_id > n * n) return PixelRect{};
  const int row = (beam_id - 1) / n;
  const int col = (beam_id - 1) % n;
  // Seen from behind the source looking out: col 0 (smallest Y) is the
  // rightmost column, row 0 (largest Z) the top row.
  return PixelRect{grid.x + (n - 1 - col) * cell_size, grid.y + row * cell_size, cell_size,
                   cell_size};
}

namespace {

using plot_internal::Align;
using plot_internal::Font;
using plot_internal::PlotCanvas;
using plot_internal::Rgb;
using plot_internal::Rgb8;
using plot_internal::TextBox;
using plot_internal::TextMeter;

const Rgb kWhite = Rgb8(255, 255, 255);
const Rgb kBlack = Rgb8(0, 0, 0);
const Rgb kDarkGrey = Rgb8(70, 70, 70);
const Rgb kNoDataFill = Rgb8(217, 217, 217);
const Rgb kNoDataHatch = Rgb8(160, 160, 160);
const Rgb kNoiseMark = Rgb8(0, 110, 70);  // dark bluish green

constexpr int kMargin = 24;
constexpr Font kTitleFont{19, true};
constexpr Font kSubtitleFont{14, false};
constexpr Font kNoteFont{13, false};
constexpr Font kNoiseFont{14, true};
constexpr Font kTickFont{13, false};
constexpr Font kBarLabelFont{14, false};
constexpr double kMinTextSize = 9;
constexpr int kBarWidth = 22;
constexpr int kBarGap = 28;  // grid -> colour bar
constexpr int kTickLength = 6;
constexpr int kGlyphArm = 40;  // axis glyph arrows

int Up(double px) { return static_cast<int>(std::ceil(px - 1e-9)); }

std::string Printf(const char* format, int digits, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, digits, value);
  return buf;
}

// 1, 2 or 5 times a power of ten, about scale_max / 5.
double NiceTickStep(double scale_max) {
  const double raw = scale_max / 5.0;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  const double mantissa = raw / power;
  if (mantissa < 1.5) return power;
  if (mantissa < 3.5) return 2 * power;
  if (mantissa < 7.5) return 5 * power;
  return 10 * power;
}

int DecimalsForStep(double step) {
  return std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
}

std::string FormatTick(double tick, int decimals) {
  return decimals <= 6 && tick < 1e6 ? Printf("%.*f", decimals, tick) : Printf("%.*g", 3, tick);
}

std::string FormatValue(double value, int decimals) {
  std::string s = Printf("%.*f", decimals, value);
  if (s.size() > 8) s = Printf("%.*g", 3, value);
  return s;
}

// Everything LayoutGridHeatmap returns plus what the renderer needs.
struct FullLayout {
  GridHeatmapLayout pub;
  int n = 0;
  bool any_above_scale = false;
  int value_decimals = 0;
  int tick_decimals = 0;
  double tick_step = 0;
  std::vector<std::string> value_texts;  // per beam, "no data" for NaN

  // Header lines: baseline y of each, and the text.
  std::string title;
  Font title_font = kTitleFont;
  int title_baseline = 0;
  std::string subtitle;
  Font subtitle_font = kSubtitleFont;
  int subtitle_baseline = 0;
  std::string noise_text;  // "" unless every beam is at the noise level
  int noise_baseline = 0;
  int view_baseline = 0;
  std::string view_text;

  // Labels around the grid.
  Font axis_label_font{11.5, false};
  int col_label_baseline = 0;
  int row_label_right = 0;  // right edge of the row labels

  // Cell text.
  Font id_font{9.5, false};
  Font value_font{13, false};
  Font no_data_font{10, false};

  // Colour bar.
  int tick_label_x = 0;
  int bar_label_x = 0;  // left edge (cap tops) of the rotated value label
  Font bar_label_font = kBarLabelFont;
  std::string bar_label;  // value_label, shrunk or cut to the bar's length

  // Below the grid: axis glyph origin and notes.
  int glyph_x = 0, glyph_y = 0;
  int notes_x = 0;
  int notes_first_baseline = 0;
  int notes_line_step = 0;
  std::vector<std::string> notes;
};

Status Validate(const GridHeatmap& h) {
  const int n = h.beams_per_side;
  if (n < 3 || n > kGridHeatmapMaxBeamsPerSide || n % 2 == 0) {
    return Status::InvalidArgument("GridHeatmap.beams_per_side: must be odd and in [3, " +
                                   std::to_string(kGridHeatmapMaxBeamsPerSide) + "], got " +
                                   std::to_string(n));
  }
  const size_t expected = static_cast<size_t>(n) * static_cast<size_t>(n);
  if (h.values.size() != expected) {
    return Status::InvalidArgument("GridHeatmap.values: has " + std::to_string(h.values.size()) +
                                   " entries, expected beams_per_side^2 = " +
                                   std::to_string(expected));
  }
  for (size_t i = 0; i < h.values.size(); ++i) {
    const double v = h.values[i];
    if (std::isnan(v)) continue;
    const std::string field =
        "GridHeatmap.values[" + std::to_string(i) + "] (beam " + std::to_string(i + 1) + "): ";
    if (std::isinf(v)) {
      return Status::InvalidArgument(field + "must be finite or NaN (no data), got " +
                                     FormatNumber(v));
    }
    if (v < 0) {
      return Status::InvalidArgument(field + "must be >= 0 or NaN (no data), got " +
                                     FormatNumber(v));
    }
  }
  if (h.title.empty()) return Status::InvalidArgument("GridHeatmap.title: must not be empty");
  if (h.value_label.empty()) {
    return Status::InvalidArgument(
        "GridHeatmap.value_label: must not be empty (it names the value and its unit)");
  }
  if (h.scale_max.has_value() && !(std::isfinite(*h.scale_max) && *h.scale_max > 0)) {
    return Status::InvalidArgument("GridHeatmap.scale_max: must be finite and > 0, got " +
                                   FormatNumber(*h.scale_max));
  }
  if (!std::isnan(h.noise_level) && !(std::isfinite(h.noise_level) && h.noise_level >= 0)) {
    return Status::InvalidArgument(
        "GridHeatmap.noise_level: must be finite and >= 0 or NaN (none), got " +
        FormatNumber(h.noise_level));
  }
  return Status::Ok();
}

FullLayout ComputeLayout(const GridHeatmap& h, const TextMeter& meter) {
  FullLayout L;
  const int n = h.beams_per_side;
  L.n = n;
  L.pub.beams_per_side = n;

  // Colour scale and number formats.
  double max_value = 0;
  bool any_value = false;
  for (double v : h.values) {
    if (!std::isfinite(v)) continue;
    max_value = std::max(max_value, v);
    any_value = true;
  }
  const double scale_max = h.scale_max.value_or(max_value > 0 ? max_value : 1.0);
  L.pub.scale_max = scale_max;
  L.any_above_scale = max_value > scale_max;
  L.tick_step = NiceTickStep(scale_max);
  L.tick_decimals = DecimalsForStep(L.tick_step);
  // Cell values to 0.5 % .. 5 % of the scale: 0.031 on a 0..0.046 scale,
  // 0.85 on 0..1, 12 on 0..35.
  L.value_decimals =
      std::max(0, static_cast<int>(std::ceil(-std::log10(0.05 * scale_max) - 1e-9)));
  L.value_texts.reserve(h.values.size());
  for (double v : h.values) {
    L.value_texts.push_back(std::isnan(v) ? std::string("no data")
                                          : FormatValue(v, L.value_decimals));
  }
  L.pub.all_at_noise_level = any_value && !std::isnan(h.noise_level) && max_value <= h.noise_level;

  // Cells: 64 px, larger for small grids.
  const int cell = std::max(64, 480 / n);
  L.pub.cell_size = cell;
  const double cell_factor = cell / 64.0;
  L.id_font.size_px = std::min(9.5 * cell_factor, 15.0);
  L.axis_label_font.size_px = std::min(11.5 * cell_factor, 14.0);
  // The value font: as large as fits the widest value text, at most 13 px
  // for a 64 px cell (bold from 20 px); "no data" as large as the values if
  // it fits.
  double widest = 0;
  for (size_t i = 0; i < h.values.size(); ++i) {
    if (std::isnan(h.values[i])) continue;
    widest = std::max(widest, meter.Measure(L.value_texts[i], Font{1, false}).width);
  }
  const double max_size = std::min(13.0 * cell_factor, 26.0);
  L.value_font.size_px = std::min(max_size, (cell - 12.0) / std::max(widest, 1e-3));
  L.value_font.bold = L.value_font.size_px >= 20;
  L.no_data_font.size_px =
      std::min(L.value_font.size_px, (cell - 14.0) / meter.Measure("no data", Font{1, false}).width);

  // Header.
  L.view_text =
      "Seen from behind the source, looking out along +X (the central beam, into the page)";
  L.title = h.title;
  L.subtitle = h.subtitle;
  if (L.pub.all_at_noise_level) {
    L.noise_text = "All beams at the noise level (<= " + FormatNumber(h.noise_level) +
                   (h.value_unit.empty() ? "" : " " + h.value_unit) +
                   (h.noise_note.empty() ? "" : "; " + h.noise_note) + ")";
  }
  const TextBox view = meter.Measure(L.view_text, kNoteFont);

  // Column labels above the grid, row labels at its left.
  const TextBox col_label =
      meter.Measure("col " + std::to_string(n - 1), L.axis_label_font);
  const TextBox row_label =
      meter.Measure("row " + std::to_string(n - 1), L.axis_label_font);
  const int grid_size = n * cell;

  // Horizontal extent of the grid block, relative to its left edge x0.
  const int row_label_width = Up(row_label.width) + 10;
  double tick_label_width = 0;
  const int ticks = static_cast<int>(std::floor(scale_max / L.tick_step + 1e-9));
  for (int k = 0; k <= ticks; ++k) {
    tick_label_width = std::max(
        tick_label_width, meter.Measure(FormatTick(k * L.tick_step, L.tick_decimals), kTickFont).width);
  }
  // The value label along the bar: shrunk, and if need be cut, to the bar's
  // length.
  std::tie(L.bar_label, L.bar_label_font) =
      meter.Fit(h.value_label, kBarLabelFont, grid_size, kMinTextSize);
  const TextBox bar_label = meter.Measure(L.bar_label, L.bar_label_font);
  const int block_width = row_label_width + grid_size + kBarGap + kBarWidth + kTickLength + 4 +
                          Up(tick_label_width) + 12 + Up(bar_label.height + bar_label.baseline);

  // Below the grid: axis glyph and notes.
  const int id_central = (n * n + 1) / 2;
  L.notes = {
      "row 0 = top (largest Z), col 0 = right (smallest Y); beam id = row x " +
          std::to_string(n) + " + col + 1",
      "beam " + std::to_string(id_central) + " = central beam (+X, az = el = 0); "
          "grey hatched = no data",
      "colour: viridis, 0 to " + FormatValue(scale_max, L.value_decimals) +
          (h.scale_note.empty() ? "" : " (" + h.scale_note + ")") +
          (L.any_above_scale ? " (triangle: values above the scale)" : ""),
  };
  const TextBox note = meter.Measure(L.notes[0], kNoteFont);
  double notes_width = 0;
  for (const std::string& t : L.notes) {
    notes_width = std::max(notes_width, meter.Measure(t, kNoteFont).width);
  }
  const int glyph_block_width = kGlyphArm + 40 + 24;  // "+Y" left of the arrow, "+X" right
  const int below_width = glyph_block_width + 20 + Up(notes_width);

  // Image width: the widest of the parts; the grid block is centred. Very
  // long titles are shrunk (then cut) rather than widening the image without
  // bound.
  const int max_title_width = std::max(block_width, below_width) + 400;
  std::tie(L.title, L.title_font) = meter.Fit(h.title, kTitleFont, max_title_width, kMinTextSize);
  std::tie(L.subtitle, L.subtitle_font) =
      meter.Fit(h.subtitle, kSubtitleFont, max_title_width, kMinTextSize);
  const TextBox title = meter.Measure(L.title, L.title_font);
  const TextBox subtitle = meter.Measure(L.subtitle, L.subtitle_font);
  const TextBox noise = meter.Measure(L.noise_text, kNoiseFont);
  const int content_width = std::max({block_width, below_width, Up(title.width),
                                      Up(subtitle.width), Up(view.width), Up(noise.width)});
  const int width = content_width + 2 * kMargin;

  int y = kMargin;
  L.title_baseline = y + Up(title.height);
  y = L.title_baseline + Up(title.baseline) + 10;
  if (!L.subtitle.empty()) {
    L.subtitle_baseline = y + Up(subtitle.height);
    y = L.subtitle_baseline + Up(subtitle.baseline) + 8;
  }
  if (!L.noise_text.empty()) {
    L.noise_baseline = y + Up(noise.height);
    y = L.noise_baseline + Up(noise.baseline) + 8;
  }
  L.view_baseline = y + Up(view.height);
  y = L.view_baseline + Up(view.baseline) + 18;
  L.col_label_baseline = y + Up(col_label.height);
  y = L.col_label_baseline + Up(col_label.baseline) + 6;
  const int grid_top = y;

  const int x0 = kMargin + (content_width - block_width) / 2;
  L.row_label_right = x0 + row_label_width - 10;
  L.pub.grid = PixelRect{x0 + row_label_width, grid_top, grid_size, grid_size};
  const int bar_x = L.pub.grid.x + grid_size + kBarGap;
  L.pub.colour_bar = PixelRect{bar_x, grid_top, kBarWidth, grid_size};
  L.tick_label_x = bar_x + kBarWidth + kTickLength + 4;
  L.bar_label_x = L.tick_label_x + Up(tick_label_width) + 12;

  y = grid_top + grid_size + 22;
  const int below_x0 = std::min(L.pub.grid.x - row_label_width,
                                kMargin + (content_width - below_width) / 2);
  L.glyph_x = below_x0 + 24 + kGlyphArm;
  L.glyph_y = y + kGlyphArm + 4;
  L.notes_x = below_x0 + glyph_block_width + 20;
  L.notes_line_step = Up(note.height + note.baseline) + 8;
  const int notes_height = static_cast<int>(L.notes.size()) * L.notes_line_step;
  const int glyph_height = kGlyphArm + 30;
  L.notes_first_baseline = y + Up(note.height) + std::max(0, (glyph_height - notes_height) / 2);
  y += std::max(glyph_height, notes_height);

  L.pub.image_width = width;
  L.pub.image_height = y + kMargin;
  return L;
}

// Viridis colours of levels 0..255 (OpenCV's table, RGB).
Rgb LevelColour(int level) {
  static const cv::Mat lut = [] {
    cv::Mat levels(256, 1, CV_8UC1);
    for (int i = 0; i < 256; ++i) levels.at<unsigned char>(i, 0) = static_cast<unsigned char>(i);
    cv::Mat colours;
    cv::applyColorMap(levels, colours, cv::COLORMAP_VIRIDIS);
    return colours;
  }();
  const cv::Vec3b c = lut.at<cv::Vec3b>(std::clamp(level, 0, 255), 0);  // BGR
  return Rgb8(c[2], c[1], c[0]);
}

int ValueLevel(double value, double scale_max) {
  return static_cast<int>(std::lround(255.0 * std::clamp(value / scale_max, 0.0, 1.0)));
}

double LinearChannel(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// Black or white, whichever has the larger WCAG contrast ratio with `fill`.
Rgb ContrastingText(Rgb fill) {
  const double lum = 0.2126 * LinearChannel(fill.r) + 0.7152 * LinearChannel(fill.g) +
                     0.0722 * LinearChannel(fill.b);
  const double with_white = 1.05 / (lum + 0.05);
  const double with_black = (lum + 0.05) / 0.05;
  return with_black >= with_white ? kBlack : kWhite;
}

void DrawCell(const PlotCanvas& c, const TextMeter& meter, const FullLayout& L,
              const GridHeatmap& h, int beam_id) {
  const PixelRect r = L.pub.CellOfBeam(beam_id);
  const PixelRect fill{r.x, r.y, r.width - 1, r.height - 1};  // 1 px white line right, bottom
  const double v = h.values[static_cast<size_t>(beam_id - 1)];
  const bool no_data = std::isnan(v);
  const Rgb colour = no_data ? kNoDataFill : LevelColour(ValueLevel(v, L.pub.scale_max));
  c.FillPixels(fill, colour);
  if (no_data) {  // diagonal hatching, 12 px apart
    c.ClipTo(fill);
    cairo_t* cr = c.cr();
    c.SetColour(kNoDataHatch);
    cairo_set_line_width(cr, 1);
    for (int k = 6; k < 2 * fill.width; k += 12) {
      cairo_move_to(cr, fill.x + k, fill.y - 0.5);
      cairo_line_to(cr, fill.x - 0.5, fill.y + k);
    }
    cairo_stroke(cr);
    c.Unclip();
  }
  const Rgb text = no_data ? kBlack : ContrastingText(colour);
  const int pad = std::max(3, r.width / 16);

  // Beam id, top left (on a plain patch over the hatching).
  const std::string id = std::to_string(beam_id);
  const TextBox id_box = meter.Measure(id, L.id_font);
  const double id_baseline = r.y + pad + id_box.height;
  if (no_data) {
    c.FillPixels(PixelRect{r.x + pad - 2, r.y + pad - 2, Up(id_box.width) + 4,
                           Up(id_box.height + id_box.baseline) + 4},
                 kNoDataFill);
  }
  c.Text(id, r.x + pad, id_baseline, L.id_font, text);

  // Value, centred a little below the middle.
  const std::string& value_text = L.value_texts[static_cast<size_t>(beam_id - 1)];
  const Font font = no_data ? L.no_data_font : L.value_font;
  const TextBox vb = meter.Measure(value_text, font);
  const double cx = r.x + 0.5 * (r.width - 2);
  const double baseline = r.y + (r.height - 1) * 5.0 / 8.0 + 0.5 * vb.height;
  if (no_data) {
    c.FillPixels(PixelRect{static_cast<int>(std::floor(cx - 0.5 * vb.width)) - 2,
                           static_cast<int>(std::floor(baseline - vb.height)) - 2,
                           Up(vb.width) + 4, Up(vb.height + vb.baseline) + 4},
                 kNoDataFill);
  }
  c.Text(value_text, cx, baseline, font, text, Align::kCentre);
}

void DrawArrow(cairo_t* cr, double x0, double y0, double x1, double y1) {
  const double len = std::hypot(x1 - x0, y1 - y0);
  const double ux = (x1 - x0) / len, uy = (y1 - y0) / len;
  const double head = 0.25 * len;
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 2);
  cairo_move_to(cr, x0, y0);
  cairo_line_to(cr, x1 - ux * 0.5 * head, y1 - uy * 0.5 * head);
  cairo_stroke(cr);
  cairo_move_to(cr, x1, y1);
  cairo_line_to(cr, x1 - ux * head - uy * 0.45 * head, y1 - uy * head + ux * 0.45 * head);
  cairo_line_to(cr, x1 - ux * head + uy * 0.45 * head, y1 - uy * head - ux * 0.45 * head);
  cairo_close_path(cr);
  cairo_fill(cr);
}

void DrawColourBar(const PlotCanvas& c, const TextMeter& meter, const FullLayout& L) {
  const PixelRect b = L.pub.colour_bar;
  for (int row = 0; row < b.height; ++row) {
    const int level =
        static_cast<int>(std::lround(255.0 * (b.height - 1 - row) / std::max(1, b.height - 1)));
    c.FillPixels(PixelRect{b.x, b.y + row, b.width, 1}, LevelColour(level));
  }
  c.FrameAround(b, kBlack);
  cairo_t* cr = c.cr();
  if (L.any_above_scale) {  // a triangle on top: values above the scale
    const double top = b.y - 3;
    cairo_move_to(cr, b.x - 1, top);
    cairo_line_to(cr, b.x + b.width, top);
    cairo_line_to(cr, b.x + 0.5 * (b.width - 1), top - b.width * 0.75);
    cairo_close_path(cr);
    c.SetColour(LevelColour(255));
    cairo_fill_preserve(cr);
    c.SetColour(kBlack);
    cairo_set_line_width(cr, 1);
    cairo_stroke(cr);
  }

  // Ticks at multiples of the step.
  const double digit = meter.Measure("0", kTickFont).height;
  const int ticks = static_cast<int>(std::floor(L.pub.scale_max / L.tick_step + 1e-9));
  for (int k = 0; k <= ticks; ++k) {
    const double t = k * L.tick_step;
    const int y = b.y + b.height - 1 -
                  static_cast<int>(std::lround(t / L.pub.scale_max * (b.height - 1)));
    c.PixelLine(b.x + b.width, y, b.x + b.width + kTickLength - 1, y, kBlack);
    c.Text(FormatTick(t, L.tick_decimals), L.tick_label_x, y + 0.5 * digit, kTickFont, kBlack);
  }
  // The value label, rotated to read bottom-up, centred along the bar.
  c.TextUp(L.bar_label, L.bar_label_x, b.y + 0.5 * (b.height - 1), L.bar_label_font, kBlack);
}

void DrawAxisGlyph(const PlotCanvas& c, const TextMeter& meter, const FullLayout& L) {
  cairo_t* cr = c.cr();
  const double ox = L.glyph_x, oy = L.glyph_y;
  // +Y points left, +Z up (seen from behind the source looking out).
  DrawArrow(cr, ox - 7, oy, ox - kGlyphArm, oy);
  DrawArrow(cr, ox, oy - 7, ox, oy - kGlyphArm);
  const double cap = meter.Measure("+Y", kNoteFont).height;
  c.Text("+Y", ox - kGlyphArm - 4, oy + 0.5 * cap, kNoteFont, kBlack, Align::kRight);
  c.Text("+Z", ox, oy - kGlyphArm - 6, kNoteFont, kBlack, Align::kCentre);
  // +X into the page: a circled cross at the origin.
  c.SetColour(kBlack);
  cairo_set_line_width(cr, 1);
  cairo_new_sub_path(cr);
  cairo_arc(cr, ox, oy, 6, 0, 2 * M_PI);
  cairo_move_to(cr, ox - 4, oy - 4);
  cairo_line_to(cr, ox + 4, oy + 4);
  cairo_move_to(cr, ox - 4, oy + 4);
  cairo_line_to(cr, ox + 4, oy - 4);
  cairo_stroke(cr);
  c.Text("+X", ox + 10, oy + cap + 8, kNoteFont, kBlack);
}

void Draw(const PlotCanvas& c, const TextMeter& meter, const GridHeatmap& h,
          const FullLayout& L) {
  const double centre_x = 0.5 * (L.pub.image_width - 1);
  c.Text(L.title, centre_x, L.title_baseline, L.title_font, kBlack, Align::kCentre);
  c.Text(L.subtitle, centre_x, L.subtitle_baseline, L.subtitle_font, kBlack, Align::kCentre);
  c.Text(L.noise_text, centre_x, L.noise_baseline, kNoiseFont, kNoiseMark, Align::kCentre);
  c.Text(L.view_text, centre_x, L.view_baseline, kNoteFont, kDarkGrey, Align::kCentre);

  const int n = L.n;
  for (int col = 0; col < n; ++col) {
    const PixelRect r = L.pub.CellOfBeam(col + 1);
    c.Text("col " + std::to_string(col), r.x + 0.5 * (r.width - 2), L.col_label_baseline,
           L.axis_label_font, kDarkGrey, Align::kCentre);
  }
  const double row_cap = meter.Measure("row", L.axis_label_font).height;
  for (int row = 0; row < n; ++row) {
    const PixelRect r = L.pub.CellOfBeam(row * n + n);  // leftmost cell of the row
    c.Text("row " + std::to_string(row), L.row_label_right, r.y + 0.5 * (r.height - 2) + 0.5 * row_cap,
           L.axis_label_font, kDarkGrey, Align::kRight);
  }
  for (int id = 1; id <= n * n; ++id) DrawCell(c, meter, L, h, id);

  DrawColourBar(c, meter, L);
  DrawAxisGlyph(c, meter, L);
  for (size_t i = 0; i < L.notes.size(); ++i) {
    c.Text(L.notes[i], L.notes_x,
           L.notes_first_baseline + static_cast<int>(i) * L.notes_line_step, kNoteFont,
           kDarkGrey);
  }
}

Result<std::vector<unsigned char>> Render(const GridHeatmap& h, PlotFormat format,
                                          const PlotMetadata& metadata) {
  OPL_RETURN_IF_ERROR(Validate(h));
  const TextMeter meter;
  const FullLayout layout = ComputeLayout(h, meter);
  Result<std::unique_ptr<PlotCanvas>> canvas =
      PlotCanvas::Create(format, layout.pub.image_width, layout.pub.image_height, h.title,
                         metadata, "grid heat map");
  if (!canvas.ok()) return canvas.status();
  Draw(**canvas, meter, h, layout);
  return (*canvas)->Finish();
}

}  // namespace

double SharedScaleMax(const std::vector<GridHeatmap>& heatmaps) {
  double max_value = 0;
  for (const GridHeatmap& h : heatmaps) {
    for (double v : h.values) {
      if (std::isfinite(v)) max_value = std::max(max_value, v);
    }
  }
  return max_value > 0 ? max_value : 1.0;
}

Result<GridHeatmapLayout> LayoutGridHeatmap(const GridHeatmap& heatmap) {
  OPL_RETURN_IF_ERROR(Validate(heatmap));
  try {
    const TextMeter meter;
    return ComputeLayout(heatmap, meter).pub;
  } catch (const std::exception& e) {  // std::bad_alloc
    return Status::IoError(std::string("grid heat map: cannot lay out the figure: ") + e.what());
  }
}

Result<std::vector<unsigned char>> RenderGridHeatmap(const GridHeatmap& heatmap,
                                                     PlotFormat format,
                                                     const PlotMetadata& metadata) {
  try {
    return Render(heatmap, format, metadata);
  } catch (const std::exception& e) {  // cv::Exception, std::bad_alloc
    return Status::IoError(std::string("grid heat map: cannot render the ") +
                           PlotFormatName(format) + ": " + e.what());
  }
}

Status WriteGridHeatmap(const GridHeatmap& heatmap, const std::string& path,
                        const PlotMetadata& metadata) {
  Result<PlotFormat> format = PlotFormatFromPath(path);
  if (!format.ok()) return format.status();
  Result<std::vector<unsigned char>> bytes = RenderGridHeatmap(heatmap, *format, metadata);
  if (!bytes.ok()) return bytes.status();
  return WriteFileAtomically(path, std::string(bytes->begin(), bytes->end()));
}

}  // namespace opl
