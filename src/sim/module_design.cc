#include "opl/sim/module_design.h"

#include "opl/core/format.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <set>

#include "opl/sim/random.h"

namespace opl {
namespace {

bool IsProperRotation(const Eigen::Matrix3d& R) {
  return R.allFinite() &&
         (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-9 &&
         std::abs(R.determinant() - 1.0) <= 1e-9;
}

// The pattern with the source's fabrication error (SourceDesign::beam_error_mrad).
Result<BeamPattern> WithBeamError(const SourceDesign& source, const BeamPattern& ideal) {
  if (source.beam_error_mrad == 0.0) return ideal;
  uint64_t seed = source.beam_error_seed;
  for (unsigned char c : source.name) seed = SplitMix64(seed ^ c).Next();
  std::mt19937_64 rng(seed);
  NormalGenerator normal;
  const double sigma = source.beam_error_mrad * 1e-3;
  const int n = ideal.beams_per_side();
  const int central = ideal.central_beam_id();
  std::vector<Beam> beams = ideal.beams();
  for (Beam& b : beams) {
    const double daz = sigma * normal(rng), del = sigma * normal(rng);  // drawn for every beam
    if (b.id == central) continue;
    b.az_rad += daz;
    b.el_rad += del;
  }
  // Level the central row again (sum az_j el_j = 0, the gauge of
  // docs/calibrate.md): el_j -= k az_j with k the least-squares roll.
  const int m = (n - 1) / 2;
  double az_el = 0.0, az_az = 0.0;
  for (const Beam& b : beams) {
    if (BeamRow(b.id, n) == m) {
      az_el += b.az_rad * b.el_rad;
      az_az += b.az_rad * b.az_rad;
    }
  }
  if (az_az > 0.0) {
    const double k = az_el / az_az;
    for (Beam& b : beams) {
      if (BeamRow(b.id, n) == m) b.el_rad -= k * b.az_rad;
    }
  }
  Result<BeamPattern> pattern = BeamPattern::Create(n, std::move(beams));
  if (!pattern.ok()) {
    return Status::InvalidArgument("source '" + source.name + "': beam_error_mrad: " +
                                   pattern.status().message());
  }
  return pattern;
}

}  // namespace

Status ModuleDesign::Validate() const {
  if (sources.empty()) return Status::InvalidArgument("module design has no sources");
  std::set<std::string> names;
  for (size_t k = 0; k < sources.size(); ++k) {
    const SourceDesign& s = sources[k];
    if (s.name.empty()) {
      return Status::InvalidArgument("source " + std::to_string(k) + " has an empty name");
    }
    const std::string who = "source '" + s.name + "': ";
    if (!names.insert(s.name).second) {
      return Status::InvalidArgument("duplicate source name '" + s.name + "'");
    }
    if (s.pattern == PatternModel::kFile) {
      if (s.pattern_file.empty()) {
        return Status::InvalidArgument(who + "pattern 'file' needs a pattern_file");
      }
    } else {
      const Status st = CheckPatternParameters(s.pattern, s.beams_per_side,
                                               s.full_angle_deg * kPi / 180.0, s.wavelength_nm);
      if (!st.ok()) return Status::InvalidArgument(who + st.message());
    }
    if (!(std::isfinite(s.beam_error_mrad) && s.beam_error_mrad >= 0.0 && s.beam_error_mrad < 100.0)) {
      return Status::InvalidArgument(who + "beam_error_mrad must be finite, >= 0 and < 100, got " +
                                     FormatNumber(s.beam_error_mrad));
    }
    if (!(std::isfinite(s.wavelength_nm) && s.wavelength_nm > 0.0)) {
      return Status::InvalidArgument(who + "wavelength_nm must be finite and > 0, got " +
                                     FormatNumber(s.wavelength_nm));
    }
    if (!s.scene_from_source.translation.allFinite() ||
        !s.scene_from_source.rotation.coeffs().allFinite() ||
        std::abs(s.scene_from_source.rotation.norm() - 1.0) > 1e-9) {
      return Status::InvalidArgument(who + "pose is not finite or its quaternion is not unit");
    }
  }
  const Status st = surface.Validate();
  if (!st.ok()) {
    return Status::InvalidArgument(std::string("surface (") + surface.TypeName() +
                                   "): " + st.message());
  }
  if (!spot_noise_mm.allFinite() || (spot_noise_mm.array() < 0.0).any()) {
    return Status::InvalidArgument("spot_noise_mm must be finite and >= 0, got [" +
                                   FormatNumber(spot_noise_mm.x()) + ", " + FormatNumber(spot_noise_mm.y()) +
                                   ", " + FormatNumber(spot_noise_mm.z()) + "]");
  }
  if (!IsProperRotation(noise_frame_rotation)) {
    return Status::InvalidArgument("noise_frame_rotation is not a proper rotation");
  }
  return Status::Ok();
}

Eigen::Matrix3d ModuleDesign::SpotCovarianceMm2() const {
  return noise_frame_rotation * spot_noise_mm.array().square().matrix().asDiagonal() *
         noise_frame_rotation.transpose();
}

ModuleDesign ModuleDesign::Transformed(const Rigid3d& new_from_old) const {
  ModuleDesign out = *this;
  for (SourceDesign& s : out.sources) s.scene_from_source = new_from_old * s.scene_from_source;
  out.surface = surface.Transformed(new_from_old);
  out.noise_frame_rotation = new_from_old.RotationMatrix() * noise_frame_rotation;
  return out;
}

const SourceDesign* ModuleDesign::FindSource(const std::string& name) const {
  for (const SourceDesign& s : sources) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

Result<BeamPattern> MakePattern(const SourceDesign& source) {
  const std::string who = "source '" + source.name + "': ";
  const double full_angle_rad = source.full_angle_deg * kPi / 180.0;
  switch (source.pattern) {
    case PatternModel::kEqualAngle:
    case PatternModel::kGrating: {
      const Status st = CheckPatternParameters(source.pattern, source.beams_per_side,
                                               full_angle_rad, source.wavelength_nm);
      if (!st.ok()) return Status::InvalidArgument(who + st.message());
      Result<BeamPattern> ideal =
          source.pattern == PatternModel::kEqualAngle
              ? MakeEqualAnglePattern(source.beams_per_side, full_angle_rad)
              : MakeGratingPattern(source.beams_per_side, full_angle_rad, source.wavelength_nm);
      if (!ideal.ok()) return ideal;
      return WithBeamError(source, *ideal);
    }
    case PatternModel::kFile: {
      if (source.pattern_file.empty()) {
        return Status::InvalidArgument(who + "pattern 'file' needs a pattern_file");
      }
      Result<BeamPattern> pattern = ReadPatternCsv(source.pattern_file);
      if (!pattern.ok()) {
        return Status(pattern.status().code(), who + pattern.status().message());
      }
      if (pattern->beams_per_side() != source.beams_per_side) {
        return Status::InvalidArgument(
            who + source.pattern_file + " has beams_per_side " +
            std::to_string(pattern->beams_per_side()) + " but the design says " +
            std::to_string(source.beams_per_side));
      }
      return WithBeamError(source, *pattern);
    }
  }
  return Status::InvalidArgument(who + "unknown pattern model");
}

Result<ModuleCalibration> ExactCalibration(const ModuleDesign& design) {
  OPL_RETURN_IF_ERROR(design.Validate());
  ModuleCalibration cal;
  for (const SourceDesign& s : design.sources) {
    Result<BeamPattern> pattern = MakePattern(s);
    if (!pattern.ok()) return pattern.status();
    cal.sources.push_back({s.name, std::move(pattern).value(), s.scene_from_source, {}});
  }
  cal.separations = ModuleCalibration::SeparationsFromOrigins(cal.sources);
  OPL_RETURN_IF_ERROR(cal.Validate());
  return cal;
}

}  // namespace opl
