// Bundle adjustment: cameras and 3D points refined together from their pixel
// observations (docs/multiview.md).
//
// The model. Camera i has a pose cam_from_scene_i = (q_i, t_i) (unit
// quaternion, translation) and the intrinsics of its physical camera k(i)
// (camera_model.h: fx, fy, cx, cy, k1, k2, p1, p2, k3), shared by every image
// that camera took. Observation o saw point j(o) in camera i(o) at pixel u_o
// with covariance Sigma_o (px^2). Its residual is whitened,
//
//   r_o = L_o^-1 (pi(K_k, q_i X_j + t_i) - u_o),   Sigma_o = L_o L_o^T,
//
// so that |r_o|^2 is the observation's chi^2 and sum_o |r_o|^2 / 2 is the
// Ceres cost. pi is ProjectPointInCamera; the cost functor below is templated
// so that Ceres differentiates it automatically. Rotations live on
// ceres::EigenQuaternionManifold. Any intrinsics, pose or point can be held
// constant.
//
// The gauge. Pixels determine the scene only up to a similarity (7 degrees of
// freedom: rotation, translation, scale). Either
//  - BundleGauge::kFixedByCaller: constant poses and/or points hold it (e.g.
//    two cameras of a calibrated rig, or one camera and a known point). The
//    solve and the covariances are in the caller's frame; if the constant
//    blocks do not fix all 7 degrees, covariances are reported unavailable.
//  - BundleGauge::kThreePointDatum: nothing is constant (the solve floats;
//    Levenberg-Marquardt's damping keeps the free directions still); after the
//    solve everything is moved to the scene frame of points A, B, C
//    (scene_frame.h: origin A, X towards B, XY plane through C). The scale of
//    that frame stays the solve's (unscaled) one; covariances are given with
//    the datum's six degrees AND the length |AB| held exact (the unit of the
//    unscaled frame), i.e. of
//        F(X) = (|AB|_0 / |B - A|) R(A, B, C) (X - A),
//    which does not depend on the gauge. A scale from an artifact or from the
//    laser module multiplies the points afterwards (ScaleFromArtifact).
//
// Covariances (options.compute_point_covariances): first order, assuming the
// Sigma_o are the true observation covariances (variance_factor in the result
// says whether they were: about 1), intrinsics held constant count as exact.
// Computed by the Schur complement on the Jacobian Ceres evaluates at the
// solution: H = J^T J = [A B; B^T D] (cameras, points), S = A - B D^-1 B^T,
//   Cov(X_j, X_l) = delta_jl D_j^-1 + D_j^-1 B_j^T S^- B_l D_l^-1,
// S^- the inverse of S (kFixedByCaller) or its pseudo-inverse with the seven
// gauge directions dropped (kThreePointDatum: any generalised inverse gives
// the same covariance of the gauge-free F above), then propagated through F.
//
// Linear solver: SPARSE_SCHUR with SuiteSparse; DENSE_SCHUR when SuiteSparse
// is not available at run time (the result says which was used).
//
// Errors (Status, never an abort): InvalidArgument for bad options, an
// observation with a bad camera/point index, a non-finite pixel or a
// covariance that is not symmetric positive definite (names the observation
// index), an invalid intrinsics entry or pose (names the camera), a free point
// seen by fewer than 2 cameras (names the point), a datum with constant
// blocks; NoSolution when a point projects behind a camera at the start or
// the solver fails.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/vision/camera_model.h"

namespace opl {

// One physical camera's intrinsics, shared by the images it took.
struct BundleIntrinsics {
  std::string name;
  CameraIntrinsics intrinsics;
  bool constant = true;  // calibrated cameras: held; false refines all 9 values
};

// One image: a pose and which intrinsics it uses.
struct BundleCamera {
  std::string name;
  int intrinsics_index = 0;  // into BundleData::intrinsics
  Rigid3d cam_from_scene;
  bool pose_constant = false;
};

struct BundlePoint {
  Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();
  bool constant = false;
};

struct BundleObservation {
  int camera = -1;  // into BundleData::cameras
  int point = -1;   // into BundleData::points
  Eigen::Vector2d pixel_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Identity();  // symmetric positive definite
};

struct BundleData {
  std::vector<BundleIntrinsics> intrinsics;
  std::vector<BundleCamera> cameras;
  std::vector<BundlePoint> points;
  std::vector<BundleObservation> observations;

