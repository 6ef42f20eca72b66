#include "opl/report/grid_heatmap.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "opl/io/atomic_file.h"

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

// Colours, BGR as OpenCV stores them.
const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kDarkGrey(70, 70, 70);
const cv::Scalar kNoDataFill(217, 217, 217);
const cv::Scalar kNoDataHatch(160, 160, 160);

constexpr int kMargin = 24;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kTitleFont = cv::FONT_HERSHEY_DUPLEX;
constexpr double kTitleScale = 0.8;
constexpr double kSubtitleScale = 0.55;
constexpr double kNoteScale = 0.5;
constexpr double kTickScale = 0.5;
constexpr double kBarLabelScale = 0.55;
constexpr int kBarWidth = 22;
constexpr int kBarGap = 28;    // grid -> colour bar
constexpr int kTickLength = 6;
constexpr int kGlyphArm = 40;  // axis glyph arrows

struct TextBox {
  int width = 0;
  int height = 0;    // above the baseline
  int baseline = 0;  // below the baseline
};

TextBox MeasureText(const std::string& text, int font, double scale, int thickness) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &baseline);
  return TextBox{size.width, size.height, baseline};
}

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
  int title_baseline = 0;
  int subtitle_baseline = 0;
  int view_baseline = 0;
  std::string view_text;
  double title_scale = kTitleScale;
  double subtitle_scale = kSubtitleScale;

  // Labels around the grid.
  double axis_label_scale = 0.45;
  int col_label_baseline = 0;
  int row_label_right = 0;  // right edge of the row labels

  // Cell text.
  double id_scale = 0.38;
  double value_scale = 0.5;
  double no_data_scale = 0.4;
  int value_thickness = 1;

  // Colour bar.
  int tick_label_x = 0;
  int bar_label_x = 0;  // left edge of the rotated value label
  double bar_label_scale = kBarLabelScale;
  std::string bar_label;  // value_label, cut with "..." if longer than the bar

  // Below the grid: axis glyph origin and notes.
  cv::Point glyph_origin;
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
  return Status::Ok();
}

