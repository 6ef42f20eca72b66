// Locating one source (the measurement solve, method.md).
//
// Given the calibrated beam directions (az_b, el_b) of a source and measured
// scene points p_b of some of its spots, find scene_from_source = (R, t) so that,
// seen from the projection origin t in the rotated frame, every spot points
// where its beam points:
//
//   q_b = R^T (p_b - t)
//   minimise  sum_b  rho( | W_b [ az(q_b) - az_b ,  el(q_b) - el_b ] |^2 )
//
// W_b whitens the angular residual of spot b: when the spot's covariance is
// known (SpotObservation::cov_in_scene), the 2x2 angular covariance is
//   C_b = J_b Sigma_b J_b^T,   J_b = d(az, el)/dp_b  (+ the beam's own cov_azel)
// and W_b^T W_b = C_b^-1, so residuals are in units of standard deviations.
// Without covariances W_b = I and residuals are radians.
//
// No starting guess is needed: the problem is a camera resection with known
// bearing vectors, initialised by a minimal 3-point solver (P3P, in the spirit
// of Lambda Twist, Persson & Nordberg, ECCV 2018) inside RANSAC, then refined by
// Levenberg-Marquardt on SourcePoseCostFunction's problem (analytic Jacobians,
// checked against autodiff), run on its 6 x 6 normal equations summed spot by
// spot (PoseNormalEquations, pose_normal_equations.h: ceres::TinySolver's steps
// and stopping rules, tested to give TinySolver's pose). Any rotation works.
//
// Outliers: RANSAC's inliers are refined; then every spot whose whitened
// residual norm exceeds `outlier_threshold` standard deviations is flagged and
// left out, and the solve repeats until the inlier set is stable. The standard
// deviation is 1 with covariances (or the robust estimate from the residuals,
// if larger: understated sigmas do not flag good spots), and without them the
// robust estimate itself. An optional robust loss (Huber, Cauchy) is solved by
// iteratively reweighted least squares. Covariance of the pose: (J^T J)^-1 of
// the whitened problem over the inliers at the solution; with covariances given
// it is used as is, without them it is scaled by the a-posteriori variance
// factor (RSS / (2N - 6)). A robust loss's weights are not in the covariance.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/model/beam_pattern.h"
#include "opl/model/spot.h"

namespace opl {

enum class RobustLoss {
  kNone,    // plain least squares
  kHuber,   // rho(s) = s for s <= a^2, 2a sqrt(s) - a^2 beyond
  kCauchy,  // rho(s) = a^2 log(1 + s / a^2)
};

struct LocateOptions {
  // Robust loss on each spot's whitened squared residual; `loss_scale` is `a`
  // above, in standard deviations (or radians when spots have no covariance).
  // Default none: gross outliers are removed by RANSAC and flagging, and plain
  // least squares keeps the estimate efficient and its covariance exact.
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale = 3.0;
  double loss_scale_unweighted_rad = 1e-3;

  // RANSAC over minimal 3-spot samples. The inlier threshold is an angle
  // between a spot's direction and its beam's direction, radians.
  double ransac_inlier_threshold_rad = 2e-3;
  int ransac_max_iterations = 2000;   // hard cap on minimal samples tried
  double ransac_confidence = 0.9999;  // stop when P(all-inlier sample seen) >= this
  uint64_t ransac_seed = 1;           // fixed seed: results repeat run to run

  // Spots whose final whitened residual norm exceeds this many standard
  // deviations are flagged as outliers and excluded. Without covariances the
  // standard deviation is a robust estimate from the residuals themselves
  // (1.4826 * median of residual norms / sqrt(2 ln 2) for a 2D Gaussian),
  // floored at `min_unweighted_sigma_rad`.
  double outlier_threshold = 5.0;
  double min_unweighted_sigma_rad = 1e-7;
  // The solve fails (NoSolution) unless at least this fraction of the spots
  // are inliers: a pose explaining a few spots by chance is not an answer.
  double min_inlier_fraction = 0.5;

  // Optional starting pose. When given, RANSAC is skipped if at least 90% of
  // spots are inliers of this guess; otherwise RANSAC runs as usual.
  std::optional<Rigid3d> initial_scene_from_source;

  // Levenberg-Marquardt settings for each refinement (ceres::TinySolver's
  // rules, pose_normal_equations.h).
  int max_iterations = 50;
  // Stop when the max-norm of the (Jacobi-scaled) gradient falls below this;
  // 0 disables.
  double gradient_tolerance = 0.0;
  // Stop when a step would move the pose by less than this fraction of the
  // scene size D (the mean distance from the origin to the spots): the origin
  // by < tol * D, the rotation by < tol rad. 1e-8 is 10 nm at 1 m. Noisy data
  // converge linearly (about 2 digits per iteration), so the pose is then
  // within ~1e-10 D of the optimum, far inside its uncertainty; noise-free data
  // converge quadratically and end at rounding level.
  double parameter_tolerance = 1e-8;

  // Checks every field; the message names the field, its value and the rule.
  Status Validate() const;
};

// Per-spot outcome of a locate.
struct SpotResidual {
  int beam_id = 0;
  Eigen::Vector2d residual_rad = Eigen::Vector2d::Zero();  // (az, el) measured - beam
  double normalized = 0.0;  // |W r|: standard deviations (or rad without covariances)
  bool outlier = false;
};

struct LocateResult {
  Rigid3d scene_from_source;  // origin = scene_from_source.translation
  // Covariance of (dtheta, dt): dtheta the left rotation perturbation in the
  // scene frame (rad), dt the origin (scene units). Rows/cols 0-2 rotation,
  // 3-5 origin.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix3d origin_covariance = Eigen::Matrix3d::Zero();       // scene units^2
  Eigen::Vector3d rotation_xyz_rad = Eigen::Vector3d::Zero();        // R = Rx Ry Rz
  Eigen::Matrix3d rotation_xyz_covariance = Eigen::Matrix3d::Zero();  // rad^2

  double rms_residual_rad = 0.0;  // RMS of the angular residuals of inliers (per component)
  double variance_factor = 1.0;   // chi^2 / dof of the final solve (1 expected when weighted)
  bool weighted = false;          // true when spot covariances were used
  bool covariance_scaled = false;  // true when scaled by variance_factor
  int num_spots = 0;               // spots given (with a beam known to the pattern)
  int num_inliers = 0;
  int ransac_iterations = 0;
  int solver_iterations = 0;
  std::vector<SpotResidual> residuals;  // one per spot, in input order

  std::vector<int> OutlierBeamIds() const;
  // One line: origin, rms, inliers, outliers.
  std::string BriefReport() const;
};

// Locates one source. Errors (Status):
//  - InvalidArgument: bad options, a spot with a non-finite value, a beam id
//    unknown to the pattern, a duplicate beam id, an invalid covariance;
//  - NoSolution: fewer than 4 spots, spots degenerate (all collinear, or all
//    bearings nearly parallel), RANSAC finds no consistent pose, or the final
//    solve fails.
Result<LocateResult> LocateSource(const BeamPattern& pattern,
                                  const std::vector<SpotObservation>& spots,
                                  const LocateOptions& options = LocateOptions());

}  // namespace opl
