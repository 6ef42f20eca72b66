// opl_simulate: simulated data of a module design (docs/cli.md).
//   opl_simulate spots --design D.json --out spots.csv [--seed S] [--missing F]
//                      [--outliers F] [--outlier-distance MM] [--noise-scale F]
//   opl_simulate calibration --design D.json --out cal.json
// The work is done by opl::SimulateSpots and opl::ExactCalibration
// (include/opl/sim/); this file parses options, reads the design, writes the
// output atomically and maps errors to exit codes.
#include <cmath>
#include <cstdio>
#include <string>

#include "cli_common.h"
#include "opl/io/atomic_file.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/module_design_json.h"
#include "opl/io/spots_csv.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_spots.h"

namespace {

constexpr const char* kTool = "opl_simulate";

struct Args {
  std::string design_path;
  std::string out_path;
  opl::SpotSimulationOptions spots;
  double noise_scale = 1.0;
};

int SimulateSpotsCommand(const Args& args) {
  using namespace opl;
  if (!(std::isfinite(args.noise_scale) && args.noise_scale >= 0.0)) {
    return cli::Fail(kTool, "--noise-scale must be finite and >= 0, got " +
                                std::to_string(args.noise_scale),
                     cli::kExitBadInput);
  }
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  design->spot_noise_mm *= args.noise_scale;

  // A spots CSV carries per-coordinate standard deviations, which must be > 0:
  // attach them only when the noise has a positive variance on every axis.
  SpotSimulationOptions options = args.spots;
  const Eigen::Vector3d variance = design->SpotCovarianceMm2().diagonal();
  options.attach_covariance = (variance.array() > 0.0).all();
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
  }

  Result<std::vector<SimulatedSpot>> simulated = SimulateSpots(*design, options);
  if (!simulated.ok()) return cli::FailInput(kTool, simulated.status());

  // Standard columns, then the simulation's ground truth (ignored by readers).
  SpotsCsvExtraColumn slice{"slice", {}}, outlier{"outlier", {}};
  SpotsCsvExtraColumn true_xyz[3] = {{"true_x", {}}, {"true_y", {}}, {"true_z", {}}};
  for (const SimulatedSpot& s : *simulated) {
    slice.values.push_back(std::to_string(s.slice));
    outlier.values.push_back(s.outlier ? "1" : "0");
    for (int k = 0; k < 3; ++k) {
      char buffer[32];
      std::snprintf(buffer, sizeof(buffer), "%.17g", s.true_point_in_scene[k]);
      true_xyz[k].values.push_back(buffer);
    }
  }
  Result<std::string> csv = FormatSpotsCsv(
      SpotsOf(*simulated), {slice, outlier, true_xyz[0], true_xyz[1], true_xyz[2]});
  if (!csv.ok()) return cli::FailInput(kTool, csv.status());
  if (Status st = WriteFileAtomically(args.out_path, *csv); !st.ok()) {
    return cli::FailWrite(kTool, st);
  }
  return cli::kExitOk;
}

int CalibrationCommand(const Args& args) {
  using namespace opl;
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  Result<ModuleCalibration> calibration = ExactCalibration(*design);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  Result<std::string> json = FormatModuleCalibrationJson(*calibration);
  if (!json.ok()) return cli::FailInput(kTool, json.status());
  if (Status st = WriteFileAtomically(args.out_path, *json); !st.ok()) {
    return cli::FailWrite(kTool, st);
  }
  return cli::kExitOk;
}

void AddDesignAndOut(CLI::App* command, Args* args, const std::string& out_help) {
  command
      ->add_option("--design", args->design_path,
                   "Module design JSON (docs/simulation.md, 'Module design JSON')")
      ->required()
      ->type_name("FILE");
  command->add_option("--out", args->out_path, out_help)->required()->type_name("FILE");
}

int Run(int argc, char** argv) {
  Args args;
  CLI::App app(
      "Simulates the data of an optically projected length scale module from its design\n"
      "(sources, patterns, poses, surface, spot noise): the spots its grids throw on the\n"
      "design's surface, or the exact calibration of the design. A simulated calibration\n"
      "and simulated spots are what opl_measure reads, so the two tools together test a\n"
      "design end to end (with zero noise, opl_measure finds s = 1).\n",
      kTool);
  app.require_subcommand(1);
  const std::string examples =
      "  opl_simulate calibration --design examples/prototype_design.json --out cal.json\n"
      "  opl_simulate spots --design examples/prototype_design.json --out spots.csv --seed 7 \\\n"
      "      --missing 0.1 --outliers 0.02\n"
      "  opl_simulate spots --design examples/prototype_design.json --out exact.csv --noise-scale 0\n"
      "  opl_measure --calibration cal.json --spots spots.csv\n";
  app.footer(opl::cli::HelpFooter(examples));

  CLI::App* spots = app.add_subcommand(
      "spots",
      "Write the simulated spots of every source as a spots CSV: source,beam,x,y,z\n"
      "(mm, the design's scene frame), sx,sy,sz (the noise standard deviations, when\n"
      "> 0 on every axis), then ground truth columns slice,outlier,true_x,true_y,true_z.");
  AddDesignAndOut(spots, &args, "Spots CSV to write (atomically)");
  spots->add_option("--seed", args.spots.seed,
                    "Seed of every random choice; the same seed gives the same spots")
      ->capture_default_str();
  spots->add_option("--missing", args.spots.missing_fraction,
                    "Fraction of the spots dropped, in [0, 1]")
      ->capture_default_str();
  spots->add_option("--outliers", args.spots.outlier_fraction,
                    "Fraction of the kept spots made outliers, in [0, 1]")
      ->capture_default_str();
  spots->add_option("--outlier-distance", args.spots.outlier_distance_mm,
                    "Displacement of an outlier across its beam, mm, > 0")
      ->capture_default_str();
  spots->add_option("--noise-scale", args.noise_scale,
                    "Multiplies the design's spot noise (spot_noise_mm); 0 gives noise-free\n"
                    "spots (written without sx,sy,sz), >= 0")
      ->capture_default_str();
  spots->footer(opl::cli::HelpFooter(examples));

  CLI::App* calibration = app.add_subcommand(
      "calibration",
      "Write the exact (noise-free) module calibration of the design: its patterns, its\n"
      "source poses (the calibration frame is the design's scene frame) and the\n"
      "separations between every pair of origins, with zero uncertainty.");
  AddDesignAndOut(calibration, &args, "Module calibration JSON to write (atomically)");
  calibration->footer(opl::cli::HelpFooter(examples));

  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;
  if (spots->parsed()) return SimulateSpotsCommand(args);
  return CalibrationCommand(args);
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
