// The scene frame: a datum defined by three targets, and the scale of a
// scene from a calibrated artifact.
//
// Photogrammetry (triangulation, bundle adjustment: triangulation.h,
// bundle_adjustment.h) determines points and cameras only up to a similarity
// (rotation, translation, scale) unless something holds them. The scene frame
// fixes the rigid part by convention, from three targets A, B, C:
//
//   origin   at A,
//   X axis   along B - A,                         X = (B - A) / |B - A|
//   Z axis   normal to the plane of A, B, C,      Z = X x (C - A) / |X x (C - A)|
//   Y axis   completing a right-handed frame,     Y = Z x X
//
// so that A = (0, 0, 0), B = (|AB|, 0, 0), C = (., > 0, 0) in the new frame.
// SceneFromThreePoints returns the rigid transform new_scene_from_old with
//   point_in_new_scene = R (point_in_old_scene - A),  R = [X Y Z]^T.
//
// The scale is not fixed by the frame. ScaleFromArtifact gives the factor
// s = L_cal / |P2 - P1| from two targets a calibrated distance apart, with its
// first-order uncertainty; the laser module (method.md) gives it otherwise.
// TransformScene applies new_scene_from_old and a scale to cameras and points
// so that every pixel projection is unchanged.
//
// Errors (Status, never an abort): non-finite input, coincident or collinear
// targets (the message gives the distance or the angle that is too small).
#pragma once

#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/vision/camera_model.h"

namespace opl {

struct SceneFrameOptions {
  // A, B (and C's distance from A) closer than this fraction of the largest
  // of |AB|, |AC|, |BC| are coincident.
  double min_relative_distance = 1e-9;
  // C closer than this angle [deg] to the line AB, seen from A or from B, is
  // collinear (the XY plane would be undetermined).
  double min_angle_deg = 0.5;

  Status Validate() const;
};

// new_scene_from_old for the frame of targets a, b, c (header comment).
Result<Rigid3d> SceneFromThreePoints(const Eigen::Vector3d& a_in_old,
                                     const Eigen::Vector3d& b_in_old,
                                     const Eigen::Vector3d& c_in_old,
                                     const SceneFrameOptions& options = SceneFrameOptions());

// The same frame as a templated rotation R (rows X, Y, Z) and origin A, for
// double and ceres::Jet (used to propagate covariances through the datum).
// No checks: for well-separated, non-collinear points.
template <typename T>
void ThreePointFrame(const T* a, const T* b, const T* c, T* rotation_rows /* 9, row-major */) {
  T x[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const T ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  using std::sqrt;
  const T nx = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (T& v : x) v /= nx;
  T z[3] = {x[1] * ac[2] - x[2] * ac[1], x[2] * ac[0] - x[0] * ac[2],
            x[0] * ac[1] - x[1] * ac[0]};
  const T nz = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  for (T& v : z) v /= nz;
  const T y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2],
                  z[0] * x[1] - z[1] * x[0]};
  for (int i = 0; i < 3; ++i) {
    rotation_rows[i] = x[i];
    rotation_rows[3 + i] = y[i];
    rotation_rows[6 + i] = z[i];
  }
}

// cam_from_new_scene of a camera whose pose was cam_from_old_scene, when the
// scene is mapped by point_in_new = scale * (new_scene_from_old * point_in_old):
//   cam_from_new = (R_c R^T, scale (t_c - R_c R^T t)),
// which leaves every projected pixel unchanged (the camera frame is scaled too).
Rigid3d CamFromNewScene(const Rigid3d& cam_from_old_scene, const Rigid3d& new_scene_from_old,
                        double scale);

// Applies point_in_new = scale * (new_scene_from_old * point_in_old) to
// `points_in_scene` and the matching pose change to `cameras` (either may be
// null). InvalidArgument for a non-positive or non-finite scale.
Status TransformScene(const Rigid3d& new_scene_from_old, double scale,
                      std::vector<Camera>* cameras,
                      std::vector<Eigen::Vector3d>* points_in_scene);

struct ArtifactScale {
  double scale = 1.0;             // s = calibrated_length / measured_length
  double scale_sigma = 0.0;       // first-order standard deviation of s
  double measured_length = 0.0;   // |p2 - p1|, scene units
  double measured_length_sigma = 0.0;  // from the points' covariances
};

// Scale factor of the scene from a calibrated artifact whose two targets were
// measured at p1, p2 (scene units) with 3x3 covariances cov1, cov2 (assumed
// uncorrelated; zero for exact points). With u = (p2 - p1) / |p2 - p1|,
//   var(|p2 - p1|) = u^T (cov1 + cov2) u,
//   (sigma_s / s)^2 = var(|p2 - p1|) / |p2 - p1|^2 + (sigma_cal / L_cal)^2.
// Errors: coincident points, non-positive length, negative sigma, a
// covariance that is not symmetric positive semi-definite, non-finite input.
Result<ArtifactScale> ScaleFromArtifact(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                                        double calibrated_length,
                                        const Eigen::Matrix3d& cov1 = Eigen::Matrix3d::Zero(),
                                        const Eigen::Matrix3d& cov2 = Eigen::Matrix3d::Zero(),
                                        double calibrated_length_sigma = 0.0);

}  // namespace opl
