// opl_measure: the scale factor of a scene from the spots of a module's
// sources (docs/cli.md). The work is done by opl::MeasureScale
// (include/opl/pipeline/measure.h); this file parses options, reads files,
// prints and maps errors to exit codes.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "cli_common.h"
#include "overlays_output.h"
#include "progress_bar.h"
#include "spots_input.h"
#include "opl/core/format.h"
#include "opl/io/colmap_model.h"
#include "opl/io/output_set.h"
#include "opl/io/provenance_stamp.h"
#include "opl/io/scene_json.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/scale_point_file.h"
#include "opl/io/spots_csv.h"
#include "opl/pipeline/measure.h"
#include "opl/pipeline/colmap_measure.h"
#include "opl/pipeline/measure_images.h"
#include "opl/pipeline/measure_overlays.h"

namespace {

constexpr const char* kTool = "opl_measure";

struct Args {
  std::string calibration_path;
  opl::cli::SpotsInputArgs spots;
  std::string identified_path;
  bool json = false;
  std::string apply_path;
  std::string out_path;
  std::string apply_format = "auto";
  std::string images_dir;
  std::string overlays_dir;
  std::string scene_path;
  std::string spots_out_path;
  std::string colmap_dir;
  std::string colmap_out_dir;
  int threads = 0;
  bool one_pose_per_camera = false;
  bool no_scale_in_adjustment = false;
  opl::cli::ImageRunArgs image_run;  // --spot-channel, --force, --verbose
};

// --apply: the options of the streamed scaling (format, progress bar).
opl::ScalePointFileOptions ApplyOptions(const Args& args) {
  opl::ScalePointFileOptions options;
  options.format = *opl::ParsePointFileFormat(args.apply_format);  // checked by CLI11
  return options;
}

// Before anything is read: an --out whose extension names another format
// than the --apply file's is a usage error (the output has the input's
// format). std::nullopt when fine (or when the input's format is unknown:
// CheckApply refuses that), else the exit code.
std::optional<int> CheckOutFormat(const Args& args) {
  using namespace opl;
  if (args.apply_path.empty()) return std::nullopt;
  const ScalePointFileOptions options = ApplyOptions(args);
  Result<PointFileFormat> in_format = options.format != PointFileFormat::kAuto
                                          ? Result<PointFileFormat>(options.format)
                                          : PointFileFormatFromPath(args.apply_path);
  Result<PointFileFormat> out_format = PointFileFormatFromPath(args.out_path);
  if (in_format.ok() && out_format.ok() && *out_format != *in_format) {
    return cli::Fail(kTool,
                     "--out '" + args.out_path + "' names a " + PointFileFormatName(*out_format) +
                         " file but --apply '" + args.apply_path + "' is " +
                         PointFileFormatName(*in_format) +
                         ": the output has the input's format (see --help)",
                     cli::kExitUsage);
  }
  return std::nullopt;
}

// Before any solve: the --apply file opens, its format is known and its header
// is valid. std::nullopt when fine, else the exit code (3).
std::optional<int> CheckApply(const Args& args) {
  using namespace opl;
  if (args.apply_path.empty()) return std::nullopt;
  if (Status st = CheckPointFile(args.apply_path, ApplyOptions(args)); !st.ok()) {
    return cli::FailInput(kTool, st);
  }
  return std::nullopt;
}

// --apply FILE --out FILE with the measured s: streamed, staged in `outputs`
// (it appears at their commit), with the run's provenance. The exit
// code on failure (3 bad input, 4 unusable s, 5 cannot write), else nullopt.
std::optional<int> ApplyScale(const Args& args, double s, opl::OutputSet* outputs,
                              const opl::Provenance* provenance) {
  using namespace opl;
  if (!(std::isfinite(s) && s > 0.0)) {
    return cli::Fail(kTool, "scale factor must be finite and > 0, got " + std::to_string(s),
                     cli::kExitNoSolution);
  }
  ScalePointFileOptions options = ApplyOptions(args);
  options.outputs = outputs;
  options.provenance = provenance;
  cli::ProgressBar bar("apply (MiB)", cli::StderrIsTerminal());
  options.progress = [&bar](int64_t done, int64_t total) {
    bar.Update(static_cast<int>(done >> 20), static_cast<int>(total >> 20));
  };
  ScalePointFileSummary summary;
  Status st = ScalePointFile(args.apply_path, args.out_path, s, options, &summary);
  bar.Finish();
  if (!st.ok()) return summary.output_failed ? cli::FailWrite(kTool, st) : cli::FailInput(kTool, st);
  return std::nullopt;
}

// opl_measure --images: the image front end, then the measurement.
int RunImages(const Args& args, int argc, char** argv) {
  using namespace opl;
  if (!args.identified_path.empty()) {
    return cli::Fail(kTool, "--identified is for --spots; with --images use --spots-out",
                     cli::kExitUsage);
  }
  if (args.threads < 0) {
    return cli::Fail(kTool, "--threads must be >= 0, got " + std::to_string(args.threads),
                     cli::kExitUsage);
  }
  Result<ModuleCalibration> calibration = ReadModuleCalibrationJson(args.calibration_path);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  Result<Scene> scene = ReadSceneJson(args.scene_path, SceneUse::kMeasure);
  if (!scene.ok()) return cli::FailInput(kTool, scene.status());
  if (Status st = CheckSceneHasLasers(*scene); !st.ok()) {
    return cli::Fail(kTool, args.scene_path + ": " + st.message(), cli::kExitBadInput);
  }
  if (std::optional<int> code = CheckApply(args)) return *code;
  if (std::optional<int> code = cli::CheckOverlaysOutput(
          kTool, args.overlays_dir, *scene, args.images_dir,
          {{"--calibration", args.calibration_path},
           {"--scene", args.scene_path},
           {"--apply", args.apply_path}},
          {{"--out", args.out_path}, {"--spots-out", args.spots_out_path}})) {
    return *code;
  }
  std::optional<ColmapModel> colmap;
  if (!args.colmap_dir.empty()) {
    Result<ColmapModel> model = ReadColmapModel(args.colmap_dir);
    if (!model.ok()) return cli::FailInput(kTool, model.status());
    colmap = std::move(model).value();
  }
  // The provenance hashes every input, the shots' images included (a missing
  // image is the front end's to report).
  std::vector<std::string> inputs = {args.calibration_path, args.scene_path, args.apply_path,
                                     args.colmap_dir};
  for (std::string& image : cli::ExistingShotImages(*scene, args.images_dir)) inputs.push_back(std::move(image));
  Provenance provenance;
  if (std::optional<int> code = cli::MakeRunProvenance(kTool, argc, argv, inputs, &provenance)) {
    return *code;
  }
  ImageMeasureOptions options;
  options.front_end.num_threads = args.threads;
  options.front_end.one_pose_per_camera = args.one_pose_per_camera;
  options.front_end.scale_in_adjustment = !args.no_scale_in_adjustment;
  cli::ApplyImageRunOptions(args.image_run, &options.front_end);
  cli::ProgressBar bar("images", cli::StderrIsTerminal());
  options.front_end.progress = bar.StageCallback("detect");
  Result<ImageMeasureReport> report = Status::NoSolution("not run");
  if (colmap) {
    ColmapMeasureOptions colmap_options;
    colmap_options.image = options;
    report = MeasureScaleFromColmap(*scene, args.images_dir, *colmap, *calibration, colmap_options);
  } else {
    report = MeasureScaleFromImages(*scene, args.images_dir, *calibration, options);
  }
  bar.Finish();
  if (!report.ok()) return cli::FailInput(kTool, report.status());
  if (args.image_run.verbose) std::cerr << report->front_end.bundle_report;

  std::string spots_csv;
  if (!args.spots_out_path.empty()) {
    const std::vector<Spot>& labelled = report->spots;
    Result<std::string> csv = FormatSpotsCsv(labelled, {});
    if (!csv.ok()) return cli::FailInput(kTool, csv.status());
    spots_csv = std::move(*csv);
  }
  std::vector<std::pair<std::string, std::string>> overlays;
  if (!args.overlays_dir.empty()) {
    Result<std::vector<std::pair<std::string, std::string>>> drawn =
        RenderOverlays(*scene, args.images_dir, *report, args.threads);
    if (!drawn.ok()) return cli::FailInput(kTool, drawn.status());
    overlays = std::move(*drawn);
  }
  // Every output or none: all are staged (stamped with the provenance), then
  // committed together. The COLMAP folder is written first (one rename) and
  // removed if the rest fails.
  // The folders made for the outputs are removed again unless every output
  // is written (after the set's temporary files: declared first).
  cli::NewFolders new_folders;
  OutputSet outputs(provenance);
  if (Status st = cli::StageOverlays(args.overlays_dir, overlays, &new_folders, &outputs); !st.ok()) {
    return cli::FailWrite(kTool, st);
  }
  if (!args.apply_path.empty()) {
    if (std::optional<int> code =
            ApplyScale(args, report->scale_factor, &outputs, &provenance)) {
      return *code;
    }
  }
  if (!args.spots_out_path.empty()) {
    if (Status st = outputs.Add(args.spots_out_path, spots_csv); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  if (colmap && !args.colmap_out_dir.empty()) {
    const double s = report->scale_factor;
    const ColmapModel scaled = ScaledColmapModel(*colmap, s);
    Result<std::string> ply = StampProvenance("points3D.ply", FormatColmapPointsPly(scaled), provenance);
    Result<std::string> json = StampProvenance(
        "opl_provenance.json", "{\"scale_factor_mm_per_model_unit\": " + FormatRoundTrip(s) + "}\n",
        provenance);
    if (!ply.ok() || !json.ok()) {
      return cli::FailWrite(kTool, !ply.ok() ? ply.status() : json.status());
    }
    if (Status st = WriteColmapModel(scaled, args.colmap_out_dir, colmap->format,
                                     {{"points3D.ply", *ply}, {"opl_provenance.json", *json}});
        !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  if (Status st = outputs.Commit(); !st.ok()) {
    std::error_code ec;
    if (colmap && !args.colmap_out_dir.empty()) std::filesystem::remove_all(args.colmap_out_dir, ec);
    return cli::FailWrite(kTool, st);
  }
  new_folders.Keep();
  return args.json ? cli::PrintJsonToStdout(kTool, report->ToJson(), provenance)
                   : cli::PrintToStdout(kTool, report->ToText());
}

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
      "point file (PLY, XYZ or points CSV, streamed: 10 million points need no more\n"
      "memory than ten), keeping everything else in it (docs/formats.md, 'Point files').\n"
      "\n"
      "Spots need not be sorted: points without a source or beam (empty fields, or no\n"
      "such columns, e.g. a point table read with --columns id,x,y,z) are identified\n"
      "against the calibrated patterns first, whatever the module's pose, with grids\n"
      "mixed, spots missing and spurious points present. A grid that cannot be\n"
      "identified for sure (too few spots, a pattern symmetric under the observed roll)\n"
      "is reported and not used: the tool refuses rather than guesses. --identified\n"
      "writes every point with the source and beam it was given.\n"
      "\n"
      "From photographs (--images DIR --scene scene.json): the images listed as shots in\n"
      "the scene JSON (docs/formats.md, 'Scene JSON': calibrated cameras, the nominal tag\n"
      "size, the three frame tags, which lasers were on in each shot) are read from DIR;\n"
      "AprilTag (tag36h11) targets and laser spots are detected in every image, the\n"
      "cameras posed from the tags, the spots matched across views and everything refined\n"
      "in one bundle adjustment (docs/images.md); the 3D spots are then identified and\n"
      "measured as above (the two-step s). Then the module enters the adjustment as a\n"
      "calibrated projector and the scale comes out of the adjustment itself: that s is\n"
      "the result (the last line, JSON 'scale_factor', what --apply uses) unless\n"
      "--no-scale-in-adjustment; the report says which s it gives and why. A per-image\n"
      "report (tags, spots detected and matched, RMS) comes first; progress is shown on\n"
      "a terminal. --spots-out writes the 3D spots (unscaled).\n",
      kTool);
  app.add_option("--calibration", args.calibration_path,
                 "Module calibration JSON (docs/formats.md, 'Module calibration JSON')")
      ->required()
      ->type_name("FILE");
  app.add_option("--spots", args.spots.path,
                 "Spots CSV: [source,beam,]x,y,z[,sx,sy,sz] in scene units (docs/formats.md);\n"
                 "empty or absent source/beam: identified. With --columns: any point table")
      ->type_name("FILE");
  cli::AddPointTableOptions(app, &args.spots);
  CLI::Option* images =
      app.add_option("--images", args.images_dir,
                     "Folder of the shots' image files (instead of --spots); needs --scene")
          ->type_name("DIR");
  CLI::Option* scene =
      app.add_option("--scene", args.scene_path,
                     "Scene JSON: cameras, tags, frame tags, shots (docs/formats.md)")
          ->type_name("FILE");
  CLI::Option* spots_out =
      app.add_option("--spots-out", args.spots_out_path,
                     "With --images: write the 3D spots as a spots CSV with the source and beam\n"
                     "each was assigned and its sx,sy,sz (atomically)")
          ->type_name("FILE");
  app.add_option("--overlays", args.overlays_dir,
                 "With --images: write, for every image, DIR/<image>_overlay.jpg: the image\n"
                 "dimmed, with the tags found (cyan, with ids), the spots identified (green,\n"
                 "with source and beam), matched (yellow), unmatched (orange) and the blobs\n"
                 "rejected as not laser spots (red x); refused before any work when DIR cannot\n"
                 "be written or an overlay would replace an input or another output\n"
                 "(docs/images.md, 'Overlays')")
      ->needs(images);
  app.add_option("--threads", args.threads, "With --images: detection threads, >= 0; 0 = every core")
      ->capture_default_str();
  app.add_flag("--one-pose-per-camera", args.one_pose_per_camera,
               "With --images: the shots of one camera share one pose (cameras on tripods,\n"
               "untouched for the whole session); refused when a camera's shots place it\n"
               "more than 5 mm or 2 mrad apart (docs/images.md)")
      ->needs(images);
  app.add_flag("--no-scale-in-adjustment", args.no_scale_in_adjustment,
               "With --images: report the two-step s (the unscaled adjustment, then the\n"
               "located sources) instead of the default, the scale inside the adjustment: after\n"
               "the two-step measurement the module enters the adjustment again as a calibrated\n"
               "projector (each spot a depth along its calibrated beam, the calibration a\n"
               "prior), and its s and u(s) are the result, about 30 times more precise\n"
               "(docs/multiview.md, 'The projector model'). With --colmap the two-step s is\n"
               "used anyway (the COLMAP path keeps no adjustment of its own)")
      ->needs(images);
  CLI::Option* colmap_option =
      app.add_option("--colmap", args.colmap_dir,
                     "With --images: a COLMAP sparse model (folder of cameras, images, points3D;\n"
                     "text or binary) gives the cameras and poses instead of the tags: each shot's\n"
                     "image is the model's image of the same name; the model's points are tie\n"
                     "points of the adjustment; s then scales the model to mm (docs/colmap.md)")
          ->needs(images);
  app.add_option("--colmap-out", args.colmap_out_dir,
                 "With --colmap: write the model scaled by s (points and camera centres times s)\n"
                 "to this new (or empty) folder, in the format it was read, all files or none")
      ->needs(colmap_option);
  images->needs(scene);
  scene->needs(images);
  spots_out->needs(images);
  app.add_option("--identified", args.identified_path,
                 "Write the spots as a spots CSV with the source and beam each was assigned\n"
                 "(empty when unassigned), in input order, plus an `id` column when the input\n"
                 "had one (atomically)")
      ->type_name("FILE");
  app.add_flag("--json", args.json,
               "Print one JSON object (format opl.measure_report) instead of the text summary");
  cli::AddImageRunOptions(app, &args.image_run);
  CLI::Option* apply =
      app.add_option("--apply", args.apply_path,
                     "Point file to multiply by s, streamed (any size): PLY (.ply: ascii or\n"
                     "binary; vertex x,y,z scaled, every other property, element and comment\n"
                     "kept), XYZ (.xyz, .txt: 'x y z [rest]' per line, rest kept; '#' comments)\n"
                     "or points CSV (.csv: x,y,z columns by name, other columns kept)")
          ->type_name("FILE");
  CLI::Option* out =
      app.add_option("--out", args.out_path,
                     "Where --apply writes the scaled points: the input's format, atomically")
          ->type_name("FILE");
  app.add_option("--format", args.apply_format,
                 "Format of the --apply file instead of its extension's: ply, xyz, csv")
      ->check(CLI::IsMember({"auto", "ply", "xyz", "csv"}))
      ->type_name("FORMAT")
      ->capture_default_str()
      ->needs(apply);
  apply->needs(out);
  out->needs(apply);
  app.footer(opl::cli::HelpFooter(
      "  opl_measure --calibration cal.json --spots spots.csv\n"
      "  opl_measure --calibration cal.json --spots spots.csv --json > report.json\n"
      "  opl_measure --calibration cal.json --spots spots.csv --apply scene.csv --out scene_mm.csv\n"
      "  opl_measure --calibration cal.json --spots spots.csv --apply scan.ply --out scan_mm.ply\n"
      "  opl_measure --calibration cal.json --spots spots.csv --apply cloud.pts --format xyz \\\n"
      "      --out cloud_mm.pts\n"
      "  opl_measure --calibration cal.json --spots export.txt --columns id,x,y,z,sx,sy,sz \\\n"
      "      --skip-rows 1 --identified sorted.csv\n"
      "  opl_measure --calibration cal.json --images shots/ --scene scene.json\n"
      "  opl_measure --calibration cal.json --images shots/ --scene scene.json \\\n"
      "      --colmap sparse/0 --colmap-out sparse_mm\n"));
  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;
  if (std::optional<int> code = cli::RefuseOutputsOverInputs(
          kTool,
          {{"--calibration", args.calibration_path},
           {"--spots", args.spots.path},
           {"--apply", args.apply_path},
           {"--scene", args.scene_path},
           {"--colmap", args.colmap_dir}},
          {{"--out", args.out_path},
           {"--colmap-out", args.colmap_out_dir},
           {"--identified", args.identified_path},
           {"--spots-out", args.spots_out_path}})) {
    return *code;
  }
  if (std::optional<int> code = CheckOutFormat(args)) return *code;
  if (args.image_run.verbose) cli::ShowSolverLogging();
  if (args.spots.path.empty() == args.images_dir.empty()) {
    return cli::Fail(kTool, "give either --spots or --images (with --scene) (see --help)",
                     cli::kExitUsage);
  }
  if (!args.images_dir.empty()) return RunImages(args, argc, argv);

  // Read every input first: input errors (3) come before any computation.
  Result<ModuleCalibration> calibration = ReadModuleCalibrationJson(args.calibration_path);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  bool usage_error = false;
  Result<SpotsCsvData> spots = cli::ReadSpotsInput(args.spots, &usage_error);
  if (!spots.ok()) {
    if (usage_error) return cli::Fail(kTool, spots.status().message(), cli::kExitUsage);
    return cli::FailInput(kTool, spots.status());
  }
  if (std::optional<int> code = CheckApply(args)) return *code;
  Provenance provenance;
  if (std::optional<int> code = cli::MakeRunProvenance(
          kTool, argc, argv, {args.calibration_path, args.spots.path, args.apply_path}, &provenance)) {
    return *code;
  }

  // Identifying tens of thousands of unassigned spots takes seconds: a
  // progress line on a terminal (nothing in logs and pipes).
  cli::ProgressBar identify_bar("identify", cli::StderrIsTerminal());
  MeasureOptions measure_options;
  measure_options.identify.progress = identify_bar.IdentifyCallback();
  Result<MeasureReport> report = MeasureScale(*calibration, spots->spots, measure_options);
  identify_bar.Finish();
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

  OutputSet outputs(provenance);
  if (!args.apply_path.empty()) {
    if (std::optional<int> code =
            ApplyScale(args, report->scale.scale_factor, &outputs, &provenance)) {
      return *code;
    }
  }
  if (!args.identified_path.empty()) {
    if (Status st = outputs.Add(args.identified_path, identified_csv); !st.ok()) {
      return cli::FailWrite(kTool, st);
    }
  }
  if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);
  return args.json ? cli::PrintJsonToStdout(kTool, report->ToJson(), provenance)
                   : cli::PrintToStdout(kTool, report->ToText());
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
