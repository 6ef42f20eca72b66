// opl_calibrate: a module calibration from a calibration session (docs/cli.md,
// docs/calibrate.md). The work is done by opl::CalibrateModule
// (include/opl/calibrate/) and the report by include/opl/report/; this file
// parses options, reads files, writes outputs atomically and maps errors to
// exit codes.
#include <cmath>
#include <limits>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cli_common.h"
#include "overlays_output.h"
#include "progress_bar.h"
#include "spots_input.h"
#include "opl/calibrate/calibrate_module.h"
#include "opl/identify/identify_slices.h"
#include "opl/io/module_design_json.h"
#include "opl/io/scene_json.h"
#include "opl/pipeline/calibrate_images.h"
#include "opl/pipeline/calibrate_overlays.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/points_csv.h"
#include "opl/io/spots_csv.h"
#include "opl/io/output_set.h"
#include "opl/report/calibration_report.h"
#include "opl/report/grid_heatmap.h"
#include "opl/report/plot_format.h"

namespace {

constexpr const char* kTool = "opl_calibrate";

// Columns opl_simulate writes as ground truth, which opl_calibrate ignores;
// any other unknown column is refused unless --allow-extra-columns.
const char* const kKnownExtraColumns[] = {"screen", "outlier", "true_x", "true_y", "true_z"};

struct Args {
  opl::cli::SpotsInputArgs spots;
  std::string design_path;
  std::string out_path;
  std::string report_dir;
  double heatmap_max_mm = 0.0;  // 0: one scale for all sources, their largest value
  double heatmap_noise_mm = std::numeric_limits<double>::quiet_NaN();  // NaN: from the session (PointToRayNoiseLevel)
  std::string heatmap_format = "png";
  int beams_per_side = 0;
  bool allow_extra_columns = false;
  std::string loss = "cauchy";
  double outlier_threshold = 5.0;
  std::string targets_path;
  std::vector<std::string> artifact_ids;
  double artifact_length_mm = 0.0;
  double artifact_u_mm = 0.0;
  std::string images_dir;
  std::string scene_path;
  std::string overlays_dir;
  int threads = 0;
  bool one_pose_per_camera = false;
  opl::cli::ImageRunArgs image_run;  // --spot-channel, --force, --verbose
  int argc = 0;  // the command line, for the outputs' provenance
  char** argv = nullptr;
};

// Reads the artifact's two targets from the targets file and computes the
// scaling; exit code on failure.
std::optional<int> ArtifactScaling(const Args& args,
                                   std::optional<opl::CalibrationScaling>* scaling) {
  using namespace opl;
  Result<PointsCsv> targets = PointsCsv::Read(args.targets_path);
  if (!targets.ok()) return cli::FailInput(kTool, targets.status());
  if (targets->ids().empty()) {
    return cli::Fail(kTool,
                     args.targets_path + ": no 'id' or 'name' column to find the artifact's "
                                         "targets by",
                     cli::kExitBadInput);
  }
  ArtifactMeasurement artifact;
  artifact.from_target = args.artifact_ids[0];
  artifact.to_target = args.artifact_ids[1];
  artifact.length_mm = args.artifact_length_mm;
  artifact.u_length_mm = args.artifact_u_mm;
  for (int end = 0; end < 2; ++end) {
    const std::string& id = args.artifact_ids[end];
    int found = -1;
    for (int i = 0; i < targets->num_points(); ++i) {
      if (targets->ids()[i] != id) continue;
      if (found >= 0) {
        return cli::Fail(kTool,
                         args.targets_path + ":" + std::to_string(targets->lines()[i]) +
                             ": target '" + id + "' appears twice (also line " +
                             std::to_string(targets->lines()[found]) + ")",
                         cli::kExitBadInput);
      }
      found = i;
    }
    if (found < 0) {
      return cli::Fail(kTool, args.targets_path + ": no target '" + id + "' (--artifact)",
                       cli::kExitBadInput);
    }
    (end == 0 ? artifact.from_point : artifact.to_point) = targets->points()[found];
  }
  Result<CalibrationScaling> computed = ComputeArtifactScaling(artifact);
  if (!computed.ok()) return cli::FailInput(kTool, computed.status());
  *scaling = *computed;
  return std::nullopt;
}

// The --report files inside its folder, for the checks that no output names
// an input or another output.
std::vector<opl::cli::NamedPath> ReportFiles(const Args& args) {
  if (args.report_dir.empty()) return {};
  const std::filesystem::path dir(args.report_dir);
  return {{"--report (beams.csv)", (dir / "beams.csv").string()},
          {"--report (samples.csv)", (dir / "samples.csv").string()}};
}

// With --images: the photographs of the session and, with --overlays, their
// overlays (name, JPEG) to write into that folder.
struct ImageOutputs {
  const opl::Scene* scene = nullptr;
  std::vector<std::pair<std::string, std::string>> overlays;
};

// Writes the calibration JSON (and the --report folder, the --overlays),
// everything made before the first write; prints `text_before` and the
// summary.
int WriteOutputs(const Args& args, const opl::ModuleCalibrationResult& result,
                 const std::string& text_before, const ImageOutputs& from_images = ImageOutputs()) {
  using namespace opl;
  std::vector<std::string> inputs = {args.spots.path, args.targets_path, args.design_path,
                                     args.scene_path};
  if (from_images.scene != nullptr) {
    for (std::string& image : cli::ExistingShotImages(*from_images.scene, args.images_dir)) {
      inputs.push_back(std::move(image));
    }
  }
  Provenance provenance;
  if (std::optional<int> code =
          cli::MakeRunProvenance(kTool, args.argc, args.argv, inputs, &provenance)) {
    return *code;
  }
  // Folders this run creates (the overlays', the report's) are removed again
  // when it writes nothing (after the set's temporary files: declared first).
  cli::NewFolders new_folders;
  OutputSet outputs(provenance);
  Result<std::string> json = FormatModuleCalibrationJson(result.calibration);
  if (!json.ok()) return cli::Fail(kTool, json.status().message(), cli::kExitNoSolution);

  // Everything is computed (and the heat maps rendered) before the first
  // write. The heat maps share one colour scale, so that the sources compare
  // by colour: --heatmap-max-mm, or the largest value of them all. --out is
  // staged first, so that a bad --out fails before the report folder exists.
  if (Status st = outputs.Add(args.out_path, *json); !st.ok()) return cli::FailWrite(kTool, st);
  if (Status st = cli::StageOverlays(args.overlays_dir, from_images.overlays, &new_folders, &outputs);
      !st.ok()) {
    return cli::FailWrite(kTool, st);
  }
  if (!args.report_dir.empty()) {
    std::vector<GridHeatmap> heatmaps;
    std::string names;
    for (const SourceCalibrationResult& s : result.sources) {
      heatmaps.push_back(PointToRayHeatmap(s));
      names += (names.empty() ? "" : ", ") + s.calibration.name;
    }
    const bool fixed = args.heatmap_max_mm > 0;
    const double scale_max = fixed ? args.heatmap_max_mm : SharedScaleMax(heatmaps);
    const std::string scale_note = fixed ? "--heatmap-max-mm"
                                   : heatmaps.size() > 1 ? "one scale for sources " + names
                                                         : "";
    Result<PlotFormat> format = PlotFormatFromPath("heatmap." + args.heatmap_format);
    if (!format.ok()) return cli::Fail(kTool, format.status().message(), cli::kExitUsage);
    PlotMetadata metadata;  // a PDF's provenance (the others are stamped)
    metadata.creator = "OPL " + provenance.tool + " " + provenance.version;
    metadata.subject = FormatProvenanceJson(provenance);
    std::vector<std::pair<std::string, std::vector<unsigned char>>> images;
    for (size_t i = 0; i < heatmaps.size(); ++i) {
      heatmaps[i].scale_max = scale_max;
      heatmaps[i].scale_note = scale_note;
      // --heatmap-noise-mm, or the level derived from the source's own noise.
      if (std::isnan(args.heatmap_noise_mm)) {
        heatmaps[i].noise_level = PointToRayNoiseLevel(result.sources[i]);
        heatmaps[i].noise_note = "from the session's noise, 95 % family-wise";
      } else {
        heatmaps[i].noise_level = args.heatmap_noise_mm;
      }
      heatmaps[i].value_unit = "mm";
      Result<std::vector<unsigned char>> bytes = RenderGridHeatmap(heatmaps[i], *format, metadata);
      if (!bytes.ok()) return cli::Fail(kTool, bytes.status().message(), cli::kExitInternalError);
      images.emplace_back("heatmap_" + result.sources[i].calibration.name + "." +
                              PlotFormatName(*format),
                          std::move(*bytes));
    }
    if (Status st = new_folders.Create(args.report_dir); !st.ok()) return cli::FailWrite(kTool, st);
    const std::filesystem::path dir(args.report_dir);
    for (const auto& [name, text] :
         {std::pair<std::string, std::string>{"beams.csv", BeamQualityCsv(result)},
          {"samples.csv", SampleResidualsCsv(result)}}) {
      if (Status st = outputs.Add((dir / name).string(), text); !st.ok()) {
        return cli::FailWrite(kTool, st);
      }
    }
    for (const auto& [name, bytes] : images) {
      const std::string text(bytes.begin(), bytes.end());
      // A PDF carries its provenance in its metadata (set when drawn).
      const Status st = *format == PlotFormat::kPdf ? outputs.AddVerbatim((dir / name).string(), text)
                                                    : outputs.Add((dir / name).string(), text);
      if (!st.ok()) return cli::FailWrite(kTool, st);
    }
  }
  // All of them or none (io/output_set.h).
  if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);
  new_folders.Keep();
  return cli::PrintToStdout(kTool, text_before + CalibrationSummaryText(result));
}

