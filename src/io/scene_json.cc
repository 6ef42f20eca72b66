#include "opl/io/scene_json.h"

#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/json_reader.h"
#include "io/scene_camera_json.h"
#include "io/module_design_json_internal.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"
#include "opl/io/module_design_json.h"
#include "opl/vision/shot_image.h"

namespace opl {
namespace {

using json = nlohmann::json;

constexpr int kVersion = 1;

class SceneReader : public json_internal::JsonReader {
 public:
  Status OptionalBool(const json& obj, const std::string& path, const std::string& key,
                      bool* out) const {
    const json* v = Find(obj, key);
    if (v == nullptr) return Status::Ok();
    if (!v->is_boolean()) {
      return Error(Join(path, key), "expected true or false, got " + Describe(*v));
    }
    *out = v->get<bool>();
    return Status::Ok();
  }

  SceneReader(std::string name, std::string base_dir, SceneUse use)
      : JsonReader(std::move(name)), base_dir_(std::move(base_dir)), use_(use) {}

  Result<Scene> Parse(const std::string& text) {
    Result<json> root = ParseText(text);
    if (!root.ok()) return root.status();
    Scene scene;
    OPL_RETURN_IF_ERROR(ParseRoot(*root, &scene));
    if (Status s = scene.Validate(); !s.ok()) return Status::ParseError(name() + ": " + s.message());
    return scene;
  }

