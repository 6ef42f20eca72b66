// Errors that the samples of a calibration session share, carried into the
// calibration (docs/calibrate.md, "Shared errors").
//
// CalibrateModule treats every sample as independent: its covariance is the
// sample's own. Samples triangulated from photographs are not: every spot of
// an image moves with that image's camera pose error, and every spot with the
// datum tags' errors (FrontEndSpot::shared_factor). Such an error moves a
// whole slice of one grid at once; it does not average down over the slice's
// beams, and the two sources of a module, photographed in different images,
// get different ones, so it reaches their separation in full.
//
// The model: sample i's error is own_i + K_i z, own_i ~ N(0, its own
// covariance, the one CalibrateModule weighted it by), z ~ N(0, I_m) the
// same for every sample. AddSharedErrors propagates z to the calibration by
// central differences (every sample moved by +- K_i e_k, the calibration
// solved again on the same samples, k = 1..m: 2m solves), and adds
//   sum_k g_k g_k^T,   g_k = (result(+e_k) - result(-e_k)) / 2,
// to every source's pose covariance, every beam's (az, el) covariance and
// every separation's variance. The re-solves use the samples the base solve
// used (no robust phase, no flagging), so that a one-sigma move cannot change
// which samples count; the artifact's scale is held (its own uncertainty is
// already in the separations).
//
//   Result<ModuleCalibrationResult> r = CalibrateModule(spots_own_cov, slices, scaling);
//   Result<SharedErrorSummary> s = AddSharedErrors(spots_own_cov, slices, scaling, {},
//                                                  factors, &*r);
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "opl/calibrate/calibrate_module.h"
#include "opl/core/status.h"
#include "opl/model/spot.h"

namespace opl {

// What AddSharedErrors added, per separation (parallel to
// ModuleCalibration::separations): u^2 = own^2 + shared^2.
struct SharedErrorSummary {
  int components = 0;  // m
  std::vector<double> u_separation_own_mm;
  std::vector<double> u_separation_shared_mm;
};

// `spots`, `slices`, `scaling` and `options`: exactly what `result` was
// calibrated from (CalibrateModule); `shared_factors[i]` is spot i's K_i,
// 3 x m, in the units of the spots' points (before the artifact scaling,
// which AddSharedErrors applies), the same m for every spot; m = 0 adds
// nothing. Errors: InvalidArgument when the sizes differ, m differs between
// spots or a factor is not finite; a re-solve's error (NoSolution, ...),
// prefixed with the component; NoSolution when a re-solve calibrates other
// sources or beams than `result`. `result` is changed only on success.
// The re-solves run on `num_threads` threads (< 1: one); the result does
// not depend on it.
Result<SharedErrorSummary> AddSharedErrors(const std::vector<Spot>& spots,
                                           const std::vector<int>& slices,
                                           const std::optional<CalibrationScaling>& scaling,
                                           const CalibrateModuleOptions& options,
                                           const std::vector<Eigen::MatrixXd>& shared_factors,
                                           ModuleCalibrationResult* result, int num_threads = 1);

}  // namespace opl