// opl_calibrate --images: the image front end, the artifact scaling, the
// identification against --design, the calibration.
int RunImages(const Args& args) {
  using namespace opl;
  if (args.design_path.empty()) {
    return cli::Fail(kTool, "--images needs --design (the nominal patterns to identify the grids)",
                     cli::kExitUsage);
  }
  if (!args.targets_path.empty()) {
    return cli::Fail(kTool,
                     "--targets/--artifact are for --spots; with --images the scene JSON's "
                     "'artifact' names the artifact's tags",
                     cli::kExitUsage);
  }
  Result<Scene> scene = ReadSceneJson(args.scene_path, SceneUse::kMeasure);
  if (!scene.ok()) return cli::FailInput(kTool, scene.status());
  if (Status st = CheckSceneHasLasers(*scene); !st.ok()) {
    return cli::Fail(kTool, args.scene_path + ": " + st.message(), cli::kExitBadInput);
  }
  std::vector<cli::NamedPath> outputs = ReportFiles(args);
  outputs.push_back({"--out", args.out_path});
  if (std::optional<int> code = cli::CheckOverlaysOutput(
          kTool, args.overlays_dir, *scene, args.images_dir,
          {{"--scene", args.scene_path}, {"--design", args.design_path}}, outputs)) {
    return *code;
  }
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  Result<ModuleCalibration> nominal = ExactCalibration(*design);
  if (!nominal.ok()) return cli::FailInput(kTool, nominal.status());
  ImageCalibrationOptions options;
  if (args.beams_per_side > 0) options.calibrate.beams_per_side = args.beams_per_side;
  options.calibrate.source.loss = args.loss == "cauchy" ? RobustLoss::kCauchy
                                  : args.loss == "huber" ? RobustLoss::kHuber
                                                         : RobustLoss::kNone;
  options.calibrate.source.outlier_threshold = args.outlier_threshold;
  options.front_end.num_threads = args.threads;
  options.front_end.one_pose_per_camera = args.one_pose_per_camera;
  cli::ApplyImageRunOptions(args.image_run, &options.front_end);
  cli::ProgressBar bar("images", cli::StderrIsTerminal());
  options.front_end.progress = bar.StageCallback("detect");
  Result<ImageCalibrationReport> report =
      CalibrateFromImages(*scene, args.images_dir, *nominal, options);
  bar.Finish();
  if (!report.ok()) return cli::FailInput(kTool, report.status());
  if (args.image_run.verbose) std::cerr << report->front_end.bundle_report;
  ImageOutputs image_outputs;
  image_outputs.scene = &*scene;
  if (!args.overlays_dir.empty()) {
    Result<std::vector<std::pair<std::string, std::string>>> drawn =
        RenderOverlays(*scene, args.images_dir, *report, args.threads);
    if (!drawn.ok()) return cli::FailInput(kTool, drawn.status());
    image_outputs.overlays = std::move(*drawn);
  }
  return WriteOutputs(args, report->calibration, report->ToText(), image_outputs);
}