 private:
  Status ParseRoot(const json& root, Scene* scene) {
    if (!root.is_object()) {
      return Error("", "expected a JSON object at the top level, got " + Describe(root));
    }
    OPL_RETURN_IF_ERROR(CheckFormatAndVersion(root, "opl.scene", kVersion));
    OPL_RETURN_IF_ERROR(CheckKeys(root, "",
                                  {"format", "version", "description", "cameras", "tags", "frame",
                                   "artifact", "module", "spots", "image", "seed", "shots",
                                   "module_placements", "check_lengths", "provenance"}));
    if (const json* d = Find(root, "description")) {
      std::string ignored;
      OPL_RETURN_IF_ERROR(String(*d, "description", &ignored));
    }
    // How the file was made (docs/formats.md, "Provenance"): informative.
    if (const json* p = Find(root, "provenance")) OPL_RETURN_IF_ERROR(CheckObject(*p, "provenance"));
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(Require(root, "", "cameras", &v));
    OPL_RETURN_IF_ERROR(CheckArray(*v, "cameras"));
    for (size_t k = 0; k < v->size(); ++k) {
      SceneCamera camera;
      OPL_RETURN_IF_ERROR(ParseCamera((*v)[k], Index("cameras", k), &camera));
      scene->cameras.push_back(std::move(camera));
    }
    OPL_RETURN_IF_ERROR(Require(root, "", "tags", &v));
    OPL_RETURN_IF_ERROR(ParseTags(*v, "tags", &scene->tags));
    if (const json* f = Find(root, "frame")) {
      SceneFrameTags frame;
      OPL_RETURN_IF_ERROR(CheckObject(*f, "frame"));
      OPL_RETURN_IF_ERROR(CheckKeys(*f, "frame", {"origin_tag", "axis_tag", "plane_tag"}));
      OPL_RETURN_IF_ERROR(RequiredInteger(*f, "frame", "origin_tag", &frame.origin_tag));
      OPL_RETURN_IF_ERROR(RequiredInteger(*f, "frame", "axis_tag", &frame.axis_tag));
      OPL_RETURN_IF_ERROR(RequiredInteger(*f, "frame", "plane_tag", &frame.plane_tag));
      scene->frame = frame;
    }
    if (const json* a = Find(root, "artifact")) {
      SceneArtifact artifact;
      OPL_RETURN_IF_ERROR(CheckObject(*a, "artifact"));
      OPL_RETURN_IF_ERROR(
          CheckKeys(*a, "artifact", {"tag_1", "tag_2", "length_mm", "length_sigma_mm"}));
      OPL_RETURN_IF_ERROR(RequiredInteger(*a, "artifact", "tag_1", &artifact.tag_1));
      OPL_RETURN_IF_ERROR(RequiredInteger(*a, "artifact", "tag_2", &artifact.tag_2));
      OPL_RETURN_IF_ERROR(RequiredNumber(*a, "artifact", "length_mm", &artifact.length_mm));
      OPL_RETURN_IF_ERROR(OptionalNumber(*a, "artifact", "length_sigma_mm", &artifact.length_sigma_mm));
      scene->artifact = artifact;
    }
    if (const json* m = Find(root, "module")) OPL_RETURN_IF_ERROR(ParseModule(*m, scene));
    if (const json* s = Find(root, "spots")) {
      OPL_RETURN_IF_ERROR(CheckObject(*s, "spots"));
      OPL_RETURN_IF_ERROR(CheckKeys(
          *s, "spots", {"diameter_mm", "peak_fraction", "speckle_contrast", "speckle_grain_px"}));
      SpotLook& l = scene->spots;
      OPL_RETURN_IF_ERROR(OptionalNumber(*s, "spots", "diameter_mm", &l.diameter_mm));
      OPL_RETURN_IF_ERROR(OptionalNumber(*s, "spots", "peak_fraction", &l.peak_fraction));
      OPL_RETURN_IF_ERROR(OptionalNumber(*s, "spots", "speckle_contrast", &l.speckle_contrast));
      OPL_RETURN_IF_ERROR(OptionalNumber(*s, "spots", "speckle_grain_px", &l.speckle_grain_px));
    }
    if (const json* i = Find(root, "image")) {
      OPL_RETURN_IF_ERROR(CheckObject(*i, "image"));
      OPL_RETURN_IF_ERROR(CheckKeys(*i, "image",
                                    {"bit_depth", "background_level", "black_level", "white_level",
                                     "blur_sigma_px", "read_noise", "gain_e_per_dn",
                                     "subpixels_per_axis", "color", "laser_response_rgb", "bayer",
                                     "wall_texture", "wall_texture_contrast", "ambient_gradient",
                                     "ambient_angle_deg", "vignetting", "defocus_sigma_px",
                                     "distractors", "format", "jpeg_quality", "exif_orientation"}));
      ImageLook& l = scene->image;
      OPL_RETURN_IF_ERROR(OptionalInteger(*i, "image", "bit_depth", &l.bit_depth));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "background_level", &l.background_level));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "black_level", &l.black_level));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "white_level", &l.white_level));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "blur_sigma_px", &l.blur_sigma_px));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "read_noise", &l.read_noise));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "gain_e_per_dn", &l.gain_e_per_dn));
      OPL_RETURN_IF_ERROR(
          OptionalInteger(*i, "image", "subpixels_per_axis", &l.subpixels_per_axis));
      OPL_RETURN_IF_ERROR(OptionalBool(*i, "image", "color", &l.color));
      OPL_RETURN_IF_ERROR(OptionalBool(*i, "image", "bayer", &l.bayer));
      if (const json* r = Find(*i, "laser_response_rgb")) {
        Eigen::Vector3d rgb;
        OPL_RETURN_IF_ERROR(Vec3(*r, "image.laser_response_rgb", &rgb));
        l.laser_response_rgb = {rgb.x(), rgb.y(), rgb.z()};
      }
      if (const json* t = Find(*i, "wall_texture")) {
        OPL_RETURN_IF_ERROR(String(*t, "image.wall_texture", &l.wall_texture));
        if (l.wall_texture.empty()) return Error("image.wall_texture", "must not be empty");
        std::filesystem::path p(l.wall_texture);
        if (p.is_relative() && !base_dir_.empty()) p = std::filesystem::path(base_dir_) / p;
        l.wall_texture = p.string();
      }
      OPL_RETURN_IF_ERROR(
          OptionalNumber(*i, "image", "wall_texture_contrast", &l.wall_texture_contrast));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "ambient_gradient", &l.ambient_gradient));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "ambient_angle_deg", &l.ambient_angle_deg));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "vignetting", &l.vignetting));
      OPL_RETURN_IF_ERROR(OptionalNumber(*i, "image", "defocus_sigma_px", &l.defocus_sigma_px));
      OPL_RETURN_IF_ERROR(OptionalInteger(*i, "image", "distractors", &l.distractors));
      if (const json* f = Find(*i, "format")) {
        OPL_RETURN_IF_ERROR(String(*f, "image.format", &l.format));
      }
      OPL_RETURN_IF_ERROR(OptionalInteger(*i, "image", "jpeg_quality", &l.jpeg_quality));
      OPL_RETURN_IF_ERROR(OptionalInteger(*i, "image", "exif_orientation", &l.exif_orientation));
    }
    if (const json* s = Find(root, "seed")) {
      if (!s->is_number_unsigned()) {
        return Error("seed", "expected an integer >= 0, got " + Describe(*s));
      }
      scene->seed = s->get<uint64_t>();
    }
    if (const json* p = Find(root, "module_placements")) {
      OPL_RETURN_IF_ERROR(CheckArray(*p, "module_placements"));
      for (size_t k = 0; k < p->size(); ++k) {
        const std::string path = Index("module_placements", k);
        const json& e = (*p)[k];
        OPL_RETURN_IF_ERROR(CheckObject(e, path));
        OPL_RETURN_IF_ERROR(CheckKeys(e, path, {"name", "rotation_deg", "translation_mm"}));
        SceneModulePlacement placement;
        OPL_RETURN_IF_ERROR(RequiredString(e, path, "name", &placement.name));
        if (const json* r = Find(e, "rotation_deg")) {
          OPL_RETURN_IF_ERROR(Vec3(*r, Join(path, "rotation_deg"), &placement.rotation_deg));
        }
        if (const json* t = Find(e, "translation_mm")) {
          OPL_RETURN_IF_ERROR(Vec3(*t, Join(path, "translation_mm"), &placement.translation_mm));
        }
        scene->module_placements.push_back(std::move(placement));
      }
    }
    if (const json* c = Find(root, "check_lengths")) {
      OPL_RETURN_IF_ERROR(CheckArray(*c, "check_lengths"));
      for (size_t k = 0; k < c->size(); ++k) {
        const std::string path = Index("check_lengths", k);
        const json& e = (*c)[k];
        OPL_RETURN_IF_ERROR(CheckObject(e, path));
        OPL_RETURN_IF_ERROR(
            CheckKeys(e, path, {"name", "tag_1", "tag_2", "length_mm", "length_sigma_mm"}));
        SceneCheckLength length;
        OPL_RETURN_IF_ERROR(RequiredString(e, path, "name", &length.name));
        OPL_RETURN_IF_ERROR(RequiredInteger(e, path, "tag_1", &length.tag_1));
        OPL_RETURN_IF_ERROR(RequiredInteger(e, path, "tag_2", &length.tag_2));
        OPL_RETURN_IF_ERROR(RequiredNumber(e, path, "length_mm", &length.length_mm));
        OPL_RETURN_IF_ERROR(OptionalNumber(e, path, "length_sigma_mm", &length.length_sigma_mm));
        scene->check_lengths.push_back(std::move(length));
      }
    }
    OPL_RETURN_IF_ERROR(Require(root, "", "shots", &v));
    OPL_RETURN_IF_ERROR(CheckArray(*v, "shots"));
    for (size_t k = 0; k < v->size(); ++k) {
      SceneShot shot;
      OPL_RETURN_IF_ERROR(ParseShot((*v)[k], Index("shots", k), &shot));
      scene->shots.push_back(std::move(shot));
    }
    return Status::Ok();
  }

  Status RequiredInteger(const json& obj, const std::string& path, const std::string& key,
                         int* out) const {
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(Require(obj, path, key, &v));
    return Integer(*v, Join(path, key), out);
  }

  Status RequiredString(const json& obj, const std::string& path, const std::string& key,
                        std::string* out) const {
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(Require(obj, path, key, &v));
    return String(*v, Join(path, key), out);
  }

  Status ParseCamera(const json& c, const std::string& path, SceneCamera* camera) const {
    return json_internal::ParseSceneCamera(*this, c, path, camera);
  }

  Status ParseTags(const json& t, const std::string& path, SceneTags* tags) const {
    OPL_RETURN_IF_ERROR(CheckObject(t, path));
    OPL_RETURN_IF_ERROR(CheckKeys(t, path, {"family", "size_mm", "placements"}));
    if (const json* f = Find(t, "family")) {
      OPL_RETURN_IF_ERROR(String(*f, Join(path, "family"), &tags->family));
      if (tags->family != "tag36h11") {
        return Error(Join(path, "family"), "only \"tag36h11\" is supported, got " + Describe(*f));
      }
    }
    OPL_RETURN_IF_ERROR(RequiredNumber(t, path, "size_mm", &tags->size_mm));
    if (!(tags->size_mm > 0.0)) {
      return Error(Join(path, "size_mm"), "must be > 0, got " + FormatNumber(tags->size_mm));
    }
    const json* v = nullptr;
    const std::string lpath = Join(path, "placements");
    // Measuring finds the tags in the images: the list is optional then.
    if (use_ == SceneUse::kMeasure && Find(t, "placements") == nullptr) return Status::Ok();
    OPL_RETURN_IF_ERROR(Require(t, path, "placements", &v));
    OPL_RETURN_IF_ERROR(CheckArray(*v, lpath));
    std::map<int, size_t> index_of_id;
    for (size_t k = 0; k < v->size(); ++k) {
      const std::string ppath = Index(lpath, k);
      const json& p = (*v)[k];
      OPL_RETURN_IF_ERROR(CheckObject(p, ppath));
      OPL_RETURN_IF_ERROR(CheckKeys(p, ppath, {"id", "center_mm", "normal", "up"}));
      SceneTag tag;
      OPL_RETURN_IF_ERROR(RequiredInteger(p, ppath, "id", &tag.id));
      if (tag.id < 0 || tag.id > 586) {
        return Error(Join(ppath, "id"),
                     "must be in [0, 586] (tag36h11), got " + std::to_string(tag.id));
      }
      const auto [it, inserted] = index_of_id.emplace(tag.id, k);
      if (!inserted) {
        return Error(Join(ppath, "id"), "duplicate tag id " + std::to_string(tag.id) + " (also " +
                                            Index(lpath, it->second) + ")");
      }
      const bool posed = Find(p, "center_mm") || Find(p, "normal") || Find(p, "up");
      if (posed) {
        Eigen::Vector3d center, normal, up;
        OPL_RETURN_IF_ERROR(RequiredVec3(p, ppath, "center_mm", &center));
        OPL_RETURN_IF_ERROR(NonZeroVec3(p, ppath, "normal", &normal));
        OPL_RETURN_IF_ERROR(NonZeroVec3(p, ppath, "up", &up));
        const Eigen::Vector3d n = normal.normalized();
        const Eigen::Vector3d up_in_wall = up - up.dot(n) * n;
        if (up_in_wall.norm() < 1e-6 * up.norm()) {
          return Error(Join(ppath, "up"), "must not be parallel to the normal");
        }
        Eigen::Matrix3d R;  // columns: the tag's x, y, z in the scene
        R.col(1) = -up_in_wall.normalized();
        R.col(2) = -n;
        R.col(0) = R.col(1).cross(R.col(2));
        tag.scene_from_tag = Rigid3d(R, center);
      }
      tags->tags.push_back(tag);
    }
    return Status::Ok();
  }

  Status ParseModule(const json& m, Scene* scene) const {
    if (m.is_string()) {
      const std::string file = m.get<std::string>();
      if (file.empty()) return Error("module", "must not be empty");
      if (use_ == SceneUse::kMeasure) return Status::Ok();  // not used: not opened
      std::filesystem::path p(file);
      if (p.is_relative() && !base_dir_.empty()) p = std::filesystem::path(base_dir_) / p;
      Result<ModuleDesign> design = ReadModuleDesignJson(p.string());
      if (!design.ok()) {
        // The design reader's messages start with the path, from this file.
        const std::string message =
            json_internal::WithSafePathPrefix(design.status().message(), p.string());
        return Status(design.status().code(), Error("module", message).message());
      }
      scene->module = std::move(*design);
      return Status::Ok();
    }
    if (!m.is_object()) {
      return Error("module", "expected the path of a module design JSON or a design object, got " +
                                 Describe(m));
    }
    if (use_ == SceneUse::kMeasure) return Status::Ok();  // not used: not parsed
    Result<ModuleDesign> design = ParseModuleDesignValue(m, name(), "module", base_dir_);
    if (!design.ok()) return design.status();
    scene->module = std::move(*design);
    return Status::Ok();
  }

  Status ParseShot(const json& s, const std::string& path, SceneShot* shot) const {
    OPL_RETURN_IF_ERROR(CheckObject(s, path));
    OPL_RETURN_IF_ERROR(
        CheckKeys(s, path, {"camera", "file", "lasers", "slice", "placement", "exposure"}));
    OPL_RETURN_IF_ERROR(RequiredString(s, path, "camera", &shot->camera));
    OPL_RETURN_IF_ERROR(RequiredString(s, path, "file", &shot->file));
    if (const json* l = Find(s, "lasers")) {
      const std::string lpath = Join(path, "lasers");
      OPL_RETURN_IF_ERROR(CheckArray(*l, lpath));
      for (size_t k = 0; k < l->size(); ++k) {
        std::string name;
        OPL_RETURN_IF_ERROR(String((*l)[k], Index(lpath, k), &name));
        shot->lasers.push_back(name);
      }
    }
    OPL_RETURN_IF_ERROR(OptionalInteger(s, path, "slice", &shot->slice));
    if (const json* p = Find(s, "placement")) {
      OPL_RETURN_IF_ERROR(String(*p, Join(path, "placement"), &shot->placement));
      if (shot->placement.empty()) return Error(Join(path, "placement"), "must not be empty");
    }
    OPL_RETURN_IF_ERROR(OptionalNumber(s, path, "exposure", &shot->exposure));
    return Status::Ok();
  }

  std::string base_dir_;
  SceneUse use_;
};

}  // namespace

