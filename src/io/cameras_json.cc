#include "opl/io/cameras_json.h"

#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/json_reader.h"
#include "io/scene_camera_json.h"
#include "opl/core/message_text.h"
#include "opl/io/atomic_file.h"
#include "opl/io/scene_json.h"

namespace opl {
namespace {

using json = nlohmann::json;
using json_internal::JsonReader;

constexpr int kVersion = 1;

}  // namespace

Result<std::vector<SceneCamera>> ParseCamerasJson(const std::string& text, const std::string& name) {
  const JsonReader r(name);
  Result<json> parsed = r.ParseText(text);
  if (!parsed.ok()) return parsed.status();
  const json& root = *parsed;
  if (!root.is_object()) {
    return r.Error("", "expected a JSON object at the top level, got " + JsonReader::Describe(root));
  }
  OPL_RETURN_IF_ERROR(r.CheckFormatAndVersion(root, "opl.cameras", kVersion));
  OPL_RETURN_IF_ERROR(r.CheckKeys(root, "", {"format", "version", "description", "cameras", "provenance"}));
  if (const json* d = JsonReader::Find(root, "description")) {
    std::string ignored;
    OPL_RETURN_IF_ERROR(r.String(*d, "description", &ignored));
  }
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(r.Require(root, "", "cameras", &v));
  OPL_RETURN_IF_ERROR(r.CheckArray(*v, "cameras"));
  if (v->empty()) return r.Error("cameras", "must hold at least one camera");
  std::vector<SceneCamera> cameras;
  std::set<std::string> names;
  for (size_t k = 0; k < v->size(); ++k) {
    SceneCamera camera;
    const std::string path = JsonReader::Index("cameras", k);
    OPL_RETURN_IF_ERROR(json_internal::ParseSceneCamera(r, (*v)[k], path, &camera));
    if (camera.name.empty()) return r.Error(JsonReader::Join(path, "name"), "must not be empty");
    if (!names.insert(camera.name).second) {
      return r.Error(JsonReader::Join(path, "name"),
                     "duplicate camera name " + QuoteForMessage(camera.name));
    }
    cameras.push_back(std::move(camera));
  }
  return cameras;
}

Result<std::vector<SceneCamera>> ReadCamerasJson(const std::string& path) {
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseCamerasJson(*text, path);
}

std::string FormatCamerasJson(const std::vector<SceneCamera>& cameras) {
  nlohmann::ordered_json root;
  root["format"] = "opl.cameras";
  root["version"] = kVersion;
  root["cameras"] = nlohmann::ordered_json::array();
  for (const SceneCamera& c : cameras) root["cameras"].push_back(json_internal::SceneCameraToJson(c));
  return root.dump(2) + "\n";
}

namespace {

// The document's format, "opl.scene" or "opl.cameras", after checking that
// the document reads with the reader of that format.
Result<std::string> CheckedFormat(const std::string& text, const std::string& name, const std::string& base_dir) {
  const JsonReader r(name);
  Result<json> parsed = r.ParseText(text);
  if (!parsed.ok()) return parsed.status();
  std::string format;
  if (parsed->is_object()) {
    if (const json* f = JsonReader::Find(*parsed, "format"); f != nullptr && f->is_string()) {
      format = f->get<std::string>();
    }
  }
  if (format == "opl.scene") {
    OPL_RETURN_IF_ERROR(ParseSceneJson(text, name, base_dir).status());
  } else if (format == "opl.cameras") {
    OPL_RETURN_IF_ERROR(ParseCamerasJson(text, name).status());
  } else {
    return r.Error("format", "expected \"opl.scene\" or \"opl.cameras\" (a scene or a cameras JSON)");
  }
  return format;
}

}  // namespace

Status CheckCamerasBlockDocument(const std::string& text, const std::string& name, const std::string& base_dir) {
  return CheckedFormat(text, name, base_dir).status();
}

Result<CamerasBlockUpdate> UpdateCamerasBlock(const std::string& text, const std::string& name,
                                              const std::string& base_dir, const SceneCamera& camera) {
  // The document as it is must be valid, by the reader of its format.
  Result<std::string> checked = CheckedFormat(text, name, base_dir);
  if (!checked.ok()) return checked.status();
  const std::string format = *checked;
  auto validate = [&](const std::string& document) -> Status {
    if (format == "opl.scene") return ParseSceneJson(document, name, base_dir).status();
    return ParseCamerasJson(document, name).status();
  };

  nlohmann::ordered_json root = nlohmann::ordered_json::parse(text);  // valid: parsed above
  nlohmann::ordered_json& cameras = root["cameras"];
  const nlohmann::ordered_json block = json_internal::SceneCameraToJson(camera);
  CamerasBlockUpdate update;
  for (auto& c : cameras) {
    if (c.value("name", std::string()) != camera.name) continue;
    for (const char* key : {"width_px", "height_px", "intrinsics"}) c[key] = block[key];
    if (block.contains("calibration")) {
      c["calibration"] = block["calibration"];
    } else {
      c.erase("calibration");
    }
    update.replaced = true;
  }
  if (!update.replaced) cameras.push_back(block);
  update.text = root.dump(2) + "\n";
  if (Status s = validate(update.text); !s.ok()) {
    return Status::ParseError(name + ": the updated document does not validate: " + s.message());
  }
  return update;
}

}  // namespace opl
