#include "opl/pipeline/scene_init.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/pipeline/calibrate_camera_images.h"
#include "opl/vision/shot_image.h"

namespace opl {
namespace {

namespace fs = std::filesystem;

std::string Upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::toupper(c); });
  return s;
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

std::string JoinInts(const std::vector<int>& values) {
  std::string out;
  for (int v : values) out += (out.empty() ? "" : ", ") + std::to_string(v);
  return out;
}

// The image files of `folder` as paths relative to `root`, by name; an empty
// list when the folder holds none.
Result<std::vector<std::string>> RelativeImages(const std::string& root, const std::string& folder) {
  Result<std::vector<std::string>> files = ListImageFiles(folder);
  if (!files.ok()) {
    std::error_code ec;
    if (fs::is_directory(folder, ec)) return std::vector<std::string>{};  // no image in it
    return files.status();
  }
  // Lexically (symbolic links are not resolved: an image may be a link),
  // with "session/" and "./session" the same folder as "session".
  fs::path base = fs::path(root).lexically_normal();
  if (!base.has_filename() && base.has_parent_path()) base = base.parent_path();
  std::vector<std::string> relative;
  for (const std::string& f : *files) {
    relative.push_back(fs::path(f).lexically_normal().lexically_relative(base).generic_string());
  }
  return relative;
}

// One line of the matching table.
std::string Row(const std::string& line, const std::string& run, const std::string& slice, const std::string& step,
                const std::string& lasers, const std::string& images) {
  auto pad = [](const std::string& s, size_t w) { return s.size() >= w ? s + " " : s + std::string(w - s.size(), ' '); };
  return "  " + pad(line, 6) + pad(run, 5) + pad(slice, 6) + pad(step, 9) + pad(lasers, 11) + images + "\n";
}

}  // namespace

Status SceneInitOptions::Validate() const {
  if (images_dir.empty()) return Status::InvalidArgument("images: no folder given");
  if (cameras.empty()) return Status::InvalidArgument("cameras: at least one camera is needed");
  if (frames.empty()) return Status::InvalidArgument(metadata_name + ": no frame");
  if (!(tag_size_mm > 0.0 && tag_size_mm < 1e6)) {
    return Status::InvalidArgument("tag size: must be > 0 mm (and below 1e6), got " + FormatNumber(tag_size_mm));
  }
  for (const auto& [laser, source] : laser_sources) {
    if (laser.empty() || source.empty()) {
      return Status::InvalidArgument("laser mapping: empty name in '" + laser + "=" + source + "'");
    }
  }
  return Status::Ok();
}

