// ProjectorSpotCostFunction: the pixel residual of one laser spot seen in one
// image, when the spot is modelled as a point on its calibrated beam (the
// laser module as a calibrated projector, projector_adjustment.h), with
// analytic Jacobians.
//
// The model. A spot of beam b of source s, shown by the module at placement
// m, seen by camera i:
//   d(az, el)   = (cos el cos az, cos el sin az, sin el)      beam, source frame
//   p_source    = depth d                                     mm, source frame
//   p_module    = R(q_s) p_source + lambda o_s                module frame
//   p_scene     = R(q_m) p_module + t_m                       scene_from_module
//   p_cam       = R(q_i) p_scene + t_i                        cam_from_scene
//   r           = W (pi(K_i, p_cam) - u)                      2 residuals
// where o_s is the source's calibrated origin in the module frame (fixed
// data), lambda the module's length factor (1 for the calibration), q_s the
// source's rotation module_from_source, W = L^-1 for the spot's pixel
// covariance Sigma = L L^T, pi the Brown-Conrady projection of
// camera_model.h with the camera's intrinsics K_i held (data, not a
// parameter).
//
// Parameter blocks, in this order (quaternions in Eigen's x, y, z, w storage,
// meant for ceres::EigenQuaternionManifold):
//   0 q_cam (4)  1 t_cam (3)  2 q_module (4)  3 t_module (3)  4 lambda (1)
//   5 q_source (4)  6 beam (az, el) rad (2)  7 depth mm (1)
// The Jacobians are with respect to these ambient coordinates. R(q) v is
// Eigen's v + 2 w (u x v) + 2 u x (u x v) (q = (u, w)), differentiated as it
// stands: d/dw = 2 u x v, d/du = -2 w [v]x + 2 ((u.v) I + u v^T - 2 v u^T).
// Checked against ceres::AutoDiffCostFunction of ProjectorSpotFunctor
// (tests/vision/projector_adjustment_test.cc).
#pragma once

#include <ceres/sized_cost_function.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "opl/vision/camera_model.h"

namespace opl {

class ProjectorSpotCostFunction final
    : public ceres::SizedCostFunction<2, 4, 3, 4, 3, 1, 4, 2, 1> {
 public:
  // origin_in_module: o_s, mm. whitening: W, 2x2.
  ProjectorSpotCostFunction(const CameraIntrinsics& intrinsics, const Eigen::Vector2d& pixel_px,
                            const Eigen::Matrix2d& whitening,
                            const Eigen::Vector3d& origin_in_module);

  // False when the spot is at or behind the camera.
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  std::array<double, kNumCameraParameters> intrinsics_;
  Eigen::Vector2d pixel_px_;
  Eigen::Matrix2d whitening_;
  Eigen::Vector3d origin_in_module_;
};

// The same residual for automatic differentiation (the reference the
// analytic Jacobians are tested against).
struct ProjectorSpotFunctor {
  ProjectorSpotFunctor(const CameraIntrinsics& intrinsics, const Eigen::Vector2d& pixel_px,
                       const Eigen::Matrix2d& whitening, const Eigen::Vector3d& origin_in_module)
      : intrinsics_(intrinsics.Packed()), pixel_px_(pixel_px), whitening_(whitening),
        origin_(origin_in_module) {}

  template <typename T>
  bool operator()(const T* q_cam, const T* t_cam, const T* q_module, const T* t_module,
                  const T* lambda, const T* q_source, const T* beam, const T* depth,
                  T* residual) const {
    using V3 = Eigen::Matrix<T, 3, 1>;
    using std::cos;
    using std::sin;
    const V3 d(cos(beam[1]) * cos(beam[0]), cos(beam[1]) * sin(beam[0]), sin(beam[1]));
    const V3 p_source = depth[0] * d;
    const V3 p_module = Eigen::Map<const Eigen::Quaternion<T>>(q_source) * p_source +
                        lambda[0] * origin_.cast<T>();
    const V3 p_scene = Eigen::Map<const Eigen::Quaternion<T>>(q_module) * p_module +
                       Eigen::Map<const V3>(t_module);
    const V3 p_cam =
        Eigen::Map<const Eigen::Quaternion<T>>(q_cam) * p_scene + Eigen::Map<const V3>(t_cam);
    T packed[kNumCameraParameters];
    for (int k = 0; k < kNumCameraParameters; ++k) packed[k] = T(intrinsics_[static_cast<size_t>(k)]);
    T pixel[2];
    if (!ProjectPointInCamera(packed, p_cam.data(), pixel)) return false;
    const T du = pixel[0] - T(pixel_px_.x());
    const T dv = pixel[1] - T(pixel_px_.y());
    residual[0] = T(whitening_(0, 0)) * du + T(whitening_(0, 1)) * dv;
    residual[1] = T(whitening_(1, 0)) * du + T(whitening_(1, 1)) * dv;
    return true;
  }

 private:
  std::array<double, kNumCameraParameters> intrinsics_;
  Eigen::Vector2d pixel_px_;
  Eigen::Matrix2d whitening_;
  Eigen::Vector3d origin_;
};

// d(R(q) v)/dq, 3x4, ambient (x, y, z, w) coordinates (header comment).
Eigen::Matrix<double, 3, 4> RotatedVectorJacobianWrtQuaternion(const Eigen::Quaterniond& q,
                                                                const Eigen::Vector3d& v);

}  // namespace opl