int Run(int argc, char** argv) {
  using namespace opl;
  Args args;
  CLI::App app(
      "Calibrates an optically projected length scale module from a calibration session\n"
      "(docs/calibrate.md): the module stays fixed, a screen is placed at several depths\n"
      "and each grid is measured on it, one grid at a time. For every source it finds the\n"
      "projection origin, the pose and every beam's pointing direction (one joint solve,\n"
      "no starting guess, wrong samples flagged), then the separations between the\n"
      "origins: the module's calibrated length scales, with their uncertainty.\n"
      "\n"
      "Input: a spots CSV (docs/formats.md) with a `slice` column. A slice is one grid on\n"
      "one screen position (one photograph), so it holds the spots of one source; all\n"
      "slices are in one frame, in mm, unless an artifact scales them (--targets,\n"
      "--artifact, --artifact-length-mm). Columns other than source,beam,x,y,z,sx,sy,sz,\n"
      "slice (and opl_simulate's ground truth screen,outlier,true_x,true_y,true_z) are\n"
      "refused, to catch a misnamed column; --allow-extra-columns ignores them.\n"
      "Spots without source or beam (empty fields, no such columns, or a point table\n"
      "read with --columns id,x,y,z,slice) are identified slice by slice against the\n"
      "nominal patterns of --design, numbered as the design mounts each source (the\n"
      "module must be mounted within 30 deg of its design orientation); a slice whose\n"
      "grid cannot be identified for sure is left out and reported.\n"
      "\n"
      "Output: the module calibration JSON (--out), with per-beam covariances and per-\n"
      "source quality figures, and a summary on stdout. With --report DIR also:\n"
      "beams.csv (per-beam quality), samples.csv (every sample's residual and status)\n"
      "and heatmap_<source>.png (mean point-to-ray distance per beam over the grid; all\n"
      "sources on one colour scale, so that equal colours are equal distances).\n",
      kTool);
  app.add_option("--spots", args.spots.path,
                 "Spots CSV of the session: [source,beam,]x,y,z[,sx,sy,sz],slice")
      ->type_name("FILE");
  CLI::Option* images =
      app.add_option("--images", args.images_dir,
                     "Folder of the session's images (instead of --spots); needs --scene and\n"
                     "--design")
          ->type_name("DIR");
  CLI::Option* scene =
      app.add_option("--scene", args.scene_path,
                     "Scene JSON of the session: cameras, tags, frame and artifact tags, shots\n"
                     "with their lasers and slice (docs/formats.md)")
          ->type_name("FILE");
  app.add_option("--threads", args.threads,
                 "With --images: threads for the detection and for the re-solves that\n"
                 "carry the spots' shared errors, >= 0; 0 = every core")
      ->capture_default_str();
  cli::AddImageRunOptions(app, &args.image_run);
  app.add_flag("--one-pose-per-camera", args.one_pose_per_camera,
               "With --images: the shots of one camera share one pose (cameras on tripods,\n"
               "untouched for the whole session); refused when a camera's shots place it\n"
               "more than 5 mm or 2 mrad apart (docs/images.md)")
      ->needs(images);
  app.add_option("--overlays", args.overlays_dir,
                 "With --images: write, for every image, DIR/<image>_overlay.jpg: the image\n"
                 "dimmed, with the tags found (cyan, with ids), the spots identified (green,\n"
                 "with source and beam, as the calibration used them), matched (yellow),\n"
                 "unmatched (orange) and the blobs rejected as not laser spots (red x); refused\n"
                 "before any work when DIR cannot be written or an overlay would replace an\n"
                 "input or another output (docs/images.md, 'Overlays')")
      ->type_name("DIR")
      ->needs(images);
  images->needs(scene);
  scene->needs(images);
  opl::cli::AddPointTableOptions(app, &args.spots);
  app.add_option("--design", args.design_path,
                 "Module design JSON (docs/simulation.md): the nominal patterns and mounting of\n"
                 "the sources, in the session's frame; needed to identify unassigned spots")
      ->type_name("FILE");
  app.add_option("--out", args.out_path, "Module calibration JSON to write (atomically)")
      ->required()
      ->type_name("FILE");
  app.add_option("--report", args.report_dir,
                 "Folder for beams.csv, samples.csv and heatmap_<source>.png (or .svg, .pdf;\n"
                 "created if missing; files written atomically)")
      ->type_name("DIR");
  app.add_option("--heatmap-max-mm", args.heatmap_max_mm,
                 "With --report: top of the heat maps' colour scale, mm (> 0), e.g. to compare\n"
                 "runs; larger distances get the top colour and a triangle on the bar. Default:\n"
                 "the largest mean point-to-ray distance of all sources (one scale per run)")
      ->type_name("MM");
  app.add_option("--heatmap-noise-mm", args.heatmap_noise_mm,
                 "With --report: the mean point-to-ray distance noise alone gives, mm (>= 0;\n"
                 "about 1.25 x the spots' standard deviation across the beam). A map whose\n"
                 "beams are all at or below it says 'All beams at the noise level'. Default:\n"
                 "derived per source from the session's own residuals, the level that pure\n"
                 "noise keeps every beam under in 95 % of sessions (docs/report.md)")
      ->type_name("MM");
  app.add_option("--heatmap-format", args.heatmap_format,
                 "With --report: png (default), svg or pdf (vector, for print); the PDF\n"
                 "carries the provenance in its metadata")
      ->check(CLI::IsMember({"png", "svg", "pdf"}))
      ->type_name("FORMAT");
  app.add_option("--beams-per-side", args.beams_per_side,
                 "n of the n x n grids (odd, 3 to 201); default: the smallest odd n with\n"
                 "n^2 >= the largest beam id of each source")
      ->check(cli::BeamsPerSideValidator())
      ->type_name("N");
  app.add_flag("--allow-extra-columns", args.allow_extra_columns,
               "Ignore unknown columns of the spots CSV instead of refusing them");
  app.add_option("--loss", args.loss,
                 "Robust loss before flagging wrong samples: cauchy (default), huber or none")
      ->check(CLI::IsMember({"cauchy", "huber", "none"}))
      ->type_name("NAME");
  app.add_option("--outlier-threshold", args.outlier_threshold,
                 "Flag samples beyond this many standard deviations (default 5)")
      ->type_name("SIGMAS");
  CLI::Option* targets =
      app.add_option("--targets", args.targets_path,
                     "Points CSV (id or name, x, y, z) holding the artifact's two targets, in\n"
                     "the frame of the spots")
          ->type_name("FILE");
  CLI::Option* artifact = app.add_option("--artifact", args.artifact_ids,
                                         "The artifact's two target ids, e.g. --artifact T1,T2")
                              ->delimiter(',')
                              ->expected(2)
                              ->type_name("ID,ID");
  CLI::Option* length =
      app.add_option("--artifact-length-mm", args.artifact_length_mm,
                     "Calibrated length of the artifact, mm (e.g. 1677.66)")
          ->type_name("MM");
  CLI::Option* u_length =
      app.add_option("--artifact-u-mm", args.artifact_u_mm,
                     "Standard uncertainty (k = 1) of that length, mm (default 0)")
          ->type_name("MM");
  targets->needs(artifact)->needs(length);
  artifact->needs(targets);
  length->needs(targets);
  u_length->needs(targets);
  app.footer(cli::HelpFooter(
      "  opl_simulate slices --design examples/prototype_design.json --depths 750:65:1335 \\\n"
      "      --out slices.csv\n"
      "  opl_calibrate --spots slices.csv --out module.json --report report/\n"
      "  # vector heat maps for print, on the scale of an earlier run, noise marked:\n"
      "  opl_calibrate --spots slices.csv --out module.json --report report/ \\\n"
      "      --heatmap-format pdf --heatmap-max-mm 0.2 --heatmap-noise-mm 0.1\n"
      "  opl_calibrate --spots session.txt --columns id,x,y,z,slice --design design.json \\\n"
      "      --out module.json\n"
      "  opl_calibrate --spots session.csv --targets targets.csv --artifact T1,T2 \\\n"
      "      --artifact-length-mm 1677.66 --artifact-u-mm 0.005 --out module.json\n"
      "  opl_calibrate --images session/ --scene session.json --design design.json \\\n"
      "      --out module.json --overlays session_overlays/\n"));
  if (std::optional<int> code = cli::ParseCommandLine(app, argc, argv)) return *code;
  args.argc = argc;
  args.argv = argv;
  {
    // --report writes beams.csv and samples.csv (and PNGs) into its folder.
    std::vector<cli::NamedPath> outputs = {{"--out", args.out_path}};
    for (cli::NamedPath& file : ReportFiles(args)) outputs.push_back(std::move(file));
    if (std::optional<int> code = cli::RefuseOutputsOverInputs(
            kTool,
            {{"--spots", args.spots.path},
             {"--design", args.design_path},
             {"--targets", args.targets_path},
             {"--scene", args.scene_path}},
            outputs)) {
      return *code;
    }
  }
  if (app.count("--heatmap-max-mm") > 0 &&
      !(std::isfinite(args.heatmap_max_mm) && args.heatmap_max_mm > 0)) {
    return cli::Fail(kTool, "--heatmap-max-mm must be finite and > 0, got " +
                                FormatNumber(args.heatmap_max_mm),
                     cli::kExitUsage);
  }
  if (app.count("--heatmap-noise-mm") > 0 &&
      !(std::isfinite(args.heatmap_noise_mm) && args.heatmap_noise_mm >= 0)) {
    return cli::Fail(kTool, "--heatmap-noise-mm must be finite and >= 0, got " +
                                FormatNumber(args.heatmap_noise_mm),
                     cli::kExitUsage);
  }
  if (args.image_run.verbose) cli::ShowSolverLogging();
  if (args.spots.path.empty() == args.images_dir.empty()) {
    return cli::Fail(kTool, "give either --spots or --images (with --scene) (see --help)",
                     cli::kExitUsage);
  }
  if (args.threads < 0) {
    return cli::Fail(kTool, "--threads must be >= 0, got " + std::to_string(args.threads),
                     cli::kExitUsage);
  }
  if (!args.images_dir.empty()) return RunImages(args);

  CalibrateModuleOptions options;
  if (app.count("--beams-per-side") > 0) options.beams_per_side = args.beams_per_side;
  options.source.loss = args.loss == "cauchy" ? RobustLoss::kCauchy
                        : args.loss == "huber" ? RobustLoss::kHuber
                                               : RobustLoss::kNone;
  options.source.outlier_threshold = args.outlier_threshold;
  if (Status st = options.source.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
  }

  bool usage_error = false;
  Result<SpotsCsvData> spots = cli::ReadSpotsInput(args.spots, &usage_error);
  if (!spots.ok()) {
    if (usage_error) return cli::Fail(kTool, spots.status().message(), cli::kExitUsage);
    return cli::FailInput(kTool, spots.status());
  }
  if (!args.allow_extra_columns) {
    for (const std::string& column : spots->other_columns) {
      bool known = false;
      for (const char* k : kKnownExtraColumns) known |= column == k;
      if (!known) {
        return cli::Fail(kTool,
                         args.spots.path + ":1: unknown column '" + column +
                             "' (expected source,beam,x,y,z,sx,sy,sz,slice; "
                             "--allow-extra-columns ignores it)",
                         cli::kExitBadInput);
      }
    }
  }
  if (spots->slices.empty()) {
    return cli::Fail(kTool,
                     args.spots.path + ":1: missing column 'slice' (a calibration session "
                                       "needs the slice of every spot)",
                     cli::kExitBadInput);
  }
  // Unassigned spots: identified against the design's nominal patterns.
  std::string identification_text;
  if (spots->num_unassigned() > 0) {
    if (args.design_path.empty()) {
      return cli::Fail(kTool,
                       args.spots.path + ": " + std::to_string(spots->num_unassigned()) +
                           " spots have no source or beam: give --design (the nominal patterns "
                           "and mounting of the module) to identify them",
                       cli::kExitBadInput);
    }
    Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
    if (!design.ok()) return cli::FailInput(kTool, design.status());
    Result<ModuleCalibration> nominal = ExactCalibration(*design);
    if (!nominal.ok()) return cli::FailInput(kTool, nominal.status());
    Result<SessionIdentification> identified =
        IdentifySessionSlices(*nominal, spots->spots, spots->slices);
    if (!identified.ok()) return cli::FailInput(kTool, identified.status());
    identification_text = identified->ToText();
    if (identified->spots.empty()) {
      const SliceIdentification& first = identified->per_slice.front();
      return cli::Fail(kTool,
                       args.spots.path + ": no spot identified in any of the " +
                           std::to_string(identified->per_slice.size()) + " slices (slice " +
                           std::to_string(first.slice) + ": " + first.detail + ")",
                       cli::kExitNoSolution);
    }
    spots->spots = std::move(identified->spots);
    spots->slices = std::move(identified->slices);
  }
  std::optional<CalibrationScaling> scaling;
  if (!args.targets_path.empty()) {
    if (std::optional<int> code = ArtifactScaling(args, &scaling)) return *code;
  }

  Result<ModuleCalibrationResult> result =
      CalibrateModule(spots->spots, spots->slices, scaling, options);
  if (!result.ok()) return cli::FailInput(kTool, result.status());
  return WriteOutputs(args, *result, identification_text);
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
