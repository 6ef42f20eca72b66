#include "simulate/commands.h"

#include <optional>
#include <vector>

#include "cli_common.h"
#include "simulate/spot_simulation.h"

namespace opl {
namespace simulate_cli {
namespace {

int SimulateSpotsCommand(const Args& args) {
  using namespace opl;
  ModuleDesign design;
  SpotSimulationOptions options;
  if (std::optional<int> code = PrepareSpotSimulation(args, &design, &options)) return *code;
  Result<std::vector<SimulatedSpot>> simulated = SimulateSpots(design, options);
  if (!simulated.ok()) return cli::FailInput(kTool, simulated.status());
  return WriteSimulatedSpots(args, *simulated, design, args.out_path);
}

}  // namespace

Subcommand AddSpotsCommand(CLI::App& app, Args* args, const std::string& examples) {
  CLI::App* spots = app.add_subcommand(
      "spots",
      "Write the simulated spots of every source as a spots CSV: source,beam,x,y,z\n"
      "(mm, the design's scene frame), sx,sy,sz (the noise standard deviations, when\n"
      "> 0 on every axis), then ground truth columns slice,outlier,true_x,true_y,true_z.");
  AddDesignAndOut(spots, args, "Spots CSV to write (atomically)");
  AddSpotOptions(spots, args);
  spots->footer(opl::cli::HelpFooter(examples));
  return {spots, [args] { return SimulateSpotsCommand(*args); }};
}

}  // namespace simulate_cli
}  // namespace opl