Result<Scene> ParseSceneJson(const std::string& text, const std::string& name_for_messages,
                             const std::string& base_dir, SceneUse use) {
  try {
    return SceneReader(name_for_messages, base_dir, use).Parse(text);
  } catch (const std::exception& e) {
    // Defensive: nothing above should throw past the parse, but never let it escape.
    return Status::ParseError(name_for_messages + ": " + e.what());
  }
}

std::string FormatSceneTruthJson(const SceneRenderer& renderer,
                                 const std::vector<RenderedShot>& shots) {
  using ojson = nlohmann::ordered_json;  // keys in the order written
  auto vec = [](const auto& v) {
    ojson a = ojson::array();
    for (Eigen::Index k = 0; k < v.size(); ++k) {
      if (std::isfinite(v[k])) {
        a.push_back(v[k]);
      } else {
        a.push_back(nullptr);
      }
    }
    return a;
  };
  ojson root;
  root["format"] = "opl.scene_truth";
  root["version"] = 1;
  root["units"] = "mm";
  root["pixel_convention"] = "OpenCV: (0, 0) is the centre of the top-left pixel, u right, v down";
  ojson tags = ojson::array();
  for (const SceneTagTruth& t : renderer.tags()) {
    ojson corners = ojson::array();
    for (const Eigen::Vector3d& c : t.corners_in_scene) corners.push_back(vec(c));
    tags.push_back({{"id", t.id}, {"center_mm", vec(t.center_in_scene)}, {"corners_mm", corners}});
  }
  root["tags"] = tags;
  ojson spots = ojson::array();
  for (const SceneSpotTruth& s : renderer.spots()) {
    ojson spot = {{"source", s.source},
                  {"beam", s.beam},
                  {"slice", s.slice},
                  {"point_mm", vec(s.point_in_scene)},
                  {"normal", vec(s.normal_in_scene)}};
    if (!s.placement.empty()) spot["placement"] = s.placement;
    spots.push_back(spot);
  }
  root["spots"] = spots;
  ojson shot_list = ojson::array();
  for (const RenderedShot& r : shots) {
    const SceneShot& shot = renderer.scene().shots[static_cast<size_t>(r.shot_index)];
    ojson tag_views = ojson::array();
    for (const TagView& v : r.tags) {
      ojson corners = ojson::array();
      for (const Eigen::Vector2d& c : v.corners_px) corners.push_back(vec(c));
      tag_views.push_back({{"id", v.id}, {"corners_px", corners}, {"facing", v.facing},
                           {"in_image", v.in_image}});
    }
    ojson spot_views = ojson::array();
    for (const SpotView& v : r.spots) {
      const SceneSpotTruth& s = renderer.spots()[static_cast<size_t>(v.spot_index)];
      ojson view = {{"spot", v.spot_index}, {"source", s.source}, {"beam", s.beam},
                   {"center_px", vec(v.center_px)}, {"visible", v.visible}};
      if (v.visible) {
        view["shape_px2"] = ojson::array({v.shape_covariance_px2(0, 0), v.shape_covariance_px2(0, 1),
                                         v.shape_covariance_px2(1, 1)});
        view["saturated_pixels"] = v.saturated_pixels;
      }
      spot_views.push_back(view);
    }
    ojson shot_json = {{"index", r.shot_index},
                       {"file", shot.file},
                       {"camera", shot.camera},
                       {"lasers", shot.lasers},
                       {"slice", shot.slice},
                       {"tags", tag_views},
                       {"spots", spot_views}};
    if (!shot.placement.empty()) shot_json["placement"] = shot.placement;
    if (shot.exposure != 1.0) shot_json["exposure"] = shot.exposure;
    if (!r.distractors.empty()) {
      ojson distractors = ojson::array();
      for (const Distractor& d : r.distractors) {
        distractors.push_back(
            {{"kind", DistractorKindName(d.kind)},
             {"center_px", vec(d.center_px)},
             {"shape_px2", ojson::array({d.shape_covariance_px2(0, 0), d.shape_covariance_px2(0, 1),
                                         d.shape_covariance_px2(1, 1)})},
             {"peak_fraction", d.peak_fraction}});
      }
      shot_json["distractors"] = distractors;
    }
    shot_list.push_back(shot_json);
  }
  root["shots"] = shot_list;
  return root.dump(1) + "\n";
}

