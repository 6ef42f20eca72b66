// Scene JSON: a photogrammetry set-up (lab/scene.h) as a file (full format:
// docs/formats.md, "Scene JSON").
//
//   {
//     "format": "opl.scene", "version": 1,
//     "cameras": [
//       {"name": "cam0", "width_px": 1024, "height_px": 768,
//        "intrinsics": {"fx": 1000, "fy": 1000, "cx": 511.5, "cy": 383.5,
//                       "k1": -0.05, "k2": 0, "p1": 0, "p2": 0, "k3": 0},
//        "pose": {"center_mm": [..], "look_at_mm": [..], "roll_deg": 0}}, ...],
//     "tags": {"family": "tag36h11", "size_mm": 140,
//              "placements": [{"id": 0, "center_mm": [..], "normal": [..],
//                              "up": [..]}, ...]},
//     "frame": {"origin_tag": 0, "axis_tag": 1, "plane_tag": 2},
//     "artifact": {"tag_1": 8, "tag_2": 9, "length_mm": 1000, "length_sigma_mm": 0.01},
//     "module": "scene_small_module.json",      (or an inline design object)
//     "spots": {"diameter_mm": 8, "peak_fraction": 0.6, ...},
//     "image": {"bit_depth": 8, "background_level": 0.25, ...},
//     "seed": 1,
//     "shots": [{"camera": "cam0", "file": "cam0_A.png", "lasers": ["A"], "slice": 0}, ...]
//   }
//
// A camera's pose is either "pose" (CamFromSceneLookingAt: centre, the point
// the optical axis passes through, roll about it in degrees) or
// "cam_from_scene" ({"quaternion_wxyz": [..], "translation_mm": [..]}), or
// absent (a measured scene). A tag placement gives the centre of the black
// square, the wall's normal pointing OUT of the wall towards the viewer, and
// a direction in the wall that is "up" as the tag is printed (projected on
// the wall); the tag frame is then x right, y = -up, z = -normal (into the
// wall). Placements may give only the id (a measured scene: pose identity).
//
// "module" as a string is the path of a module design JSON (io/
// module_design_json.h), relative to the scene file's folder; as an object
// it is the design itself ("format"/"version" may be omitted).
//
// Errors are one line, "<file>: <field path>: <what is wrong>", e.g.
//   scene.json: shots[3].camera: no camera named 'cam9'
// IoError when the file (or the module file) cannot be read, ParseError for
// invalid JSON, a missing field, a field of the wrong type or out of its
// domain, an unknown field (typos must not pass silently), and anything
// Scene::Validate() rejects.
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/scene.h"

namespace opl {

// What a scene is read for. A scene JSON serves two uses (lab/scene.h), and a
// field one use does not need must not stop it (issue 18: a copied example
// failed to measure because its `module` file was missing):
//  - kRender (`opl_simulate images`, the default): every field is read; the
//    module (a path or an inline design) is read and checked, and the shots'
//    lasers and slices are checked against it; `tags.placements` is required.
//  - kMeasure (`opl_measure --images`, `opl_calibrate --images`, the image
//    front end): the module is neither opened nor parsed (it must still be a
//    path or an object; Scene::module stays empty) and `tags.placements` is
//    optional (the front end finds the tags in the images; when placements
//    are listed, the frame and artifact tags must be among them). Every other
//    field present is read and checked as for rendering (a typo or a value out
//    of range is still an error), and unknown fields are still refused.
enum class SceneUse { kRender, kMeasure };

// Reads and validates (Scene::Validate) a scene file; a module given as a
// path is resolved against the folder of `path`.
Result<Scene> ReadSceneJson(const std::string& path, SceneUse use = SceneUse::kRender);

// The same from text; `name_for_messages` starts every message, and relative
// module and pattern paths are resolved against `base_dir` (the working
// directory when empty).
Result<Scene> ParseSceneJson(const std::string& text, const std::string& name_for_messages,
                             const std::string& base_dir = "", SceneUse use = SceneUse::kRender);

// A scene JSON for measuring (format "opl.scene", version 1) holding what the
// image front end uses: `description` (when not empty), the cameras
// (name, size, intrinsics, calibration record; no pose), `tags` (family,
// size_mm, and the placements' ids when the scene lists tags, without poses),
// `frame`, `artifact`, the shots, and `provenance_json` (a JSON object, e.g.
// FormatProvenanceJson, io/provenance.h) as "provenance" when not empty.
// The module, the looks, the seed and true poses are not written. Numbers are
// written to full precision; ParseSceneJson(..., SceneUse::kMeasure) reads
// the same scene back.
std::string FormatMeasurementSceneJson(const Scene& scene, const std::string& description,
                                       const std::string& provenance_json = "");

// The scene truth JSON (format "opl.scene_truth", version 1; docs/formats.md,
// "Scene truth JSON") of rendered shots: every tag's 3D centre and corners,
// every spot's source, beam, slice and 3D point (mm, scene frame), and per
// shot its file, camera, lasers and slice, the tags' corner pixels and the
// spots' centre pixels (OpenCV pixel convention; null behind the camera),
// with in_image / visible flags. `shots` need not hold their images.
std::string FormatSceneTruthJson(const SceneRenderer& renderer,
                                 const std::vector<RenderedShot>& shots);

}  // namespace opl
