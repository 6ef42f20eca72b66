// opl_scene: makes the scene JSON of a measurement or calibration session
// from its files, so that no one writes a scene by hand (docs/cli.md
// "opl_scene"). The work is done by opl::InitScene (include/opl/pipeline/
// scene_init.h), the files by include/opl/io/ (cameras JSON, the sequencer's
// per-frame metadata, the scene writer); this file parses options, writes
// the output atomically and maps errors to exit codes.
#include <cctype>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "opl/io/atomic_file.h"
#include "opl/io/cameras_json.h"
#include "opl/io/frame_metadata_jsonl.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/provenance.h"
#include "opl/io/scene_json.h"
#include "opl/pipeline/scene_init.h"

namespace {

constexpr const char* kTool = "opl_scene";

struct Args {
  std::string images_dir;
  std::string cameras_path;
  std::string metadata_path;
  std::string calibration_path;
  std::string out_path;
  double tag_size_mm = 0.0;
  std::vector<int> frame;     // origin, axis, plane
  std::vector<double> artifact;  // tag_1, tag_2, length_mm[, sigma_mm]
  std::vector<int> runs;
  std::vector<std::string> lasers;  // "a=A"
  std::string description;
};

bool IsTagId(double v) { return v >= 0 && v <= 586 && v == static_cast<int>(v); }

int Init(const Args& args, int argc, char** argv) {
  using namespace opl;
  SceneInitOptions options;
  options.images_dir = args.images_dir;
  options.metadata_name = args.metadata_path;
  options.runs = args.runs;
  options.tag_size_mm = args.tag_size_mm;
  for (const std::string& m : args.lasers) {
    const size_t eq = m.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == m.size()) {
      return cli::Fail(kTool, "--laser: expected LASER=SOURCE (e.g. a=A), got '" + m + "'", cli::kExitUsage);
    }
    if (!options.laser_sources.emplace(m.substr(0, eq), m.substr(eq + 1)).second) {
      return cli::Fail(kTool, "--laser: laser '" + m.substr(0, eq) + "' mapped twice", cli::kExitUsage);
    }
  }
  if (!args.frame.empty()) {
    if (args.frame.size() != 3) {
      return cli::Fail(kTool, "--frame: expected three tag ids ORIGIN,AXIS,PLANE", cli::kExitUsage);
    }
    options.frame = SceneFrameTags{args.frame[0], args.frame[1], args.frame[2]};
  }
  if (!args.artifact.empty()) {
    if (args.artifact.size() != 3 && args.artifact.size() != 4) {
      return cli::Fail(kTool, "--artifact: expected TAG1,TAG2,LENGTH_MM[,SIGMA_MM]", cli::kExitUsage);
    }
    if (!IsTagId(args.artifact[0]) || !IsTagId(args.artifact[1])) {
      return cli::Fail(kTool, "--artifact: the first two values must be tag ids 0..586", cli::kExitUsage);
    }
    options.artifact = SceneArtifact{static_cast<int>(args.artifact[0]), static_cast<int>(args.artifact[1]),
                                     args.artifact[2], args.artifact.size() == 4 ? args.artifact[3] : 0.0};
  }
  if (std::optional<int> code = cli::RefuseOutputsOverInputs(
          kTool,
          {{"--cameras", args.cameras_path}, {"--metadata", args.metadata_path},
           {"--calibration", args.calibration_path}},
          {{"--out", args.out_path}})) {
    return *code;
  }
  Result<std::vector<SceneCamera>> cameras = ReadCamerasJson(args.cameras_path);
  if (!cameras.ok()) return cli::FailInput(kTool, cameras.status());
  options.cameras = *cameras;
  Result<std::vector<FrameMetadata>> frames = ReadFrameMetadataJsonl(args.metadata_path);
  if (!frames.ok()) return cli::FailInput(kTool, frames.status());
  options.frames = *frames;
  if (!args.calibration_path.empty()) {
    Result<ModuleCalibration> calibration = ReadModuleCalibrationJson(args.calibration_path);
    if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
    for (const auto& source : calibration->sources) options.known_sources.push_back(source.name);
  }
  if (Status s = options.Validate(); !s.ok()) return cli::Fail(kTool, s.message(), cli::kExitUsage);
  Result<SceneInit> init = InitScene(options);
  if (!init.ok()) return cli::FailInput(kTool, init.status());

