// opl_simulate: simulated data of a module design (docs/cli.md).
//   opl_simulate spots --design D.json --out spots.csv [--seed S] [--missing F]
//                      [--outliers F] [--outlier-distance MM] [--noise-scale F]
//   opl_simulate slices --design D.json --out slices.csv [--depths LIST]
//                      [--tilt-deg A] [--curvature C] [the options of spots]
//   opl_simulate calibration --design D.json --out cal.json
//   opl_simulate mc --design D.json --iterations N [--seed S] [--threads T]
//                   [--noise-scale F] [--weighting W] [--json [--samples]]
//                   [--plot FIG.png]
//                   [--calibration [--depths LIST] [--tilt-deg A] [--curvature C]]
//   opl_simulate sweep --design D.json --param P --values LIST --out sweep.csv
//                   [--plot sweep.png] [--iterations N] [--seed S] [--threads T]
//                   [--weighting W]
//   opl_simulate images --scene S.json --out DIR [--shots LIST] [--threads T]
// Each subcommand is in its own file (apps/simulate/commands.h); this file
// holds the tool's help, the checks every subcommand shares (no output over
// an input, the run's provenance) and the dispatch. The work is done by
// opl::SimulateSpots, opl::MakeCalibrationScreens, opl::SimulateSlices,
// opl::ExactCalibration (include/opl/sim/), opl::RunMeasurementMonteCarlo,
// opl::MonteCarloFigure, opl::RunDesignSweep (include/opl/uncertainty/),
// opl::RenderLinePlot (include/opl/report/) and opl::SceneRenderer
// (include/opl/lab/render_scene.h).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "simulate/commands.h"
#include "simulate/simulate_args.h"

namespace {

using opl::simulate_cli::kTool;

int Run(int argc, char** argv) {
  opl::simulate_cli::Args args;
  CLI::App app(
      "Simulates the data of an optically projected length scale module from its design\n"
      "(sources, patterns, poses, surface, spot noise): the spots its grids throw on the\n"
      "design's surface, the spots of a calibration session (a screen at several depths),\n"
      "or the exact calibration of the design. A simulated calibration and simulated\n"
      "spots are what opl_measure reads, so the two tools together test a design end to\n"
      "end (with zero noise, opl_measure finds s = 1). `mc` runs the Monte Carlo\n"
      "uncertainty of a measurement (JCGM 101) of the design, `sweep` a design study.\n"
      "`images` renders the camera images of a whole scene (tags and laser spots) with\n"
      "their ground truth, for the image front end.\n",
      kTool);
  app.require_subcommand(1);
  const std::string examples =
      "  opl_simulate calibration --design examples/prototype_design.json --out cal.json\n"
      "  opl_simulate spots --design examples/prototype_design.json --out spots.csv --seed 7 \\\n"
      "      --missing 0.1 --outliers 0.02\n"
      "  opl_simulate spots --design examples/prototype_design.json --out exact.csv --noise-scale 0\n"
      "  opl_measure --calibration cal.json --spots spots.csv\n"
      "  opl_simulate slices --design examples/prototype_design.json --depths 750:65:1335 \\\n"
      "      --out slices.csv --tilt-deg 3 --curvature 2e-5 --missing 0.05 --outliers 0.01\n";
  app.footer(opl::cli::HelpFooter(examples));

  using namespace opl::simulate_cli;
  const std::vector<Subcommand> commands = {
      AddSpotsCommand(app, &args, examples),       AddSlicesCommand(app, &args, examples),
      AddCalibrationCommand(app, &args, examples), AddMonteCarloCommand(app, &args),
      AddSweepCommand(app, &args),                 AddImagesCommand(app, &args)};

  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;
  if (std::optional<int> code = opl::cli::RefuseOutputsOverInputs(
          kTool, {{"--design", args.design_path}, {"--scene", args.scene_path}},
          {{"--out", args.out_path}, {"--plot", args.plot_path}})) {
    return *code;
  }
  {
    // The provenance hashes the inputs that exist (a missing one is its
    // reader's to report, with its own message).
    std::vector<std::string> inputs;
    for (const std::string& path : {args.design_path, args.scene_path}) {
      std::error_code ec;
      if (!path.empty() && std::filesystem::is_regular_file(path, ec)) inputs.push_back(path);
    }
    if (std::optional<int> code =
            opl::cli::MakeRunProvenance(kTool, argc, argv, inputs, &args.provenance)) {
      return *code;
    }
  }
  for (const Subcommand& command : commands) {
    if (command.app->parsed()) return command.run();
  }
  return opl::cli::Fail(kTool, "no subcommand (see --help)", opl::cli::kExitUsage);
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}