#include "simulate/commands.h"

#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "opl/io/module_design_json.h"
#include "opl/uncertainty/design_sweep.h"
#include "simulate/monte_carlo_output.h"

namespace opl {
namespace simulate_cli {
namespace {

int SweepCommand(const Args& args) {
  using namespace opl;
  if (std::optional<int> code = CheckPlotPath(args.plot_path)) return *code;
  Result<SweepParameter> parameter = ParseSweepParameter(args.param);
  if (!parameter.ok()) return cli::Fail(kTool, "--param: " + parameter.status().message(), cli::kExitUsage);
  if (args.log_x && IsCategoricalSweep(*parameter)) {
    return cli::Fail(kTool, "--log-x: --param " + args.param + " has named values, not a numeric axis",
                     cli::kExitUsage);
  }
  Result<std::vector<double>> values = ParseSweepValues(args.param, args.values);
  if (!values.ok()) return cli::Fail(kTool, "--values: " + values.status().message(), cli::kExitUsage);
  Result<SpotWeighting> weighting = ParseSpotWeighting(args.weighting);
  if (!weighting.ok()) {
    return cli::Fail(kTool, "--weighting: " + weighting.status().message(), cli::kExitUsage);
  }
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  MonteCarloOptions options;
  options.iterations = args.iterations;
  options.seed = args.spots.seed;
  options.threads = args.threads;
  options.weighting = *weighting;
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: --" + st.message(), cli::kExitBadInput);
  }
  // Every value is checked before the first Monte Carlo runs.
  for (double value : *values) {
    Result<ModuleDesign> changed = ApplySweepValue(*design, *parameter, value);
    if (!changed.ok()) return cli::FailInput(kTool, changed.status());
  }
  cli::ProgressBar bar("sweep", cli::StderrIsTerminal());
  options.progress = [&bar](int done, int total) { bar.Update(done, total); };
  Result<DesignSweep> sweep = RunDesignSweep(*design, *parameter, *values, options);
  bar.Finish();
  if (!sweep.ok()) return cli::FailInput(kTool, sweep.status());

  // Both outputs are made before either is written.
  const std::string csv = sweep->ToCsv();
  // Both or neither (io/output_set.h).
  OutputSet outputs(args.provenance);
  if (Status st = outputs.Add(args.out_path, csv); !st.ok()) return cli::FailWrite(kTool, st);
  if (!args.plot_path.empty()) {
    LinePlot plot = sweep->ToPlot();
    for (PlotPanel& panel : plot.panels) {
      panel.log_x = args.log_x;
      panel.log_y = args.log_y;
    }
    bool render_failed = false;
    if (Status st = StagePlot(plot, args.plot_path, args.provenance, &outputs, &render_failed); !st.ok()) {
      return render_failed ? cli::Fail(kTool, "plot: " + st.message(), cli::kExitInternalError)
                           : cli::FailWrite(kTool, st);
    }
  }
  if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);

  char line[256];
  std::snprintf(line, sizeof(line), "%-16s %-7s %12s %12s %12s %7s %13s %6s\n",
                SweepParameterName(*parameter), "L", "std MC (mm)", "FO (mm)", "CRB (mm)",
                "MC/CRB", "u(L)/L (ppm)", "failed");
  std::string table = line;
  for (const DesignSweepPoint& p : sweep->points) {
    for (const MonteCarloLength& l : p.report.lengths) {
      const SampleSummary& s = l.photo_mm;
      std::snprintf(line, sizeof(line), "%-16s %-7s %12.5f %12.5f %12.5f %7.3f %13.0f %6d\n",
                    SweepValueText(*parameter, p.value).c_str(), (l.from + "-" + l.to).c_str(), s.std_dev, s.first_order_std,
                    s.cramer_rao_std, s.cramer_rao_std > 0 ? s.std_dev / s.cramer_rao_std : 0.0,
                    1e6 * s.std_dev / l.true_mm, p.report.failed);
      table += line;
    }
  }
  return cli::PrintToStdout(kTool, table);
}

}  // namespace

