#include "opl/calibrate/calibrate_module.h"

#include <cmath>
#include <map>
#include <string>
#include <utility>

#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/model/beam_pattern.h"

namespace opl {

Result<CalibrationScaling> ComputeArtifactScaling(const ArtifactMeasurement& artifact) {
  const std::string which =
      "artifact " + artifact.from_target + "-" + artifact.to_target + ": ";
  if (!(std::isfinite(artifact.length_mm) && artifact.length_mm > 0.0)) {
    return Status::InvalidArgument(which + "length must be finite and > 0 mm, got " +
                                   FormatNumber(artifact.length_mm));
  }
  if (!(std::isfinite(artifact.u_length_mm) && artifact.u_length_mm >= 0.0)) {
    return Status::InvalidArgument(which + "length uncertainty must be finite and >= 0 mm, got " +
                                   FormatNumber(artifact.u_length_mm));
  }
  if (!artifact.from_point.allFinite() || !artifact.to_point.allFinite()) {
    return Status::InvalidArgument(which + "target coordinates are not finite");
  }
  const Eigen::Vector3d v = artifact.to_point - artifact.from_point;
  const double d = v.norm();
  if (!(d > 0.0)) return Status::InvalidArgument(which + "the two targets coincide");
  const Eigen::Vector3d g = v / d;
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  if (artifact.from_cov) C += *artifact.from_cov;
  if (artifact.to_cov) C += *artifact.to_cov;
  if (!C.allFinite()) return Status::InvalidArgument(which + "target covariance not finite");
  CalibrationScaling s;
  s.from_target = artifact.from_target;
  s.to_target = artifact.to_target;
  s.artifact_length_mm = artifact.length_mm;
  s.u_artifact_length_mm = artifact.u_length_mm;
  s.measured_length = d;
  s.u_measured_length = std::sqrt(std::max(0.0, g.dot(C * g)));
  s.scale = artifact.length_mm / d;
  const double rel_a = artifact.u_length_mm / artifact.length_mm;
  const double rel_d = s.u_measured_length / d;
  s.u_scale_relative = std::sqrt(rel_a * rel_a + rel_d * rel_d);
  return s;
}

Result<ModuleCalibrationResult> CalibrateModule(const std::vector<Spot>& spots,
                                                const std::vector<int>& slices,
                                                const std::optional<CalibrationScaling>& scaling,
                                                const CalibrateModuleOptions& options) {
  if (slices.empty() && !spots.empty()) {
    return Status::InvalidArgument(
        "the spots have no slice column: a calibration session needs the slice of every spot");
  }
  if (slices.size() != spots.size()) {
    return Status::InvalidArgument("slices (" + std::to_string(slices.size()) +
                                   ") and spots (" + std::to_string(spots.size()) +
                                   ") differ in number");
  }
  if (spots.empty()) return Status::InvalidArgument("no spots");
  if (options.beams_per_side) {
    if (const std::string problem = BeamsPerSideProblem(*options.beams_per_side);
        !problem.empty()) {
      return Status::InvalidArgument("beams per side " + problem);
    }
  }
  double scale = 1.0;
  if (scaling) {
    if (!(std::isfinite(scaling->scale) && scaling->scale > 0.0 &&
          std::isfinite(scaling->u_scale_relative) && scaling->u_scale_relative >= 0.0)) {
      return Status::InvalidArgument("artifact scaling: scale must be finite and > 0");
    }
    scale = scaling->scale;
  }
  // Samples by source (order of first appearance); each slice to one source.
  std::vector<std::string> order;
  std::map<std::string, std::vector<CalibrationSample>> by_source;
  std::map<std::string, int> max_id;
  std::map<int, size_t> slice_owner;  // slice -> first spot index
  std::map<std::pair<int, int>, size_t> first_of_beam;  // (slice, beam) -> spot index
  std::map<std::string, std::string> max_id_where;      // where the largest id was read
  for (size_t i = 0; i < spots.size(); ++i) {
    const Spot& s = spots[i];
    const int beam_id = s.observation.beam_id;
    if (beam_id < 1) {
      return Status::InvalidArgument(s.where + ": beam id " + std::to_string(beam_id) +
                                     " of source " + QuoteForMessage(s.source) +
                                     " must be >= 1");
    }
    if (options.beams_per_side &&
        beam_id > *options.beams_per_side * *options.beams_per_side) {
      return Status::InvalidArgument(
          s.where + ": beam id " + std::to_string(beam_id) + " of source " +
          QuoteForMessage(s.source) + " is outside 1.." +
          std::to_string(*options.beams_per_side * *options.beams_per_side) + " (a grid of " +
          std::to_string(*options.beams_per_side) + " x " +
          std::to_string(*options.beams_per_side) + " beams)");
    }
    auto [owner, inserted] = slice_owner.emplace(slices[i], i);
    if (!inserted && spots[owner->second].source != s.source) {
      const Spot& first = spots[owner->second];
      return Status::InvalidArgument(
          s.where + ": slice " + std::to_string(slices[i]) + " holds spots of source '" +
          s.source + "' and of source " + QuoteForMessage(first.source) + " (" + first.where +
          "): a slice is one grid at one screen position");
    }
    if (auto [first_spot, new_beam] = first_of_beam.emplace(std::make_pair(slices[i], beam_id), i);
        !new_beam) {
      return Status::InvalidArgument(
          s.where + ": a second spot of beam " + std::to_string(beam_id) + " of source " +
          QuoteForMessage(s.source) + " in slice " + std::to_string(slices[i]) + " (the first is " +
          spots[first_spot->second].where + "): a slice holds each beam's spot once");
    }
    if (!by_source.count(s.source)) order.push_back(s.source);
    CalibrationSample sample;
    sample.beam_id = s.observation.beam_id;
    sample.slice = slices[i];
    sample.point_mm = scale * s.observation.point_in_scene;
    if (s.observation.cov_in_scene) sample.cov_mm2 = scale * scale * *s.observation.cov_in_scene;
    by_source[s.source].push_back(sample);
    int& m = max_id[s.source];
    if (sample.beam_id > m) {
      m = sample.beam_id;
      max_id_where[s.source] = s.where;
    }
  }
  ModuleCalibrationResult result;
  for (const std::string& name : order) {
    int n = 3;
    if (options.beams_per_side) {
      n = *options.beams_per_side;
    } else {
      // Bounded: n^2 never overflows, and an id beyond the largest grid is refused.
      while (n < kMaxBeamsPerSide && n * n < max_id[name]) n += 2;
      if (n * n < max_id[name]) {
        const std::string& where = max_id_where[name];
        return Status::InvalidArgument(
            (where.empty() ? std::string() : where + ": ") + "source " + QuoteForMessage(name) +
            ": beam id " + std::to_string(max_id[name]) +
            " is beyond the largest grid (" + std::to_string(kMaxBeamsPerSide) + " x " +
            std::to_string(kMaxBeamsPerSide) + " = " +
            std::to_string(kMaxBeamsPerSide * kMaxBeamsPerSide) + " beams)");
      }
    }
    Result<SourceCalibrationResult> source =
        CalibrateSource(name, n, by_source[name], options.source);
    if (!source.ok()) {
      if (options.beams_per_side) return source.status();
      return Status(source.status().code(),
                    source.status().message() + " (grid of " + std::to_string(n) + " x " +
                        std::to_string(n) + " inferred from the largest beam id, " +
                        std::to_string(max_id[name]) + ": give the beams per side if wrong)");
    }
    result.calibration.sources.push_back(source->calibration);
    result.sources.push_back(std::move(*source));
  }
  const double u_rel = scaling ? scaling->u_scale_relative : 0.0;
  for (size_t i = 0; i < result.sources.size(); ++i) {
    for (size_t j = i + 1; j < result.sources.size(); ++j) {
      const SourceCalibrationResult& a = result.sources[i];
      const SourceCalibrationResult& b = result.sources[j];
      const Eigen::Vector3d v = b.calibration.calibration_from_source.translation -
                                a.calibration.calibration_from_source.translation;
      const double L = v.norm();
      if (!(L > 0.0)) {
        return Status::NoSolution("sources '" + a.calibration.name + "' and '" +
                                  b.calibration.name + "' have the same origin");
      }
      const Eigen::Vector3d g = v / L;
      const Eigen::Matrix3d C = a.pose_covariance.bottomRightCorner<3, 3>() +
                                b.pose_covariance.bottomRightCorner<3, 3>();
      Separation sep;
      sep.from = a.calibration.name;
      sep.to = b.calibration.name;
      sep.length_mm = L;
      sep.u_length_mm = std::sqrt(std::max(0.0, g.dot(C * g)) + (L * u_rel) * (L * u_rel));
      result.calibration.separations.push_back(sep);
    }
  }
  result.calibration.scaling = scaling;
  return result;
}

}  // namespace opl
