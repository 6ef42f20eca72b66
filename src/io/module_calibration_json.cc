#include "opl/io/module_calibration_json.h"

#include <cmath>
#include <limits>
#include <algorithm>
#include <map>
#include <utility>

#include <nlohmann/json.hpp>

#include "io/csv.h"
#include "io/json_reader.h"
#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/geometry/rotation.h"
#include "opl/io/atomic_file.h"
#include "opl/model/beam_pattern.h"

namespace opl {
namespace {

using nlohmann::json;

constexpr const char* kFormat = "opl.module_calibration";
constexpr int kVersion = 1;

// Reads fields of a parsed document, naming the file and the JSON path of the
// field in every error.
class Fields {
 public:
  explicit Fields(std::string name) : name_(std::move(name)) {}

  Status Error(const std::string& path, const std::string& what) const {
    return Status::ParseError(name_ + ": " + path + ": " + what);
  }

  // The member `key` of object `obj` (at `path`), or an error when missing.
  Result<const json*> Member(const json& obj, const std::string& path,
                             const std::string& key) const {
    const std::string where = Join(path, key);
    if (!obj.is_object()) {
      return Error(path.empty() ? "(top level)" : path,
                   "expected an object, got " + std::string(obj.type_name()));
    }
    auto it = obj.find(key);
    if (it == obj.end()) return Error(where, "missing");
    return &*it;
  }

  Result<double> Number(const json& value, const std::string& path) const {
    if (!value.is_number()) {
      return Error(path, std::string("expected a finite number, got ") + value.type_name());
    }
    const double v = value.get<double>();
    if (!std::isfinite(v)) return Error(path, "expected a finite number, got " + value.dump());
    return v;
  }

  Result<int> Int(const json& value, const std::string& path) const {
    if (!value.is_number_integer()) {
      return Error(path, std::string("expected an integer, got ") +
                             (value.is_number() ? value.dump() : value.type_name()));
    }
    if (value.is_number_unsigned()) {
      if (value.get<uint64_t>() > static_cast<uint64_t>(std::numeric_limits<int>::max())) {
        return Error(path, "integer out of range: " + value.dump());
      }
    } else {
      const int64_t v = value.get<int64_t>();
      if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
        return Error(path, "integer out of range: " + value.dump());
      }
    }
    return static_cast<int>(value.get<int64_t>());
  }

  Result<std::string> String(const json& value, const std::string& path) const {
    if (!value.is_string()) {
      return Error(path, std::string("expected a string, got ") + value.type_name());
    }
    return value.get<std::string>();
  }

  Result<const json*> Array(const json& value, const std::string& path) const {
    if (!value.is_array()) {
      return Error(path, std::string("expected an array, got ") + value.type_name());
    }
    return &value;
  }

  // An array of exactly n finite numbers.
  template <int N>
  Result<Eigen::Matrix<double, N, 1>> Vector(const json& value, const std::string& path) const {
    if (!value.is_array() || value.size() != static_cast<size_t>(N)) {
      return Error(path, "expected an array of " + std::to_string(N) + " numbers, got " +
                             (value.is_array() ? std::to_string(value.size()) + " elements"
                                               : std::string(value.type_name())));
    }
    Eigen::Matrix<double, N, 1> v;
    for (int i = 0; i < N; ++i) {
      Result<double> x = Number(value[static_cast<size_t>(i)], Index(path, i));
      if (!x.ok()) return x.status();
      v[i] = *x;
    }
    return v;
  }

  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  static std::string Index(const std::string& path, size_t i) {
    return path + "[" + std::to_string(i) + "]";
  }

