#include "opl/io/module_design_json.h"

#include "opl/core/format.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/json_reader.h"
#include "io/module_design_json_internal.h"
#include "opl/geometry/rotation.h"
#include "opl/io/atomic_file.h"
#include "opl/model/beam_pattern.h"

namespace opl {
namespace {

using json = nlohmann::json;

constexpr int kVersion = 1;

class Reader : public json_internal::JsonReader {
 public:
  Reader(std::string name, std::string base_dir, std::string prefix = "")
      : JsonReader(std::move(name), std::move(prefix)), base_dir_(std::move(base_dir)) {}

  Result<ModuleDesign> Parse(const std::string& text) {
    Result<json> root = ParseText(text);
    if (!root.ok()) return root.status();
    return ParseRoot(*root, /*header_required=*/true);
  }

  // The design object; format and version are optional when !header_required
  // (a design inlined in another document) but checked when present.
  Result<ModuleDesign> ParseRoot(const json& root, bool header_required) {
    if (!root.is_object()) {
      return Error("", "expected a JSON object" +
                           std::string(header_required ? " at the top level" : "") + ", got " +
                           Describe(root));
    }
    if (header_required || Find(root, "format") != nullptr || Find(root, "version") != nullptr) {
      OPL_RETURN_IF_ERROR(CheckFormatAndVersion(root, "opl.module_design", kVersion));
    }
    return ParseBody(root);
  }

 private:
  Result<ModuleDesign> ParseBody(const json& root) {
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(CheckKeys(root, "",
                                  {"format", "version", "description", "sources", "surface",
                                   "spot_noise_mm", "noise_frame_rotation_xyz_rad", "provenance"}));
    if (const json* d = Find(root, "description")) {
      std::string ignored;
      OPL_RETURN_IF_ERROR(String(*d, "description", &ignored));
    }

    ModuleDesign design;
    OPL_RETURN_IF_ERROR(Require(root, "", "sources", &v));
    if (!v->is_array()) return Error("sources", "expected an array, got " + Describe(*v));
    if (v->empty()) return Error("sources", "must hold at least one source");
    std::map<std::string, size_t> index_of_name;
    for (size_t k = 0; k < v->size(); ++k) {
      const std::string path = "sources[" + std::to_string(k) + "]";
      SourceDesign source;
      OPL_RETURN_IF_ERROR(ParseSource((*v)[k], path, &source));
      const auto [it, inserted] = index_of_name.emplace(source.name, k);
      if (!inserted) {
        return Error(path + ".name", "duplicate source name \"" + source.name +
                                         "\" (also sources[" + std::to_string(it->second) + "])");
      }
      design.sources.push_back(std::move(source));
    }

    OPL_RETURN_IF_ERROR(Require(root, "", "surface", &v));
    OPL_RETURN_IF_ERROR(ParseSurface(*v, "surface", &design.surface));

    OPL_RETURN_IF_ERROR(RequiredVec3(root, "", "spot_noise_mm", &design.spot_noise_mm));
    for (int k = 0; k < 3; ++k) {
      if (design.spot_noise_mm[k] < 0.0) {
        return Error("spot_noise_mm[" + std::to_string(k) + "]",
                     "standard deviation must be >= 0, got " + Describe(root["spot_noise_mm"][k]));
      }
    }
    if (const json* r = Find(root, "noise_frame_rotation_xyz_rad")) {
      Eigen::Vector3d xyz;
      OPL_RETURN_IF_ERROR(Vec3(*r, "noise_frame_rotation_xyz_rad", &xyz));
      design.noise_frame_rotation = RotationFromXyzAnglesRad(xyz);
    }

    const Status st = design.Validate();
    if (!st.ok()) return Error("", st.message());
    return design;
  }

