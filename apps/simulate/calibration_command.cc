#include "simulate/commands.h"

#include "cli_common.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/module_design_json.h"
#include "opl/sim/module_design.h"

namespace opl {
namespace simulate_cli {
namespace {

int CalibrationCommand(const Args& args) {
  using namespace opl;
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  Result<ModuleCalibration> calibration = ExactCalibration(*design);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  Result<std::string> json = FormatModuleCalibrationJson(*calibration);
  if (!json.ok()) return cli::FailInput(kTool, json.status());
  if (Status st = WriteStamped(args, args.out_path, *json); !st.ok()) {
    return cli::FailWrite(kTool, st);
  }
  return cli::kExitOk;
}

}  // namespace

Subcommand AddCalibrationCommand(CLI::App& app, Args* args, const std::string& examples) {
  CLI::App* calibration = app.add_subcommand(
      "calibration",
      "Write the exact (noise-free) module calibration of the design: its patterns, its\n"
      "source poses (the calibration frame is the design's scene frame) and the\n"
      "separations between every pair of origins, with zero uncertainty.");
  AddDesignAndOut(calibration, args, "Module calibration JSON to write (atomically)");
  calibration->footer(opl::cli::HelpFooter(examples));
  return {calibration, [args] { return CalibrationCommand(*args); }};
}

}  // namespace simulate_cli
}  // namespace opl
