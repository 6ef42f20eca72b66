#include "opl/pipeline/calibrate_images.h"
#include "opl/pipeline/measure_images.h"

#include <algorithm>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "opl/core/format.h"

namespace opl {

Status ImageCalibrationOptions::Validate() const {
  OPL_RETURN_IF_ERROR(front_end.Validate());
  OPL_RETURN_IF_ERROR(calibrate.source.Validate());
  return identify.Validate();
}

std::string ImageCalibrationReport::ToText() const {
  std::ostringstream out;
  out << front_end.ToText() << identification.ToText() << "\n"
      << "artifact: tags " << scaling.from_target << " - " << scaling.to_target << ", "
      << FormatNumber(scaling.measured_length, 8) << " +- "
      << FormatNumber(scaling.u_measured_length, 3) << " (unscaled) for "
      << FormatNumber(scaling.artifact_length_mm, 8) << " mm: scale "
      << FormatNumber(scaling.scale, 10) << " (u_rel " << FormatNumber(scaling.u_scale_relative, 3)
      << ")\n";
  if (shared.components > 0) {
    for (size_t l = 0; l < calibration.calibration.separations.size(); ++l) {
      const Separation& sep = calibration.calibration.separations[l];
      out << "u(" << sep.from << "-" << sep.to << ") = sqrt(own^2 + shared^2): own "
          << FormatNumber(shared.u_separation_own_mm[l], 3) << " mm (the spots' own errors), shared "
          << FormatNumber(shared.u_separation_shared_mm[l], 3)
          << " mm (camera poses and datum tags, common to many spots; "
          << shared.components << " components)\n";
    }
  }
  return out.str();
}

Result<ImageCalibrationReport> CalibrateFromImages(const Scene& scene,
                                                   const std::string& images_dir,
                                                   const ModuleCalibration& nominal,
                                                   const ImageCalibrationOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (!scene.artifact) {
    return Status::InvalidArgument(
        "scene: no 'artifact': a calibration session needs the scale artifact's two tags");
  }
  if (Status st = CheckSceneHasLasers(scene); !st.ok()) {
    return Status::InvalidArgument("scene: " + st.message());
  }
  Result<FrontEndResult> front_end = RunImageFrontEnd(scene, images_dir, options.front_end);
  if (!front_end.ok()) return front_end.status();
  ImageCalibrationReport report;
  report.front_end = std::move(*front_end);

  // Scale from the artifact's tag centres.
  const SceneArtifact& artifact = *scene.artifact;
  ArtifactMeasurement measurement;
  measurement.from_target = "tag " + std::to_string(artifact.tag_1);
  measurement.to_target = "tag " + std::to_string(artifact.tag_2);
  measurement.length_mm = artifact.length_mm;
  measurement.u_length_mm = artifact.length_sigma_mm;
  for (int end = 0; end < 2; ++end) {
    const int id = end == 0 ? artifact.tag_1 : artifact.tag_2;
    const auto center = report.front_end.tag_centers.find(id);
    if (center == report.front_end.tag_centers.end()) {
      return Status::NoSolution("artifact tag " + std::to_string(id) +
                                " was not found in two placed images");
    }
    (end == 0 ? measurement.from_point : measurement.to_point) = center->second;
    (end == 0 ? measurement.from_cov : measurement.to_cov) =
        report.front_end.tag_center_covariances.at(id);
  }
  Result<CalibrationScaling> scaling = ComputeArtifactScaling(measurement);
  if (!scaling.ok()) return Status::NoSolution("artifact: " + scaling.status().message());
  report.scaling = *scaling;

  // The spots of every group are one slice (one grid, one screen position).
  std::vector<Spot> spots;
  std::vector<int> slices;
  std::map<std::string, size_t> front_end_index;  // by `where`
  for (size_t k = 0; k < report.front_end.spots.size(); ++k) {
    const FrontEndSpot& s = report.front_end.spots[k];
    Spot spot;
    spot.observation.point_in_scene = s.point_in_scene;
    spot.observation.cov_in_scene = s.covariance;
    spot.where = "spot " + std::to_string(k + 1) + " (group " + std::to_string(s.group) + ")";
    front_end_index[spot.where] = k;
    spots.push_back(spot);
    slices.push_back(s.group);
  }
  Result<SessionIdentification> identified =
      IdentifySessionSlices(nominal, spots, slices, options.identify);
  if (!identified.ok()) return identified.status();
  report.identification = std::move(*identified);
  if (report.identification.spots.empty()) {
    return Status::NoSolution("no spot was identified in any of the " +
                              std::to_string(report.front_end.groups.size()) +
                              " exposure groups");
  }
  // The own / shared split of every identified spot, when the front end gave
  // it.
  std::vector<Spot> assigned = report.identification.spots;
  std::vector<const FrontEndSpot*> source_spots;
  std::vector<Eigen::MatrixXd> factors;
  bool split = options.propagate_shared_errors;
  for (const Spot& s : assigned) {
    const size_t k = front_end_index.at(s.where);
    report.identified_front_end_spots.push_back(static_cast<int>(k));
    const FrontEndSpot& f = report.front_end.spots.at(k);
    split &= f.shared_factor.size() > 0 &&
             (factors.empty() || f.shared_factor.cols() == factors.front().cols());
    source_spots.push_back(&f);
    factors.push_back(f.shared_factor);
  }
  if (split) {
    for (size_t i = 0; i < assigned.size(); ++i) {
      assigned[i].observation.cov_in_scene = source_spots[i]->own_covariance;
    }
  }
  Result<ModuleCalibrationResult> calibrated = CalibrateModule(
      assigned, report.identification.slices, report.scaling, options.calibrate);
  if (!calibrated.ok()) return calibrated.status();
  report.calibration = std::move(*calibrated);
  if (split) {
    const int threads = options.front_end.num_threads > 0
                            ? options.front_end.num_threads
                            : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    Result<SharedErrorSummary> shared =
        AddSharedErrors(assigned, report.identification.slices, report.scaling,
                        options.calibrate, factors, &report.calibration, threads);
    if (!shared.ok()) return shared.status();
    report.shared = std::move(*shared);
  }
  return report;
}

}  // namespace opl
