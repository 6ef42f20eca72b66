#include "opl/io/module_design_json.h"

#include "opl/core/format.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "opl/geometry/rotation.h"

namespace opl {
namespace {

using json = nlohmann::json;

constexpr int kVersion = 1;
std::string Describe(const json& v) {
  std::string d = v.dump();
  if (d.size() > 40) d = d.substr(0, 37) + "...";
  return d;
}

// (line, column), 1-based, of byte offset `byte` (0-based) of `text`.
std::pair<size_t, size_t> LineColumn(const std::string& text, size_t byte) {
  size_t line = 1, column = 1;
  for (size_t i = 0; i < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return {line, column};
}

// Detects duplicate keys (nlohmann keeps the last one silently) and records
// the field path of the first one.
class DuplicateKeyFinder {
 public:
  bool operator()(int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start: {
        std::string path;
        if (!frames_.empty()) {
          const Frame& parent = frames_.back();
          path = parent.is_array ? parent.path + "[" + std::to_string(parent.count) + "]"
                                 : Join(parent.path, parent.last_key);
        }
        frames_.push_back({event == json::parse_event_t::array_start, 0, path, "", {}});
        break;
      }
      case json::parse_event_t::key: {
        if (frames_.empty()) break;
        Frame& f = frames_.back();
        f.last_key = parsed.is_string() ? parsed.get<std::string>() : parsed.dump();
        if (!f.keys.insert(f.last_key).second && duplicate_.empty()) {
          duplicate_ = Join(f.path, f.last_key);
        }
        break;
      }
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!frames_.empty()) frames_.pop_back();
        if (!frames_.empty() && frames_.back().is_array) ++frames_.back().count;
        break;
      case json::parse_event_t::value:
        if (!frames_.empty() && frames_.back().is_array) ++frames_.back().count;
        break;
    }
    return true;
  }
  const std::string& duplicate() const { return duplicate_; }

 private:
  struct Frame {
    bool is_array = false;
    size_t count = 0;
    std::string path;
    std::string last_key;
    std::set<std::string> keys;
  };
  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  std::vector<Frame> frames_;
  std::string duplicate_;
};

class Reader {
 public:
  Reader(std::string name, std::string base_dir)
      : name_(std::move(name)), base_dir_(std::move(base_dir)) {}

  Result<ModuleDesign> Parse(const std::string& text) {
    json root;
    // nlohmann copies the callback: keep the finder's state behind a shared_ptr.
    auto finder = std::make_shared<DuplicateKeyFinder>();
    try {
      root = json::parse(
          text, [finder](int depth, json::parse_event_t event, json& parsed) {
            return (*finder)(depth, event, parsed);
          });
    } catch (const json::parse_error& e) {
      const auto [line, column] = LineColumn(text, e.byte > 0 ? e.byte - 1 : 0);
      return Status::ParseError(name_ + ":" + std::to_string(line) + ":" +
                                std::to_string(column) + ": invalid JSON: " + StripNlohmann(e.what()));
    } catch (const json::exception& e) {
      // e.g. out_of_range.406 "number overflow parsing '1e999'": locate the literal.
      const std::string what = StripNlohmann(e.what());
      std::string where = name_;
      const size_t q = what.find('\'');
      const size_t q2 = q == std::string::npos ? q : what.find('\'', q + 1);
      if (q2 != std::string::npos) {
        const size_t at = text.find(what.substr(q + 1, q2 - q - 1));
        if (at != std::string::npos) {
          const auto [line, column] = LineColumn(text, at);
          where += ":" + std::to_string(line) + ":" + std::to_string(column);
        }
      }
      return Status::ParseError(where + ": invalid JSON: " + what +
                                " (numbers must be finite doubles)");
    }
    if (!finder->duplicate().empty()) {
      return Error(finder->duplicate(), "duplicate key (each field may appear once)");
    }
    return ParseRoot(root);
  }

 private:
  static std::string StripNlohmann(const std::string& what) {
    // "[json.exception.parse_error.101] parse error at line 3, column 7: syntax error ..."
    std::string s = what;
    if (!s.empty() && s[0] == '[') {
      const size_t close = s.find("] ");
      if (close != std::string::npos) s = s.substr(close + 2);
    }
    const std::string at = "parse error at line ";
    if (s.compare(0, at.size(), at) == 0) {
      const size_t colon = s.find(": ");
      if (colon != std::string::npos) s = s.substr(colon + 2);
    }
    return s;
  }

  Status Error(const std::string& path, const std::string& what) const {
    return Status::ParseError(name_ + ": " + (path.empty() ? "" : path + ": ") + what);
  }

  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }

  Status CheckObject(const json& v, const std::string& path) const {
    if (!v.is_object()) return Error(path, "expected an object, got " + Describe(v));
    return Status::Ok();
  }

