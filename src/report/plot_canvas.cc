#include "plot_canvas.h"

#include <cairo-pdf.h>
#include <cairo-svg.h>

#include <algorithm>
#include <cmath>

namespace opl::plot_internal {
namespace {

constexpr const char* kFontFace = "DejaVu Sans";
constexpr double kHalf = 0.5;  // layout pixel centres -> cairo's pixel corners

void SetFont(cairo_t* cr, Font font) {
  cairo_select_font_face(cr, kFontFace, CAIRO_FONT_SLANT_NORMAL,
                         font.bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, font.size_px);
}

// The same glyph metrics on every surface: no hinting of metrics or outlines.
void SetFontOptions(cairo_t* cr) {
  cairo_font_options_t* options = cairo_font_options_create();
  cairo_font_options_set_hint_metrics(options, CAIRO_HINT_METRICS_OFF);
  cairo_font_options_set_hint_style(options, CAIRO_HINT_STYLE_NONE);
  cairo_font_options_set_antialias(options, CAIRO_ANTIALIAS_GRAY);
  cairo_set_font_options(cr, options);
  cairo_font_options_destroy(options);
}

TextBox MeasureOn(cairo_t* cr, const std::string& text, Font font) {
  SetFont(cr, font);
  cairo_text_extents_t e;
  cairo_text_extents(cr, text.c_str(), &e);
  cairo_text_extents_t cap;
  cairo_text_extents(cr, "H", &cap);
  cairo_text_extents_t desc;
  cairo_text_extents(cr, "g", &desc);
  return TextBox{e.x_advance, -cap.y_bearing, desc.y_bearing + desc.height};
}

cairo_status_t Append(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

std::string XmlEscaped(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      default:
        // Control characters are not allowed in XML 1.0.
        out += (static_cast<unsigned char>(c) < 0x20 && c != '\t') ? ' ' : c;
    }
  }
  return out;
}

}  // namespace

TextMeter::TextMeter() {
  surface_ = cairo_image_surface_create(CAIRO_FORMAT_A8, 1, 1);
  cr_ = cairo_create(surface_);
  SetFontOptions(cr_);
}

TextMeter::~TextMeter() {
  cairo_destroy(cr_);
  cairo_surface_destroy(surface_);
}

TextBox TextMeter::Measure(const std::string& text, Font font) const {
  return MeasureOn(cr_, text, font);
}

std::pair<std::string, Font> TextMeter::Fit(const std::string& text, Font font,
                                            double max_width, double min_size_px) const {
  if (text.empty() || max_width <= 0) return {text, font};
  TextBox box = Measure(text, font);
  if (box.width <= max_width) return {text, font};
  font.size_px = std::max(std::min(min_size_px, font.size_px),
                          font.size_px * max_width / box.width * 0.999);
  std::string t = text;
  box = Measure(t, font);
  // Cut whole UTF-8 characters (never a continuation byte) until it fits.
  while (box.width > max_width && t.size() > 1) {
    std::string body = t.size() > 3 && t.compare(t.size() - 3, 3, "...") == 0
                           ? t.substr(0, t.size() - 3)
                           : t;
    if (body.empty()) break;
    size_t cut = body.size() - 1;
    while (cut > 0 && (static_cast<unsigned char>(body[cut]) & 0xC0) == 0x80) --cut;
    if (cut == 0) {
      t = "...";
      break;
    }
    t = body.substr(0, cut) + "...";
    box = Measure(t, font);
  }
  return {t, font};
}

Result<std::unique_ptr<PlotCanvas>> PlotCanvas::Create(PlotFormat format, int width, int height,
                                                       const std::string& title,
                                                       const PlotMetadata& metadata,
                                                       const std::string& what) {
  std::unique_ptr<PlotCanvas> c(new PlotCanvas());
  c->format_ = format;
  c->what_ = what;
  c->title_ = title;
  switch (format) {
    case PlotFormat::kPng:
      c->surface_ = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
      break;
    case PlotFormat::kSvg:
      c->surface_ = cairo_svg_surface_create_for_stream(Append, &c->stream_, width, height);
      cairo_svg_surface_set_document_unit(c->surface_, CAIRO_SVG_UNIT_PX);
      break;
    case PlotFormat::kPdf:
      c->surface_ = cairo_pdf_surface_create_for_stream(Append, &c->stream_, width, height);
      if (!title.empty()) {
        cairo_pdf_surface_set_metadata(c->surface_, CAIRO_PDF_METADATA_TITLE, title.c_str());
      }
      if (!metadata.creator.empty()) {
        cairo_pdf_surface_set_metadata(c->surface_, CAIRO_PDF_METADATA_CREATOR,
                                       metadata.creator.c_str());
      }
      if (!metadata.subject.empty()) {
        cairo_pdf_surface_set_metadata(c->surface_, CAIRO_PDF_METADATA_SUBJECT,
                                       metadata.subject.c_str());
      }
      break;
  }
  if (cairo_surface_status(c->surface_) != CAIRO_STATUS_SUCCESS) {
    return Status::IoError(what + ": cannot create the " + PlotFormatName(format) + " surface (" +
                           std::to_string(width) + " x " + std::to_string(height) +
                           "): " + cairo_status_to_string(cairo_surface_status(c->surface_)));
  }
  c->cr_ = cairo_create(c->surface_);
  SetFontOptions(c->cr_);
  cairo_set_source_rgb(c->cr_, 1, 1, 1);
  cairo_paint(c->cr_);
  cairo_translate(c->cr_, kHalf, kHalf);
  cairo_set_line_cap(c->cr_, CAIRO_LINE_CAP_BUTT);
  cairo_set_line_join(c->cr_, CAIRO_LINE_JOIN_ROUND);
  return c;
}

