#include "opl/report/board_print.h"

#include <cairo-pdf.h>
#include <cairo.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "opl/core/format.h"
#include "opl/lab/planar_target_image.h"

namespace opl {
namespace {

constexpr double kMmPerInch = 25.4;
constexpr double kPointsPerMm = 72.0 / kMmPerInch;
constexpr double kFontMm = 3.2;     // text height (about 9 pt)
constexpr double kLineMm = 5.0;     // text line spacing
constexpr double kScaleMm = 100.0;  // the scale check line
constexpr int kMaxPngSidePx = 30000;
constexpr const char* kFont = "DejaVu Sans";

double Cell(const TagBoard& b) { return b.tag_size / 8.0; }
double GridWidth(const TagBoard& b) { return b.columns * b.tag_size + (b.columns - 1) * b.tag_gap; }
double GridHeight(const TagBoard& b) { return b.rows * b.tag_size + (b.rows - 1) * b.tag_gap; }

std::vector<std::string> CaptionLines(const TagBoard& b) {
  return {
      "OPL calibration board: tag36h11, " + std::to_string(b.columns) + " x " + std::to_string(b.rows) +
          " tags (cols x rows), ids " + std::to_string(b.first_id) + ".." +
          std::to_string(b.first_id + b.NumTags() - 1) + " row-major from the top left",
      "tag " + FormatNumber(b.tag_size, 8) + " mm (black square), gap " + FormatNumber(b.tag_gap, 8) +
          " mm, pitch " + FormatNumber(b.tag_size + b.tag_gap, 8) + " mm",
      "Print at 100 % (no \"fit to page\"); the line above must measure 100.0 mm, else use the measured sizes."};
}

// Width of the widest caption line [mm].
double CaptionWidthMm(const TagBoard& board) {
  cairo_surface_t* s = cairo_image_surface_create(CAIRO_FORMAT_A8, 1, 1);
  cairo_t* cr = cairo_create(s);
  cairo_select_font_face(cr, kFont, CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, kFontMm);
  double width = 0.0;
  for (const std::string& line : CaptionLines(board)) {
    cairo_text_extents_t e;
    cairo_text_extents(cr, line.c_str(), &e);
    width = std::max(width, e.x_advance);
  }
  cairo_destroy(cr);
  cairo_surface_destroy(s);
  return width;
}

Status CheckBoard(const TagBoard& board) {
  OPL_RETURN_IF_ERROR(board.Validate());
  if (board.tag_gap < Cell(board) * (1.0 - 1e-9) && (board.columns > 1 || board.rows > 1)) {
    return Status::InvalidArgument("the gap between tags (" + FormatNumber(board.tag_gap) +
                                   " mm) must be at least one tag cell (tag size / 8 = " +
                                   FormatNumber(Cell(board)) + " mm): each tag needs a white quiet zone");
  }
  return Status::Ok();
}

// Draws the page in millimetres (the caller has scaled the context).
void DrawPage(cairo_t* cr, const TagBoard& board, const BoardPrintLayout& layout) {
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_rectangle(cr, 0, 0, layout.page_width_mm, layout.page_height_mm);
  cairo_fill(cr);
  // Every black cell of every tag in one path: no seams between cells.
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_fill_rule(cr, CAIRO_FILL_RULE_WINDING);
  const double cell = Cell(board), pitch = board.tag_size + board.tag_gap;
  for (int k = 0; k < board.NumTags(); ++k) {
    const int r = k / board.columns, c = k % board.columns;
    Result<cv::Mat> tex = MakeTag36h11Texture(board.first_id + k, 0);
    if (!tex.ok()) continue;  // ids validated by CheckBoard
    const double x0 = layout.board_x_mm + c * pitch, y0 = layout.board_y_mm + r * pitch;
    for (int i = 0; i < tex->rows; ++i) {
      for (int j = 0; j < tex->cols; ++j) {
        if (tex->at<uint8_t>(i, j) < 128) cairo_rectangle(cr, x0 + j * cell, y0 + i * cell, cell, cell);
      }
    }
  }
  cairo_fill(cr);
  // The scale check line: 100 mm, end ticks, 10 mm ticks.
  const double x = layout.board_x_mm, y = layout.scale_line_y_mm;
  cairo_set_line_width(cr, 0.25);
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_BUTT);
  cairo_move_to(cr, x, y);
  cairo_line_to(cr, x + kScaleMm, y);
  for (int t = 0; t <= 10; ++t) {
    const double h = (t == 0 || t == 10) ? 3.0 : (t == 5 ? 2.0 : 1.2);
    cairo_move_to(cr, x + 10.0 * t, y - h);
    cairo_line_to(cr, x + 10.0 * t, y);
  }
  cairo_stroke(cr);
  cairo_select_font_face(cr, kFont, CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, kFontMm);
  cairo_move_to(cr, x + kScaleMm + 3.0, y + 0.5 * kFontMm - 0.3);
  cairo_show_text(cr, "100 mm");
  const std::vector<std::string> lines = CaptionLines(board);
  for (size_t k = 0; k < lines.size(); ++k) {
    cairo_move_to(cr, x, y + 7.0 + kLineMm * static_cast<double>(k));
    cairo_show_text(cr, lines[k].c_str());
  }
}

cairo_status_t AppendBytes(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

uint32_t Crc32(const std::string& bytes) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t n = 0; n < 256; ++n) {
      uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

void AppendBigEndian(std::string* out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out->push_back(static_cast<char>((v >> s) & 0xFFu));
}

// Inserts a pHYs chunk (pixels per metre) after the IHDR chunk of a PNG.
std::string WithPhys(const std::string& png, double dpi) {
  const size_t ihdr_end = 8 + 4 + 4 + 13 + 4;  // signature, length, type, data, CRC
  if (png.size() < ihdr_end || png.compare(12, 4, "IHDR") != 0) return png;
  const uint32_t ppm = static_cast<uint32_t>(std::lround(dpi / 0.0254));
  std::string chunk = "pHYs";
  AppendBigEndian(&chunk, ppm);
  AppendBigEndian(&chunk, ppm);
  chunk.push_back(1);  // unit: metre
  std::string out = png.substr(0, ihdr_end);
  AppendBigEndian(&out, 9);
  out += chunk;
  AppendBigEndian(&out, Crc32(chunk));
  out += png.substr(ihdr_end);
  return out;
}

}  // namespace

Status BoardPrintOptions::Validate() const {
  if (!(margin_mm >= 5.0 && margin_mm <= 500.0)) {
    return Status::InvalidArgument("BoardPrintOptions.margin_mm = " + FormatNumber(margin_mm) +
                                   ": must be in [5, 500] mm");
  }
  if (page != "fit" && page != "a4" && page != "a3" && page != "letter") {
    return Status::InvalidArgument("BoardPrintOptions.page = '" + page + "': must be fit, a4, a3 or letter");
  }
  if (!(dpi >= 50.0 && dpi <= 2400.0)) {
    return Status::InvalidArgument("BoardPrintOptions.dpi = " + FormatNumber(dpi) + ": must be in [50, 2400]");
  }
  return Status::Ok();
}

Result<BoardPrintLayout> LayOutBoardPrint(const TagBoard& board, const BoardPrintOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(CheckBoard(board));
  if (options.margin_mm < 2.0 * Cell(board) * (1.0 - 1e-9)) {
    return Status::InvalidArgument("the margin (" + FormatNumber(options.margin_mm) +
                                   " mm) must be at least two tag cells (" + FormatNumber(2.0 * Cell(board)) +
                                   " mm): the outer tags need a white quiet zone");
  }
  BoardPrintLayout l;
  const double m = options.margin_mm;
  l.board_x_mm = m;
  l.board_y_mm = m;
  const double below = std::max(2.0 * Cell(board), 6.0) + 3.0;
  l.scale_line_y_mm = m + GridHeight(board) + below;
  const double caption_w = std::max(kScaleMm + 18.0, CaptionWidthMm(board));
  const double need_w = std::max(GridWidth(board), caption_w) + 2.0 * m;
  const double need_h = l.scale_line_y_mm + 7.0 + 2.0 * kLineMm + 10.0;
  if (options.page == "fit") {
    l.page_width_mm = need_w;
    l.page_height_mm = need_h;
  } else {
    const double w = options.page == "a4" ? 210.0 : options.page == "a3" ? 297.0 : 215.9;
    const double h = options.page == "a4" ? 297.0 : options.page == "a3" ? 420.0 : 279.4;
    if (need_w <= w && need_h <= h) {
      l.page_width_mm = w;
      l.page_height_mm = h;
    } else if (need_w <= h && need_h <= w) {
      l.page_width_mm = h;
      l.page_height_mm = w;
    } else {
      return Status::InvalidArgument("the board with its margins and caption (" + FormatPrintf("%.1f", need_w) +
                                     " x " + FormatPrintf("%.1f", need_h) + " mm) does not fit on " + options.page +
                                     " (" + FormatNumber(w) + " x " + FormatNumber(h) + " mm)");
    }
  }
  const double px_per_mm = options.dpi / kMmPerInch;
  const double wpx = std::round(l.page_width_mm * px_per_mm), hpx = std::round(l.page_height_mm * px_per_mm);
  if (wpx > kMaxPngSidePx || hpx > kMaxPngSidePx) {
    return Status::InvalidArgument("at " + FormatNumber(options.dpi) + " dpi the page would be " +
                                   FormatNumber(wpx) + " x " + FormatNumber(hpx) + " px, beyond " +
                                   std::to_string(kMaxPngSidePx) + " px a side: lower the dpi");
  }
  l.png_width_px = static_cast<int>(wpx);
  l.png_height_px = static_cast<int>(hpx);
  return l;
}

Result<std::string> RenderBoardPdf(const TagBoard& board, const BoardPrintOptions& options) {
  Result<BoardPrintLayout> layout = LayOutBoardPrint(board, options);
  if (!layout.ok()) return layout.status();
  std::string bytes;
  cairo_surface_t* surface = cairo_pdf_surface_create_for_stream(
      AppendBytes, &bytes, layout->page_width_mm * kPointsPerMm, layout->page_height_mm * kPointsPerMm);
  cairo_pdf_surface_set_metadata(surface, CAIRO_PDF_METADATA_TITLE, "OPL calibration board");
  cairo_pdf_surface_set_metadata(
      surface, CAIRO_PDF_METADATA_CREATOR,
      options.pdf_creator.empty() ? "opl_camera board" : options.pdf_creator.c_str());
  if (!options.pdf_subject.empty()) {
    cairo_pdf_surface_set_metadata(surface, CAIRO_PDF_METADATA_SUBJECT, options.pdf_subject.c_str());
  }
  cairo_t* cr = cairo_create(surface);
  cairo_scale(cr, kPointsPerMm, kPointsPerMm);
  DrawPage(cr, board, *layout);
  cairo_show_page(cr);
  const cairo_status_t draw_status = cairo_status(cr);
  cairo_destroy(cr);
  cairo_surface_finish(surface);
  const cairo_status_t status = cairo_surface_status(surface);
  cairo_surface_destroy(surface);
  if (draw_status != CAIRO_STATUS_SUCCESS || status != CAIRO_STATUS_SUCCESS) {
    return Status::IoError(std::string("cairo could not draw the PDF: ") +
                           cairo_status_to_string(draw_status != CAIRO_STATUS_SUCCESS ? draw_status : status));
  }
  return bytes;
}

Result<std::string> RenderBoardPng(const TagBoard& board, const BoardPrintOptions& options) {
  Result<BoardPrintLayout> layout = LayOutBoardPrint(board, options);
  if (!layout.ok()) return layout.status();
  cairo_surface_t* surface =
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, layout->png_width_px, layout->png_height_px);
  if (cairo_surface_status(surface) != CAIRO_STATUS_SUCCESS) {
    cairo_surface_destroy(surface);
    return Status::IoError("cairo could not allocate a " + std::to_string(layout->png_width_px) + " x " +
                           std::to_string(layout->png_height_px) + " image");
  }
  cairo_t* cr = cairo_create(surface);
  const double px_per_mm = options.dpi / kMmPerInch;
  cairo_scale(cr, px_per_mm, px_per_mm);
  DrawPage(cr, board, *layout);
  cairo_destroy(cr);
  cairo_surface_flush(surface);
  // RGB24 is 32 bits per pixel (xRGB, native endian); grey = the blue byte
  // (every colour drawn is grey).
  const int stride = cairo_image_surface_get_stride(surface);
  const unsigned char* data = cairo_image_surface_get_data(surface);
  cv::Mat grey(layout->png_height_px, layout->png_width_px, CV_8UC1);
  for (int r = 0; r < grey.rows; ++r) {
    const uint32_t* row = reinterpret_cast<const uint32_t*>(data + static_cast<size_t>(r) * stride);
    for (int c = 0; c < grey.cols; ++c) grey.at<uint8_t>(r, c) = static_cast<uint8_t>(row[c] & 0xFFu);
  }
  cairo_surface_destroy(surface);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", grey, png)) return Status::IoError("could not encode the board PNG");
  return WithPhys(std::string(png.begin(), png.end()), options.dpi);
}

}  // namespace opl