  Result<Provenance> provenance =
      MakeProvenance(kTool, argc, argv, {args.cameras_path, args.metadata_path, args.calibration_path});
  if (!provenance.ok()) return cli::FailInput(kTool, provenance.status());
  std::string description = args.description;
  if (description.empty()) {
    description = "Made by opl_scene init from the images in " + args.images_dir + ", the cameras of " +
                  args.cameras_path + " and the frames of " + args.metadata_path + ".";
  }
  const std::string text = FormatMeasurementSceneJson(init->scene, description, FormatProvenanceJson(*provenance));
  // The scene written must read back as the scene made (as opl_measure reads it).
  const std::string base_dir =
      args.out_path.empty() ? std::string() : std::filesystem::path(args.out_path).parent_path().string();
  if (Result<Scene> back = ParseSceneJson(text, args.out_path.empty() ? "stdout" : args.out_path, base_dir,
                                          SceneUse::kMeasure);
      !back.ok()) {
    return cli::Fail(kTool, "internal error: the scene made does not read back: " + back.status().message(),
                     cli::kExitInternalError);
  }
  if (args.out_path.empty()) {
    // A dry run: the scene on stdout (a valid JSON document), the matching on stderr.
    std::cerr << init->ToText();
    return cli::PrintToStdout(kTool, text);
  }
  if (Status s = WriteFileAtomically(args.out_path, text); !s.ok()) return cli::FailWrite(kTool, s);
  return cli::PrintToStdout(kTool, init->ToText() + "  wrote " + args.out_path +
                                       "\n  shot files are relative to the images folder: measure with\n"
                                       "  opl_measure --scene " + args.out_path + " --images " + args.images_dir +
                                       " --calibration CAL.json\n");
}

