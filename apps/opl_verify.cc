// opl_verify: the acceptance test of a session (VDI/VDE 2634 Part 1, ISO
// 10360-13): calibrated check lengths through the measuring volume, each
// measured with the scene scaled by the laser module alone and by the
// scene's bar, with E = L - L_cal and U(E) (docs/verify.md). The work is
// done by opl::MeasureScaleFromImages and opl::VerifyLengths
// (include/opl/pipeline/verify_lengths.h); this file parses options, reads
// files, writes the outputs and maps errors to exit codes.
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "progress_bar.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/output_set.h"
#include "opl/io/scene_json.h"
#include "opl/pipeline/measure_images.h"
#include "opl/pipeline/verify_lengths.h"
#include "opl/report/line_plot.h"
#include "opl/report/plot_format.h"

namespace {

constexpr const char* kTool = "opl_verify";

struct Args {
  std::string scene_path;
  std::string images_dir;
  std::string calibration_path;
  std::string csv_path;
  std::string json_path;
  std::string plot_path;
  int threads = 0;
  bool one_pose_per_camera = false;
  bool no_scale_in_adjustment = false;
  opl::cli::ImageRunArgs image_run;  // --spot-channel, --no-dark-frames(-exposure), --force, --verbose
};

int Run(int argc, char** argv) {
  using namespace opl;
  Args args;
  CLI::App app(
      "The acceptance test of an optical 3D measuring system as VDI/VDE 2634 Part 1 and\n"
      "ISO 10360-13 define it, on one photographed session: calibrated test lengths (pairs\n"
      "of tags whose centres are a certified distance apart, the scene JSON's\n"
      "'check_lengths') placed through the measuring volume, each measured, and for each\n"
      "the length measurement error E = L - L_cal with its expanded uncertainty U(E)\n"
      "(k = 2). The standards ask for at least 7 positions (space diagonals, edges,\n"
      "several orientations) and a longest length of at least 2/3 of the volume's space\n"
      "diagonal: a session that does not meet that is still reported, with a warning.\n"
      "\n"
      "The session is measured as opl_measure --images measures it (tags and laser spots\n"
      "detected, cameras posed, one bundle adjustment, s from the module's spots); then\n"
      "every check length is measured three ways: the adjusted (unscaled) tag centres\n"
      "scaled by s, the laser module alone (column 'OPL', the two-step path); the same\n"
      "tags in the bundle adjustment that holds the module as a calibrated projector, so\n"
      "that the scene comes out in mm (column 'adj', the module alone again, about 30x\n"
      "more precise; --no-scale-in-adjustment leaves it out; docs/multiview.md); and the\n"
      "unscaled centres scaled by the scene's 'artifact', the conventional scale bar\n"
      "(column 'bar'; absent without one). U(E) keeps the correlations between the scale\n"
      "and the tags (shared cameras, shared datum) and adds the certificate's u(L_cal).\n"
      "|E| <= U(E) means the error is explained by the stated uncertainty; OPL 'meets the\n"
      "bar' when its E are as small as the bar's.\n"
      "\n"
      "A table goes to stdout (one row per check length: L_cal, then L, E, U(E) of each\n"
      "column; the summary and the warnings). --csv, --json and --plot write the same as\n"
      "files, all of them or none (docs/verify.md, 'Files').\n",
      kTool);
  app.add_option("--scene", args.scene_path,
                 "Scene JSON with 'check_lengths' (docs/formats.md, 'Scene JSON'; docs/verify.md)")
      ->required()
      ->type_name("FILE");
  app.add_option("--images", args.images_dir, "Folder of the shots' image files")
      ->required()
      ->type_name("DIR");
  app.add_option("--calibration", args.calibration_path,
                 "Module calibration JSON (docs/formats.md, 'Module calibration JSON')")
      ->required()
      ->type_name("FILE");
  app.add_option("--csv", args.csv_path,
                 "Write the table as CSV: one row per check length (docs/verify.md)")
      ->type_name("FILE");
  app.add_option("--json", args.json_path,
                 "Write the report as JSON (format opl.verify_report, docs/verify.md)")
      ->type_name("FILE");
  app.add_option("--plot", args.plot_path,
                 "Write a plot of E against L_cal, every column with its +-U(E); the name's\n"
                 "extension picks the format: .png, .svg or .pdf (vector, for print)")
      ->type_name("FILE");
  app.add_option("--threads", args.threads, "Detection threads, >= 0; 0 = every core")
      ->capture_default_str();
  app.add_flag("--one-pose-per-camera", args.one_pose_per_camera,
               "The shots of one camera share one pose (cameras on tripods, untouched for\n"
               "the whole session; docs/images.md)");
  app.add_flag("--no-scale-in-adjustment", args.no_scale_in_adjustment,
               "Leave out the column of the scale inside the adjustment (column 'adj')");
  cli::AddImageRunOptions(app, &args.image_run);
  app.footer(cli::HelpFooter(
      "  opl_verify --scene scene.json --images shots/ --calibration cal.json\n"
      "  opl_verify --scene scene.json --images shots/ --calibration cal.json \\\n"
      "      --csv verify.csv --json verify.json --plot verify.png\n"
      "  # a virtual lab run (docs/verify.md):\n"
      "  opl_simulate calibration --design examples/scene_small_module.json --out cal.json\n"
      "  opl_simulate images --scene examples/scene_verify_18mp.json --out shots/\n"
      "  opl_verify --scene examples/scene_verify_18mp.json --images shots/ --calibration cal.json\n"));
  if (std::optional<int> code = cli::ParseCommandLine(app, argc, argv)) return *code;
  if (std::optional<int> code = cli::RefuseOutputsOverInputs(
          kTool, {{"--scene", args.scene_path}, {"--calibration", args.calibration_path}},
          {{"--csv", args.csv_path}, {"--json", args.json_path}, {"--plot", args.plot_path}})) {
    return *code;
  }
  std::optional<opl::PlotFormat> plot_format;
  if (!args.plot_path.empty()) {
    opl::Result<opl::PlotFormat> format = opl::PlotFormatFromPath(args.plot_path);
    if (!format.ok()) return cli::Fail(kTool, "--plot " + format.status().message(), cli::kExitUsage);
    plot_format = *format;
  }
  if (args.threads < 0) {
    return cli::Fail(kTool, "--threads must be >= 0, got " + std::to_string(args.threads),
                     cli::kExitUsage);
  }
  if (args.image_run.verbose) cli::ShowSolverLogging();

  // Every input is read and checked before any image is.
  Result<ModuleCalibration> calibration = ReadModuleCalibrationJson(args.calibration_path);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  Result<Scene> scene = ReadSceneJson(args.scene_path, SceneUse::kMeasure);
  if (!scene.ok()) return cli::FailInput(kTool, scene.status());
  for (const Status& st : {CheckSceneHasLasers(*scene), CheckSceneHasCheckLengths(*scene)}) {
    if (!st.ok()) return cli::Fail(kTool, args.scene_path + ": " + st.message(), cli::kExitBadInput);
  }
  std::vector<std::string> inputs = {args.calibration_path, args.scene_path};
  for (std::string& image : cli::ExistingShotImages(*scene, args.images_dir)) {
    inputs.push_back(std::move(image));
  }
  Provenance provenance;
  if (std::optional<int> code = cli::MakeRunProvenance(kTool, argc, argv, inputs, &provenance)) {
    return *code;
  }

  ImageMeasureOptions options;
  options.front_end.num_threads = args.threads;
  options.front_end.one_pose_per_camera = args.one_pose_per_camera;
  options.front_end.scale_in_adjustment = !args.no_scale_in_adjustment;
  if (!args.no_scale_in_adjustment) options.projector_tag_lengths = CheckLengthTags(*scene);
  cli::ApplyImageRunOptions(args.image_run, &options.front_end);
  cli::ProgressBar bar("images", cli::StderrIsTerminal());
  options.front_end.progress = bar.StageCallback("detect");
  Result<ImageMeasureReport> measured =
      MeasureScaleFromImages(*scene, args.images_dir, *calibration, options);
  bar.Finish();
  if (!measured.ok()) return cli::FailInput(kTool, measured.status());
  if (args.image_run.verbose) std::cerr << measured->front_end.ToText() << measured->front_end.bundle_report;
  Result<VerifyReport> report = VerifyLengths(*scene, *measured);
  if (!report.ok()) {
    return cli::Fail(kTool, args.scene_path + ": " + report.status().message(),
                     cli::ExitCodeForInputStatus(report.status()));
  }

  // Every output or none: staged (stamped with the provenance), then
  // committed together.
  OutputSet outputs(provenance);
  if (!args.csv_path.empty()) {
    if (Status st = outputs.Add(args.csv_path, report->ToCsv()); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  if (!args.json_path.empty()) {
    if (Status st = outputs.Add(args.json_path, report->ToJson()); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  if (!args.plot_path.empty()) {
    const std::string scene_name = std::filesystem::path(args.scene_path).filename().string();
    PlotMetadata metadata;  // a PDF's provenance (PNG and SVG are stamped by Add)
    metadata.creator = "OPL " + provenance.tool + " " + provenance.version;
    metadata.subject = FormatProvenanceJson(provenance);
    Result<std::vector<unsigned char>> plot =
        RenderLinePlot(report->ToPlot(scene_name), *plot_format, metadata);
    if (!plot.ok()) return cli::FailWrite(kTool, plot.status());
    const std::string bytes(plot->begin(), plot->end());
    const Status st = *plot_format == PlotFormat::kPdf ? outputs.AddVerbatim(args.plot_path, bytes)
                                                       : outputs.Add(args.plot_path, bytes);
    if (!st.ok()) return cli::FailWrite(kTool, st);
  }
  if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);
  return cli::PrintToStdout(kTool, report->ToText());
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
