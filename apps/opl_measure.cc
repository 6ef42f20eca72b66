// opl_measure: the scale factor of a scene from the spots of a module's
// sources (docs/cli.md). The work is done by opl::MeasureScale
// (include/opl/pipeline/measure.h); this file parses options, reads files,
// prints and maps errors to exit codes.
#include <string>

#include "cli_common.h"
#include "opl/io/atomic_file.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/points_csv.h"
#include "opl/io/spots_csv.h"
#include "opl/pipeline/measure.h"

namespace {

constexpr const char* kTool = "opl_measure";

struct Args {
  std::string calibration_path;
  std::string spots_path;
  bool json = false;
  std::string apply_path;
  std::string out_path;
};

int Run(int argc, char** argv) {
  using namespace opl;
  Args args;
  CLI::App app(
      "Measures the scale factor of a photogrammetry scene from the laser spots of an\n"
      "optically projected length scale module. Every source of the module is located\n"
      "from its spots (robustly: outliers are reported by beam id), the distances between\n"
      "the located projection origins are compared with the calibrated ones, and the\n"
      "scale factor s (mm per scene unit, with its standard uncertainty) is printed.\n"
      "Multiply every scene coordinate by s to get millimetres; --apply does that to a\n"
      "points CSV.\n",
      kTool);
  app.add_option("--calibration", args.calibration_path,
                 "Module calibration JSON (docs/formats.md, 'Module calibration JSON')")
      ->required()
      ->type_name("FILE");
  app.add_option("--spots", args.spots_path,
                 "Spots CSV: source,beam,x,y,z[,sx,sy,sz] in scene units (docs/formats.md)")
      ->required()
      ->type_name("FILE");
  app.add_flag("--json", args.json,
               "Print one JSON object (format opl.measure_report) instead of the text summary");
  CLI::Option* apply =
      app.add_option("--apply", args.apply_path,
                     "Points CSV with x,y,z columns to scale by s (other columns copied verbatim)")
          ->type_name("FILE");
  CLI::Option* out =
      app.add_option("--out", args.out_path, "Where --apply writes the scaled points (atomically)")
          ->type_name("FILE");
  apply->needs(out);
  out->needs(apply);
  app.footer(opl::cli::HelpFooter(
      "  opl_measure --calibration cal.json --spots spots.csv\n"
      "  opl_measure --calibration cal.json --spots spots.csv --json > report.json\n"
      "  opl_measure --calibration cal.json --spots spots.csv --apply scene.csv --out scene_mm.csv\n"));
  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;

  // Read every input first: input errors (3) come before any computation.
  Result<ModuleCalibration> calibration = ReadModuleCalibrationJson(args.calibration_path);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  Result<SpotsCsvData> spots = ReadSpotsCsv(args.spots_path);
  if (!spots.ok()) return cli::FailInput(kTool, spots.status());
  std::optional<PointsCsv> points;
  if (!args.apply_path.empty()) {
    Result<PointsCsv> read = PointsCsv::Read(args.apply_path);
    if (!read.ok()) return cli::FailInput(kTool, read.status());
    points = std::move(read).value();
  }

  Result<MeasureReport> report = MeasureScale(*calibration, spots->spots, MeasureOptions());
  if (!report.ok()) return cli::FailInput(kTool, report.status());

  if (points) {
    if (Status st = points->Scale(report->scale.scale_factor); !st.ok()) {
      return cli::Fail(kTool, st.message(), cli::kExitNoSolution);
    }
    if (Status st = WriteFileAtomically(args.out_path, points->Format()); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  return cli::PrintToStdout(kTool, args.json ? report->ToJson() : report->ToText());
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
