// Calibrating one source (method.md, "Calibrating a source").
//
// Input: the scaled 3D points ("samples") of one source's beams, measured on a
// screen placed at several depths ("slices"), all in one calibration frame
// (mm). Every sample of beam b must lie on the ray from the projection origin
// t along the beam's direction. One joint Ceres problem finds
//   - the pose calibration_from_source = (R, t) of the source,
//   - every beam's direction (az_b, el_b) in the source frame,
// minimising the spherical-angle residuals of every sample seen from the origin
// (BeamRayCostFunction), with the gauge fixed as method.md states: the central
// beam is az = el = 0 and the central row has mean elevation 0 (exactly, by
// parameterisation: ZeroSumManifold).
//
// No starting guess is needed: each beam's samples are fitted with a 3D line
// (least median of squares over sample pairs, then a least-squares refit of
// the inliers), the origin is the point nearest to all lines, the central
// beam's line gives the pose's X axis and the grid's column and row directions
// its Y and Z axes.
//
// Weighting: with sample covariances (sx, sy, sz) each angular residual is
// whitened by its propagated covariance (as in LocateSource), residuals are in
// standard deviations and the covariance is used as is; without them residuals
// are radians and the covariance is scaled by the a-posteriori variance factor.
//
// Wrong samples: a robust phase (Cauchy or Huber by iteratively reweighted
// least squares) is followed by flagging: every sample whose whitened residual
// norm exceeds `outlier_threshold` standard deviations is left out and the
// solve repeats, plain least squares, until the flags are stable. Beams left
// with fewer than `min_samples_per_beam` samples are dropped from the pattern
// (reported). The covariance is that of the final plain least-squares solve.
//
// Covariance: (J^T J)^-1 of the whitened problem in the tangent space, giving
// the 6x6 pose covariance (left rotation perturbation in the calibration frame,
// then the origin, as LocateResult) and each beam's 2x2 (az, el) covariance.
// The central beam's direction is fixed by the gauge: its covariance is zero
// and its uncertainty is carried by the pose.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/locate/locate_source.h"  // RobustLoss
#include "opl/model/module_calibration.h"

namespace opl {

// One measured point of one beam in one slice (calibration frame, mm).
struct CalibrationSample {
  int beam_id = 0;
  int slice = 0;
  Eigen::Vector3d point_mm = Eigen::Vector3d::Zero();
  std::optional<Eigen::Matrix3d> cov_mm2;  // covariance of point_mm, when known
};

struct CalibrateOptions {
  // Robust phase before flagging (kNone skips it). loss_scale is in standard
  // deviations (weighted) or radians (loss_scale_unweighted_rad).
  RobustLoss loss = RobustLoss::kCauchy;
  double loss_scale = 3.0;
  double loss_scale_unweighted_rad = 2e-4;
  int max_robust_rounds = 8;

  // Flagging: samples beyond this many standard deviations are left out.
  // Without covariances the standard deviation is the robust estimate from the
  // residuals (as in LocateOptions), floored at min_unweighted_sigma_rad.
  double outlier_threshold = 5.0;
  double min_unweighted_sigma_rad = 1e-8;
  int max_flagging_rounds = 10;

  // A beam needs at least this many unflagged samples to be calibrated (>= 2).
  int min_samples_per_beam = 2;
  // The line fit of the initialisation calls a sample an inlier within
  // max(this, 5 x the robust spread of the line fit) of the line, mm.
  double init_inlier_distance_mm = 0.5;

  // Levenberg-Marquardt (Ceres, dense Schur complement: the beams are
  // eliminated, the pose and the central row's elevations remain).
  int max_iterations = 100;
  double parameter_tolerance = 1e-12;
  double function_tolerance = 1e-14;

  Status Validate() const;
};

// What became of one sample.
struct CalibrationSampleResidual {
  int beam_id = 0;
  int slice = 0;
  Eigen::Vector2d residual_rad = Eigen::Vector2d::Zero();  // (az, el) measured - beam
  double normalized = 0.0;        // |W r|: standard deviations (or rad unweighted)
  double point_to_ray_mm = 0.0;   // distance of the sample from its beam's ray
  bool outlier = false;           // flagged and left out
  bool beam_dropped = false;      // its beam was dropped (too few samples)
};

// Quality of one calibrated beam.
struct BeamCalibrationQuality {
  int beam_id = 0;
  int samples_used = 0;
  int samples_flagged = 0;
  double mean_point_to_ray_mm = 0.0;  // over the used samples
  double max_point_to_ray_mm = 0.0;   // over the used samples
  double rms_residual_rad = 0.0;      // RMS of its used samples' angle residuals
};

struct SourceCalibrationResult {
  // name, pattern (calibrated beams with cov_azel_rad2), pose, quality.
  SourceCalibration calibration;
  // Covariance of (dtheta, dt): dtheta the left rotation perturbation in the
  // calibration frame (rad), dt the origin (mm).
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double variance_factor = 1.0;     // chi^2 / dof of the final solve
  bool weighted = false;            // sample covariances were used
  bool covariance_scaled = false;   // scaled by variance_factor
  int num_slices = 0;               // distinct slices among the samples
  int solver_iterations = 0;        // summed over all solves
  std::vector<BeamCalibrationQuality> beams;      // calibrated beams, by id
  std::vector<int> dropped_beam_ids;              // beams with samples but not calibrated
  std::vector<CalibrationSampleResidual> residuals;  // one per sample, input order
};

// Calibrates one source named `name` with an n x n grid (n = beams_per_side).
// Errors:
//  - InvalidArgument: bad options or n, a beam id outside 1..n^2, a non-finite
//    value, two samples of one beam in one slice, an invalid covariance;
//  - NoSolution: fewer than two distinct slices, the central beam or every
//    other central-row beam without usable samples, fewer than three usable
//    beams, lines that do not meet (degenerate geometry), a singular problem,
//    or a solve that fails.
Result<SourceCalibrationResult> CalibrateSource(const std::string& name, int beams_per_side,
                                                const std::vector<CalibrationSample>& samples,
                                                const CalibrateOptions& options = {});

}  // namespace opl