  Status CheckKeys(const json& obj, const std::string& path,
                   const std::set<std::string>& allowed) const {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (!allowed.count(it.key())) {
        std::string list;
        for (const std::string& k : allowed) list += (list.empty() ? "" : ", ") + k;
        return Error(Join(path, it.key()), "unknown field (allowed here: " + list + ")");
      }
    }
    return Status::Ok();
  }

  // The field, or nullptr when absent.
  static const json* Find(const json& obj, const std::string& key) {
    const auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
  }

  Status Require(const json& obj, const std::string& path, const std::string& key,
                 const json** out) const {
    *out = Find(obj, key);
    if (*out == nullptr) return Error(Join(path, key), "missing field");
    return Status::Ok();
  }

  Status Number(const json& v, const std::string& path, double* out) const {
    if (!v.is_number()) return Error(path, "expected a number, got " + Describe(v));
    *out = v.get<double>();
    if (!std::isfinite(*out)) return Error(path, "not a finite number");
    return Status::Ok();
  }

  Status Integer(const json& v, const std::string& path, int* out) const {
    if (!v.is_number_integer()) return Error(path, "expected an integer, got " + Describe(v));
    const auto x = v.get<long long>();
    if (x < -1000000000LL || x > 1000000000LL) return Error(path, "integer out of range");
    *out = static_cast<int>(x);
    return Status::Ok();
  }

  Status String(const json& v, const std::string& path, std::string* out) const {
    if (!v.is_string()) return Error(path, "expected a string, got " + Describe(v));
    *out = v.get<std::string>();
    return Status::Ok();
  }

  Status Vec3(const json& v, const std::string& path, Eigen::Vector3d* out) const {
    if (!v.is_array() || v.size() != 3) {
      return Error(path, "expected an array of 3 numbers, got " + Describe(v));
    }
    for (int k = 0; k < 3; ++k) {
      OPL_RETURN_IF_ERROR(Number(v[k], path + "[" + std::to_string(k) + "]", &(*out)[k]));
    }
    return Status::Ok();
  }

  Status RequiredNumber(const json& obj, const std::string& path, const std::string& key,
                        double* out) const {
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(Require(obj, path, key, &v));
    return Number(*v, Join(path, key), out);
  }

  Status RequiredVec3(const json& obj, const std::string& path, const std::string& key,
                      Eigen::Vector3d* out) const {
    const json* v = nullptr;
    OPL_RETURN_IF_ERROR(Require(obj, path, key, &v));
    return Vec3(*v, Join(path, key), out);
  }

  Status NonZeroVec3(const json& obj, const std::string& path, const std::string& key,
                     Eigen::Vector3d* out) const {
    OPL_RETURN_IF_ERROR(RequiredVec3(obj, path, key, out));
    if (out->norm() == 0.0) return Error(Join(path, key), "must not be the zero vector");
    return Status::Ok();
  }

  Result<ModuleDesign> ParseRoot(const json& root) {
    if (!root.is_object()) {
      return Error("", "expected a JSON object at the top level, got " + Describe(root));
    }
    const json* v = nullptr;
    std::string format;
    OPL_RETURN_IF_ERROR(Require(root, "", "format", &v));
    OPL_RETURN_IF_ERROR(String(*v, "format", &format));
    if (format != "opl.module_design") {
      return Error("format", "expected \"opl.module_design\", got " + Describe(*v));
    }
    int version = 0;
    OPL_RETURN_IF_ERROR(Require(root, "", "version", &v));
    OPL_RETURN_IF_ERROR(Integer(*v, "version", &version));
    if (version != kVersion) {
      return Error("version", "unsupported version " + std::to_string(version) +
                                  " (this reader reads version " + std::to_string(kVersion) + ")");
    }
    OPL_RETURN_IF_ERROR(CheckKeys(root, "",
                                  {"format", "version", "description", "sources", "surface",
                                   "spot_noise_mm", "noise_frame_rotation_xyz_rad"}));
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
      if (source->beams_per_side < 3 || source->beams_per_side % 2 == 0) {
        return Error(path + ".beams_per_side", "must be odd and >= 3, got " + Describe(*n));
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
        return Status(read.status().code(),
                      name_ + ": " + path + ".pattern_file: " + read.status().message());
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

  std::string name_;
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

Result<ModuleDesign> ReadModuleDesignJson(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return Status::IoError(path + ": cannot read: is a directory");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IoError(path + ": cannot open: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Status::IoError(path + ": read error");
  const std::string base_dir = std::filesystem::path(path).parent_path().string();
  return ParseModuleDesignJson(text.str(), path, base_dir);
}

}  // namespace opl
