// A scene JSON for measuring, made from a session's files instead of by hand
// (`opl_scene init`; docs/cli.md "opl_scene", docs/formats.md "Scene JSON"):
// the photographs, the calibrated cameras (a cameras JSON, io/cameras_json.h,
// as `opl_camera calibrate` writes it) and the sequencer's per-frame metadata
// (io/frame_metadata_jsonl.h: which lasers were on, which slice).
//
//   SceneInitOptions o;
//   o.images_dir = "session/";                 // session/cam0/*.jpg, session/cam1/*.jpg
//   o.cameras = *ReadCamerasJson("cameras.json");
//   o.frames = *ReadFrameMetadataJsonl("frames.jsonl");
//   o.metadata_name = "frames.jsonl";
//   o.tag_size_mm = 140;
//   Result<SceneInit> init = InitScene(o);      // init->scene, init->ToText()
//
// Which images belong to which camera:
//  - one sub-folder per camera, named as the camera (images_dir/cam0/, ...):
//    every camera of the cameras file must have one; the images directly in
//    images_dir are then refused (ambiguous);
//  - else, with a single camera in the cameras file, the images directly in
//    images_dir are that camera's.
// Which image is which frame (the matching rule): a camera's images sorted by
// file name (byte order, as ListImageFiles) are its frames in the order of
// the metadata lines. Cameras number their files in shooting order
// (IMG_0001.JPG, ...); rename them if the counter wrapped during a session.
// EXIF time is not used: it has a resolution of one second (four frames
// take about 0.3 s) and the camera's clock is not the sequencer's. Each
// camera must have exactly one image per selected frame; any other count is
// refused, naming the folder and both counts.
//
// Which frames: every line of the metadata file, or those of `runs` (the
// daemon appends every run to one file). Manual triggers (sequence "manual")
// are frames too (the cameras fired). Measurement and calibration runs may
// not be mixed in one scene (refused: choose with `runs`).
//
// A PNG or JPEG whose header gives another size than its camera's is refused
// (an image in the wrong camera's folder); other formats are checked when
// measured.
//
// Each (frame, camera) becomes a shot, frame-major (frame 0 of every camera in
// the cameras file's order, then frame 1, ...): `camera`, `file` (relative to
// images_dir, e.g. "cam0/IMG_0001.JPG"), `lasers` (the source names of the
// lasers that were on, mapped by `laser_sources`; empty = a dark frame) and
// `slice` (the metadata's slice; 0 for a manual trigger).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/io/frame_metadata_jsonl.h"
#include "opl/lab/scene.h"

namespace opl {

struct SceneInitOptions {
  std::string images_dir;
  std::vector<SceneCamera> cameras;   // at least one, names unique
  std::vector<FrameMetadata> frames;  // the metadata file's lines
  std::string metadata_name;          // the metadata file, for messages
  std::vector<int> runs;              // the runs to take; empty: every line
  // Sequencer laser name -> the module's source name. A laser not listed is
  // named by its upper-case ("a" -> "A", "b" -> "B": the sources of the
  // bundled examples and of opl_simulate's designs).
  std::map<std::string, std::string> laser_sources;
  // When not empty (the sources of a module calibration), every source a lit
  // laser maps to must be one of them.
  std::vector<std::string> known_sources;
  double tag_size_mm = 0.0;  // the printed tags' black square, mm, > 0
  std::optional<SceneFrameTags> frame;
  std::optional<SceneArtifact> artifact;

  Status Validate() const;
};

struct SceneInit {
  Scene scene;          // valid as a measurement scene (Scene::Validate)
  std::vector<int> runs;              // the runs taken, ascending
  std::vector<FrameMetadata> frames;  // the frames taken, file order
  bool per_camera_folders = false;    // images in images_dir/<camera>/

  // The matching, for a person: one line per frame (line of the metadata,
  // run, slice, step, lasers on, and each camera's image).
  std::string ToText() const;
};

Result<SceneInit> InitScene(const SceneInitOptions& options);

}  // namespace opl
