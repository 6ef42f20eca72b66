// ModuleCalibration: what a calibration knows about a module. For each source
// its beam pattern and its pose in the calibration frame (millimetres), and the
// calibrated separations (length scales) between projection origins.
// File format: docs/formats.md, "Module calibration JSON".
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/model/beam_pattern.h"

namespace opl {

// Quality figures of a calibrated source, as opl_calibrate writes them
// (docs/formats.md, "quality"); absent from exact or hand-made calibrations.
struct SourceCalibrationQuality {
  int slices = 0;           // distinct slices the source was sampled in
  int samples_used = 0;     // samples in the final solve
  int samples_flagged = 0;  // samples flagged as wrong and left out
  int beams_dropped = 0;    // beams with samples but too few to calibrate
  double rms_residual_urad = 0.0;     // RMS angle residual of the used samples
  double variance_factor = 1.0;       // chi^2 / dof of the final solve
  double mean_point_to_ray_mm = 0.0;  // over all used samples
  double max_point_to_ray_mm = 0.0;
  Eigen::Matrix3d origin_cov_mm2 = Eigen::Matrix3d::Zero();         // of origin_mm
  Eigen::Matrix3d rotation_xyz_cov_rad2 = Eigen::Matrix3d::Zero();  // of rotation_xyz_rad
};

struct SourceCalibration {
  std::string name;
  BeamPattern pattern;
  // Pose of the source in the calibration frame, mm; translation = origin.
  Rigid3d calibration_from_source;
  std::optional<SourceCalibrationQuality> quality;
};

// How a calibration session was scaled by an artifact (a bar with two
// targets of calibrated distance), when it was: every sample was multiplied by
// `scale` = artifact_length_mm / measured_length before the solve.
struct CalibrationScaling {
  std::string from_target;                 // the artifact's two target ids
  std::string to_target;
  double artifact_length_mm = 0.0;         // calibrated length of the artifact
  double u_artifact_length_mm = 0.0;       // its standard uncertainty
  double measured_length = 0.0;            // the targets' distance in the data's units
  double u_measured_length = 0.0;          // its standard uncertainty (from target sigmas)
  double scale = 1.0;
  double u_scale_relative = 0.0;           // u(scale) / scale
};

struct Separation {
  std::string from;          // source name
  std::string to;            // source name
  double length_mm = 0.0;    // calibrated distance between the two origins
  double u_length_mm = 0.0;  // its standard uncertainty (k = 1)
};

struct ModuleCalibration {
  std::vector<SourceCalibration> sources;
  std::vector<Separation> separations;
  std::optional<CalibrationScaling> scaling;

  // Names unique and non-empty, patterns valid, separations name known sources,
  // lengths positive and finite, uncertainties >= 0.
  Status Validate() const;
  // nullptr when there is no source of that name.
  const SourceCalibration* FindSource(const std::string& name) const;
  // Separations between every pair of sources from their calibrated origins,
  // with zero uncertainty (used by simulation to write an exact calibration).
  static std::vector<Separation> SeparationsFromOrigins(
      const std::vector<SourceCalibration>& sources);
};

}  // namespace opl