Subcommand AddSweepCommand(CLI::App& app, Args* args) {
  CLI::App* sweep = app.add_subcommand(
      "sweep",
      "Design study (docs/uncertainty.md, 'Design sweeps'): how the uncertainty of every\n"
      "length L moves with one design parameter. For every value the design is changed in\n"
      "that parameter alone and a measurement Monte Carlo of it runs (as `mc`, the same\n"
      "seed at every value, so neighbouring points differ by the design, not by the draw),\n"
      "with its first-order prediction and Cramer-Rao bound. Writes a CSV (one row per\n"
      "value and length) and, with --plot, a PNG: std of L (mm) and u(L)/L (ppm) against\n"
      "the parameter. Prints a table.\n"
      "\n"
      "Parameters (every source alike):\n"
      "  noise_mm        largest per-axis spot noise sigma, mm (the other axes keep their ratio)\n"
      "  full_angle_deg  full fan angle of every pattern, deg\n"
      "  beams_per_side  n of every pattern (odd)\n"
      "  separation_mm   distance of the first two origins, mm (origins scaled about their\n"
      "                  centroid)\n"
      "  distance_mm     projection distance, mm (the surface moved along the viewing direction)\n"
      "  stagger_deg     layout of two sources: the baseline turned from across (0, side by\n"
      "                  side) towards the viewing direction (45 staggered, 90 in line)\n"
      "  layout          the designs of stagger_deg 0 and 45, named side_by_side and\n"
      "                  staggered: categorical (plotted at 1, 2, ... as markers only)");
  sweep->add_option("--design", args->design_path, "Module design JSON: the base design")
      ->required()
      ->type_name("FILE");
  sweep->add_option("--param", args->param, "The parameter swept (see above)")->required()->type_name("P");
  sweep->add_option("--values", args->values,
                    "Its values: first:step:last (last included) or a comma-separated list")
      ->required()
      ->type_name("LIST");
  sweep->add_option("--out", args->out_path, "Sweep CSV to write (atomically)")->required()->type_name("FILE");
  sweep->add_option("--plot", args->plot_path,
                    "Plot to write, .png, .svg or .pdf (atomically, with the CSV or not at all):\n"
                    "Monte Carlo markers with error bars, first order (solid line with markers),\n"
                    "Cramer-Rao bound (dashed over it); layout: markers only, at ticks named\n"
                    "by the layouts")
      ->type_name("FILE.png|svg|pdf");
  sweep->add_flag("--log-x", args->log_x, "Logarithmic parameter axis in the plot (not for layout)");
  sweep->add_flag("--log-y", args->log_y,
                  "Logarithmic uncertainty axes in the plot (a power law is a straight line)");
  args->iterations = 1000;
  sweep->add_option("--iterations", args->iterations,
                    "Monte Carlo trials per value, 1 to 10000000")
      ->check(opl::cli::MonteCarloIterationsValidator())
      ->capture_default_str()
      ->type_name("N");
  sweep->add_option("--seed", args->spots.seed, "Seed, 0 to 2^64 - 1 (the same at every value)")
      ->check(opl::cli::SeedValidator())
      ->capture_default_str();
  sweep->add_option("--threads", args->threads, "Worker threads, >= 0; 0 = every core")
      ->capture_default_str();
  sweep->add_option("--weighting", args->weighting, "efficient or unweighted (see `mc`)")
      ->capture_default_str()
      ->type_name("W");
  const std::string sweep_examples =
      "  opl_simulate sweep --design examples/staggered_design.json --param noise_mm \\\n"
      "      --values 0.05:0.05:0.3 --out noise.csv --plot noise.png\n"
      "  opl_simulate sweep --design examples/staggered_design.json --param full_angle_deg \\\n"
      "      --values 10:5:45 --iterations 2000 --out angle.csv --plot angle.png --log-x --log-y\n"
      "  opl_simulate sweep --design examples/prototype_design.json --param layout \\\n"
      "      --values side_by_side,staggered --out layout.csv\n";
  sweep->footer(opl::cli::HelpFooter(sweep_examples));
  return {sweep, [args] { return SweepCommand(*args); }};
}

}  // namespace simulate_cli
}  // namespace opl
