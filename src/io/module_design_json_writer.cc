// Module design JSON writer (io/module_design_json.h): the reader's format,
// field for field (src/io/module_design_json.cc).
#include <climits>
#include <filesystem>
#include <string>
#include <variant>

#include <nlohmann/json.hpp>

#include "opl/geometry/rotation.h"
#include "opl/io/atomic_file.h"
#include "opl/io/json_text.h"
#include "opl/io/module_design_json.h"
#include "opl/sim/pattern_models.h"

namespace opl {
namespace {

using ojson = nlohmann::ordered_json;

// "+ 0.0" turns a negative zero (the angle decomposition gives some) into 0.
ojson Vec3(const Eigen::Vector3d& v) { return ojson::array({v.x() + 0.0, v.y() + 0.0, v.z() + 0.0}); }

ojson PlaneJson(const PlaneSurface& p) {
  ojson j;
  j["point_mm"] = Vec3(p.point_mm);
  j["normal"] = Vec3(p.normal);
  return j;
}

ojson SurfaceJson(const Surface& surface) {
  ojson j;
  j["type"] = surface.TypeName();
  std::visit(
      [&j](const auto& shape) {
        using T = std::decay_t<decltype(shape)>;
        if constexpr (std::is_same_v<T, PlaneSurface>) {
          j.update(PlaneJson(shape));
        } else if constexpr (std::is_same_v<T, SphereSurface>) {
          j["center_mm"] = Vec3(shape.center_mm);
          j["radius_mm"] = shape.radius_mm;
        } else if constexpr (std::is_same_v<T, BoxCornerSurface>) {
          j["corner_mm"] = Vec3(shape.corner_mm);
          j["rotation_xyz_rad"] = Vec3(XyzAnglesRadFromRotation(shape.scene_from_box));
        } else if constexpr (std::is_same_v<T, ParaboloidSurface>) {
          j["vertex_mm"] = Vec3(shape.vertex_mm);
          j["axis"] = Vec3(shape.axis);
          j["curvature_per_mm"] = shape.curvature_per_mm;
        } else {
          ojson planes = ojson::array();
          for (const PlaneSurface& p : shape.planes) planes.push_back(PlaneJson(p));
          j["planes"] = std::move(planes);
        }
      },
      surface.shape());
  return j;
}

}  // namespace

Result<std::string> FormatModuleDesignJson(const ModuleDesign& design, const std::string& json_dir,
                                           const std::string& description) {
  if (Status st = design.Validate(); !st.ok()) {
    return Status::InvalidArgument("module design: " + st.message());
  }
  ojson root;
  root["format"] = "opl.module_design";
  root["version"] = 1;
  if (!description.empty()) root["description"] = description;
  ojson sources = ojson::array();
  for (const SourceDesign& s : design.sources) {
    if (s.beam_error_seed > static_cast<uint64_t>(INT_MAX)) {
      return Status::InvalidArgument("module design: source '" + s.name + "': beam_error_seed " +
                                     std::to_string(s.beam_error_seed) +
                                     " cannot be written (the format holds 0 to 2147483647)");
    }
    ojson j;
    j["name"] = s.name;
    j["pattern"] = PatternModelName(s.pattern);
    j["beams_per_side"] = s.beams_per_side;
    if (s.pattern == PatternModel::kFile) {
      std::filesystem::path file(s.pattern_file);
      if (!json_dir.empty()) {
        std::error_code ec;
        const std::filesystem::path relative =
            std::filesystem::relative(std::filesystem::absolute(file, ec),
                                      std::filesystem::absolute(json_dir, ec), ec);
        if (!ec && !relative.empty()) file = relative;
      }
      j["pattern_file"] = file.generic_string();
    } else {
      j["full_angle_deg"] = s.full_angle_deg;
    }
    j["wavelength_nm"] = s.wavelength_nm;
    j["origin_mm"] = Vec3(s.scene_from_source.translation);
    j["rotation_xyz_rad"] = Vec3(XyzAnglesRadFromRotation(s.scene_from_source.rotation.toRotationMatrix()));
    if (s.beam_error_mrad != 0.0) {
      j["beam_error_mrad"] = s.beam_error_mrad;
      j["beam_error_seed"] = static_cast<int>(s.beam_error_seed);
    }
    sources.push_back(std::move(j));
  }
  root["sources"] = std::move(sources);
  root["surface"] = SurfaceJson(design.surface);
  root["spot_noise_mm"] = Vec3(design.spot_noise_mm);
  root["noise_frame_rotation_xyz_rad"] = Vec3(XyzAnglesRadFromRotation(design.noise_frame_rotation));
  return CompactNumberArrays(root.dump(2)) + "\n";
}

Status WriteModuleDesignJson(const ModuleDesign& design, const std::string& path,
                             const std::string& description) {
  const std::string dir = std::filesystem::path(path).parent_path().string();
  Result<std::string> text = FormatModuleDesignJson(design, dir.empty() ? "." : dir, description);
  if (!text.ok()) return text.status();
  return WriteFileAtomically(path, *text);
}

}  // namespace opl
