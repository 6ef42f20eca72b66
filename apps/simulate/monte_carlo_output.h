// What `mc` and `sweep` of opl_simulate share: a Monte Carlo run with a
// progress bar, and the --plot figure (checked before any work, staged with
// the run's other outputs).
#pragma once

#include <cstdio>
#include <optional>
#include <string>

#include "cli_common.h"
#include "opl/io/output_set.h"
#include "opl/io/provenance.h"
#include "opl/report/line_plot.h"
#include "progress_bar.h"
#include "simulate/simulate_args.h"

namespace opl {
namespace simulate_cli {

// Runs a Monte Carlo (`run` on `options`) with a progress bar on a terminal
// and warns on stderr about failed iterations. Returns the exit code when the
// run failed.
template <class Options, class Run, class Report>
std::optional<int> RunWithProgress(Options options, const Run& run, Report* report) {
  using namespace opl;
  cli::ProgressBar bar("mc", cli::StderrIsTerminal());
  options.progress = [&bar](int done, int total) { bar.Update(done, total); };
  auto result = run(options);
  bar.Finish();
  if (!result.ok()) return cli::FailInput(kTool, result.status());
  *report = std::move(*result);
  if (report->failed > 0) {
    std::fprintf(stderr, "%s: warning: %d of %d iterations failed and were left out; %s\n",
                 kTool, report->failed, report->iterations, report->first_failure.c_str());
  }
  return std::nullopt;
}

// --plot names a .png, .svg or .pdf (report/plot_format.h), checked before
// any work.
std::optional<int> CheckPlotPath(const std::string& path);

// Renders `plot` in the format its path names and stages it in `outputs`
// with the run's provenance (PNG text chunks and SVG metadata are stamped by
// OutputSet::Add; a PDF carries it in its document metadata). A non-OK
// result is a failure to render (kExitInternalError) or to stage (a write
// error), told apart by *render_failed.
Status StagePlot(const LinePlot& plot, const std::string& path, const Provenance& provenance,
                 OutputSet* outputs, bool* render_failed);

}  // namespace simulate_cli
}  // namespace opl