int Run(int argc, char** argv) {
  Args args;
  CLI::App app(
      "Makes the scene JSON of a session from its files (docs/cli.md, 'opl_scene';\n"
      "docs/formats.md, 'Scene JSON'), so that no one writes a scene by hand.\n"
      "\n"
      "  init  reads the calibrated cameras (a cameras JSON, as opl_camera calibrate\n"
      "        writes it), the sequencer's per-frame metadata (frames.jsonl: which\n"
      "        lasers were on, which slice; docs/sequencer.md) and lists the\n"
      "        photographs; matches each frame to one image per camera and writes\n"
      "        the scene: cameras, tag size, frame and artifact tags, and one shot\n"
      "        per image with the lasers that were on (none: a dark frame) and the\n"
      "        slice. Without --out the scene goes to stdout (a dry run) and the\n"
      "        matching table to stderr.\n",
      kTool);
  app.require_subcommand(1);
  app.footer(opl::cli::HelpFooter(
      "  opl_scene init --images session/ --cameras cameras.json --metadata frames.jsonl \\\n"
      "      --tag-size-mm 140 --frame 0,1,2 --out scene.json\n"
      "  opl_measure --scene scene.json --images session/ --calibration cal.json\n"));

  CLI::App* init = app.add_subcommand(
      "init",
      "Make a scene JSON from a folder of photographs, a cameras JSON and the\n"
      "sequencer's per-frame metadata.\n"
      "\n"
      "Which images are which camera's: with one camera in the cameras file, the\n"
      "images directly in --images; with several, a folder per camera named as the\n"
      "camera (--images session/ holds session/cam0/, session/cam1/, ...).\n"
      "\n"
      "Which image is which frame: a camera's images sorted by file name are its\n"
      "frames in the order of the metadata lines (cameras number files in shooting\n"
      "order; rename them if the counter wrapped). EXIF time is not used: it has a\n"
      "resolution of one second (a measurement's four frames take about 0.3 s) and\n"
      "the camera's clock is not the sequencer's. Every camera must have exactly one\n"
      "image per frame: otherwise nothing is written and the message names the\n"
      "folder and both counts (a missed trigger or a stray image: remove the stray\n"
      "image, or the frame's line with --run).\n"
      "\n"
      "Which frames: every line of the metadata file, or those of --run N (the\n"
      "daemon appends every run to one file). A measurement run is four frames:\n"
      "grid_a (laser a), grid_b (b), both, dark (lasers off: the dark frame). Laser\n"
      "names become source names by upper-case (a -> A) unless --laser a=NAME;\n"
      "--calibration checks them against a module calibration's sources.\n"
      "\n"
      "Output: format opl.scene with the cameras (intrinsics and calibration\n"
      "record), tags (family, size), frame, artifact, shots, and a provenance\n"
      "record (tool, version, time, command line, SHA-256 of the cameras,\n"
      "metadata and calibration files). Shot files are relative to --images, so\n"
      "measure with the same --images. The module, spot and image looks and camera\n"
      "poses are only for rendering and are not written (measuring does not use\n"
      "them).");
  init->add_option("--images", args.images_dir, "Folder of photographs (.png .jpg .jpeg .tif .tiff .bmp .pgm .ppm)")
      ->required()
      ->type_name("DIR");
  init->add_option("--cameras", args.cameras_path, "Cameras JSON (opl_camera calibrate --out)")
      ->required()
      ->type_name("FILE");
  init->add_option("--metadata", args.metadata_path, "The sequencer's per-frame metadata (JSON lines)")
      ->required()
      ->type_name("FILE");
  init->add_option("--tag-size-mm", args.tag_size_mm,
                   "Side of the printed tags' black square, mm (approximate is enough: the\n"
                   "scale comes from the module or the artifact)")
      ->required()
      ->type_name("MM")
      ->check(CLI::Range(1e-3, 1e6));
  init->add_option("--frame", args.frame, "Tags of the scene frame: origin, X axis, XY plane (e.g. 0,1,2)")
      ->delimiter(',')
      ->expected(3)
      ->type_name("O,A,P")
      ->check(CLI::Range(0, 586));
  init->add_option("--artifact", args.artifact,
                   "Scale bar: its two tags, their distance and its standard uncertainty, mm\n"
                   "(calibration sessions; e.g. 8,9,800,0.01)")
      ->delimiter(',')
      ->expected(3, 4)
      ->type_name("T1,T2,MM[,SIGMA]");
  init->add_option("--run", args.runs, "Take only this run's frames (repeatable; default every line)")
      ->type_name("N")
      ->check(CLI::Range(1, 1000000000));
  init->add_option("--laser", args.lasers, "Name a laser's source: LASER=SOURCE (repeatable; default a=A, b=B)")
      ->type_name("L=S");
  init->add_option("--calibration", args.calibration_path,
                   "Module calibration JSON: check that every lit laser is one of its sources")
      ->type_name("FILE");
  init->add_option("--description", args.description, "The scene's description (default: how it was made)")
      ->type_name("TEXT");
  init->add_option("--out", args.out_path, "Scene JSON to write (atomically); default: stdout (dry run)")
      ->type_name("FILE");
  init->footer(opl::cli::HelpFooter(
      "  opl_scene init --images session/ --cameras cameras.json --metadata frames.jsonl \\\n"
      "      --tag-size-mm 140 --frame 0,1,2                      (dry run: scene on stdout)\n"
      "  opl_scene init --images session/ --cameras cameras.json --metadata frames.jsonl \\\n"
      "      --tag-size-mm 140 --frame 0,1,2 --run 3 --calibration cal.json --out scene.json\n"
      "  opl_scene init --images screens/ --cameras cameras.json --metadata frames.jsonl \\\n"
      "      --tag-size-mm 60 --artifact 8,9,1677.66,0.005 --out session.json\n"));

  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;
  return Init(args, argc, argv);
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
