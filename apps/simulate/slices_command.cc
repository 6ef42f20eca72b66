#include "simulate/commands.h"

#include <optional>
#include <vector>

#include "cli_common.h"
#include "opl/sim/simulate_slices.h"
#include "simulate/spot_simulation.h"

namespace opl {
namespace simulate_cli {
namespace {

int SimulateSlicesCommand(const Args& args) {
  using namespace opl;
  // The syntax of --depths is part of the command line: a usage error.
  ScreenSlicesOptions screen_options;
  if (args.depths_given) {
    Result<std::vector<double>> depths = ParseDepthList(args.depths);
    if (!depths.ok()) {
      return cli::Fail(kTool, "--depths: " + depths.status().message() + " (see --help)",
                       cli::kExitUsage);
    }
    screen_options.depths_mm = std::move(*depths);
  }
  screen_options.tilt_deg = args.tilt_deg;
  screen_options.curvature_per_mm = args.curvature_per_mm;

  ModuleDesign design;
  SpotSimulationOptions options;
  if (std::optional<int> code = PrepareSpotSimulation(args, &design, &options)) return *code;

  std::vector<Surface> screens;
  if (!args.depths_given) {
    if (design.surface.type() != SurfaceType::kPlanes) {
      return cli::Fail(kTool,
                       "--depths is required: the design's surface is a " +
                           std::string(design.surface.TypeName()) +
                           ", not a list of planes (see --help)",
                       cli::kExitUsage);
    }
    screens = SlicesOf(design.surface);
  } else {
    if (Status st = screen_options.Validate(); !st.ok()) {
      return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
    }
    Result<std::vector<Surface>> made = MakeCalibrationScreens(design, screen_options);
    if (!made.ok()) return cli::FailInput(kTool, made.status());
    screens = std::move(*made);
  }
  Result<std::vector<SimulatedSpot>> simulated = SimulateSlices(design, screens, options);
  if (!simulated.ok()) return cli::FailInput(kTool, simulated.status());
  return WriteSimulatedSpots(args, *simulated, design, args.out_path,
                             static_cast<int>(screens.size()));
}

}  // namespace

Subcommand AddSlicesCommand(CLI::App& app, Args* args, const std::string& examples) {
  CLI::App* slices = app.add_subcommand(
      "slices",
      "Simulate a calibration session (docs/simulation.md, 'Simulating a calibration\n"
      "session'): the module stays fixed and a screen is placed at several depths; every\n"
      "grid throws its spots on every screen, one grid photographed at a time. Written as\n"
      "the spots CSV of `spots`, ready for opl_calibrate: a slice is one grid on one\n"
      "screen, so source i (design order) on screen k is slice i * K + k (K screens),\n"
      "and a `screen` column after `slice` gives k. Missing spots, outliers and noise are\n"
      "drawn for each screen on its own (seed derived from --seed and k), so --missing\n"
      "0.1 drops 10% of the spots of every screen.\n"
      "\n"
      "Depths (--depths) are in mm, in the design's scene frame, measured from the mean\n"
      "projection origin of the sources along the module's mean viewing direction (the\n"
      "mean of the sources' central beams). For examples/prototype_design.json (sources\n"
      "at y = +-27.5 mm looking along +X) a depth is the scene x of the screen.\n"
      "  --depths 750:65:1335     first:step:last, last included: 750, 815, ..., 1335\n"
      "  --depths 750,815,1000    a comma-separated list\n"
      "Without --depths the design's surface must be a list of planes (\"planes\"):\n"
      "each plane is a slice. --tilt-deg turns screen k about the module's up axis by\n"
      "+A (even k) or -A (odd k) degrees, so neighbouring screens are not parallel;\n"
      "--curvature makes every screen a paraboloid z' = C/2 r'^2 (C > 0: the edges bend\n"
      "towards the module). Either way the point at each depth on the viewing axis stays\n"
      "on its screen.");
  AddDesignAndOut(slices, args, "Spots CSV to write (atomically), with the slice column");
  CLI::Option* depths =
      slices
          ->add_option("--depths", args->depths,
                       "Screen depths, mm: first:step:last or a comma-separated list; required\n"
                       "unless the design's surface is a list of planes")
          ->type_name("LIST");
  slices
      ->add_option("--tilt-deg", args->tilt_deg,
                   "Tilt of the screens about the module's up axis, degrees, |A| < 90,\n"
                   "alternating sign (+A, -A, +A, ...)")
      ->needs(depths)
      ->capture_default_str();
  slices
      ->add_option("--curvature", args->curvature_per_mm,
                   "Curvature of every screen, 1/mm (0: flat); > 0 bends the edges towards\n"
                   "the module")
      ->needs(depths)
      ->capture_default_str();
  AddSpotOptions(slices, args);
  slices->footer(opl::cli::HelpFooter(examples));
  return {slices, [args, depths] {
    args->depths_given = depths->count() > 0;
    return SimulateSlicesCommand(*args);
  }};
}

}  // namespace simulate_cli
}  // namespace opl
