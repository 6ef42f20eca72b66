// opl_measure: the scale factor of a scene from the spots of a module's
// sources (docs/cli.md). The work is done by opl::MeasureScale
// (include/opl/pipeline/measure.h); this file parses options, reads files,
// prints and maps errors to exit codes.
#include <string>

#include "cli_common.h"
#include "spots_input.h"
#include "opl/io/atomic_file.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/points_csv.h"
#include "opl/io/spots_csv.h"
#include "opl/pipeline/measure.h"

namespace {

constexpr const char* kTool = "opl_measure";

struct Args {
  std::string calibration_path;
  opl::cli::SpotsInputArgs spots;
  std::string identified_path;
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
      "points CSV.\n"
      "\n"
      "Spots need not be sorted: points without a source or beam (empty fields, or no\n"
      "such columns, e.g. a point table read with --columns id,x,y,z) are identified\n"
      "against the calibrated patterns first, whatever the module's pose, with grids\n"
      "mixed, spots missing and spurious points present. A grid that cannot be\n"
      "identified for sure (too few spots, a pattern symmetric under the observed roll)\n"
      "is reported and not used: the tool refuses rather than guesses. --identified\n"
      "writes every point with the source and beam it was given.\n",
      kTool);
  app.add_option("--calibration", args.calibration_path,
                 "Module calibration JSON (docs/formats.md, 'Module calibration JSON')")
      ->required()
      ->type_name("FILE");
  app.add_option("--spots", args.spots.path,
                 "Spots CSV: [source,beam,]x,y,z[,sx,sy,sz] in scene units (docs/formats.md);\n"
                 "empty or absent source/beam: identified. With --columns: any point table")
      ->required()
      ->type_name("FILE");
  cli::AddPointTableOptions(app, &args.spots);
  app.add_option("--identified", args.identified_path,
                 "Write the spots as a spots CSV with the source and beam each was assigned\n"
                 "(empty when unassigned), in input order, plus an `id` column when the input\n"
                 "had one (atomically)")
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
      "  opl_measure --calibration cal.json --spots spots.csv --apply scene.csv --out scene_mm.csv\n"
      "  opl_measure --calibration cal.json --spots export.txt --columns id,x,y,z,sx,sy,sz \\\n"
      "      --skip-rows 1 --identified sorted.csv\n"));
  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;

  // Read every input first: input errors (3) come before any computation.
  Result<ModuleCalibration> calibration = ReadModuleCalibrationJson(args.calibration_path);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  bool usage_error = false;
  Result<SpotsCsvData> spots = cli::ReadSpotsInput(args.spots, &usage_error);
  if (!spots.ok()) {
    if (usage_error) return cli::Fail(kTool, spots.status().message(), cli::kExitUsage);
    return cli::FailInput(kTool, spots.status());
  }
  std::optional<PointsCsv> points;
  if (!args.apply_path.empty()) {
    Result<PointsCsv> read = PointsCsv::Read(args.apply_path);
    if (!read.ok()) return cli::FailInput(kTool, read.status());
    points = std::move(read).value();
  }

  Result<MeasureReport> report = MeasureScale(*calibration, spots->spots, MeasureOptions());
  if (!report.ok()) return cli::FailInput(kTool, report.status());

  // Every output is made before the first is written.
  std::string identified_csv;
  if (!args.identified_path.empty()) {
    std::vector<Spot> labelled = spots->spots;
    if (report->identification) {
      const IdentifyResult& id = *report->identification;
      for (size_t i = 0; i < labelled.size(); ++i) {
        const int source = id.source_index[i];
        labelled[i].source = source >= 0 ? id.sources[static_cast<size_t>(source)].name : "";
        labelled[i].observation.beam_id = source >= 0 ? id.beam_id[i] : 0;
      }
    }
    std::vector<SpotsCsvExtraColumn> extra;
    if (!spots->point_ids.empty()) extra.push_back({"id", spots->point_ids});
    Result<std::string> csv = FormatSpotsCsv(labelled, extra);
    if (!csv.ok()) return cli::FailInput(kTool, csv.status());
    identified_csv = std::move(*csv);
  }

  if (points) {
    if (Status st = points->Scale(report->scale.scale_factor); !st.ok()) {
      return cli::Fail(kTool, st.message(), cli::kExitNoSolution);
    }
    if (Status st = WriteFileAtomically(args.out_path, points->Format()); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  if (!args.identified_path.empty()) {
    if (Status st = WriteFileAtomically(args.identified_path, identified_csv); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  return cli::PrintToStdout(kTool, args.json ? report->ToJson() : report->ToText());
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
