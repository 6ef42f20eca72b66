// What the spot simulations of opl_simulate share: `spots` and `slices`
// (their options and their CSV), and `mc`, `sweep` (the design prepared with
// its noise scaled).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "opl/sim/module_design.h"
#include "opl/sim/simulate_spots.h"
#include "simulate/simulate_args.h"

namespace opl {
namespace simulate_cli {

// What `spots`, `slices` and `mc` share before simulating: checks
// --noise-scale, reads the design, scales its noise and validates the spot
// options. Returns the exit code when the command must stop.
std::optional<int> PrepareSpotSimulation(const Args& args, ModuleDesign* design,
                                         SpotSimulationOptions* options);

// Writes simulated spots as a spots CSV (atomically): the standard columns,
// then the simulation's ground truth (ignored by readers).
// With `screens` (a calibration session of that many screens), the slice
// column numbers the grid photographs, as opl_calibrate reads them (one
// source per slice): source i (design order) on screen k is slice i * screens
// + k, and a `screen` column gives k.
int WriteSimulatedSpots(const Args& args, const std::vector<SimulatedSpot>& simulated,
                        const ModuleDesign& design, const std::string& path, int screens = 0);

// The options of the random spot simulation (SpotSimulationOptions and the
// noise scale), shared by `spots` and `slices`.
void AddSpotOptions(CLI::App* command, Args* args);

}  // namespace simulate_cli
}  // namespace opl
