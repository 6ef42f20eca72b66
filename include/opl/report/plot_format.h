// The file formats of OPL's report figures (line plots, grid heat maps) and
// how a figure's file name picks one.
//
// Figures are drawn once with cairo and written as
//   .png  an 8-bit RGB raster, 1 px per layout pixel (the layouts' PixelRect
//         coordinates are its pixels); its provenance is stamped afterwards
//         as PNG text chunks (io/provenance_stamp.h);
//   .svg  a vector drawing in the same pixel units (width="640px"); text is
//         drawn as glyph outlines, so the document also carries the figure's
//         title as its <title> element; provenance: a <metadata> element
//         stamped afterwards (io/provenance_stamp.h);
//   .pdf  one vector page, 1 layout pixel = 1 pt; text stays text
//         (searchable); provenance: the document information dictionary
//         (Title, Creator, Subject), set when the PDF is drawn from
//         PlotMetadata (a PDF cannot be stamped afterwards).
#pragma once

#include <string>

#include "opl/core/status.h"

namespace opl {

enum class PlotFormat { kPng, kSvg, kPdf };

// The format named by the extension of `path` (".png", ".svg" or ".pdf", any
// case). InvalidArgument otherwise, e.g.
//   "out/plot.jpg: a figure must be named .png, .svg or .pdf (got '.jpg')"
Result<PlotFormat> PlotFormatFromPath(const std::string& path);

// "png", "svg" or "pdf".
const char* PlotFormatName(PlotFormat format);

// What a PDF figure says about itself in its document information
// dictionary (ignored for PNG and SVG, which are stamped after rendering).
// Empty fields are left out; the PDF's Title is the figure's title.
struct PlotMetadata {
  std::string creator;  // e.g. "OPL opl_calibrate 0.1.0 (commit ...)"
  std::string subject;  // e.g. the run's provenance JSON (io/provenance.h)
};

}  // namespace opl
