// What the subcommands of opl_simulate share (apps/opl_simulate.cc has main
// and the dispatch; docs/cli.md, "opl_simulate"): the parsed options, the
// provenance-stamped writing of an output, and the shape of a subcommand.
#pragma once

#include <functional>
#include <string>

#include <CLI/CLI.hpp>

#include "opl/core/status.h"
#include "opl/io/provenance.h"
#include "opl/sim/simulate_spots.h"

namespace opl {
namespace simulate_cli {

inline constexpr const char* kTool = "opl_simulate";

// Every subcommand's options (each reads those it registered).
struct Args {
  std::string design_path;
  std::string out_path;
  opl::SpotSimulationOptions spots;
  double noise_scale = 1.0;
  // slices only
  bool depths_given = false;  // false: the design's own planes are the slices
  std::string depths;
  double tilt_deg = 0.0;
  double curvature_per_mm = 0.0;
  // mc only
  int iterations = 0;
  int threads = 0;
  bool json = false;
  std::string weighting = "efficient";
  bool calibration = false;  // mc of a calibration session
  bool samples = false;      // mc --json: every iteration's values too
  // mc and sweep
  std::string plot_path;
  // sweep only
  std::string param;
  std::string values;
  bool log_x = false;
  bool log_y = false;
  // images only
  std::string scene_path;
  std::string shots;
  // Written into every output (io/provenance_stamp.h).
  opl::Provenance provenance;
};

// A subcommand: its CLI11 app (options registered) and what runs it once the
// command line is parsed (exit code). `run` may finish reading the options
// (e.g. whether one was given) before calling the command.
struct Subcommand {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

// `contents` written to `path` atomically with the run's provenance.
Status WriteStamped(const Args& args, const std::string& path, const std::string& contents);

// --design FILE (required) and --out FILE (required, `out_help`).
void AddDesignAndOut(CLI::App* command, Args* args, const std::string& out_help);

}  // namespace simulate_cli
}  // namespace opl
