// Triangulation: one 3D point from its pixels in two or more calibrated views.
//
// The model. View i is a calibrated camera (camera_model.h: intrinsics and
// cam_from_scene, held exact) that observed the point at the pixel u_i with a
// 2x2 covariance Sigma_i (px^2; identity when not given). The point X (scene
// frame) minimises the whitened reprojection error
//
//   sum_i  (pi_i(X) - u_i)^T Sigma_i^-1 (pi_i(X) - u_i),
//
// pi_i the camera's projection with its Brown-Conrady distortion.
//
// The algorithm.
//  1. Each pixel is undistorted (UndistortPixel) to a ray from the camera
//     centre C_i along d_i = R_i^T (x_i, y_i, 1) / |.|, in the scene frame.
//  2. Linear start (the N-view midpoint): the point closest to all rays in
//     the least-squares sense, sum_i |(I - d_i d_i^T)(X - C_i)|^2, a 3x3
//     linear system.
//  3. Gauss-Newton on the whitened pixel residuals, Jacobians by automatic
//     differentiation of ProjectPointInCamera, until the step is below
//     `step_tolerance` of the distance to the nearest camera.
//  4. Covariance (first order): (sum_i J_i^T Sigma_i^-1 J_i)^-1 at the
//     solution, J_i = d pi_i / d X. It assumes the Sigma_i are the true
//     observation covariances; `variance_factor` (chi^2 / (2n - 3)) says how
//     well the residuals agree with them.
//
// The triangulation angle is the largest angle between two rays from camera
// centres to the solution: a point seen by rays closer than
// `min_triangulation_angle_deg` is rejected (its depth is barely determined).
//
// Errors (Status, never an abort): InvalidArgument for fewer than 2 views,
// an invalid camera, a non-finite pixel, a covariance that is not symmetric
// positive definite (each names the view index); NoSolution for a pixel that
// cannot be undistorted, a point behind a camera (names the view), nearly
// parallel rays (names the angle), a Gauss-Newton that does not converge.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/vision/camera_model.h"

namespace opl {

// One view of the point.
struct PointObservation {
  const Camera* camera = nullptr;  // not owned; must outlive the call
  Eigen::Vector2d pixel_px = Eigen::Vector2d::Zero();
  // Covariance of the pixel [px^2], symmetric positive definite.
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Identity();
};

struct TriangulationOptions {
  // Rays whose largest pairwise angle is below this [deg] give NoSolution
  // (the point's depth is not determined).
  double min_triangulation_angle_deg = 1.0;
  // Gauss-Newton iterations at most.
  int max_iterations = 20;
  // Convergence: the Gauss-Newton step is below this fraction of the distance
  // from the point to its nearest camera centre.
  double step_tolerance = 1e-12;

  Status Validate() const;
};

struct TriangulatedPoint {
  Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();
  // First-order covariance of point_in_scene [scene units^2] (header comment).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  // Per view, the reprojection residual pi_i(X) - u_i [px], input order.
  std::vector<Eigen::Vector2d> residuals_px;
  double rms_residual_px = 0.0;      // sqrt(mean |residual|^2 / 2), per coordinate
  double chi2 = 0.0;                 // sum of whitened squared residuals
  double variance_factor = 0.0;      // chi2 / (2 n - 3); 0 for two views
  double triangulation_angle_deg = 0.0;  // largest angle between two rays
  int iterations = 0;                // Gauss-Newton iterations used

  // One line: point, sigmas, RMS residual, angle.
  std::string ToText() const;
};

// Triangulates one point from `observations` (header comment).
Result<TriangulatedPoint> TriangulatePoint(
    const std::vector<PointObservation>& observations,
    const TriangulationOptions& options = TriangulationOptions());

}  // namespace opl
