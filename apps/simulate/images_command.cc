#include "simulate/commands.h"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "cli_common.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/shot_file.h"
#include "progress_bar.h"

namespace opl {
namespace simulate_cli {
namespace {

// The shot indices of --shots ("0,3,5"; empty: every shot), or an error
// message.
std::optional<std::string> ParseShotList(const std::string& text, int num_shots,
                                         std::vector<int>* indices) {
  indices->clear();
  if (text.empty()) {
    for (int k = 0; k < num_shots; ++k) indices->push_back(k);
    return std::nullopt;
  }
  std::set<int> seen;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, comma - start);
    size_t used = 0;
    int index = -1;
    try {
      index = std::stoi(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || index < 0) {
      return "--shots: '" + item + "' is not a shot index (expected e.g. 0,3,5)";
    }
    if (index >= num_shots) {
      return "--shots: " + item + ": the scene has " + std::to_string(num_shots) +
             " shots, 0.." + std::to_string(num_shots - 1);
    }
    if (seen.insert(index).second) indices->push_back(index);
    start = comma + 1;
  }
  return std::nullopt;
}

int ImagesCommand(const Args& args) {
  using namespace opl;
  namespace fs = std::filesystem;
  Result<Scene> scene = ReadSceneJson(args.scene_path);
  if (!scene.ok()) return cli::FailInput(kTool, scene.status());
  std::vector<int> indices;
  if (std::optional<std::string> bad =
          ParseShotList(args.shots, static_cast<int>(scene->shots.size()), &indices)) {
    return cli::Fail(kTool, *bad + " (see --help)", cli::kExitUsage);
  }
  if (args.threads < 0) return cli::Fail(kTool, "--threads must be >= 0", cli::kExitUsage);
  for (size_t k = 0; k < scene->shots.size(); ++k) {
    const fs::path file(scene->shots[k].file);
    bool escapes = file.is_absolute();
    for (const fs::path& part : file) escapes = escapes || part == "..";
    if (escapes || file.filename().empty()) {
      return cli::Fail(kTool,
                       args.scene_path + ": shots[" + std::to_string(k) + "].file: '" +
                           scene->shots[k].file +
                           "': must be a relative file path inside the output folder",
                       cli::kExitBadInput);
    }
  }
  Result<SceneRenderer> renderer = SceneRenderer::Create(*scene);
  if (!renderer.ok()) return cli::FailInput(kTool, Status(renderer.status().code(),
                                                          args.scene_path + ": " +
                                                              renderer.status().message()));

  // Output folders (created when missing).
  const fs::path out_dir(args.out_path);
  std::error_code ec;
  std::set<fs::path> folders = {out_dir};
  for (int k : indices) {
    folders.insert((out_dir / scene->shots[static_cast<size_t>(k)].file).parent_path());
  }
  // The folders this run creates, removed again (when empty) on failure.
  std::set<fs::path> created;
  for (const fs::path& folder : folders) {
    for (fs::path p = folder; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
      created.insert(p);
    }
  }
  auto remove_created = [&created, &ec]() {
    for (auto it = created.rbegin(); it != created.rend(); ++it) fs::remove(*it, ec);
  };
  for (const fs::path& folder : folders) {
    fs::create_directories(folder, ec);
    if (ec || !fs::is_directory(folder)) {
      remove_created();
      return cli::Fail(kTool, folder.string() + ": cannot create the output folder: " +
                                  (ec ? ec.message() : std::string("not a directory")),
                       cli::kExitWriteFailed);
    }
  }

  // Render, encode and write the shots, `threads` at a time.
  const int total = static_cast<int>(indices.size());
  unsigned threads = args.threads > 0 ? static_cast<unsigned>(args.threads)
                                      : std::max(1u, std::thread::hardware_concurrency());
  threads = std::min(threads, static_cast<unsigned>(std::max(1, total)));
  std::vector<RenderedShot> rendered(indices.size());
  std::vector<std::string> written;
  std::atomic<int> next{0};
  std::mutex mutex;
  Status failure;
  bool write_failure = false;
  int done = 0;
  cli::ProgressBar bar("images", cli::StderrIsTerminal());
  bar.Update(0, total);
  auto work = [&]() {
    for (;;) {
      const int slot = next.fetch_add(1);
      if (slot >= total) return;
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (!failure.ok()) return;
      }
      const int index = indices[static_cast<size_t>(slot)];
      const SceneShot& shot = scene->shots[static_cast<size_t>(index)];
      const std::string path = (out_dir / shot.file).string();
      Result<RenderedShot> r = renderer->RenderShot(index);
      Status st = r.ok() ? Status::Ok()
                         : Status(r.status().code(), "shots[" + std::to_string(index) +
                                                         "]: " + r.status().message());
      bool is_write = false;
      if (st.ok()) {
        Result<std::string> file = EncodeShotImage(r->image, scene->image);
        r->image.release();
        if (!file.ok()) {
          st = Status::IoError(path + ": " + file.status().message());
          is_write = true;
        } else {
          st = WriteStamped(args, path, *file);
          is_write = !st.ok();
        }
      }
      std::lock_guard<std::mutex> lock(mutex);
      if (!st.ok()) {
        if (failure.ok()) {
          failure = st;
          write_failure = is_write;
        }
        return;
      }
      written.push_back(path);
      rendered[static_cast<size_t>(slot)] = std::move(*r);
      bar.Update(++done, total);
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  bar.Finish();

  const std::string truth_path = (out_dir / "truth.json").string();
  if (failure.ok()) {
    failure = WriteStamped(args, truth_path, FormatSceneTruthJson(*renderer, rendered));
    write_failure = !failure.ok();
  }
  if (!failure.ok()) {
    // No partial output: remove the images this run wrote.
    for (const std::string& path : written) fs::remove(path, ec);
    remove_created();
    return write_failure ? cli::FailWrite(kTool, failure) : cli::FailInput(kTool, failure);
  }

  std::string summary;
  for (const RenderedShot& r : rendered) {
    const SceneShot& shot = scene->shots[static_cast<size_t>(r.shot_index)];
    int tags_in = 0, spots_in = 0;
    for (const TagView& t : r.tags) tags_in += t.in_image ? 1 : 0;
    for (const SpotView& s : r.spots) spots_in += s.visible ? 1 : 0;
    char line[512];
    std::snprintf(line, sizeof(line),
                  "%s  camera %s  lasers %d  tags in image %d/%zu  spots visible %d/%zu\n",
                  (out_dir / shot.file).string().c_str(), shot.camera.c_str(),
                  static_cast<int>(shot.lasers.size()), tags_in, r.tags.size(), spots_in,
                  r.spots.size());
    summary += line;
  }
  summary += truth_path + "\n";
  return cli::PrintToStdout(kTool, summary);
}

}  // namespace

Subcommand AddImagesCommand(CLI::App& app, Args* args) {
  CLI::App* images = app.add_subcommand(
      "images",
      "Render the images of a scene (docs/formats.md, 'Scene JSON'): every shot is the\n"
      "picture its calibrated camera takes, from its true pose, of the AprilTags\n"
      "(tag36h11) on the walls and of the laser spots of the sources lit in that shot on\n"
      "the module's surface (include/opl/lab/render_scene.h has the model). Tags: exact\n"
      "area-integrated edges, the scene's levels and blur. Spots: each beam's hit on the\n"
      "surface, drawn where it is in front of the camera, inside the image and on a\n"
      "surface facing the camera, as the projected disc of spots.diameter_mm (elliptical\n"
      "where the surface is oblique), with speckle; then shot and read noise once.\n"
      "\n"
      "Writes into DIR (created if missing), each file atomically:\n"
      "  <shot.file>   one PNG per shot (8 or 16 bit gray, image.bit_depth)\n"
      "  truth.json    the ground truth (format opl.scene_truth, docs/formats.md, 'Scene\n"
      "                truth JSON'): 3D tag centres and corners, 3D spot points by source\n"
      "                and beam (mm), and per shot the tag corner and spot centre pixels\n"
      "                (OpenCV convention: (0, 0) is the centre of the top-left pixel)\n"
      "and prints one line per image on stdout. On any error no image of this run is\n"
      "left in DIR. A progress bar is drawn on stderr when stderr is a terminal.\n"
      "Memory: about 18 bytes per pixel per thread (an 18 MP image: 330 MB).");
  images->add_option("--scene", args->scene_path, "Scene JSON (docs/formats.md, 'Scene JSON')")
      ->required()
      ->type_name("FILE");
  images->add_option("--out", args->out_path, "Output folder (created if missing)")
      ->required()
      ->type_name("DIR");
  images->add_option("--shots", args->shots,
                     "Render only these shots: comma-separated indices into the scene's shots\n"
                     "(default: all); truth.json then lists those shots only")
      ->type_name("LIST");
  CLI::Option* images_threads =
      images->add_option("--threads", args->threads,
                         "Shots rendered at once, >= 0; 0 = every core (default 1: memory)");
  images_threads->type_name("T");
  const std::string images_examples =
      "  opl_simulate images --scene examples/scene_small.json --out lab\n"
      "  opl_simulate images --scene examples/scene_small.json --out lab --shots 0,4 --threads 2\n";
  images->footer(opl::cli::HelpFooter(images_examples));
  return {images, [args, images_threads] {
    if (images_threads->count() == 0) args->threads = 1;
    return ImagesCommand(*args);
  }};
}

}  // namespace simulate_cli
}  // namespace opl
