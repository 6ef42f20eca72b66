#include "io/scene_camera_json.h"

#include <cmath>
#include <string>

#include "opl/core/format.h"
#include "opl/vision/intrinsics_limits.h"
#include "opl/vision/shot_image.h"

namespace opl {
namespace json_internal {
namespace {

using json = nlohmann::json;

constexpr const char* kParameterNames[kNumCameraParameters] = {"fx", "fy", "cx", "cy", "k1",
                                                               "k2", "p1", "p2", "k3"};

Status RequiredInteger(const JsonReader& r, const json& obj, const std::string& path,
                       const std::string& key, int* out) {
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(r.Require(obj, path, key, &v));
  return r.Integer(*v, JsonReader::Join(path, key), out);
}

Status RequiredString(const JsonReader& r, const json& obj, const std::string& path,
                      const std::string& key, std::string* out) {
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(r.Require(obj, path, key, &v));
  return r.String(*v, JsonReader::Join(path, key), out);
}

// The "calibration" record: intrinsics_std (required), rms_px, views,
// corners, board (optional).
Status ParseCalibrationRecord(const JsonReader& r, const json& cal, const std::string& path,
                              SceneCameraCalibration* record) {
  OPL_RETURN_IF_ERROR(r.CheckObject(cal, path));
  OPL_RETURN_IF_ERROR(r.CheckKeys(cal, path, {"intrinsics_std", "rms_px", "views", "corners", "board"}));
  const json* s = nullptr;
  OPL_RETURN_IF_ERROR(r.Require(cal, path, "intrinsics_std", &s));
  const std::string spath = JsonReader::Join(path, "intrinsics_std");
  OPL_RETURN_IF_ERROR(r.CheckObject(*s, spath));
  OPL_RETURN_IF_ERROR(r.CheckKeys(*s, spath, {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"}));
  for (int k = 0; k < kNumCameraParameters; ++k) {
    double& value = record->intrinsics_std[static_cast<size_t>(k)];
    OPL_RETURN_IF_ERROR(r.OptionalNumber(*s, spath, kParameterNames[k], &value));
    if (!(value >= 0.0)) {
      return r.Error(JsonReader::Join(spath, kParameterNames[k]),
                     "a standard deviation must be >= 0, got " + FormatNumber(value));
    }
  }
  OPL_RETURN_IF_ERROR(r.OptionalNumber(cal, path, "rms_px", &record->rms_px));
  if (!(record->rms_px >= 0.0)) {
    return r.Error(JsonReader::Join(path, "rms_px"), "must be >= 0, got " + FormatNumber(record->rms_px));
  }
  OPL_RETURN_IF_ERROR(r.OptionalInteger(cal, path, "views", &record->num_views));
  OPL_RETURN_IF_ERROR(r.OptionalInteger(cal, path, "corners", &record->num_corners));
  if (record->num_views < 0) {
    return r.Error(JsonReader::Join(path, "views"), "must be >= 0, got " + std::to_string(record->num_views));
  }
  if (record->num_corners < 0) {
    return r.Error(JsonReader::Join(path, "corners"),
                   "must be >= 0, got " + std::to_string(record->num_corners));
  }
  if (const json* b = JsonReader::Find(cal, "board")) {
    OPL_RETURN_IF_ERROR(r.String(*b, JsonReader::Join(path, "board"), &record->board));
  }
  return Status::Ok();
}

}  // namespace

Status ParseSceneCamera(const JsonReader& r, const json& c, const std::string& path,
                        SceneCamera* camera) {
  OPL_RETURN_IF_ERROR(r.CheckObject(c, path));
  OPL_RETURN_IF_ERROR(r.CheckKeys(
      c, path, {"name", "width_px", "height_px", "intrinsics", "pose", "cam_from_scene", "calibration"}));
  OPL_RETURN_IF_ERROR(RequiredString(r, c, path, "name", &camera->name));
  CameraIntrinsics& in = camera->intrinsics;
  OPL_RETURN_IF_ERROR(RequiredInteger(r, c, path, "width_px", &in.width_px));
  OPL_RETURN_IF_ERROR(RequiredInteger(r, c, path, "height_px", &in.height_px));
  // The image size limit of vision/shot_image.h: a camera of 100000 x 100000
  // pixels made opl_simulate images allocate 10^10 pixels a frame.
  const std::string side = std::to_string(kMaxImageSidePx);
  if (in.width_px < 1 || in.width_px > kMaxImageSidePx) {
    return r.Error(JsonReader::Join(path, "width_px"),
                 "must be in [1, " + side + "], got " + std::to_string(in.width_px));
  }
  if (in.height_px < 1 || in.height_px > kMaxImageSidePx) {
    return r.Error(JsonReader::Join(path, "height_px"),
                 "must be in [1, " + side + "], got " + std::to_string(in.height_px));
  }
  if (static_cast<long long>(in.width_px) * in.height_px > kMaxImagePixels) {
    return r.Error(path, std::to_string(in.width_px) + " x " + std::to_string(in.height_px) +
                           " pixels is beyond the limit of " +
                           std::to_string(kMaxImagePixels / 1000000) + " megapixels");
  }
  const json* v = nullptr;
  const std::string ipath = JsonReader::Join(path, "intrinsics");
  OPL_RETURN_IF_ERROR(r.Require(c, path, "intrinsics", &v));
  OPL_RETURN_IF_ERROR(r.CheckObject(*v, ipath));
  OPL_RETURN_IF_ERROR(r.CheckKeys(*v, ipath, {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"}));
  OPL_RETURN_IF_ERROR(r.RequiredNumber(*v, ipath, "fx", &in.fx_px));
  OPL_RETURN_IF_ERROR(r.RequiredNumber(*v, ipath, "fy", &in.fy_px));
  OPL_RETURN_IF_ERROR(r.RequiredNumber(*v, ipath, "cx", &in.cx_px));
  OPL_RETURN_IF_ERROR(r.RequiredNumber(*v, ipath, "cy", &in.cy_px));
  OPL_RETURN_IF_ERROR(r.OptionalNumber(*v, ipath, "k1", &in.k1));
  OPL_RETURN_IF_ERROR(r.OptionalNumber(*v, ipath, "k2", &in.k2));
  OPL_RETURN_IF_ERROR(r.OptionalNumber(*v, ipath, "p1", &in.p1));
  OPL_RETURN_IF_ERROR(r.OptionalNumber(*v, ipath, "p2", &in.p2));
  OPL_RETURN_IF_ERROR(r.OptionalNumber(*v, ipath, "k3", &in.k3));
  if (!(in.fx_px > 0.0)) {
    return r.Error(JsonReader::Join(ipath, "fx"), "must be > 0, got " + FormatNumber(in.fx_px));
  }
  if (!(in.fy_px > 0.0)) {
    return r.Error(JsonReader::Join(ipath, "fy"), "must be > 0, got " + FormatNumber(in.fy_px));
  }
  if (const IntrinsicsFault fault = FindImplausibleIntrinsics(in); !fault.field.empty()) {
    return r.Error(JsonReader::Join(ipath, fault.field), fault.what);
  }

  const json* pose = JsonReader::Find(c, "pose");
  const json* direct = JsonReader::Find(c, "cam_from_scene");
  if (pose != nullptr && direct != nullptr) {
    return r.Error(JsonReader::Join(path, "cam_from_scene"),
                 "give either \"pose\" or \"cam_from_scene\", not both");
  }
  if (pose != nullptr) {
    const std::string ppath = JsonReader::Join(path, "pose");
    OPL_RETURN_IF_ERROR(r.CheckObject(*pose, ppath));
    OPL_RETURN_IF_ERROR(r.CheckKeys(*pose, ppath, {"center_mm", "look_at_mm", "roll_deg"}));
    Eigen::Vector3d center, look_at;
    double roll_deg = 0.0;
    OPL_RETURN_IF_ERROR(r.RequiredVec3(*pose, ppath, "center_mm", &center));
    OPL_RETURN_IF_ERROR(r.RequiredVec3(*pose, ppath, "look_at_mm", &look_at));
    OPL_RETURN_IF_ERROR(r.OptionalNumber(*pose, ppath, "roll_deg", &roll_deg));
    Result<Rigid3d> cam_from_scene = CamFromSceneLookingAt(center, look_at, roll_deg * kPi / 180.0);
    if (!cam_from_scene.ok()) return r.Error(ppath, cam_from_scene.status().message());
    camera->cam_from_scene = *cam_from_scene;
  } else if (direct != nullptr) {
    const std::string dpath = JsonReader::Join(path, "cam_from_scene");
    OPL_RETURN_IF_ERROR(r.CheckObject(*direct, dpath));
    OPL_RETURN_IF_ERROR(r.CheckKeys(*direct, dpath, {"quaternion_wxyz", "translation_mm"}));
    OPL_RETURN_IF_ERROR(r.Require(*direct, dpath, "quaternion_wxyz", &v));
    const std::string qpath = JsonReader::Join(dpath, "quaternion_wxyz");
    if (!v->is_array() || v->size() != 4) {
      return r.Error(qpath, "expected an array of 4 numbers, got " + JsonReader::Describe(*v));
    }
    double q[4];
    for (size_t k = 0; k < 4; ++k) OPL_RETURN_IF_ERROR(r.Number((*v)[k], JsonReader::Index(qpath, k), &q[k]));
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (std::abs(norm - 1.0) > 1e-6) {
      return r.Error(qpath, "must be a unit quaternion (norm " + FormatNumber(norm) + ")");
    }
    Eigen::Vector3d t;
    OPL_RETURN_IF_ERROR(r.RequiredVec3(*direct, dpath, "translation_mm", &t));
    camera->cam_from_scene = Rigid3d(Eigen::Quaterniond(q[0], q[1], q[2], q[3]), t);
  }
  if (const json* cal = JsonReader::Find(c, "calibration")) {
    SceneCameraCalibration record;
    OPL_RETURN_IF_ERROR(ParseCalibrationRecord(r, *cal, JsonReader::Join(path, "calibration"), &record));
    camera->calibration = record;
  }
  return Status::Ok();
}

nlohmann::ordered_json SceneCameraToJson(const SceneCamera& camera) {
  using ojson = nlohmann::ordered_json;
  const CameraIntrinsics& in = camera.intrinsics;
  const auto packed = in.Packed();
  ojson intrinsics = ojson::object();
  for (int k = 0; k < kNumCameraParameters; ++k) intrinsics[kParameterNames[k]] = packed[static_cast<size_t>(k)];
  ojson out = {{"name", camera.name}, {"width_px", in.width_px}, {"height_px", in.height_px},
               {"intrinsics", intrinsics}};
  if (camera.calibration) {
    const SceneCameraCalibration& cal = *camera.calibration;
    ojson std_json = ojson::object();
    for (int k = 0; k < kNumCameraParameters; ++k) {
      std_json[kParameterNames[k]] = cal.intrinsics_std[static_cast<size_t>(k)];
    }
    out["calibration"] = {{"intrinsics_std", std_json}, {"rms_px", cal.rms_px}, {"views", cal.num_views},
                          {"corners", cal.num_corners}, {"board", cal.board}};
  }
  return out;
}

}  // namespace json_internal
}  // namespace opl
