// Test helpers for the image front end: the source folder, a fresh temp
// folder, and every shot of a scene rendered by the virtual lab into a folder
// (the truth stays in the returned renderer).
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "opl/core/status.h"
#include "opl/io/atomic_file.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/shot_file.h"

namespace opl::test {

// The source tree (OPL_SOURCE_DIR, set by ctest), else ".".
inline std::string SourceDir() {
  const char* dir = std::getenv("OPL_SOURCE_DIR");
  return dir ? dir : ".";
}

// An empty folder $TMPDIR/opl_<name>_<gtest random seed>, created anew.
inline std::filesystem::path FreshTempDir(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      ("opl_" + name + "_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Renders every shot of `scene` into `dir` (file names of the shots) on
// `threads` threads (RenderShot is thread-safe and a shot renders the same
// whatever else is rendered). The renderer holds the truth.
inline Result<SceneRenderer> RenderShotsTo(const Scene& scene, const std::filesystem::path& dir,
                                           int threads = 1) {
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  if (!renderer.ok()) return renderer.status();
  std::vector<Status> errors(scene.shots.size());
  const auto render = [&](size_t first) {
    for (size_t i = first; i < scene.shots.size(); i += static_cast<size_t>(threads)) {
      Result<RenderedShot> shot = renderer->RenderShot(static_cast<int>(i));
      if (!shot.ok()) {
        errors[i] = shot.status();
      } else {
        // Written as `opl_simulate images` writes it (format, quality, EXIF).
        const std::string path = (dir / scene.shots[i].file).string();
        Result<std::string> file = EncodeShotImage(shot->image, scene.image);
        errors[i] = file.ok() ? WriteFileAtomically(path, *file) : file.status();
      }
    }
  };
  std::vector<std::thread> workers;
  for (int t = 1; t < threads; ++t) workers.emplace_back(render, static_cast<size_t>(t));
  render(0);
  for (std::thread& w : workers) w.join();
  for (const Status& e : errors) {
    if (!e.ok()) return e;
  }
  return renderer;
}

}  // namespace opl::test