FullLayout ComputeLayout(const GridHeatmap& h) {
  FullLayout L;
  const int n = h.beams_per_side;
  L.n = n;
  L.pub.beams_per_side = n;

  // Colour scale and number formats.
  double max_value = 0;
  for (double v : h.values) {
    if (std::isfinite(v)) max_value = std::max(max_value, v);
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

  // Cells: 64 px, larger for small grids.
  const int cell = std::max(64, 480 / n);
  L.pub.cell_size = cell;
  const double cell_factor = cell / 64.0;
  L.id_scale = std::min(0.38 * cell_factor, 0.6);
  L.axis_label_scale = std::min(0.45 * cell_factor, 0.55);
  // The value font: as large as fits the widest value text, at most 0.5 for
  // a 64 px cell; "no data" as large as the values if it fits.
  int widest = 0;
  for (size_t i = 0; i < h.values.size(); ++i) {
    if (std::isnan(h.values[i])) continue;
    widest = std::max(widest, MeasureText(L.value_texts[i], kFont, 1.0, 1).width);
  }
  const double max_scale = std::min(0.5 * cell_factor, 1.0);
  L.value_scale = std::min(max_scale, (cell - 12.0) / std::max(widest, 1));
  L.value_thickness = L.value_scale >= 0.8 ? 2 : 1;
  L.no_data_scale =
      std::min(L.value_scale, (cell - 14.0) / MeasureText("no data", kFont, 1.0, 1).width);

  // Header.
  L.view_text =
      "Seen from behind the source, looking out along +X (the central beam, into the page)";
  TextBox title = MeasureText(h.title, kTitleFont, L.title_scale, 1);
  TextBox subtitle = MeasureText(h.subtitle, kFont, L.subtitle_scale, 1);
  const TextBox view = MeasureText(L.view_text, kFont, kNoteScale, 1);
  int y = kMargin;
  L.title_baseline = y + title.height;
  y = L.title_baseline + title.baseline + 10;
  if (!h.subtitle.empty()) {
    L.subtitle_baseline = y + subtitle.height;
    y = L.subtitle_baseline + subtitle.baseline + 8;
  }
  L.view_baseline = y + view.height;
  y = L.view_baseline + view.baseline + 18;

  // Column labels above the grid, row labels at its left.
  const TextBox col_label =
      MeasureText("col " + std::to_string(n - 1), kFont, L.axis_label_scale, 1);
  const TextBox row_label =
      MeasureText("row " + std::to_string(n - 1), kFont, L.axis_label_scale, 1);
  L.col_label_baseline = y + col_label.height;
  y = L.col_label_baseline + col_label.baseline + 6;
  const int grid_top = y;
  const int grid_size = n * cell;

  // Horizontal extent of the grid block, relative to its left edge x0.
  const int row_label_width = row_label.width + 10;
  int tick_label_width = 0;
  const int ticks = static_cast<int>(std::floor(scale_max / L.tick_step + 1e-9));
  for (int k = 0; k <= ticks; ++k) {
    tick_label_width = std::max(
        tick_label_width,
        MeasureText(FormatTick(k * L.tick_step, L.tick_decimals), kFont, kTickScale, 1).width);
  }
  // The value label along the bar: shrunk, and if need be cut, to the bar's
  // length.
  L.bar_label = h.value_label;
  TextBox bar_label = MeasureText(L.bar_label, kFont, L.bar_label_scale, 1);
  if (bar_label.width > grid_size) {
    L.bar_label_scale = std::max(0.35, L.bar_label_scale * grid_size / bar_label.width);
    bar_label = MeasureText(L.bar_label, kFont, L.bar_label_scale, 1);
    if (bar_label.width > grid_size) {  // first cut in proportion, then char by char
      const size_t keep = L.bar_label.size() * static_cast<size_t>(grid_size) /
                          static_cast<size_t>(bar_label.width);
      L.bar_label = L.bar_label.substr(0, keep) + "...";
      bar_label = MeasureText(L.bar_label, kFont, L.bar_label_scale, 1);
    }
    while (bar_label.width > grid_size && L.bar_label.size() > 3) {
      L.bar_label = L.bar_label.substr(0, L.bar_label.size() - 4) + "...";
      bar_label = MeasureText(L.bar_label, kFont, L.bar_label_scale, 1);
    }
  }
  const int block_width = row_label_width + grid_size + kBarGap + kBarWidth + kTickLength + 4 +
                          tick_label_width + 12 + bar_label.height + bar_label.baseline;

  // Below the grid: axis glyph and notes.
  const int id_central = (n * n + 1) / 2;
  L.notes = {
      "row 0 = top (largest Z), col 0 = right (smallest Y); beam id = row x " +
          std::to_string(n) + " + col + 1",
      "beam " + std::to_string(id_central) + " = central beam (+X, az = el = 0); "
          "grey hatched = no data",
      "colour: viridis, 0 to " + FormatValue(scale_max, L.value_decimals) +
          (L.any_above_scale ? " (triangle: values above the scale)" : ""),
  };
  const TextBox note = MeasureText(L.notes[0], kFont, kNoteScale, 1);
  int notes_width = 0;
  for (const std::string& t : L.notes) {
    notes_width = std::max(notes_width, MeasureText(t, kFont, kNoteScale, 1).width);
  }
  const int glyph_block_width = kGlyphArm + 40 + 24;  // "+Y" left of the arrow, "+X" right
  const int below_width = glyph_block_width + 20 + notes_width;

  // Image width: the widest of the parts; the grid block is centred. Very
  // long titles are shrunk rather than widening the image without bound.
  const int max_title_width = std::max(block_width, below_width) + 400;
  if (title.width > max_title_width) {
    L.title_scale *= static_cast<double>(max_title_width) / title.width;
    title = MeasureText(h.title, kTitleFont, L.title_scale, 1);
  }
  if (subtitle.width > max_title_width) {
    L.subtitle_scale *= static_cast<double>(max_title_width) / subtitle.width;
    subtitle = MeasureText(h.subtitle, kFont, L.subtitle_scale, 1);
  }
  const int content_width =
      std::max({block_width, below_width, title.width, subtitle.width, view.width});
  const int width = content_width + 2 * kMargin;
  const int x0 = kMargin + (content_width - block_width) / 2;
  L.row_label_right = x0 + row_label_width - 10;
  L.pub.grid = PixelRect{x0 + row_label_width, grid_top, grid_size, grid_size};
  const int bar_x = L.pub.grid.x + grid_size + kBarGap;
  L.pub.colour_bar = PixelRect{bar_x, grid_top, kBarWidth, grid_size};
  L.tick_label_x = bar_x + kBarWidth + kTickLength + 4;
  L.bar_label_x = L.tick_label_x + tick_label_width + 12;

  y = grid_top + grid_size + 22;
  const int below_x0 = std::min(L.pub.grid.x - row_label_width,
                                kMargin + (content_width - below_width) / 2);
  L.glyph_origin = cv::Point(below_x0 + 24 + kGlyphArm, y + kGlyphArm + 4);
  L.notes_x = below_x0 + glyph_block_width + 20;
  L.notes_line_step = note.height + note.baseline + 8;
  const int notes_height = static_cast<int>(L.notes.size()) * L.notes_line_step;
  const int glyph_height = kGlyphArm + 30;
  L.notes_first_baseline = y + note.height + std::max(0, (glyph_height - notes_height) / 2);
  y += std::max(glyph_height, notes_height);

  L.pub.image_width = width;
  L.pub.image_height = y + kMargin;
  return L;
}

// Viridis colours of levels 0..255 (BGR).
const cv::Mat& ViridisLut() {
  static const cv::Mat lut = [] {
    cv::Mat levels(256, 1, CV_8UC1);
    for (int i = 0; i < 256; ++i) levels.at<unsigned char>(i, 0) = static_cast<unsigned char>(i);
    cv::Mat colours;
    cv::applyColorMap(levels, colours, cv::COLORMAP_VIRIDIS);
    return colours;
  }();
  return lut;
}

cv::Scalar LevelColour(int level) {
  const cv::Vec3b c = ViridisLut().at<cv::Vec3b>(std::clamp(level, 0, 255), 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

int ValueLevel(double value, double scale_max) {
  return static_cast<int>(std::lround(255.0 * std::clamp(value / scale_max, 0.0, 1.0)));
}

double LinearChannel(double c8) {
  const double c = c8 / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// Black or white, whichever has the larger WCAG contrast ratio with `fill`.
cv::Scalar ContrastingText(const cv::Scalar& fill) {
  const double lum = 0.2126 * LinearChannel(fill[2]) + 0.7152 * LinearChannel(fill[1]) +
                     0.0722 * LinearChannel(fill[0]);
  const double with_white = 1.05 / (lum + 0.05);
  const double with_black = (lum + 0.05) / 0.05;
  return with_black >= with_white ? kBlack : kWhite;
}

void PutText(cv::Mat& img, const std::string& text, cv::Point origin, double scale,
             const cv::Scalar& colour, int font = kFont, int thickness = 1) {
  cv::putText(img, text, origin, font, scale, colour, thickness, cv::LINE_AA);
}

void PutTextCentred(cv::Mat& img, const std::string& text, int centre_x, int baseline,
                    double scale, const cv::Scalar& colour, int font = kFont, int thickness = 1) {
  const TextBox box = MeasureText(text, font, scale, thickness);
  PutText(img, text, cv::Point(centre_x - box.width / 2, baseline), scale, colour, font,
          thickness);
}

void DrawCell(cv::Mat& img, const FullLayout& L, const GridHeatmap& h, int beam_id) {
  const PixelRect r = L.pub.CellOfBeam(beam_id);
  const cv::Rect fill(r.x, r.y, r.width - 1, r.height - 1);  // 1 px white line right, bottom
  const double v = h.values[static_cast<size_t>(beam_id - 1)];
  const bool no_data = std::isnan(v);
  const cv::Scalar colour = no_data ? kNoDataFill : LevelColour(ValueLevel(v, L.pub.scale_max));
  cv::rectangle(img, fill, colour, cv::FILLED);
  if (no_data) {
    cv::Mat roi = img(fill);
    for (int k = 6; k < 2 * fill.width; k += 12) {
      cv::line(roi, cv::Point(k, 0), cv::Point(0, k), kNoDataHatch, 1, cv::LINE_8);
    }
  }
  const cv::Scalar text = no_data ? kBlack : ContrastingText(colour);
  const int pad = std::max(3, r.width / 16);

  // Beam id, top left.
  const std::string id = std::to_string(beam_id);
  const TextBox id_box = MeasureText(id, kFont, L.id_scale, 1);
  const cv::Point id_origin(r.x + pad, r.y + pad + id_box.height);
  if (no_data) {
    cv::rectangle(img, cv::Rect(id_origin.x - 2, id_origin.y - id_box.height - 2,
                                id_box.width + 4, id_box.height + id_box.baseline + 3),
                  kNoDataFill, cv::FILLED);
  }
  PutText(img, id, id_origin, L.id_scale, text);

  // Value, centred a little below the middle.
  const std::string& value_text = L.value_texts[static_cast<size_t>(beam_id - 1)];
  const double scale = no_data ? L.no_data_scale : L.value_scale;
  const int thickness = no_data ? 1 : L.value_thickness;
  const TextBox vb = MeasureText(value_text, kFont, scale, thickness);
  const int cx = r.x + (r.width - 1) / 2;
  const int baseline = r.y + (r.height - 1) * 5 / 8 + vb.height / 2;
  if (no_data) {
    cv::rectangle(img, cv::Rect(cx - vb.width / 2 - 2, baseline - vb.height - 2, vb.width + 4,
                                vb.height + vb.baseline + 3),
                  kNoDataFill, cv::FILLED);
  }
  PutText(img, value_text, cv::Point(cx - vb.width / 2, baseline), scale, text, kFont,
          thickness);
}

void DrawArrow(cv::Mat& img, cv::Point from, cv::Point to) {
  cv::arrowedLine(img, from, to, kBlack, 2, cv::LINE_AA, 0, 0.25);
}

void DrawColourBar(cv::Mat& img, const FullLayout& L) {
  const PixelRect b = L.pub.colour_bar;
  for (int row = 0; row < b.height; ++row) {
    const int level =
        static_cast<int>(std::lround(255.0 * (b.height - 1 - row) / std::max(1, b.height - 1)));
    cv::line(img, cv::Point(b.x, b.y + row), cv::Point(b.x + b.width - 1, b.y + row),
             LevelColour(level), 1, cv::LINE_8);
  }
  cv::rectangle(img, cv::Rect(b.x - 1, b.y - 1, b.width + 2, b.height + 2), kBlack, 1,
                cv::LINE_8);
  if (L.any_above_scale) {
    const std::vector<cv::Point> tri = {cv::Point(b.x - 1, b.y - 3),
                                        cv::Point(b.x + b.width, b.y - 3),
                                        cv::Point(b.x + b.width / 2, b.y - 3 - b.width * 3 / 4)};
    cv::fillConvexPoly(img, tri, LevelColour(255), cv::LINE_AA);
    cv::polylines(img, tri, true, kBlack, 1, cv::LINE_AA);
  }

  // Ticks at multiples of the step.
  const int ticks = static_cast<int>(std::floor(L.pub.scale_max / L.tick_step + 1e-9));
  for (int k = 0; k <= ticks; ++k) {
    const double t = k * L.tick_step;
    const int y = b.y + b.height - 1 -
                  static_cast<int>(std::lround(t / L.pub.scale_max * (b.height - 1)));
    cv::line(img, cv::Point(b.x + b.width, y), cv::Point(b.x + b.width + kTickLength - 1, y),
             kBlack, 1, cv::LINE_8);
    const std::string label = FormatTick(t, L.tick_decimals);
    const TextBox box = MeasureText(label, kFont, kTickScale, 1);
    PutText(img, label, cv::Point(L.tick_label_x, y + box.height / 2), kTickScale, kBlack);
  }

  // The value label, rotated to read bottom-up, centred along the bar.
  const TextBox box = MeasureText(L.bar_label, kFont, L.bar_label_scale, 1);
  cv::Mat label(box.height + box.baseline + 4, box.width + 4, CV_8UC3, kWhite);
  PutText(label, L.bar_label, cv::Point(2, 2 + box.height), L.bar_label_scale, kBlack);
  cv::Mat rotated;
  cv::rotate(label, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  cv::Rect dst(L.bar_label_x, b.y + (b.height - rotated.rows) / 2, rotated.cols, rotated.rows);
  const cv::Rect clipped = dst & cv::Rect(0, 0, img.cols, img.rows);
  if (clipped.area() > 0) {
    rotated(cv::Rect(clipped.x - dst.x, clipped.y - dst.y, clipped.width, clipped.height))
        .copyTo(img(clipped));
  }
}

void DrawAxisGlyph(cv::Mat& img, const FullLayout& L) {
  const cv::Point o = L.glyph_origin;
  const double s = kNoteScale;
  // +Y points left, +Z up (seen from behind the source looking out).
  DrawArrow(img, cv::Point(o.x - 7, o.y), cv::Point(o.x - kGlyphArm, o.y));
  DrawArrow(img, cv::Point(o.x, o.y - 7), cv::Point(o.x, o.y - kGlyphArm));
  const TextBox y_box = MeasureText("+Y", kFont, s, 1);
  PutText(img, "+Y", cv::Point(o.x - kGlyphArm - y_box.width - 4, o.y + y_box.height / 2), s,
          kBlack);
  PutTextCentred(img, "+Z", o.x, o.y - kGlyphArm - 6, s, kBlack);
  // +X into the page: a circled cross at the origin.
  cv::circle(img, o, 6, kBlack, 1, cv::LINE_AA);
  cv::line(img, cv::Point(o.x - 4, o.y - 4), cv::Point(o.x + 4, o.y + 4), kBlack, 1, cv::LINE_AA);
  cv::line(img, cv::Point(o.x - 4, o.y + 4), cv::Point(o.x + 4, o.y - 4), kBlack, 1, cv::LINE_AA);
  const TextBox x_box = MeasureText("+X", kFont, s, 1);
  PutText(img, "+X", cv::Point(o.x + 10, o.y + x_box.height + 8), s, kBlack);
}

cv::Mat Render(const GridHeatmap& h, const FullLayout& L) {
  cv::Mat img(L.pub.image_height, L.pub.image_width, CV_8UC3, kWhite);
  const int centre_x = L.pub.image_width / 2;

  PutTextCentred(img, h.title, centre_x, L.title_baseline, L.title_scale, kBlack, kTitleFont, 1);
  if (!h.subtitle.empty()) {
    PutTextCentred(img, h.subtitle, centre_x, L.subtitle_baseline, L.subtitle_scale, kBlack);
  }
  PutTextCentred(img, L.view_text, centre_x, L.view_baseline, kNoteScale, kDarkGrey);

  const int n = L.n;
  for (int col = 0; col < n; ++col) {
    const PixelRect r = L.pub.CellOfBeam(col + 1);
    PutTextCentred(img, "col " + std::to_string(col), r.x + (r.width - 1) / 2,
                   L.col_label_baseline, L.axis_label_scale, kDarkGrey);
  }
  for (int row = 0; row < n; ++row) {
    const PixelRect r = L.pub.CellOfBeam(row * n + n);  // leftmost cell of the row
    const std::string label = "row " + std::to_string(row);
    const TextBox box = MeasureText(label, kFont, L.axis_label_scale, 1);
    PutText(img, label,
            cv::Point(L.row_label_right - box.width, r.y + (r.height - 1) / 2 + box.height / 2),
            L.axis_label_scale, kDarkGrey);
  }
  for (int id = 1; id <= n * n; ++id) DrawCell(img, L, h, id);

  DrawColourBar(img, L);
  DrawAxisGlyph(img, L);
  for (size_t i = 0; i < L.notes.size(); ++i) {
    PutText(img, L.notes[i],
            cv::Point(L.notes_x, L.notes_first_baseline + static_cast<int>(i) * L.notes_line_step),
            kNoteScale, kDarkGrey);
  }
  return img;
}

Status InternalError(const char* what) {
  return Status::IoError(std::string("grid heat map: cannot render the PNG: ") + what);
}

}  // namespace

Result<GridHeatmapLayout> LayoutGridHeatmap(const GridHeatmap& heatmap) {
  OPL_RETURN_IF_ERROR(Validate(heatmap));
  try {
    return ComputeLayout(heatmap).pub;
  } catch (const std::exception& e) {
    return InternalError(e.what());
  }
}

Result<std::vector<unsigned char>> RenderGridHeatmapPng(const GridHeatmap& heatmap) {
  OPL_RETURN_IF_ERROR(Validate(heatmap));
  try {
    const FullLayout layout = ComputeLayout(heatmap);
    const cv::Mat img = Render(heatmap, layout);
    std::vector<unsigned char> png;
    if (!cv::imencode(".png", img, png)) return InternalError("PNG encoder failed");
    return png;
  } catch (const std::exception& e) {  // cv::Exception, std::bad_alloc
    return InternalError(e.what());
  }
}

Status WriteGridHeatmapPng(const GridHeatmap& heatmap, const std::string& path) {
  Result<std::vector<unsigned char>> png = RenderGridHeatmapPng(heatmap);
  if (!png.ok()) return png.status();
  return WriteFileAtomically(path, std::string(png->begin(), png->end()));
}

}  // namespace opl
