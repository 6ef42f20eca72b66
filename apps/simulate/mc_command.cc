#include "simulate/commands.h"

#include <optional>
#include <string>

#include "cli_common.h"
#include "opl/sim/simulate_slices.h"
#include "opl/uncertainty/calibration_monte_carlo.h"
#include "opl/uncertainty/monte_carlo.h"
#include "opl/uncertainty/monte_carlo_figure.h"
#include "simulate/monte_carlo_output.h"
#include "simulate/spot_simulation.h"

namespace opl {
namespace simulate_cli {
namespace {

int CalibrationMonteCarloCommand(const Args& args, const opl::ModuleDesign& design) {
  using namespace opl;
  CalibrationMonteCarloOptions options;
  options.iterations = args.iterations;
  options.seed = args.spots.seed;
  options.threads = args.threads;
  if (args.depths_given) {
    Result<std::vector<double>> depths = ParseDepthList(args.depths);
    if (!depths.ok()) {
      return cli::Fail(kTool, "--depths: " + depths.status().message() + " (see --help)",
                       cli::kExitUsage);
    }
    options.screens.depths_mm = std::move(*depths);
  }
  options.screens.tilt_deg = args.tilt_deg;
  options.screens.curvature_per_mm = args.curvature_per_mm;
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
  }
  CalibrationMonteCarloReport report;
  if (std::optional<int> code = RunWithProgress(
          options,
          [&design](const CalibrationMonteCarloOptions& o) {
            return RunCalibrationMonteCarlo(design, o);
          },
          &report)) {
    return *code;
  }
  return args.json ? cli::PrintJsonToStdout(kTool, report.ToJson(), args.provenance)
                   : cli::PrintToStdout(kTool, report.ToText());
}

int MonteCarloCommand(const Args& args) {
  using namespace opl;
  if (std::optional<int> code = CheckPlotPath(args.plot_path)) return *code;
  ModuleDesign design;
  SpotSimulationOptions unused;
  if (std::optional<int> code = PrepareSpotSimulation(args, &design, &unused)) return *code;
  if (args.calibration) {
    if (args.weighting != "efficient") {
      return cli::Fail(kTool, "--weighting applies to a measurement, not to --calibration",
                       cli::kExitUsage);
    }
    if (!args.plot_path.empty() || args.samples) {
      return cli::Fail(kTool, "--plot and --samples apply to a measurement, not to --calibration",
                       cli::kExitUsage);
    }
    return CalibrationMonteCarloCommand(args, design);
  }
  if (args.depths_given || args.tilt_deg != 0.0 || args.curvature_per_mm != 0.0) {
    return cli::Fail(kTool, "--depths, --tilt-deg and --curvature need --calibration",
                     cli::kExitUsage);
  }
  MonteCarloOptions options;
  options.iterations = args.iterations;
  options.seed = args.spots.seed;
  options.threads = args.threads;
  Result<SpotWeighting> weighting = ParseSpotWeighting(args.weighting);
  if (!weighting.ok()) {
    return cli::Fail(kTool, "--weighting: " + weighting.status().message(), cli::kExitUsage);
  }
  options.weighting = *weighting;
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: --" + st.message(), cli::kExitBadInput);
  }
  MonteCarloReport report;
  if (std::optional<int> code = RunWithProgress(
          options,
          [&design](const MonteCarloOptions& o) { return RunMeasurementMonteCarlo(design, o); },
          &report)) {
    return *code;
  }
  // The figure is the run's one file: rendered, then written atomically
  // (io/output_set.h), before anything is printed; on any error nothing is
  // written and nothing printed.
  if (!args.plot_path.empty()) {
    OutputSet outputs(args.provenance);
    bool render_failed = false;
    if (Status st = StagePlot(MonteCarloFigure(report), args.plot_path, args.provenance, &outputs, &render_failed);
        !st.ok()) {
      return render_failed ? cli::Fail(kTool, "plot: " + st.message(), cli::kExitInternalError)
                           : cli::FailWrite(kTool, st);
    }
    if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);
  }
  return args.json ? cli::PrintJsonToStdout(kTool, report.ToJson(args.samples), args.provenance)
                   : cli::PrintToStdout(kTool, report.ToText());
}

}  // namespace

