// Private to src/io: one camera of a scene JSON's `cameras` block, read and
// written, shared by the scene reader (io/scene_json.h) and the cameras JSON
// (io/cameras_json.h) so that both apply the same rules with the same
// messages (docs/formats.md, "Scene JSON" and "Cameras JSON").
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "io/json_reader.h"
#include "opl/core/status.h"
#include "opl/lab/scene.h"

namespace opl {
namespace json_internal {

// Reads cameras[k] at `path` (e.g. "cameras[2]"): name, image size, intrinsics
// (held to the limits of vision/intrinsics_limits.h), the optional true pose
// and the optional "calibration" record. ParseError naming the field.
Status ParseSceneCamera(const JsonReader& reader, const nlohmann::json& c, const std::string& path,
                        SceneCamera* camera);

// The camera as JSON: name, width_px, height_px, intrinsics and, when set,
// calibration (the pose is not written: the caller keeps or adds it).
nlohmann::ordered_json SceneCameraToJson(const SceneCamera& camera);

}  // namespace json_internal
}  // namespace opl
