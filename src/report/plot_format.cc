#include "opl/report/plot_format.h"

#include <cctype>

namespace opl {

Result<PlotFormat> PlotFormatFromPath(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  std::string ext;
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) {
    ext = path.substr(dot);
  }
  std::string lower = ext;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == ".png") return PlotFormat::kPng;
  if (lower == ".svg") return PlotFormat::kSvg;
  if (lower == ".pdf") return PlotFormat::kPdf;
  return Status::InvalidArgument(path + ": a figure must be named .png, .svg or .pdf (got " +
                                 (ext.empty() ? std::string("no extension") : "'" + ext + "'") +
                                 ")");
}

const char* PlotFormatName(PlotFormat format) {
  switch (format) {
    case PlotFormat::kPng:
      return "png";
    case PlotFormat::kSvg:
      return "svg";
    case PlotFormat::kPdf:
      return "pdf";
  }
  return "png";
}

}  // namespace opl
