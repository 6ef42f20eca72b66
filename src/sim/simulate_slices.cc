#include "opl/sim/simulate_slices.h"

#include <cmath>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "opl/core/format.h"
#include "opl/core/number_list.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;

// A unit vector perpendicular to unit `d` (deterministic).
Vec3 AnyPerpendicular(const Vec3& d) {
  int k = 0;
  d.cwiseAbs().minCoeff(&k);
  return d.cross(Vec3::Unit(k)).normalized();
}

}  // namespace

Result<ModuleViewpoint> MeanViewpoint(const ModuleDesign& design) {
  {
    ModuleDesign sources_only = design;  // the design's surface is not used
    sources_only.surface = Surface();
    OPL_RETURN_IF_ERROR(sources_only.Validate());
  }
  Vec3 origin = Vec3::Zero(), view = Vec3::Zero(), up = Vec3::Zero();
  for (const SourceDesign& source : design.sources) {
    const Eigen::Matrix3d R = source.scene_from_source.RotationMatrix();
    origin += source.scene_from_source.translation;
    view += R.col(0);  // the central beam, +X of the source frame
    up += R.col(2);
  }
  const double n = static_cast<double>(design.sources.size());
  ModuleViewpoint vp;
  vp.origin_mm = origin / n;
  if (!(view.norm() > 1e-9 * n)) {
    return Status::InvalidArgument(
        "the sources' central beams cancel out: the module has no mean viewing direction");
  }
  vp.viewing_direction = view.normalized();
  const Vec3& v = vp.viewing_direction;
  const Vec3 up_perp = up - up.dot(v) * v;
  vp.up = up_perp.norm() > 1e-9 * n ? Vec3(up_perp.normalized()) : AnyPerpendicular(v);
  return vp;
}

Status ScreenSlicesOptions::Validate() const {
  if (depths_mm.empty()) {
    return Status::InvalidArgument("depths_mm is empty (at least one screen depth needed)");
  }
  for (size_t k = 0; k < depths_mm.size(); ++k) {
    if (!(std::isfinite(depths_mm[k]) && depths_mm[k] > 0.0)) {
      return Status::InvalidArgument("depths_mm[" + std::to_string(k) +
                                     "] must be finite and > 0, got " +
                                     FormatNumber(depths_mm[k]));
    }
  }
  if (!(std::isfinite(tilt_deg) && std::abs(tilt_deg) < 90.0)) {
    return Status::InvalidArgument("tilt_deg must be finite and in (-90, 90), got " +
                                   FormatNumber(tilt_deg));
  }
  if (!std::isfinite(curvature_per_mm)) {
    return Status::InvalidArgument("curvature_per_mm must be finite, got " +
                                   FormatNumber(curvature_per_mm));
  }
  return Status::Ok();
}

Result<std::vector<Surface>> MakeCalibrationScreens(const ModuleDesign& design,
                                                    const ScreenSlicesOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  Result<ModuleViewpoint> vp = MeanViewpoint(design);
  if (!vp.ok()) return vp.status();
  const Vec3& o = vp->origin_mm;
  const Vec3& v = vp->viewing_direction;
  std::vector<Surface> screens;
  screens.reserve(options.depths_mm.size());
  for (size_t k = 0; k < options.depths_mm.size(); ++k) {
    const double tilt_rad = (k % 2 == 0 ? 1.0 : -1.0) * options.tilt_deg * kPi / 180.0;
    const Vec3 normal = Eigen::AngleAxisd(tilt_rad, vp->up) * v;
    const Vec3 point = o + options.depths_mm[k] * v;
    if (options.curvature_per_mm == 0.0) {
      screens.push_back(PlaneSurface{point, -normal});
    } else {
      screens.push_back(ParaboloidSurface{point, -normal, options.curvature_per_mm});
    }
  }
  return screens;
}

std::vector<Surface> SlicesOf(const Surface& surface) {
  std::vector<Surface> slices;
  if (const auto* list = std::get_if<PlaneListSurface>(&surface.shape())) {
    for (const PlaneSurface& plane : list->planes) slices.push_back(plane);
  } else {
    slices.push_back(surface);
  }
  return slices;
}

uint64_t SliceSeed(uint64_t seed, int slice) {
  SplitMix64 seeder(seed);
  uint64_t value = seeder.Next();
  for (int k = 0; k < slice; ++k) value = seeder.Next();
  return value;
}

Result<std::vector<SimulatedSpot>> SimulateSlices(const ModuleDesign& design,
                                                  const std::vector<Surface>& screens,
                                                  const SpotSimulationOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (screens.empty()) {
    return Status::InvalidArgument("screens is empty (at least one screen needed)");
  }
  for (size_t k = 0; k < screens.size(); ++k) {
    const std::string name = "screens[" + std::to_string(k) + "]";
    if (Status st = screens[k].Validate(); !st.ok()) {
      return Status::InvalidArgument(name + ": " + st.message());
    }
    if (screens[k].num_slices() != 1) {
      return Status::InvalidArgument(name + " is a list of " +
                                     std::to_string(screens[k].num_slices()) +
                                     " planes; give each plane as its own screen (SlicesOf)");
    }
  }
  ModuleDesign slice_design = design;  // its surface is replaced by each screen
  slice_design.surface = screens[0];
  OPL_RETURN_IF_ERROR(slice_design.Validate());

  std::vector<SimulatedSpot> out;
  SpotSimulationOptions slice_options = options;
  SplitMix64 seeder(options.seed);  // slice k: the (k + 1)-th output (SliceSeed)
  for (size_t k = 0; k < screens.size(); ++k) {
    slice_design.surface = screens[k];
    slice_options.seed = seeder.Next();
    Result<std::vector<SimulatedSpot>> spots = SimulateSpots(slice_design, slice_options);
    if (!spots.ok()) {
      if (spots.status().code() == StatusCode::kNoSolution) {
        return Status::NoSolution("screen " + std::to_string(k) + ": " +
                                  spots.status().message());
      }
      return spots.status();
    }
    for (SimulatedSpot& s : *spots) {
      s.slice = static_cast<int>(k);
      out.push_back(std::move(s));
    }
  }
  return out;
}

Result<std::vector<double>> ParseDepthList(const std::string& text) {
  NumberListSyntax syntax;
  syntax.noun = "depth";
  syntax.range_example = "750:65:1335";
  syntax.list_example = "750,815,880";
  return ParseNumberList(text, syntax);
}

}  // namespace opl
