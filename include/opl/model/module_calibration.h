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

struct SourceCalibration {
  std::string name;
  BeamPattern pattern;
  // Pose of the source in the calibration frame, mm; translation = origin.
  Rigid3d calibration_from_source;
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
