#include "opl/vision/projector_spot_cost_function.h"

#include <cmath>

#include "opl/geometry/rotation.h"

namespace opl {

Eigen::Matrix<double, 3, 4> RotatedVectorJacobianWrtQuaternion(const Eigen::Quaterniond& q,
                                                                const Eigen::Vector3d& v) {
  const Eigen::Vector3d u = q.vec();
  const double w = q.w();
  Eigen::Matrix<double, 3, 4> J;
  J.leftCols<3>() = -2.0 * w * Skew(v) +
                    2.0 * (u.dot(v) * Eigen::Matrix3d::Identity() + u * v.transpose() -
                           2.0 * v * u.transpose());
  J.col(3) = 2.0 * u.cross(v);
  return J;
}

ProjectorSpotCostFunction::ProjectorSpotCostFunction(const CameraIntrinsics& intrinsics,
                                                     const Eigen::Vector2d& pixel_px,
                                                     const Eigen::Matrix2d& whitening,
                                                     const Eigen::Vector3d& origin_in_module)
    : intrinsics_(intrinsics.Packed()), pixel_px_(pixel_px), whitening_(whitening),
      origin_in_module_(origin_in_module) {}

bool ProjectorSpotCostFunction::Evaluate(double const* const* parameters, double* residuals,
                                         double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_cam(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> t_cam(parameters[1]);
  const Eigen::Map<const Eigen::Quaterniond> q_module(parameters[2]);
  const Eigen::Map<const Eigen::Vector3d> t_module(parameters[3]);
  const double lambda = parameters[4][0];
  const Eigen::Map<const Eigen::Quaterniond> q_source(parameters[5]);
  const double az = parameters[6][0];
  const double el = parameters[6][1];
  const double depth = parameters[7][0];

  const double ca = std::cos(az), sa = std::sin(az), ce = std::cos(el), se = std::sin(el);
  const Eigen::Vector3d d(ce * ca, ce * sa, se);
  const Eigen::Vector3d p_source = depth * d;
  const Eigen::Vector3d p_module = q_source * p_source + lambda * origin_in_module_;
  const Eigen::Vector3d p_scene = q_module * p_module + t_module;
  const Eigen::Vector3d p_cam = q_cam * p_scene + t_cam;
  if (!(p_cam.z() > 0.0)) return false;

  // Projection and its Jacobian d pixel / d p_cam (camera_model.h).
  const double* K = intrinsics_.data();
  const double fx = K[0], fy = K[1], cx = K[2], cy = K[3];
  const double k1 = K[4], k2 = K[5], p1 = K[6], p2 = K[7], k3 = K[8];
  const double iz = 1.0 / p_cam.z();
  const double x = p_cam.x() * iz, y = p_cam.y() * iz;
  const double x2 = x * x, y2 = y * y, xy = x * y, r2 = x2 + y2;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2);
  const double yd = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy;
  const Eigen::Vector2d e(fx * xd + cx - pixel_px_.x(), fy * yd + cy - pixel_px_.y());
  Eigen::Map<Eigen::Vector2d> res(residuals);
  res = whitening_ * e;
  if (jacobians == nullptr) return true;

  const double dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);  // d radial / d r2
  Eigen::Matrix2d D_xyd_xy;
  D_xyd_xy(0, 0) = radial + 2.0 * x2 * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
  D_xyd_xy(0, 1) = 2.0 * xy * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
  D_xyd_xy(1, 0) = 2.0 * xy * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
  D_xyd_xy(1, 1) = radial + 2.0 * y2 * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
  Eigen::Matrix<double, 2, 3> D_xy_pcam;
  D_xy_pcam << iz, 0.0, -x * iz, 0.0, iz, -y * iz;
  const Eigen::Matrix<double, 2, 3> J_pcam =
      whitening_ * Eigen::Vector2d(fx, fy).asDiagonal() * D_xyd_xy * D_xy_pcam;
  const Eigen::Matrix<double, 2, 3> J_pscene = J_pcam * q_cam.toRotationMatrix();
  const Eigen::Matrix<double, 2, 3> J_pmodule = J_pscene * q_module.toRotationMatrix();
  const Eigen::Matrix<double, 2, 3> J_psource = J_pmodule * q_source.toRotationMatrix();

  using RowMajor24 = Eigen::Matrix<double, 2, 4, Eigen::RowMajor>;
  using RowMajor23 = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;
  using RowMajor22 = Eigen::Matrix<double, 2, 2, Eigen::RowMajor>;
  if (jacobians[0]) {
    Eigen::Map<RowMajor24> J(jacobians[0]);
    J = J_pcam * RotatedVectorJacobianWrtQuaternion(q_cam, p_scene);
  }
  if (jacobians[1]) {
    Eigen::Map<RowMajor23> J(jacobians[1]);
    J = J_pcam;
  }
  if (jacobians[2]) {
    Eigen::Map<RowMajor24> J(jacobians[2]);
    J = J_pscene * RotatedVectorJacobianWrtQuaternion(q_module, p_module);
  }
  if (jacobians[3]) {
    Eigen::Map<RowMajor23> J(jacobians[3]);
    J = J_pscene;
  }
  if (jacobians[4]) {
    Eigen::Map<Eigen::Vector2d> J(jacobians[4]);
    J = J_pmodule * origin_in_module_;
  }
  if (jacobians[5]) {
    Eigen::Map<RowMajor24> J(jacobians[5]);
    J = J_pmodule * RotatedVectorJacobianWrtQuaternion(q_source, p_source);
  }
  if (jacobians[6]) {
    const Eigen::Vector3d d_az(-ce * sa, ce * ca, 0.0);
    const Eigen::Vector3d d_el(-se * ca, -se * sa, ce);
    Eigen::Matrix<double, 3, 2> D;
    D.col(0) = depth * d_az;
    D.col(1) = depth * d_el;
    Eigen::Map<RowMajor22> J(jacobians[6]);
    J = J_psource * D;
  }
  if (jacobians[7]) {
    Eigen::Map<Eigen::Vector2d> J(jacobians[7]);
    J = J_psource * d;
  }
  return true;
}

}  // namespace opl
