// Calibrating a module: every source of a calibration session, the calibrated
// separations between their origins, and the optional artifact scaling
// (method.md, "Calibrating a source"; docs/calibrate.md).
//
// The input is a spots table with a slice column (io/spots_csv.h): each row a
// sample of one beam of one source in one slice. A slice is one screen position
// photographed with one grid on, so a slice holds the spots of one source only.
// All slices are in one common frame. When that frame is not yet scaled, an
// artifact (a bar with two targets whose distance is calibrated, e.g.
// 1677.66 mm) measured in the same frame scales every sample first, and its
// uncertainty is carried into the separations (fully correlated: it scales
// every length alike).
//
// Every source is solved by CalibrateSource on its own; sources share no
// parameter, so their origin covariances are independent, and a separation
// L = |t_i - t_j| has
//   u(L)^2 = g^T (C_i + C_j) g + (L u_rel(scale))^2,    g = (t_i - t_j) / L.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/calibrate/calibrate_source.h"
#include "opl/core/status.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"

namespace opl {

// The two targets of a scale artifact as measured in the (unscaled) frame of
// the session, and the artifact's calibrated length.
struct ArtifactMeasurement {
  std::string from_target;
  std::string to_target;
  Eigen::Vector3d from_point = Eigen::Vector3d::Zero();
  Eigen::Vector3d to_point = Eigen::Vector3d::Zero();
  std::optional<Eigen::Matrix3d> from_cov;  // covariances of the measured targets
  std::optional<Eigen::Matrix3d> to_cov;
  double length_mm = 0.0;    // calibrated length, > 0
  double u_length_mm = 0.0;  // its standard uncertainty, >= 0
};

// scale = length_mm / |to - from|, with
//   u_rel(scale)^2 = (u_length_mm / length_mm)^2 + (u(d) / d)^2,
// u(d)^2 = g^T (C_from + C_to) g. InvalidArgument on non-finite values, a
// length <= 0, or coincident targets.
Result<CalibrationScaling> ComputeArtifactScaling(const ArtifactMeasurement& artifact);

struct CalibrateModuleOptions {
  CalibrateOptions source;
  // n of every source's n x n grid; by default the smallest odd n with
  // n^2 >= the largest beam id seen for that source.
  std::optional<int> beams_per_side;
};

struct ModuleCalibrationResult {
  // Sources (in order of first appearance) with their quality figures, the
  // separations of every pair (in source order), and the scaling when given.
  ModuleCalibration calibration;
  std::vector<SourceCalibrationResult> sources;  // same order
};

// `slices` is parallel to `spots` (SpotsCsvData::slices). Errors:
//  - InvalidArgument: no slice column (slices empty), sizes differ, a slice
//    holding spots of two sources (named with both spots' `where`), bad
//    options or scaling;
//  - any error of CalibrateSource, prefixed by the source.
Result<ModuleCalibrationResult> CalibrateModule(const std::vector<Spot>& spots,
                                                const std::vector<int>& slices,
                                                const std::optional<CalibrationScaling>& scaling,
                                                const CalibrateModuleOptions& options = {});

}  // namespace opl
