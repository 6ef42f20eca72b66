#include "overlays_output.h"

#include <unistd.h>

#include <map>

#include "opl/pipeline/shot_overlays.h"

namespace opl {
namespace cli {
namespace {

namespace fs = std::filesystem;

// A path's absolute, weakly canonical form (symlinks of its existing part
// resolved): two paths naming the same file compare equal.
std::string Canonical(const fs::path& path) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  if (ec) return path.lexically_normal().string();
  const fs::path canonical = fs::weakly_canonical(absolute, ec);
  return (ec ? absolute.lexically_normal() : canonical).string();
}

bool WritableFolder(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && ::access(dir.c_str(), W_OK | X_OK) == 0;
}

}  // namespace

std::optional<int> CheckOverlaysOutput(const std::string& tool, const std::string& overlays_dir,
                                       const Scene& scene, const std::string& images_dir,
                                       const std::vector<NamedPath>& inputs,
                                       const std::vector<NamedPath>& outputs) {
  if (overlays_dir.empty()) return std::nullopt;
  const std::string option = "--overlays '" + overlays_dir + "'";
  std::error_code ec;
  const fs::path dir(overlays_dir);
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) {
      return Fail(tool, option + ": not a folder (see --help)", kExitUsage);
    }
    if (!WritableFolder(dir)) return Fail(tool, option + ": folder not writable", kExitUsage);
  } else {
    // The nearest existing parent must be a folder the run can create it in.
    fs::path parent = fs::absolute(dir, ec).lexically_normal();
    while (parent.has_relative_path() && !fs::exists(parent, ec)) parent = parent.parent_path();
    if (!WritableFolder(parent)) {
      return Fail(tool,
                  option + ": cannot be created ('" + parent.string() +
                      "' is not a writable folder)",
                  kExitUsage);
    }
  }
  // Who holds each path: the shots' images and the named inputs, then the
  // named outputs.
  std::map<std::string, std::string> inputs_by_path, outputs_by_path;
  for (const SceneShot& shot : scene.shots) {
    inputs_by_path.emplace(Canonical(fs::path(images_dir) / shot.file),
                           "the image of shot '" + shot.file + "'");
  }
  for (const NamedPath& in : inputs) {
    if (!in.path.empty()) inputs_by_path.emplace(Canonical(in.path), in.option);
  }
  for (const NamedPath& out : outputs) {
    if (!out.path.empty()) outputs_by_path.emplace(Canonical(out.path), out.option);
  }
  std::map<std::string, const SceneShot*> overlay_of;
  for (const SceneShot& shot : scene.shots) {
    const std::string name = OverlayFileName(shot.file);
    const std::string path = (dir / name).string();
    const std::string canonical = Canonical(path);
    const auto [other, inserted] = overlay_of.emplace(canonical, &shot);
    if (!inserted) {
      return Fail(tool,
                  "--overlays: shots '" + other->second->file + "' and '" + shot.file +
                      "' would both have the overlay '" + name +
                      "' (give one of the images another name)",
                  kExitUsage);
    }
    if (const auto in = inputs_by_path.find(canonical); in != inputs_by_path.end()) {
      return Fail(tool,
                  "--overlays: '" + path + "' (the overlay of shot '" + shot.file +
                      "') is the same file as " + in->second +
                      ": refusing to overwrite an input (see --help)",
                  kExitUsage);
    }
    if (const auto out = outputs_by_path.find(canonical); out != outputs_by_path.end()) {
      return Fail(tool,
                  "--overlays: '" + path + "' (the overlay of shot '" + shot.file +
                      "') is the same file as " + out->second +
                      ": each output needs its own file (see --help)",
                  kExitUsage);
    }
  }
  return std::nullopt;
}

NewFolders::~NewFolders() {
  if (keep_) return;
  std::error_code ignored;
  // Deepest first; fs::remove leaves a folder that is not empty.
  for (auto it = created_.rbegin(); it != created_.rend(); ++it) fs::remove(*it, ignored);
}

Status NewFolders::Create(const fs::path& dir) {
  std::vector<fs::path> missing;  // deepest first
  std::error_code ec;
  for (fs::path p = fs::absolute(dir, ec).lexically_normal(); p.has_relative_path();
       p = p.parent_path()) {
    if (fs::exists(p, ec)) break;
    missing.push_back(p);
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (!fs::create_directory(*it, ec) && ec) {
      return Status::IoError(dir.string() + ": cannot create the folder: " + ec.message());
    }
    created_.push_back(*it);
  }
  if (!fs::is_directory(dir, ec)) return Status::IoError(dir.string() + ": not a folder");
  return Status::Ok();
}

Status StageOverlays(const std::string& overlays_dir,
                     const std::vector<std::pair<std::string, std::string>>& overlays,
                     NewFolders* folders, OutputSet* outputs) {
  for (const auto& [name, bytes] : overlays) {
    const fs::path path = fs::path(overlays_dir) / name;
    OPL_RETURN_IF_ERROR(folders->Create(path.parent_path()));
    OPL_RETURN_IF_ERROR(outputs->Add(path.string(), bytes));
  }
  return Status::Ok();
}

}  // namespace cli
}  // namespace opl
