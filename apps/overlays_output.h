// --overlays DIR of opl_measure and opl_calibrate (docs/images.md,
// "Overlays"): the checks made before any work, and the staging of the
// overlays with the run's other outputs (all or none, io/output_set.h).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cli_common.h"
#include "opl/core/status.h"
#include "opl/io/output_set.h"
#include "opl/lab/scene.h"

namespace opl {
namespace cli {

// Before any work (usage error, exit 2, one line naming the problem;
// std::nullopt when fine or when `overlays_dir` is empty):
//   - a folder that cannot take the overlays: a path that is not a folder, a
//     folder that is not writable, or a missing one whose nearest existing
//     parent is not a writable folder;
//   - two shots whose overlays would have the same name (OverlayFileName:
//     "a.png" and "a.jpg");
//   - an overlay that is the same file as a shot's image (in `images_dir`),
//     one of `inputs`, or one of `outputs`.
std::optional<int> CheckOverlaysOutput(const std::string& tool, const std::string& overlays_dir,
                                       const Scene& scene, const std::string& images_dir,
                                       const std::vector<NamedPath>& inputs,
                                       const std::vector<NamedPath>& outputs);

// The folders a run creates for its outputs, removed again (those left
// empty, deepest first) unless Keep() is called: a failed run leaves no
// folder behind either. Declare it before the OutputSet whose files go into
// them, so that it is destroyed after the set has removed its temporary files.
class NewFolders {
 public:
  NewFolders() = default;
  ~NewFolders();
  NewFolders(const NewFolders&) = delete;
  NewFolders& operator=(const NewFolders&) = delete;

  // Creates `dir` and its missing parents (an existing folder is fine).
  // IoError naming the folder when it cannot be created.
  Status Create(const std::filesystem::path& dir);
  void Keep() { keep_ = true; }

 private:
  std::vector<std::filesystem::path> created_;
  bool keep_ = false;
};

// Stages every (name, JPEG bytes) of RenderOverlays (pipeline/
// shot_overlays.h) as `overlays_dir`/name in `outputs` (stamped with the
// run's provenance), creating the folders through `folders`.
Status StageOverlays(const std::string& overlays_dir,
                     const std::vector<std::pair<std::string, std::string>>& overlays,
                     NewFolders* folders, OutputSet* outputs);

}  // namespace cli
}  // namespace opl
