// The scale factor of a scene from the located sources of a module.
//
// For every calibrated separation (i, j) with both sources located:
//   L_photo = | t_i - t_j |                 (scene units)
//   s_ij    = L_cal / L_photo               (mm per scene unit)
// u(L_photo) from the origin covariances (first order, sources independent):
//   u^2(L_photo) = e^T (C_i + C_j) e,   e = (t_i - t_j) / L_photo
// u(s_ij)^2 = s_ij^2 [ (u(L_cal)/L_cal)^2 + (u(L_photo)/L_photo)^2 ].
// With several pairs, s is their weighted mean, accounting for the correlation
// of pairs that share a source (generalised least squares with the full
// covariance of the s_ij), and consistency is reported as chi^2 / dof and the
// largest normalised deviation of a pair from s.
//
// Several placements of the module (LocatedOrigin::placement): a pair joins
// two sources located at the same placement only, and the pairs of one
// calibrated separation at different placements share its calibration
// error (their u(L_cal) terms are fully correlated), so that placements
// average the photogrammetric errors down but not the calibration's.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/model/module_calibration.h"

namespace opl {

// One located source as the scale computation needs it.
struct LocatedOrigin {
  std::string name;
  Eigen::Vector3d origin_in_scene = Eigen::Vector3d::Zero();    // scene units
  Eigen::Matrix3d origin_covariance = Eigen::Matrix3d::Zero();  // scene units^2
  std::string placement{};  // the module placement (empty: the only one)
};

struct LengthScale {
  std::string from, to;
  double photo = 0.0;    // L_photo, scene units
  double u_photo = 0.0;  // u(L_photo), scene units
  double cal_mm = 0.0;   // L_cal
  double u_cal_mm = 0.0;
  double scale = 0.0;    // s_ij = cal / photo
  double u_scale = 0.0;
  std::string placement{};  // of both sources (empty: the only one)
};

struct ScaleResult {
  std::vector<LengthScale> lengths;  // one per usable calibrated separation
  double scale_factor = 0.0;         // s, mm per scene unit
  double u_scale_factor = 0.0;       // u(s)
  // Consistency of several pairs: chi^2 of the s_ij about s, its degrees of
  // freedom (pairs - 1) and the largest |s_ij - s| / u(s_ij - s).
  double chi2 = 0.0;
  int dof = 0;
  double max_normalized_deviation = 0.0;
};

// NoSolution when no calibrated separation joins two located sources, or a
// located pair coincides (L_photo = 0).
Result<ScaleResult> ComputeScaleFactor(const ModuleCalibration& calibration,
                                       const std::vector<LocatedOrigin>& located);

}  // namespace opl