Result<SceneInit> InitScene(const SceneInitOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  const std::string& meta = options.metadata_name;
  SceneInit init;

  // The frames taken.
  const std::set<int> wanted(options.runs.begin(), options.runs.end());
  std::set<int> present, taken;
  for (const FrameMetadata& f : options.frames) {
    present.insert(f.run);
    if (wanted.empty() || wanted.count(f.run)) {
      init.frames.push_back(f);
      taken.insert(f.run);
    }
  }
  for (int run : wanted) {
    if (!present.count(run)) {
      return Status::InvalidArgument(meta + ": no frame of run " + std::to_string(run) + " (the file has runs " +
                                     JoinInts({present.begin(), present.end()}) + ")");
    }
  }
  init.runs.assign(taken.begin(), taken.end());
  const FrameMetadata* measurement = nullptr;
  const FrameMetadata* calibration = nullptr;
  for (const FrameMetadata& f : init.frames) {
    if (f.sequence == "measurement" && !measurement) measurement = &f;
    if (f.sequence == "calibration" && !calibration) calibration = &f;
  }
  if (measurement && calibration) {
    return Status::InvalidArgument(
        meta + ": measurement (run " + std::to_string(measurement->run) + ", line " +
        std::to_string(measurement->line) + ") and calibration (run " + std::to_string(calibration->run) +
        ", line " + std::to_string(calibration->line) +
        ") frames in one scene: choose the runs of one session (opl_scene init --run N)");
  }

  // The lasers' source names.
  auto source_of = [&](const std::string& laser) {
    const auto it = options.laser_sources.find(laser);
    return it != options.laser_sources.end() ? it->second : Upper(laser);
  };
  for (const auto& [laser, source] : options.laser_sources) {
    bool seen = false;
    for (const FrameMetadata& f : init.frames) seen = seen || f.lasers.count(laser) > 0;
    if (!seen) {
      return Status::InvalidArgument("laser mapping '" + laser + "=" + source + "': no laser '" + laser + "' in " +
                                     meta);
    }
  }
  if (!options.known_sources.empty()) {
    for (const FrameMetadata& f : init.frames) {
      for (const std::string& laser : f.LasersOn()) {
        const std::string source = source_of(laser);
        if (std::find(options.known_sources.begin(), options.known_sources.end(), source) ==
            options.known_sources.end()) {
          return Status::InvalidArgument(meta + ":" + std::to_string(f.line) + ": laser '" + laser +
                                         "' maps to source '" + source + "', not a source of the calibration (" +
                                         JoinNames(options.known_sources) + "): map it with --laser " + laser +
                                         "=SOURCE");
        }
      }
    }
  }

  // The images of each camera.
  std::error_code ec;
  if (!fs::is_directory(options.images_dir, ec)) {
    return Status::IoError(options.images_dir + ": not a folder");
  }
  std::vector<std::string> with_folder, without_folder;
  for (const SceneCamera& c : options.cameras) {
    (fs::is_directory(fs::path(options.images_dir) / c.name, ec) ? with_folder : without_folder).push_back(c.name);
  }
  Result<std::vector<std::string>> top = RelativeImages(options.images_dir, options.images_dir);
  if (!top.ok()) return top.status();
  std::vector<std::vector<std::string>> images_of_camera(options.cameras.size());
  if (!with_folder.empty()) {
    init.per_camera_folders = true;
    if (!without_folder.empty()) {
      return Status::InvalidArgument(options.images_dir + ": no folder for camera(s) " + JoinNames(without_folder) +
                                     " (there is one for " + JoinNames(with_folder) +
                                     "): put each camera's images in a folder named as the camera");
    }
    if (!top->empty()) {
      return Status::InvalidArgument(options.images_dir + ": " + std::to_string(top->size()) +
                                     " image(s) beside the camera folders (e.g. " + QuoteForMessage((*top)[0]) +
                                     "): to which camera do they belong? move them into its folder");
    }
    for (size_t c = 0; c < options.cameras.size(); ++c) {
      Result<std::vector<std::string>> files = RelativeImages(
          options.images_dir, (fs::path(options.images_dir) / options.cameras[c].name).string());
      if (!files.ok()) return files.status();
      images_of_camera[c] = *files;
    }
  } else {
    if (options.cameras.size() > 1) {
      std::vector<std::string> names;
      for (const SceneCamera& c : options.cameras) names.push_back(c.name);
      return Status::InvalidArgument(options.images_dir + ": the cameras file has " +
                                     std::to_string(options.cameras.size()) + " cameras (" + JoinNames(names) +
                                     "): put each camera's images in a folder named as the camera (" +
                                     (fs::path(options.images_dir) / names[0]).string() + "/, ...)");
    }
    images_of_camera[0] = *top;
  }
  const std::string runs_text = options.runs.empty() ? "every run" : "run(s) " + JoinInts(init.runs);
  for (size_t c = 0; c < options.cameras.size(); ++c) {
    const size_t n = images_of_camera[c].size();
    if (n != init.frames.size()) {
      const std::string folder =
          init.per_camera_folders ? (fs::path(options.images_dir) / options.cameras[c].name).string()
                                  : options.images_dir;
      return Status::InvalidArgument(
          folder + ": " + std::to_string(n) + " image(s) of camera '" + options.cameras[c].name + "' for " +
          std::to_string(init.frames.size()) + " frame(s) in " + meta + " (" + runs_text +
          "): each frame needs exactly one image per camera, matched in order (the k-th image by file name is "
          "the k-th frame)");
    }
  }

  // Each image's size, from its header (PNG, JPEG; others are left to the
  // measurement): an image of another camera is refused now, not after the
  // session's detection.
  for (size_t c = 0; c < options.cameras.size(); ++c) {
    const CameraIntrinsics& in = options.cameras[c].intrinsics;
    for (const std::string& file : images_of_camera[c]) {
      const std::string path = (fs::path(options.images_dir) / file).string();
      const auto size = ReadImageHeaderSize(path);
      if (size && (size->first != in.width_px || size->second != in.height_px)) {
        return Status::InvalidArgument(path + ": " + std::to_string(size->first) + " x " +
                                       std::to_string(size->second) + " pixels, but camera '" +
                                       options.cameras[c].name + "' is " + std::to_string(in.width_px) + " x " +
                                       std::to_string(in.height_px) + ": not this camera's image?");
      }
    }
  }

  // The scene.
  Scene& scene = init.scene;
  scene.cameras = options.cameras;
  for (SceneCamera& c : scene.cameras) c.cam_from_scene.reset();  // a measured scene
  scene.tags.size_mm = options.tag_size_mm;
  scene.frame = options.frame;
  scene.artifact = options.artifact;
  for (size_t k = 0; k < init.frames.size(); ++k) {
    const FrameMetadata& f = init.frames[k];
    std::vector<std::string> lasers;
    for (const std::string& laser : f.LasersOn()) lasers.push_back(source_of(laser));
    std::sort(lasers.begin(), lasers.end());
    if (std::adjacent_find(lasers.begin(), lasers.end()) != lasers.end()) {
      return Status::InvalidArgument(meta + ":" + std::to_string(f.line) +
                                     ": two lasers on map to one source: check --laser");
    }
    for (size_t c = 0; c < options.cameras.size(); ++c) {
      SceneShot shot;
      shot.camera = options.cameras[c].name;
      shot.file = images_of_camera[c][k];
      shot.lasers = lasers;
      shot.slice = f.slice.value_or(0);
      scene.shots.push_back(std::move(shot));
    }
  }
  if (Status s = scene.Validate(); !s.ok()) return Status::InvalidArgument("the scene made: " + s.message());
  return init;
}

std::string SceneInit::ToText() const {
  std::string out = "opl_scene init: " + std::to_string(frames.size()) + " frame(s) x " +
                    std::to_string(scene.cameras.size()) + " camera(s) = " + std::to_string(scene.shots.size()) +
                    " shots; runs " + JoinInts(runs) + "; images " +
                    (per_camera_folders ? "in one folder per camera" : "of the one camera") +
                    ", matched to frames by file name order\n";
  out += Row("line", "run", "slice", "step", "lasers", "images");
  const size_t num_cameras = scene.cameras.size();
  for (size_t k = 0; k < frames.size(); ++k) {
    const FrameMetadata& f = frames[k];
    const SceneShot& first = scene.shots[k * num_cameras];
    std::string lasers = first.lasers.empty() ? "off (dark)" : JoinNames(first.lasers);
    std::string images;
    for (size_t c = 0; c < num_cameras; ++c) images += (c ? " " : "") + scene.shots[k * num_cameras + c].file;
    out += Row(std::to_string(f.line), std::to_string(f.run), f.slice ? std::to_string(*f.slice) : "-",
               f.step.empty() ? "-" : SafeForMessage(f.step, 20), lasers, SafeForMessage(images, 2000));
  }
  return out;
}

}  // namespace opl
