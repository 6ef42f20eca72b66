#include "simulate/spot_simulation.h"

#include <cmath>
#include <cstdio>

#include "cli_common.h"
#include "opl/io/module_design_json.h"
#include "opl/io/spots_csv.h"

namespace opl {
namespace simulate_cli {

std::optional<int> PrepareSpotSimulation(const Args& args, opl::ModuleDesign* design,
                                         opl::SpotSimulationOptions* options) {
  using namespace opl;
  if (!(std::isfinite(args.noise_scale) && args.noise_scale >= 0.0)) {
    return cli::Fail(kTool, "--noise-scale must be finite and >= 0, got " +
                                std::to_string(args.noise_scale),
                     cli::kExitBadInput);
  }
  Result<ModuleDesign> read = ReadModuleDesignJson(args.design_path);
  if (!read.ok()) return cli::FailInput(kTool, read.status());
  *design = std::move(*read);
  design->spot_noise_mm *= args.noise_scale;

  // A spots CSV carries per-coordinate standard deviations, which must be > 0:
  // attach them only when the noise has a positive variance on every axis.
  *options = args.spots;
  const Eigen::Vector3d variance = design->SpotCovarianceMm2().diagonal();
  options->attach_covariance = (variance.array() > 0.0).all();
  if (Status st = options->Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
  }
  return std::nullopt;
}

int WriteSimulatedSpots(const Args& args, const std::vector<opl::SimulatedSpot>& simulated,
                        const opl::ModuleDesign& design, const std::string& path,
                        int screens) {
  using namespace opl;
  SpotsCsvExtraColumn slice{"slice", {}}, screen{"screen", {}}, outlier{"outlier", {}};
  SpotsCsvExtraColumn true_xyz[3] = {{"true_x", {}}, {"true_y", {}}, {"true_z", {}}};
  for (const SimulatedSpot& s : simulated) {
    int source_index = 0;
    while (design.sources[source_index].name != s.spot.source) ++source_index;
    slice.values.push_back(std::to_string(screens > 0 ? source_index * screens + s.slice : s.slice));
    screen.values.push_back(std::to_string(s.slice));
    outlier.values.push_back(s.outlier ? "1" : "0");
    for (int k = 0; k < 3; ++k) {
      char buffer[32];
      std::snprintf(buffer, sizeof(buffer), "%.17g", s.true_point_in_scene[k]);
      true_xyz[k].values.push_back(buffer);
    }
  }
  std::vector<SpotsCsvExtraColumn> extra = {slice};
  if (screens > 0) extra.push_back(screen);
  for (const SpotsCsvExtraColumn& c : {outlier, true_xyz[0], true_xyz[1], true_xyz[2]}) {
    extra.push_back(c);
  }
  Result<std::string> csv = FormatSpotsCsv(SpotsOf(simulated), extra);
  if (!csv.ok()) return cli::FailInput(kTool, csv.status());
  if (Status st = WriteStamped(args, path, *csv); !st.ok()) return cli::FailWrite(kTool, st);
  return cli::kExitOk;
}

void AddSpotOptions(CLI::App* command, Args* args) {
  command
      ->add_option("--seed", args->spots.seed,
                   "Seed of every random choice, 0 to 2^64 - 1; the same seed gives the same\n"
                   "spots")
      ->check(opl::cli::SeedValidator())
      ->capture_default_str();
  command
      ->add_option("--missing", args->spots.missing_fraction,
                   "Fraction of the spots dropped, in [0, 1]")
      ->capture_default_str();
  command
      ->add_option("--outliers", args->spots.outlier_fraction,
                   "Fraction of the kept spots made outliers, in [0, 1]")
      ->capture_default_str();
  command
      ->add_option("--outlier-distance", args->spots.outlier_distance_mm,
                   "Displacement of an outlier across its beam, mm, > 0")
      ->capture_default_str();
  command
      ->add_option("--noise-scale", args->noise_scale,
                   "Multiplies the design's spot noise (spot_noise_mm); 0 gives noise-free\n"
                   "spots (written without sx,sy,sz), >= 0")
      ->capture_default_str();
}

}  // namespace simulate_cli
}  // namespace opl
