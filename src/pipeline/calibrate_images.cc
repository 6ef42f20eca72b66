#include "opl/pipeline/calibrate_images.h"

#include <sstream>

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
  for (size_t k = 0; k < report.front_end.spots.size(); ++k) {
    const FrontEndSpot& s = report.front_end.spots[k];
    Spot spot;
    spot.observation.point_in_scene = s.point_in_scene;
    spot.observation.cov_in_scene = s.covariance;
    spot.where = "spot " + std::to_string(k + 1) + " (group " + std::to_string(s.group) + ")";
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
  Result<ModuleCalibrationResult> calibrated =
      CalibrateModule(report.identification.spots, report.identification.slices,
                      report.scaling, options.calibrate);
  if (!calibrated.ok()) return calibrated.status();
  report.calibration = std::move(*calibrated);
  return report;
}

}  // namespace opl