 private:
  std::string name_;
};

// Declares `lhs` from a Result, or returns its error. Local to this file.
#define OPL_ASSIGN_OR_RETURN(lhs, expr)                 \
  auto lhs##_result = (expr);                           \
  if (!lhs##_result.ok()) return lhs##_result.status(); \
  auto lhs = std::move(*lhs##_result)

// A 3x3 matrix written as [[..,..,..], [..], [..]].
Result<Eigen::Matrix3d> Matrix3(const Fields& f, const json& value, const std::string& path) {
  if (!value.is_array() || value.size() != 3) {
    return f.Error(path, "expected a 3x3 matrix [[a, b, c], [d, e, f], [g, h, i]]");
  }
  Eigen::Matrix3d M;
  for (size_t r = 0; r < 3; ++r) {
    OPL_ASSIGN_OR_RETURN(row, f.Vector<3>(value[r], Fields::Index(path, r)));
    M.row(static_cast<int>(r)) = row.transpose();
  }
  return M;
}

// The optional "quality" object of a source (written by opl_calibrate).
Result<SourceCalibrationQuality> ParseQuality(const Fields& f, const json& q,
                                              const std::string& path) {
  SourceCalibrationQuality quality;
  const std::pair<const char*, int*> ints[] = {{"slices", &quality.slices},
                                               {"samples_used", &quality.samples_used},
                                               {"samples_flagged", &quality.samples_flagged},
                                               {"beams_dropped", &quality.beams_dropped}};
  for (const auto& [key, target] : ints) {
    OPL_ASSIGN_OR_RETURN(member, f.Member(q, path, key));
    OPL_ASSIGN_OR_RETURN(value, f.Int(*member, path + "." + key));
    if (value < 0) return f.Error(path + "." + key, "must be >= 0, got " + member->dump());
    *target = value;
  }
  const std::pair<const char*, double*> numbers[] = {
      {"rms_residual_urad", &quality.rms_residual_urad},
      {"variance_factor", &quality.variance_factor},
      {"mean_point_to_ray_mm", &quality.mean_point_to_ray_mm},
      {"max_point_to_ray_mm", &quality.max_point_to_ray_mm}};
  for (const auto& [key, target] : numbers) {
    OPL_ASSIGN_OR_RETURN(member, f.Member(q, path, key));
    OPL_ASSIGN_OR_RETURN(value, f.Number(*member, path + "." + key));
    if (value < 0.0) return f.Error(path + "." + key, "must be >= 0, got " + member->dump());
    *target = value;
  }
  OPL_ASSIGN_OR_RETURN(origin_cov_json, f.Member(q, path, "origin_cov_mm2"));
  OPL_ASSIGN_OR_RETURN(origin_cov, Matrix3(f, *origin_cov_json, path + ".origin_cov_mm2"));
  OPL_ASSIGN_OR_RETURN(rot_cov_json, f.Member(q, path, "rotation_xyz_cov_rad2"));
  OPL_ASSIGN_OR_RETURN(rot_cov, Matrix3(f, *rot_cov_json, path + ".rotation_xyz_cov_rad2"));
  quality.origin_cov_mm2 = origin_cov;
  quality.rotation_xyz_cov_rad2 = rot_cov;
  return quality;
}

// The optional top-level "scaling" object (written by opl_calibrate).
Result<CalibrationScaling> ParseScaling(const Fields& f, const json& sj) {
  const std::string path = "scaling";
  CalibrationScaling scaling;
  for (const auto& [key, target] : {std::pair<const char*, std::string*>{"from_target", &scaling.from_target},
                                    {"to_target", &scaling.to_target}}) {
    OPL_ASSIGN_OR_RETURN(member, f.Member(sj, path, key));
    OPL_ASSIGN_OR_RETURN(value, f.String(*member, path + "." + key));
    *target = value;
  }
  const std::pair<const char*, double*> numbers[] = {
      {"artifact_length_mm", &scaling.artifact_length_mm},
      {"u_artifact_length_mm", &scaling.u_artifact_length_mm},
      {"measured_length", &scaling.measured_length},
      {"u_measured_length", &scaling.u_measured_length},
      {"scale", &scaling.scale},
      {"u_scale_relative", &scaling.u_scale_relative}};
  for (const auto& [key, target] : numbers) {
    OPL_ASSIGN_OR_RETURN(member, f.Member(sj, path, key));
    OPL_ASSIGN_OR_RETURN(value, f.Number(*member, path + "." + key));
    if (value < 0.0) return f.Error(path + "." + key, "must be >= 0, got " + member->dump());
    *target = value;
  }
  return scaling;
}

Result<SourceCalibration> ParseSource(const Fields& f, const json& src, const std::string& path) {
  SourceCalibration source;
  OPL_ASSIGN_OR_RETURN(name_json, f.Member(src, path, "name"));
  OPL_ASSIGN_OR_RETURN(name, f.String(*name_json, path + ".name"));
  if (name.empty()) return f.Error(path + ".name", "empty source name");
  source.name = name;

  OPL_ASSIGN_OR_RETURN(n_json, f.Member(src, path, "beams_per_side"));
  OPL_ASSIGN_OR_RETURN(n, f.Int(*n_json, path + ".beams_per_side"));
  if (const std::string problem = BeamsPerSideProblem(n); !problem.empty()) {
    return f.Error(path + ".beams_per_side", problem);
  }

  OPL_ASSIGN_OR_RETURN(origin_json, f.Member(src, path, "origin_mm"));
  OPL_ASSIGN_OR_RETURN(origin, f.Vector<3>(*origin_json, path + ".origin_mm"));
  OPL_ASSIGN_OR_RETURN(angles_json, f.Member(src, path, "rotation_xyz_rad"));
  OPL_ASSIGN_OR_RETURN(angles, f.Vector<3>(*angles_json, path + ".rotation_xyz_rad"));
  const Eigen::Matrix3d R_angles = RotationFromXyzAnglesRad(angles);
  source.calibration_from_source = Rigid3d(R_angles, origin);
  if (src.contains("rotation_quaternion_wxyz")) {
    const std::string qpath = path + ".rotation_quaternion_wxyz";
    OPL_ASSIGN_OR_RETURN(qv, f.Vector<4>(src["rotation_quaternion_wxyz"], qpath));
    Eigen::Quaterniond q(qv[0], qv[1], qv[2], qv[3]);
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > 1e-9) {
      return f.Error(qpath, "not a unit quaternion (norm " +
                                FormatRoundTrip(norm) + ")");
    }
    // Keep a quaternion that is unit to rounding as is, so that a file written
    // by FormatModuleCalibrationJson reads back bit-exact.
    if (std::abs(q.squaredNorm() - 1.0) > 8 * std::numeric_limits<double>::epsilon()) {
      q.normalize();
    }
    const double disagreement = RotationAngleBetweenRad(R_angles, q.toRotationMatrix());
    if (!(disagreement <= 1e-9)) {
      return f.Error(qpath, "disagrees with rotation_xyz_rad by " +
                                FormatRoundTrip(disagreement) + " rad");
    }
    source.calibration_from_source.rotation = q;
  }

  OPL_ASSIGN_OR_RETURN(beams_member, f.Member(src, path, "beams"));
  OPL_ASSIGN_OR_RETURN(beams_json, f.Array(*beams_member, path + ".beams"));
  std::vector<Beam> beams;
  std::map<int, size_t> seen;  // id -> index in the array
  for (size_t i = 0; i < beams_json->size(); ++i) {
    const json& bj = (*beams_json)[i];
    const std::string bpath = Fields::Index(path + ".beams", i);
    Beam beam;
    OPL_ASSIGN_OR_RETURN(id_json, f.Member(bj, bpath, "id"));
    OPL_ASSIGN_OR_RETURN(id, f.Int(*id_json, bpath + ".id"));
    if (id < 1 || id > n * n) {
      return f.Error(bpath + ".id", "beam id " + std::to_string(id) + " is outside 1.." +
                                        std::to_string(n * n));
    }
    if (auto it = seen.find(id); it != seen.end()) {
      return f.Error(bpath + ".id", "duplicate beam id " + std::to_string(id) + " (also beams[" +
                                        std::to_string(it->second) + "])");
    }
    seen[id] = i;
    beam.id = id;
    OPL_ASSIGN_OR_RETURN(az_json, f.Member(bj, bpath, "az_rad"));
    OPL_ASSIGN_OR_RETURN(az, f.Number(*az_json, bpath + ".az_rad"));
    OPL_ASSIGN_OR_RETURN(el_json, f.Member(bj, bpath, "el_rad"));
    OPL_ASSIGN_OR_RETURN(el, f.Number(*el_json, bpath + ".el_rad"));
    if (std::abs(az) > M_PI) return f.Error(bpath + ".az_rad", "must be in [-pi, pi]");
    if (std::abs(el) >= 0.5 * M_PI) return f.Error(bpath + ".el_rad", "must be in (-pi/2, pi/2)");
    beam.az_rad = az;
    beam.el_rad = el;
    if (bj.contains("cov_azel_rad2")) {
      const std::string cpath = bpath + ".cov_azel_rad2";
      const json& cj = bj["cov_azel_rad2"];
      if (!cj.is_array() || cj.size() != 2) {
        return f.Error(cpath, "expected [[a, b], [c, d]]");
      }
      Eigen::Matrix2d C;
      for (size_t r = 0; r < 2; ++r) {
        OPL_ASSIGN_OR_RETURN(row, f.Vector<2>(cj[r], Fields::Index(cpath, r)));
        C.row(static_cast<int>(r)) = row.transpose();
      }
      beam.cov_azel_rad2 = C;
    }
    beams.push_back(beam);
  }
  source.pattern = BeamPattern(n, std::move(beams));
  if (Status st = source.pattern.Validate(); !st.ok()) {
    return f.Error(path + ".beams", st.message());
  }
  if (src.contains("quality")) {
    OPL_ASSIGN_OR_RETURN(quality, ParseQuality(f, src["quality"], path + ".quality"));
    source.quality = quality;
  }
  return source;
}

Result<Separation> ParseSeparation(const Fields& f, const json& sj, const std::string& path,
                                   const std::map<std::string, size_t>& names) {
  Separation sep;
  for (const char* key : {"from", "to"}) {
    OPL_ASSIGN_OR_RETURN(member, f.Member(sj, path, key));
    OPL_ASSIGN_OR_RETURN(value, f.String(*member, path + "." + key));
    if (!names.count(value)) return f.Error(path + "." + key, "unknown source '" + value + "'");
    (std::string(key) == "from" ? sep.from : sep.to) = value;
  }
  if (sep.from == sep.to) return f.Error(path + ".to", "joins source '" + sep.to + "' to itself");
  OPL_ASSIGN_OR_RETURN(length_json, f.Member(sj, path, "length_mm"));
  OPL_ASSIGN_OR_RETURN(length, f.Number(*length_json, path + ".length_mm"));
  if (!(length > 0.0)) {
    return f.Error(path + ".length_mm", "must be > 0, got " + length_json->dump());
  }
  OPL_ASSIGN_OR_RETURN(u_json, f.Member(sj, path, "u_length_mm"));
  OPL_ASSIGN_OR_RETURN(u, f.Number(*u_json, path + ".u_length_mm"));
  if (!(u >= 0.0)) return f.Error(path + ".u_length_mm", "must be >= 0, got " + u_json->dump());
  sep.length_mm = length;
  sep.u_length_mm = u;
  return sep;
}

// JSON text of a double that reads back exactly (always with a '.' or an
// exponent, so that -0.0 keeps its sign and integral values stay floats).
std::string JsonDouble(double v) {
  std::string s = FormatRoundTrip(v);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}

std::string JsonString(const std::string& s) { return json(s).dump(); }

template <typename Vec>
std::string JsonArray(const Vec& v) {
  std::string out = "[";
  for (int i = 0; i < v.size(); ++i) out += (i ? ", " : "") + JsonDouble(v[i]);
  return out + "]";
}

std::string JsonMatrix3(const Eigen::Matrix3d& M) {
  std::string out = "[";
  for (int r = 0; r < 3; ++r) out += (r ? ", " : "") + JsonArray(Eigen::Vector3d(M.row(r).transpose()));
  return out + "]";
}

}  // namespace

Result<ModuleCalibration> ParseModuleCalibrationJson(const std::string& text,
                                                     const std::string& name) {
  OPL_RETURN_IF_ERROR(json_internal::CheckJsonDepth(text, name));
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    // Line and column of the error from its byte offset (1-based).
    const size_t byte = std::min<size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    int line = 1, column = 1;
    for (size_t i = 0; i < byte; ++i) {
      if (text[i] == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
    }
    return Status::ParseError(name + ":" + std::to_string(line) + ":" + std::to_string(column) +
                              ": JSON syntax error: " +
                              json_internal::JsonErrorForMessage(e.what()));
  } catch (const json::exception& e) {
    // e.g. out_of_range.406 "number overflow parsing '1e999'" (no position).
    return Status::ParseError(name + ": JSON error: " +
                              json_internal::JsonErrorForMessage(e.what()));
  }
  const Fields f(name);
  if (!doc.is_object()) {
    return Status::ParseError(name + ": expected a JSON object at the top level, got " +
                              std::string(doc.type_name()));
  }
  OPL_ASSIGN_OR_RETURN(format_json, f.Member(doc, "", "format"));
  if (!format_json->is_string() || format_json->get<std::string>() != kFormat) {
    return f.Error("format",
                   std::string("expected \"") + kFormat + "\", got " +
                       SafeForMessage(format_json->dump(), 40));
  }
  OPL_ASSIGN_OR_RETURN(version_json, f.Member(doc, "", "version"));
  if (!version_json->is_number_integer() || version_json->get<int64_t>() != kVersion) {
    return f.Error("version", "unsupported version " + SafeForMessage(version_json->dump(), 40) +
                                  " (this build reads " + std::to_string(kVersion) + ")");
  }
  OPL_ASSIGN_OR_RETURN(units_json, f.Member(doc, "", "units"));
  if (!units_json->is_string() || units_json->get<std::string>() != "mm") {
    return f.Error("units", "expected \"mm\", got " + SafeForMessage(units_json->dump(), 40));
  }

  ModuleCalibration cal;
  OPL_ASSIGN_OR_RETURN(sources_member, f.Member(doc, "", "sources"));
  OPL_ASSIGN_OR_RETURN(sources_json, f.Array(*sources_member, "sources"));
  if (sources_json->empty()) return f.Error("sources", "no sources");
  std::map<std::string, size_t> names;
  for (size_t i = 0; i < sources_json->size(); ++i) {
    const std::string path = Fields::Index("sources", i);
    OPL_ASSIGN_OR_RETURN(source, ParseSource(f, (*sources_json)[i], path));
    if (auto it = names.find(source.name); it != names.end()) {
      return f.Error(path + ".name", "duplicate source name '" + source.name + "' (also sources[" +
                                         std::to_string(it->second) + "])");
    }
    names[source.name] = i;
    cal.sources.push_back(std::move(source));
  }
  OPL_ASSIGN_OR_RETURN(separations_member, f.Member(doc, "", "separations"));
  OPL_ASSIGN_OR_RETURN(separations_json, f.Array(*separations_member, "separations"));
  std::map<std::pair<std::string, std::string>, size_t> pairs;  // {a, b} sorted -> index
  for (size_t i = 0; i < separations_json->size(); ++i) {
    const std::string path = Fields::Index("separations", i);
    OPL_ASSIGN_OR_RETURN(sep, ParseSeparation(f, (*separations_json)[i], path, names));
    // One calibrated length per pair: a second (even an equal one) is refused,
    // since a measurement would silently use one of them.
    const auto key = std::minmax(sep.from, sep.to);
    if (auto it = pairs.find({key.first, key.second}); it != pairs.end()) {
      const Separation& first = cal.separations[it->second];
      const std::string first_path = Fields::Index("separations", it->second);
      const bool same = first.length_mm == sep.length_mm && first.u_length_mm == sep.u_length_mm;
      return f.Error(path, sep.from + "-" + sep.to + " " + FormatRoundTrip(sep.length_mm) +
                               " mm " + (same ? "duplicates " : "contradicts ") + first_path +
                               ", " + first.from + "-" + first.to + " " +
                               FormatRoundTrip(first.length_mm) +
                               " mm (each pair of sources may have one separation)");
    }
    pairs[{key.first, key.second}] = i;
    cal.separations.push_back(std::move(sep));
  }
  if (doc.contains("scaling")) {
    OPL_ASSIGN_OR_RETURN(scaling, ParseScaling(f, doc["scaling"]));
    cal.scaling = scaling;
  }
  if (Status st = cal.Validate(); !st.ok()) return Status::ParseError(name + ": " + st.message());
  return cal;
}

Result<ModuleCalibration> ReadModuleCalibrationJson(const std::string& path) {
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseModuleCalibrationJson(*text, path);
}

Result<std::string> FormatModuleCalibrationJson(const ModuleCalibration& calibration) {
  if (Status st = calibration.Validate(); !st.ok()) return st;
  std::string out;
  out += "{\n  \"format\": \"" + std::string(kFormat) + "\",\n  \"version\": " +
         std::to_string(kVersion) + ",\n  \"units\": \"mm\",\n  \"sources\": [";
  for (size_t i = 0; i < calibration.sources.size(); ++i) {
    const SourceCalibration& s = calibration.sources[i];
    const Eigen::Quaterniond& q = s.calibration_from_source.rotation;
    // (+ 0.0 turns a -0.0 from atan2 into 0.0, for readers' eyes only: the
    // quaternion, not the angles, is what reads back bit-exact.)
    const Eigen::Vector3d angles =
        XyzAnglesRadFromRotation(q.toRotationMatrix()).array() + 0.0;
    out += std::string(i ? "," : "") + "\n    {\n";
    out += "      \"name\": " + JsonString(s.name) + ",\n";
    out += "      \"beams_per_side\": " + std::to_string(s.pattern.beams_per_side()) + ",\n";
    out += "      \"origin_mm\": " + JsonArray(s.calibration_from_source.translation) + ",\n";
    out += "      \"rotation_xyz_rad\": " + JsonArray(angles) + ",\n";
    out += "      \"rotation_quaternion_wxyz\": " +
           JsonArray(Eigen::Vector4d(q.w(), q.x(), q.y(), q.z())) + ",\n";
    out += "      \"beams\": [";
    const std::vector<Beam>& beams = s.pattern.beams();
    for (size_t b = 0; b < beams.size(); ++b) {
      const Beam& beam = beams[b];
      out += std::string(b ? "," : "") + "\n        {\"id\": " + std::to_string(beam.id) +
             ", \"az_rad\": " + JsonDouble(beam.az_rad) +
             ", \"el_rad\": " + JsonDouble(beam.el_rad);
      if (beam.cov_azel_rad2) {
        const Eigen::Matrix2d& C = *beam.cov_azel_rad2;
        out += ", \"cov_azel_rad2\": [" + JsonArray(Eigen::Vector2d(C.row(0).transpose())) + ", " +
               JsonArray(Eigen::Vector2d(C.row(1).transpose())) + "]";
      }
      out += "}";
    }
    out += beams.empty() ? "]" : "\n      ]";
    if (s.quality) {
      const SourceCalibrationQuality& quality = *s.quality;
      out += ",\n      \"quality\": {\"slices\": " + std::to_string(quality.slices) +
             ", \"samples_used\": " + std::to_string(quality.samples_used) +
             ", \"samples_flagged\": " + std::to_string(quality.samples_flagged) +
             ", \"beams_dropped\": " + std::to_string(quality.beams_dropped) +
             ",\n        \"rms_residual_urad\": " + JsonDouble(quality.rms_residual_urad) +
             ", \"variance_factor\": " + JsonDouble(quality.variance_factor) +
             ",\n        \"mean_point_to_ray_mm\": " + JsonDouble(quality.mean_point_to_ray_mm) +
             ", \"max_point_to_ray_mm\": " + JsonDouble(quality.max_point_to_ray_mm) +
             ",\n        \"origin_cov_mm2\": " + JsonMatrix3(quality.origin_cov_mm2) +
             ",\n        \"rotation_xyz_cov_rad2\": " + JsonMatrix3(quality.rotation_xyz_cov_rad2) + "}";
    }
    out += "\n    }";
  }
  out += "\n  ],\n  \"separations\": [";
  for (size_t i = 0; i < calibration.separations.size(); ++i) {
    const Separation& sep = calibration.separations[i];
    out += std::string(i ? "," : "") + "\n    {\"from\": " + JsonString(sep.from) +
           ", \"to\": " + JsonString(sep.to) + ", \"length_mm\": " + JsonDouble(sep.length_mm) +
           ", \"u_length_mm\": " + JsonDouble(sep.u_length_mm) + "}";
  }
  out += calibration.separations.empty() ? "]" : "\n  ]";
  if (calibration.scaling) {
    const CalibrationScaling& sc = *calibration.scaling;
    out += ",\n  \"scaling\": {\"from_target\": " + JsonString(sc.from_target) +
           ", \"to_target\": " + JsonString(sc.to_target) +
           ", \"artifact_length_mm\": " + JsonDouble(sc.artifact_length_mm) +
           ", \"u_artifact_length_mm\": " + JsonDouble(sc.u_artifact_length_mm) +
           ",\n    \"measured_length\": " + JsonDouble(sc.measured_length) +
           ", \"u_measured_length\": " + JsonDouble(sc.u_measured_length) +
           ", \"scale\": " + JsonDouble(sc.scale) +
           ", \"u_scale_relative\": " + JsonDouble(sc.u_scale_relative) + "}";
  }
  out += "\n}\n";
  return out;
}

Status WriteModuleCalibrationJson(const ModuleCalibration& calibration, const std::string& path) {
  Result<std::string> text = FormatModuleCalibrationJson(calibration);
  if (!text.ok()) return text.status();
  return WriteFileAtomically(path, *text);
}

}  // namespace opl

#undef OPL_ASSIGN_OR_RETURN
