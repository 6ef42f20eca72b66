#include "simulate/monte_carlo_output.h"

#include <vector>

#include "opl/io/provenance_stamp.h"
#include "opl/report/plot_format.h"

namespace opl {
namespace simulate_cli {

std::optional<int> CheckPlotPath(const std::string& path) {
  if (path.empty()) return std::nullopt;
  opl::Result<opl::PlotFormat> format = opl::PlotFormatFromPath(path);
  if (!format.ok()) return opl::cli::Fail(kTool, "--plot " + format.status().message(), opl::cli::kExitUsage);
  return std::nullopt;
}

Status StagePlot(const LinePlot& plot, const std::string& path, const Provenance& provenance,
                 OutputSet* outputs, bool* render_failed) {
  *render_failed = false;
  opl::Result<opl::PlotFormat> format = opl::PlotFormatFromPath(path);
  if (!format.ok()) return format.status();
  opl::PlotMetadata metadata;
  metadata.creator = "OPL " + provenance.tool + " " + provenance.version;
  metadata.subject = opl::FormatProvenanceJson(provenance);
  opl::Result<std::vector<unsigned char>> bytes = opl::RenderLinePlot(plot, *format, metadata);
  if (!bytes.ok()) {
    *render_failed = true;
    return bytes.status();
  }
  const std::string data(bytes->begin(), bytes->end());
  return *format == opl::PlotFormat::kPdf ? outputs->AddVerbatim(path, data) : outputs->Add(path, data);
}

}  // namespace simulate_cli
}  // namespace opl