Result<Scene> ReadSceneJson(const std::string& path, SceneUse use) {
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseSceneJson(*text, path, std::filesystem::path(path).parent_path().string(), use);
}

std::string FormatMeasurementSceneJson(const Scene& scene, const std::string& description,
                                       const std::string& provenance_json) {
  using ojson = nlohmann::ordered_json;
  ojson root;
  root["format"] = "opl.scene";
  root["version"] = kVersion;
  if (!description.empty()) root["description"] = description;
  if (!provenance_json.empty()) root["provenance"] = ojson::parse(provenance_json);
  root["cameras"] = ojson::array();
  for (const SceneCamera& c : scene.cameras) {
    root["cameras"].push_back(json_internal::SceneCameraToJson(c));
  }
  ojson tags;
  tags["family"] = scene.tags.family;
  tags["size_mm"] = scene.tags.size_mm;
  if (!scene.tags.tags.empty()) {
    tags["placements"] = ojson::array();
    for (const SceneTag& t : scene.tags.tags) tags["placements"].push_back({{"id", t.id}});
  }
  root["tags"] = tags;
  if (scene.frame) {
    root["frame"] = {{"origin_tag", scene.frame->origin_tag},
                     {"axis_tag", scene.frame->axis_tag},
                     {"plane_tag", scene.frame->plane_tag}};
  }
  if (scene.artifact) {
    root["artifact"] = {{"tag_1", scene.artifact->tag_1},
                        {"tag_2", scene.artifact->tag_2},
                        {"length_mm", scene.artifact->length_mm},
                        {"length_sigma_mm", scene.artifact->length_sigma_mm}};
  }
  if (!scene.module_placements.empty()) {
    root["module_placements"] = ojson::array();
    for (const SceneModulePlacement& p : scene.module_placements) {
      root["module_placements"].push_back(
          {{"name", p.name},
           {"rotation_deg", {p.rotation_deg.x(), p.rotation_deg.y(), p.rotation_deg.z()}},
           {"translation_mm", {p.translation_mm.x(), p.translation_mm.y(), p.translation_mm.z()}}});
    }
  }
  if (!scene.check_lengths.empty()) {
    root["check_lengths"] = ojson::array();
    for (const SceneCheckLength& c : scene.check_lengths) {
      root["check_lengths"].push_back({{"name", c.name},
                                       {"tag_1", c.tag_1},
                                       {"tag_2", c.tag_2},
                                       {"length_mm", c.length_mm},
                                       {"length_sigma_mm", c.length_sigma_mm}});
    }
  }
  root["shots"] = ojson::array();
  for (const SceneShot& s : scene.shots) {
    ojson shot = {{"camera", s.camera}, {"file", s.file}, {"lasers", s.lasers}, {"slice", s.slice}};
    if (!s.placement.empty()) shot["placement"] = s.placement;
    if (s.exposure != 1.0) shot["exposure"] = s.exposure;
    root["shots"].push_back(shot);
  }
  return root.dump(2) + "\n";
}

}  // namespace opl