  Status ParseSource(const json& s, const std::string& path, SourceDesign* source) {
    OPL_RETURN_IF_ERROR(CheckObject(s, path));
    OPL_RETURN_IF_ERROR(CheckKeys(s, path,
                                  {"name", "description", "pattern", "beams_per_side",
                                   "full_angle_deg", "wavelength_nm", "pattern_file", "origin_mm",
                                   "rotation_xyz_rad", "beam_error_mrad", "beam_error_seed"}));
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(Require(s, path, "name", &v));
    OPL_RETURN_IF_ERROR(String(*v, path + ".name", &source->name));
    if (source->name.empty()) return Error(path + ".name", "must not be empty");
    if (const json* d = Find(s, "description")) {
      std::string ignored;
      OPL_RETURN_IF_ERROR(String(*d, path + ".description", &ignored));
    }

    std::string pattern;
    OPL_RETURN_IF_ERROR(Require(s, path, "pattern", &v));
    OPL_RETURN_IF_ERROR(String(*v, path + ".pattern", &pattern));
    if (pattern == "equal_angle") {
      source->pattern = PatternModel::kEqualAngle;
    } else if (pattern == "grating") {
      source->pattern = PatternModel::kGrating;
    } else if (pattern == "file") {
      source->pattern = PatternModel::kFile;
    } else {
      return Error(path + ".pattern", "expected \"equal_angle\", \"grating\" or \"file\", got " +
                                          Describe(*v));
    }
    const bool from_file = source->pattern == PatternModel::kFile;

    if (const json* w = Find(s, "wavelength_nm")) {
      OPL_RETURN_IF_ERROR(Number(*w, path + ".wavelength_nm", &source->wavelength_nm));
      if (!(source->wavelength_nm > 0.0)) {
        return Error(path + ".wavelength_nm", "must be > 0, got " + Describe(*w));
      }
    }

    const json* n = Find(s, "beams_per_side");
    if (n != nullptr) {
      OPL_RETURN_IF_ERROR(Integer(*n, path + ".beams_per_side", &source->beams_per_side));
      if (const std::string problem = BeamsPerSideProblem(source->beams_per_side);
          !problem.empty()) {
        return Error(path + ".beams_per_side", problem);
      }
    } else if (!from_file) {
      return Error(path + ".beams_per_side", "missing field");
    }

    if (!from_file) {
      if (Find(s, "pattern_file") != nullptr) {
        return Error(path + ".pattern_file", "only used with \"pattern\": \"file\"");
      }
      const json* a = nullptr;
      OPL_RETURN_IF_ERROR(Require(s, path, "full_angle_deg", &a));
      OPL_RETURN_IF_ERROR(Number(*a, path + ".full_angle_deg", &source->full_angle_deg));
      const double max_deg = source->pattern == PatternModel::kGrating ? 90.0 : 180.0;
      if (!(source->full_angle_deg > 0.0 && source->full_angle_deg < max_deg)) {
        return Error(path + ".full_angle_deg",
                     "must be > 0 and < " + std::to_string(static_cast<int>(max_deg)) +
                         (source->pattern == PatternModel::kGrating
                              ? " for a grating (corner orders must propagate)"
                              : "") +
                         ", got " + Describe(*a));
      }
    } else {
      if (Find(s, "full_angle_deg") != nullptr) {
        return Error(path + ".full_angle_deg", "not used with \"pattern\": \"file\" (remove it)");
      }
      const json* f = nullptr;
      OPL_RETURN_IF_ERROR(Require(s, path, "pattern_file", &f));
      std::string file;
      OPL_RETURN_IF_ERROR(String(*f, path + ".pattern_file", &file));
      if (file.empty()) return Error(path + ".pattern_file", "must not be empty");
      std::filesystem::path p(file);
      if (p.is_relative() && !base_dir_.empty()) p = std::filesystem::path(base_dir_) / p;
      source->pattern_file = p.string();
      Result<BeamPattern> read = ReadPatternCsv(source->pattern_file);
      if (!read.ok()) {
        // The pattern file's own code (IoError or ParseError), named by field;
        // its messages start with the path, from this file.
        const std::string message =
            json_internal::WithSafePathPrefix(read.status().message(), source->pattern_file);
        return Status(read.status().code(), Error(path + ".pattern_file", message).message());
      }
      if (n == nullptr) {
        source->beams_per_side = read->beams_per_side();
      } else if (read->beams_per_side() != source->beams_per_side) {
        return Error(path + ".beams_per_side",
                     std::to_string(source->beams_per_side) + " differs from the pattern file's " +
                         std::to_string(read->beams_per_side()));
      }
      // Not used by a file pattern; record the central row's span for reports.
      source->full_angle_deg = CentralRowSpanDeg(*read);
    }

    if (const json* e = Find(s, "beam_error_mrad")) {
      OPL_RETURN_IF_ERROR(Number(*e, path + ".beam_error_mrad", &source->beam_error_mrad));
      if (!(source->beam_error_mrad >= 0.0 && source->beam_error_mrad < 100.0)) {
        return Error(path + ".beam_error_mrad", "must be >= 0 and < 100, got " + Describe(*e));
      }
    }
    if (const json* e = Find(s, "beam_error_seed")) {
      int seed = 0;
      OPL_RETURN_IF_ERROR(Integer(*e, path + ".beam_error_seed", &seed));
      if (seed < 0) return Error(path + ".beam_error_seed", "must be >= 0, got " + Describe(*e));
      source->beam_error_seed = static_cast<uint64_t>(seed);
    }

    Eigen::Vector3d origin_mm, xyz_rad;
    OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "origin_mm", &origin_mm));
    OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "rotation_xyz_rad", &xyz_rad));
    source->scene_from_source = Rigid3d(RotationFromXyzAnglesRad(xyz_rad), origin_mm);
    return Status::Ok();
  }

  // Angle between the two outermost beams of the central row, degrees (0 when
  // they are missing).
  static double CentralRowSpanDeg(const BeamPattern& pattern) {
    const int n = pattern.beams_per_side();
    const int m = (n - 1) / 2;
    const Beam* left = pattern.Find(BeamId(m, 0, n));
    const Beam* right = pattern.Find(BeamId(m, n - 1, n));
    if (left == nullptr || right == nullptr) return 0.0;
    const double c = std::clamp(left->DirectionInSource().dot(right->DirectionInSource()), -1.0, 1.0);
    return std::acos(c) * 180.0 / kPi;
  }

  Status ParseSurface(const json& s, const std::string& path, Surface* surface) {
    OPL_RETURN_IF_ERROR(CheckObject(s, path));
    const json* v = nullptr;
    std::string type;
    OPL_RETURN_IF_ERROR(Require(s, path, "type", &v));
    OPL_RETURN_IF_ERROR(String(*v, path + ".type", &type));
    if (type == "plane") {
      OPL_RETURN_IF_ERROR(CheckKeys(s, path, {"type", "point_mm", "normal"}));
      PlaneSurface p;
      OPL_RETURN_IF_ERROR(ParsePlane(s, path, &p));
      *surface = p;
    } else if (type == "sphere") {
      OPL_RETURN_IF_ERROR(CheckKeys(s, path, {"type", "center_mm", "radius_mm"}));
      SphereSurface p;
      OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "center_mm", &p.center_mm));
      OPL_RETURN_IF_ERROR(RequiredNumber(s, path, "radius_mm", &p.radius_mm));
      if (!(p.radius_mm > 0.0)) {
        return Error(path + ".radius_mm", "must be > 0, got " + Describe(s["radius_mm"]));
      }
      *surface = p;
    } else if (type == "box_corner") {
      OPL_RETURN_IF_ERROR(CheckKeys(s, path, {"type", "corner_mm", "rotation_xyz_rad"}));
      BoxCornerSurface p;
      Eigen::Vector3d xyz;
      OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "corner_mm", &p.corner_mm));
      OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "rotation_xyz_rad", &xyz));
      p.scene_from_box = RotationFromXyzAnglesRad(xyz);
      *surface = p;
    } else if (type == "paraboloid") {
      OPL_RETURN_IF_ERROR(CheckKeys(s, path, {"type", "vertex_mm", "axis", "curvature_per_mm"}));
      ParaboloidSurface p;
      OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "vertex_mm", &p.vertex_mm));
      OPL_RETURN_IF_ERROR(NonZeroVec3(s, path, "axis", &p.axis));
      OPL_RETURN_IF_ERROR(RequiredNumber(s, path, "curvature_per_mm", &p.curvature_per_mm));
      *surface = p;
    } else if (type == "planes") {
      OPL_RETURN_IF_ERROR(CheckKeys(s, path, {"type", "planes"}));
      OPL_RETURN_IF_ERROR(Require(s, path, "planes", &v));
      const std::string list_path = path + ".planes";
      if (!v->is_array()) return Error(list_path, "expected an array, got " + Describe(*v));
      if (v->empty()) return Error(list_path, "must hold at least one plane");
      PlaneListSurface list;
      for (size_t k = 0; k < v->size(); ++k) {
        const std::string p_path = list_path + "[" + std::to_string(k) + "]";
        OPL_RETURN_IF_ERROR(CheckObject((*v)[k], p_path));
        OPL_RETURN_IF_ERROR(CheckKeys((*v)[k], p_path, {"point_mm", "normal"}));
        PlaneSurface p;
        OPL_RETURN_IF_ERROR(ParsePlane((*v)[k], p_path, &p));
        list.planes.push_back(p);
      }
      *surface = std::move(list);
    } else {
      return Error(path + ".type",
                   "unknown surface type " + Describe(*v) +
                       " (expected \"plane\", \"sphere\", \"box_corner\", \"paraboloid\" or "
                       "\"planes\")");
    }
    return Status::Ok();
  }

  Status ParsePlane(const json& s, const std::string& path, PlaneSurface* p) {
    OPL_RETURN_IF_ERROR(RequiredVec3(s, path, "point_mm", &p->point_mm));
    return NonZeroVec3(s, path, "normal", &p->normal);
  }

  std::string base_dir_;
};

}  // namespace

Result<ModuleDesign> ParseModuleDesignJson(const std::string& text,
                                           const std::string& name_for_messages,
                                           const std::string& base_dir) {
  try {
    return Reader(name_for_messages, base_dir).Parse(text);
  } catch (const std::exception& e) {
    // Defensive: nothing above should throw past the parse, but never let it escape.
    return Status::ParseError(name_for_messages + ": " + e.what());
  }
}

Result<ModuleDesign> ParseModuleDesignValue(const nlohmann::json& value,
                                            const std::string& name_for_messages,
                                            const std::string& field_path,
                                            const std::string& base_dir) {
  try {
    return Reader(name_for_messages, base_dir, field_path).ParseRoot(value, false);
  } catch (const std::exception& e) {
    return Status::ParseError(name_for_messages + ": " + field_path + ": " + e.what());
  }
}

Result<ModuleDesign> ReadModuleDesignJson(const std::string& path) {
  Result<std::string> text = ReadFileToString(path);  // regular files, bounded size
  if (!text.ok()) return text.status();
  const std::string base_dir = std::filesystem::path(path).parent_path().string();
  return ParseModuleDesignJson(*text, path, base_dir);
}

}  // namespace opl
