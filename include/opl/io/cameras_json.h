// Cameras JSON: calibrated cameras as a file of their own, and the `cameras`
// block of a scene JSON updated in place (docs/formats.md, "Cameras JSON").
// `opl_camera calibrate` writes both.
//
//   {"format": "opl.cameras", "version": 1,
//    "cameras": [{"name": "cam0", "width_px": 640, "height_px": 480,
//                 "intrinsics": {"fx": 536.1, "fy": 536.0, "cx": 342.4, "cy": 235.5,
//                                "k1": -0.265, "k2": -0.047, "p1": 0.0018, "p2": -0.0003, "k3": 0},
//                 "calibration": {"intrinsics_std": {"fx": 2.1, ...}, "rms_px": 0.19,
//                                 "views": 13, "corners": 702, "board": "chessboard ..."}}]}
//
// A camera here is exactly a camera of a scene JSON (the same reader:
// io/scene_json.h, with the same limits and messages), so the block can be
// pasted into a scene. "calibration" is optional in both.
//
// Errors are one line, "<file>: <field path>: <what is wrong>" (ParseError;
// IoError when unreadable).
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"

namespace opl {

// Reads a cameras JSON: at least one camera, names unique.
Result<std::vector<SceneCamera>> ReadCamerasJson(const std::string& path);
Result<std::vector<SceneCamera>> ParseCamerasJson(const std::string& text,
                                                  const std::string& name_for_messages);

// The cameras as a cameras JSON document (poses are not written).
std::string FormatCamerasJson(const std::vector<SceneCamera>& cameras);

// OK when `text` is a valid scene JSON or cameras JSON (what
// UpdateCamerasBlock accepts), else the reader's ParseError; lets a tool
// refuse a bad --into before its long work.
Status CheckCamerasBlockDocument(const std::string& text, const std::string& name_for_messages,
                                 const std::string& base_dir);

// What UpdateCamerasBlock did.
struct CamerasBlockUpdate {
  std::string text;       // the whole updated document
  bool replaced = false;  // a camera of that name was there (else it was appended)
};

// Puts `camera` into the `cameras` block of `text`, a scene JSON
// ("opl.scene") or a cameras JSON ("opl.cameras"): a camera of the same name
// has its width_px, height_px, intrinsics and calibration replaced (its pose
// is kept), else the camera is appended. Every other field of the document is
// kept, in its order (the text is re-indented). The document must be valid
// before (ParseError naming `name_for_messages` otherwise) and is checked
// again after, by the reader of its format; relative paths in a scene are
// resolved against `base_dir`.
Result<CamerasBlockUpdate> UpdateCamerasBlock(const std::string& text,
                                              const std::string& name_for_messages,
                                              const std::string& base_dir,
                                              const SceneCamera& camera);

}  // namespace opl