  // Camera i as a camera_model.h Camera (its intrinsics and pose); i must be
  // a valid index.
  Camera CameraAt(int i) const;
};

enum class BundleLoss { kNone, kHuber, kCauchy };
enum class BundleGauge { kFixedByCaller, kThreePointDatum };

struct BundleOptions {
  // Levenberg-Marquardt iterations at most.
  int max_iterations = 100;
  // Ceres convergence tolerances (relative cost change, gradient, step).
  // Tighter than Ceres's defaults: photogrammetry wants the minimum to a
  // small fraction of its sigma.
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-14;
  double parameter_tolerance = 1e-12;
  // Robust loss on each observation, none by default. With kHuber / kCauchy
  // an observation's pixel residual larger than loss_scale_px (along its
  // whitened norm, sigma = sqrt(trace(Sigma_o) / 2)) is down-weighted.
  BundleLoss loss = BundleLoss::kNone;
  double loss_scale_px = 1.0;
  // Threads for Ceres (Jacobian evaluation and linear solver).
  int num_threads = 1;
  // Compute per-point covariances (header comment).
  bool compute_point_covariances = false;
  BundleGauge gauge = BundleGauge::kFixedByCaller;
  // kThreePointDatum: indices of the points A, B, C of the scene frame.
  std::array<int, 3> datum_points = {-1, -1, -1};

  // Checks every field; the message names the field, its value and the rule.
  Status Validate() const;
};

struct BundleResult {
  BundleData data;  // refined; in the datum frame with kThreePointDatum
  // The transform applied after the solve (identity with kFixedByCaller):
  // point_in_datum = datum_from_solve * point_in_solve.
  Rigid3d datum_from_solve;
  // "fixed by the caller (constant blocks)" or "three-point datum (points
  // a, b, c), scale of the solve".
  std::string gauge;

  // Ceres summary.
  double initial_cost = 0.0;  // sum of whitened squared residuals / 2
  double final_cost = 0.0;
  int iterations = 0;
  std::string termination;    // Ceres's termination type and message
  std::string linear_solver;  // "SPARSE_SCHUR (SUITE_SPARSE)" or "DENSE_SCHUR"
  double solve_seconds = 0.0;

  // Reprojection error (unwhitened), sqrt(mean |u - pi|^2 / 2): per coordinate.
  double rms_reprojection_px = 0.0;
  std::vector<double> camera_rms_px;  // per camera, same definition; 0 if unobserved
  // chi^2 / (observations * 2 - free parameters + gauge): ~1 when the
  // covariances of the observations are right.
  double variance_factor = 0.0;

  // Per point, 3x3 covariance of point_in_scene (zero for constant points)
  // when computed; empty otherwise. covariance_method says how, or why not.
  std::vector<Eigen::Matrix3d> point_covariances;
  // The same split into what is each point's own and what it shares with
  // every other point (the cameras' errors; with kThreePointDatum also the
  // datum points'): error_j = own_j + point_shared_factors[j] * z, z ~ N(0, I)
  // one vector for all points (its dimension m the same for every point), so
  //   point_covariances[j] = point_own_covariances[j] + K_j K_j^T,
  //   Cov(X_i, X_j) = K_i K_j^T (i != j).
  // What a later step that treats the points as independent must add back
  // (pipeline/measure_images.h). Filled with point_covariances.
  std::vector<Eigen::Matrix3d> point_own_covariances;
  std::vector<Eigen::MatrixXd> point_shared_factors;
  std::string covariance_method;

  // Multi-line report: solve, costs, RMS per camera, covariance summary.
  std::string Report() const;
};

// Refines `data` (header comment).
Result<BundleResult> BundleAdjust(const BundleData& data,
                                  const BundleOptions& options = BundleOptions());

// The residual of one observation (header comment), for Ceres automatic
// differentiation. Parameter blocks: quaternion of cam_from_scene (4, Eigen's
// x, y, z, w storage order), translation (3), packed intrinsics
// (kNumCameraParameters), point_in_scene (3). Returns false for a point at or
// behind the camera.
struct ReprojectionCostFunctor {
  ReprojectionCostFunctor(const Eigen::Vector2d& pixel_px, const Eigen::Matrix2d& whitening)
      : pixel_px_(pixel_px), whitening_(whitening) {}

  // whitening = L^-1 for Sigma = L L^T; Sigma must be positive definite.
  static Eigen::Matrix2d WhiteningOf(const Eigen::Matrix2d& covariance_px2);

  template <typename T>
  bool operator()(const T* quaternion, const T* translation, const T* intrinsics,
                  const T* point_in_scene, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(quaternion);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(translation);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> X(point_in_scene);
    const Eigen::Matrix<T, 3, 1> point_in_cam = q * X + t;
    T pixel[2];
    if (!ProjectPointInCamera(intrinsics, point_in_cam.data(), pixel)) return false;
    const T du = pixel[0] - T(pixel_px_.x());
    const T dv = pixel[1] - T(pixel_px_.y());
    residual[0] = T(whitening_(0, 0)) * du + T(whitening_(0, 1)) * dv;
    residual[1] = T(whitening_(1, 0)) * du + T(whitening_(1, 1)) * dv;
    return true;
  }

 private:
  Eigen::Vector2d pixel_px_;
  Eigen::Matrix2d whitening_;
};

}  // namespace opl