Subcommand AddMonteCarloCommand(CLI::App& app, Args* args) {
  CLI::App* mc = app.add_subcommand(
      "mc",
      "Monte Carlo uncertainty of a measurement (JCGM 101, GUM Supplement 1;\n"
      "docs/uncertainty.md). The design's surface is the scene and its exact calibration\n"
      "the calibration (so s = 1 on average). Every iteration adds the design's spot noise\n"
      "(spot_noise_mm, times --noise-scale) to the noise-free spots of every source,\n"
      "locates every source and computes every length L between origins (mm, the design's\n"
      "frame) and the scale factor s, as opl_measure would. Printed on stdout:\n"
      "  - per length: mean, standard deviation and 95 % coverage interval of L;\n"
      "  - s: mean, standard deviation (ppm), 95 % coverage interval;\n"
      "  - per source: mean and standard deviation of the origin (x, y, z) and of the\n"
      "    pose angles (R = Rx Ry Rz);\n"
      "each next to the first-order prediction (the covariance the locate and scale\n"
      "solves report for the noise-free spots carrying the design's noise) and the\n"
      "Cramer-Rao bound (the least covariance any unbiased estimator can reach for that\n"
      "noise, docs/uncertainty.md), with the ratios MC/FO and MC/CRB. Coverage\n"
      "intervals are the probabilistically symmetric ones of JCGM 101 7.7.1 (the\n"
      "shortest, 7.7.2, is also in the JSON). Use at least a few thousand iterations\n"
      "for a stable 95 % interval. --plot draws the histograms of L and s against the\n"
      "first-order normal density with both 95 % intervals (the one to look at: is the\n"
      "output normal, unbiased, as wide as predicted?); --json --samples adds every\n"
      "iteration's values to the JSON.\n"
      "\n"
      "The run uses --threads cores (default: all); the result depends only on the design,\n"
      "--iterations and --seed, never on the thread count. A progress bar is drawn on\n"
      "stderr when stderr is a terminal. Iterations whose locate fails are counted and\n"
      "reported, not fatal, unless all fail (exit 4).");
  mc->add_option("--design", args->design_path,
                 "Module design JSON (docs/simulation.md, 'Module design JSON'); its surface is\n"
                 "the measurement scene")
      ->required()
      ->type_name("FILE");
  mc->add_option("--iterations", args->iterations,
                 "Number of Monte Carlo trials M, 1 to 10000000")
      ->required()
      ->check(opl::cli::MonteCarloIterationsValidator())
      ->type_name("N");
  mc->add_option("--seed", args->spots.seed,
                 "Seed, 0 to 2^64 - 1; iteration i draws from a seed derived from it and i, so\n"
                 "the same seed gives the same report whatever --threads")
      ->check(opl::cli::SeedValidator())
      ->capture_default_str();
  mc->add_option("--threads", args->threads, "Worker threads, >= 0; 0 = every core")
      ->capture_default_str();
  mc->add_option("--noise-scale", args->noise_scale,
                 "Multiplies the design's spot noise (spot_noise_mm), > 0")
      ->capture_default_str();
  mc->add_option("--weighting", args->weighting,
                 "How each locate weights its spots: 'efficient' (each spot's covariance carried\n"
                 "into its angular residuals, as opl_measure does with sx, sy, sz) or 'unweighted'\n"
                 "(plain angular residuals, as for spots without sigmas)")
      ->capture_default_str()
      ->type_name("W");
  mc->add_flag("--calibration", args->calibration,
               "Monte Carlo of a calibration session instead of a measurement: the screens of\n"
               "`slices` (--depths, --tilt-deg, --curvature), every iteration a noisy session\n"
               "calibrated with opl_calibrate's solver: the spread of every origin, pose, beam\n"
               "direction and separation against the calibration's own uncertainty");
  CLI::Option* mc_depths =
      mc->add_option("--depths", args->depths,
                     "With --calibration: the screen depths, mm (default 750:65:1335)")
          ->type_name("LIST");
  mc->add_option("--tilt-deg", args->tilt_deg, "With --calibration: screen tilt, degrees (see slices)")
      ->capture_default_str();
  mc->add_option("--curvature", args->curvature_per_mm,
                 "With --calibration: screen curvature, 1/mm (see slices)")
      ->capture_default_str();
  CLI::Option* mc_json =
      mc->add_flag("--json", args->json,
                   "Write one JSON object (format opl.monte_carlo_report, docs/uncertainty.md)\n"
                   "instead of the text summary");
  mc->add_flag("--samples", args->samples,
               "With --json: the values of every successful iteration too (sample_iterations;\n"
               "per length samples_mm, scale_factor.samples, per source origin_samples_mm and\n"
               "rotation_samples_rad), in iteration order; about 200 bytes per iteration\n"
               "with two sources")
      ->needs(mc_json);
  mc->add_option("--plot", args->plot_path,
                 "Figure to write, .png, .svg or .pdf (atomically; before anything is printed,\n"
                 "nothing on an error): per length L (the first three) and for s - 1\n"
                 "(ppm) the histogram of the Monte Carlo values (Freedman-Diaconis bins,\n"
                 "10 to 100), the first-order normal density scaled to counts, and the 95 %\n"
                 "coverage intervals: the Monte Carlo's (JCGM 101 7.7.1) and first order\n"
                 "+-1.96 u (dashed)")
      ->type_name("FILE.png|svg|pdf");
  const std::string mc_examples =
      "  opl_simulate mc --design examples/staggered_design.json --iterations 5000\n"
      "  opl_simulate mc --design examples/staggered_design.json --iterations 5000 --seed 7 \\\n"
      "      --threads 2 --json > mc.json\n"
      "  opl_simulate mc --design examples/staggered_design.json --iterations 5000 \\\n"
      "      --plot mc.png --json --samples > mc_samples.json\n"
      "  opl_simulate mc --design examples/prototype_design.json --iterations 2000 --noise-scale 2\n"
      "  opl_simulate mc --design examples/anisotropic_design.json --iterations 2000 \\\n"
      "      --weighting unweighted\n"
      "  opl_simulate mc --design examples/prototype_design.json --iterations 500 --calibration \\\n"
      "      --depths 750:65:1335\n";
  mc->footer(opl::cli::HelpFooter(mc_examples));
  return {mc, [args, mc_depths] {
    args->depths_given = mc_depths->count() > 0;
    return MonteCarloCommand(*args);
  }};
}

}  // namespace simulate_cli
}  // namespace opl
