// Internal to src/report: the cairo drawing surface shared by the line plots
// and the grid heat maps, and the text measurement their layouts use.
//
// Coordinates are layout pixels (x right, y down) with INTEGER PIXEL CENTRES,
// as the layouts' PixelRect and LinePlotPanelLayout::PixelX/Y: the canvas
// shifts cairo's user space by half a pixel, so a 1 px line drawn at y = 12
// fills image row 12 exactly, and FillPixels({x, y, w, h}) fills columns
// x..x+w-1 and rows y..y+h-1. Text is DejaVu Sans (fontconfig falls back to
// another sans face when it is missing) with hinted metrics off, so a string
// measures the same on every surface and in TextMeter: what a layout
// measured is what gets drawn.
#pragma once

#include <cairo.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/report/grid_heatmap.h"  // PixelRect
#include "opl/report/plot_format.h"

namespace opl::plot_internal {

struct Rgb {
  double r = 0, g = 0, b = 0;  // 0..1
};
constexpr Rgb Rgb8(int r, int g, int b) { return Rgb{r / 255.0, g / 255.0, b / 255.0}; }

struct Font {
  double size_px = 12;  // the em size
  bool bold = false;
};

// A line of text: its advance width and, for placing it, the heights of the
// font's capitals above the baseline and of its descenders below (the same
// for every string of one font, so baselines line up).
struct TextBox {
  double width = 0;
  double height = 0;    // cap height above the baseline
  double baseline = 0;  // descender depth below the baseline
};

// Text measurement without a drawing (for layouts).
class TextMeter {
 public:
  TextMeter();
  ~TextMeter();
  TextMeter(const TextMeter&) = delete;
  TextMeter& operator=(const TextMeter&) = delete;

  TextBox Measure(const std::string& text, Font font) const;
  // `text` shrunk (down to `min_size_px`) and if need be cut with "..."
  // until it is at most `max_width` px wide; the font it fits in.
  std::pair<std::string, Font> Fit(const std::string& text, Font font, double max_width,
                                   double min_size_px) const;

 private:
  cairo_surface_t* surface_ = nullptr;
  cairo_t* cr_ = nullptr;
};

enum class Align { kLeft, kCentre, kRight };

// One figure being drawn on a PNG, SVG or PDF surface.
class PlotCanvas {
 public:
  // A white `width` x `height` px canvas. `title` becomes the SVG <title>
  // and the PDF Title. IoError "<what>: cannot create the <format> surface:
  // <cairo's reason>".
  static Result<std::unique_ptr<PlotCanvas>> Create(PlotFormat format, int width, int height,
                                                    const std::string& title,
                                                    const PlotMetadata& metadata,
                                                    const std::string& what);
  ~PlotCanvas();
  PlotCanvas(const PlotCanvas&) = delete;
  PlotCanvas& operator=(const PlotCanvas&) = delete;

  cairo_t* cr() const { return cr_; }
  void SetColour(Rgb c) const;
  void FillPixels(const PixelRect& r, Rgb c) const;
  // 1 px line through pixel centres, crisp: from (x0, y0) to (x1, y1), both
  // ends included.
  void PixelLine(int x0, int y0, int x1, int y1, Rgb c) const;
  // The 1 px outline just outside `r` (its pixels are left alone).
  void FrameAround(const PixelRect& r, Rgb c) const;
  // Clip to the pixels of `r` until the matching Unclip().
  void ClipTo(const PixelRect& r) const;
  void Unclip() const;

  // Text on a baseline, aligned at x.
  void Text(const std::string& text, double x, double baseline, Font font, Rgb c,
            Align align = Align::kLeft) const;
  // Text rotated 90 degrees counter-clockwise (reads bottom-up): the top of
  // its letters faces left; `left` is where the cap tops are, the text
  // centred on `centre_y`.
  void TextUp(const std::string& text, double left, double centre_y, Font font, Rgb c) const;

  // Ends the drawing and returns the file's bytes. IoError naming `what`
  // when cairo failed (out of memory).
  Result<std::vector<unsigned char>> Finish();

 private:
  PlotCanvas() = default;
  PlotFormat format_ = PlotFormat::kPng;
  std::string what_;
  std::string title_;
  std::string stream_;  // SVG and PDF bytes as cairo writes them
  cairo_surface_t* surface_ = nullptr;
  cairo_t* cr_ = nullptr;
  TextMeter meter_;
};

}  // namespace opl::plot_internal
