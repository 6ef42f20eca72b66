#include "opl/sim/simulate_slices.h"

#include <charconv>
#include <cmath>
#include <string>
#include <system_error>
#include <utility>

#include <Eigen/Geometry>

#include "opl/core/format.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;

constexpr size_t kMaxDepths = 10000;

// A unit vector perpendicular to unit `d` (deterministic).
Vec3 AnyPerpendicular(const Vec3& d) {
  int k = 0;
  d.cwiseAbs().minCoeff(&k);
  return d.cross(Vec3::Unit(k)).normalized();
}

std::string Trim(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return std::string();
  const size_t last = s.find_last_not_of(" \t");
  return s.substr(first, last - first + 1);
}

// A finite decimal number filling all of `item` (trimmed), or an error
// naming it within the whole `text`.
Result<double> ParseNumber(const std::string& item, const std::string& text) {
  const std::string s = Trim(item);
  double value = 0.0;
  const char* begin = s.data();
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') ++begin;  // from_chars takes no '+'
  const char* end = s.data() + s.size();
  const std::from_chars_result r = std::from_chars(begin, end, value);
  if (s.empty() || r.ec != std::errc() || r.ptr != end || !std::isfinite(value)) {
    return Status::InvalidArgument("depth list '" + text + "': '" + s +
                                   "' is not a finite number");
  }
  return value;
}

std::vector<std::string> Split(const std::string& s, char separator) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    const size_t at = s.find(separator, start);
    parts.push_back(s.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) break;
    start = at + 1;
  }
  return parts;
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
  const std::string syntax =
      " (expected first:step:last, e.g. 750:65:1335, or a comma-separated list, e.g. "
      "750,815,880)";
  if (Trim(text).empty()) return Status::InvalidArgument("empty depth list" + syntax);
  const bool is_range = text.find(':') != std::string::npos;
  if (is_range && text.find(',') != std::string::npos) {
    return Status::InvalidArgument("depth list '" + text + "': mixes ':' and ','" + syntax);
  }
  if (!is_range) {
    std::vector<double> depths;
    for (const std::string& item : Split(text, ',')) {
      Result<double> value = ParseNumber(item, text);
      if (!value.ok()) return value.status();
      depths.push_back(*value);
      if (depths.size() > kMaxDepths) {
        return Status::InvalidArgument("depth list '" + text.substr(0, 40) +
                                       "...': more than " + std::to_string(kMaxDepths) +
                                       " depths");
      }
    }
    return depths;
  }

  const std::vector<std::string> parts = Split(text, ':');
  if (parts.size() != 3) {
    return Status::InvalidArgument("depth list '" + text + "': a range has three fields" +
                                   syntax);
  }
  double field[3];
  for (int i = 0; i < 3; ++i) {
    Result<double> value = ParseNumber(parts[i], text);
    if (!value.ok()) return value.status();
    field[i] = *value;
  }
  const double first = field[0], step = field[1], last = field[2];
  if (!(step > 0.0)) {
    return Status::InvalidArgument("depth list '" + text + "': step must be > 0, got " +
                                   FormatNumber(step));
  }
  if (!(first <= last)) {
    return Status::InvalidArgument("depth list '" + text + "': first (" + FormatNumber(first) +
                                   ") must be <= last (" + FormatNumber(last) + ")");
  }
  // Number of whole steps; one more when the next value lands on `last`
  // within 1e-9 relative (rounding of (last - first) / step).
  const double span = (last - first) / step;
  if (!(span < static_cast<double>(kMaxDepths))) {
    return Status::InvalidArgument("depth list '" + text + "' gives more than " +
                                   std::to_string(kMaxDepths) + " depths");
  }
  auto steps = static_cast<size_t>(std::floor(span));
  const double tolerance = 1e-9 * std::max(std::abs(last), std::abs(first));
  bool ends_on_last = std::abs(first + static_cast<double>(steps) * step - last) <= tolerance;
  if (!ends_on_last &&
      std::abs(first + static_cast<double>(steps + 1) * step - last) <= tolerance) {
    ++steps;
    ends_on_last = true;
  }
  std::vector<double> depths;
  depths.reserve(steps + 1);
  for (size_t i = 0; i <= steps; ++i) depths.push_back(first + static_cast<double>(i) * step);
  if (ends_on_last) depths.back() = last;
  if (depths.size() > kMaxDepths) {
    return Status::InvalidArgument("depth list '" + text + "' gives more than " +
                                   std::to_string(kMaxDepths) + " depths");
  }
  return depths;
}

}  // namespace opl