PlotCanvas::~PlotCanvas() {
  if (cr_ != nullptr) cairo_destroy(cr_);
  if (surface_ != nullptr) cairo_surface_destroy(surface_);
}

void PlotCanvas::SetColour(Rgb c) const { cairo_set_source_rgb(cr_, c.r, c.g, c.b); }

void PlotCanvas::FillPixels(const PixelRect& r, Rgb c) const {
  if (r.width <= 0 || r.height <= 0) return;
  SetColour(c);
  cairo_rectangle(cr_, r.x - kHalf, r.y - kHalf, r.width, r.height);
  cairo_fill(cr_);
}

void PlotCanvas::PixelLine(int x0, int y0, int x1, int y1, Rgb c) const {
  // A 1 px wide rectangle covering both end pixels (horizontal or vertical).
  const int xa = std::min(x0, x1), xb = std::max(x0, x1);
  const int ya = std::min(y0, y1), yb = std::max(y0, y1);
  if (xa == xb || ya == yb) {
    FillPixels(PixelRect{xa, ya, xb - xa + 1, yb - ya + 1}, c);
    return;
  }
  SetColour(c);
  cairo_set_line_width(cr_, 1);
  cairo_move_to(cr_, x0, y0);
  cairo_line_to(cr_, x1, y1);
  cairo_stroke(cr_);
}

void PlotCanvas::FrameAround(const PixelRect& r, Rgb c) const {
  const int x0 = r.x - 1, y0 = r.y - 1, x1 = r.x + r.width, y1 = r.y + r.height;
  PixelLine(x0, y0, x1, y0, c);
  PixelLine(x0, y1, x1, y1, c);
  PixelLine(x0, y0 + 1, x0, y1 - 1, c);
  PixelLine(x1, y0 + 1, x1, y1 - 1, c);
}

void PlotCanvas::ClipTo(const PixelRect& r) const {
  cairo_save(cr_);
  cairo_rectangle(cr_, r.x - kHalf, r.y - kHalf, r.width, r.height);
  cairo_clip(cr_);
}

void PlotCanvas::Unclip() const { cairo_restore(cr_); }

void PlotCanvas::Text(const std::string& text, double x, double baseline, Font font, Rgb c,
                      Align align) const {
  if (text.empty()) return;
  const TextBox box = MeasureOn(cr_, text, font);  // also selects the font
  const double left = align == Align::kLeft     ? x
                      : align == Align::kCentre ? x - 0.5 * box.width
                                                : x - box.width;
  SetColour(c);
  // Text is placed in cairo's own pixel grid (not shifted by half a pixel).
  cairo_move_to(cr_, left - kHalf, baseline + kHalf);
  cairo_show_text(cr_, text.c_str());
  cairo_new_path(cr_);
}

void PlotCanvas::TextUp(const std::string& text, double left, double centre_y, Font font,
                        Rgb c) const {
  if (text.empty()) return;
  const TextBox box = MeasureOn(cr_, text, font);
  cairo_save(cr_);
  cairo_translate(cr_, left + box.height - kHalf, centre_y + 0.5 * box.width + kHalf);
  cairo_rotate(cr_, -M_PI / 2);
  SetColour(c);
  cairo_move_to(cr_, 0, 0);
  cairo_show_text(cr_, text.c_str());
  cairo_new_path(cr_);
  cairo_restore(cr_);
}

Result<std::vector<unsigned char>> PlotCanvas::Finish() {
  const cairo_status_t draw = cairo_status(cr_);
  cairo_destroy(cr_);
  cr_ = nullptr;
  std::string bytes;
  cairo_status_t status = draw;
  if (status == CAIRO_STATUS_SUCCESS) {
    if (format_ == PlotFormat::kPng) {
      cairo_surface_flush(surface_);
      status = cairo_surface_write_to_png_stream(surface_, Append, &bytes);
    } else {
      cairo_surface_finish(surface_);
      status = cairo_surface_status(surface_);
      bytes = std::move(stream_);
    }
  }
  cairo_surface_destroy(surface_);
  surface_ = nullptr;
  if (status != CAIRO_STATUS_SUCCESS) {
    return Status::IoError(what_ + ": cannot render the " + PlotFormatName(format_) + ": " +
                           cairo_status_to_string(status));
  }
  if (format_ == PlotFormat::kSvg && !title_.empty()) {
    // The accessible title (cairo draws text as glyph outlines): the first
    // child of the root element.
    const size_t root = bytes.find("<svg");
    const size_t end = root == std::string::npos ? root : bytes.find('>', root);
    if (end != std::string::npos) {
      bytes.insert(end + 1, "\n<title>" + XmlEscaped(title_) + "</title>");
    }
  }
  return std::vector<unsigned char>(bytes.begin(), bytes.end());
}

}  // namespace opl::plot_internal
