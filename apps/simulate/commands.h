// The subcommands of opl_simulate, each registered on the tool's app (its
// options, help and footer) in the order of `opl_simulate --help`. One file
// each: spots_command.cc, slices_command.cc, calibration_command.cc,
// mc_command.cc, sweep_command.cc, images_command.cc.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "simulate/simulate_args.h"

namespace opl {
namespace simulate_cli {

// `spots`, `slices` and `calibration` end their help with the tool's
// `examples`.
Subcommand AddSpotsCommand(CLI::App& app, Args* args, const std::string& examples);
Subcommand AddSlicesCommand(CLI::App& app, Args* args, const std::string& examples);
Subcommand AddCalibrationCommand(CLI::App& app, Args* args, const std::string& examples);
Subcommand AddMonteCarloCommand(CLI::App& app, Args* args);
// Sets the default --iterations of the sweep (1000): add it after `mc`.
Subcommand AddSweepCommand(CLI::App& app, Args* args);
Subcommand AddImagesCommand(CLI::App& app, Args* args);

}  // namespace simulate_cli
}  // namespace opl
