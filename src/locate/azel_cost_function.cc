#include "opl/locate/azel_cost_function.h"

#include <Eigen/Geometry>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"

namespace opl {

AzElCostFunction::AzElCostFunction(const Eigen::Vector3d& point_in_scene, double beam_az_rad,
                                   double beam_el_rad, const Eigen::Matrix2d& whitening)
    : point_in_scene_(point_in_scene),
      beam_az_rad_(beam_az_rad),
      beam_el_rad_(beam_el_rad),
      whitening_(whitening) {}

Eigen::Vector2d AzElCostFunction::AngularResidual(const Eigen::Matrix3d& R,
                                                  const Eigen::Vector3d& origin,
                                                  const Eigen::Vector3d& point_in_scene,
                                                  double beam_az, double beam_el) {
  const Eigen::Vector3d q = R.transpose() * (point_in_scene - origin);
  return Eigen::Vector2d(WrapAngleRad(AzimuthRad(q) - beam_az), ElevationRad(q) - beam_el);
}

bool AzElCostFunction::Evaluate(double const* const* parameters, double* residuals,
                                double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> v(parameters[0]);  // x, y, z
  const double w = parameters[0][3];
  const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
  const Eigen::Vector3d u = point_in_scene_ - t;
  const Eigen::Vector3d vxu = v.cross(u);
  const Eigen::Vector3d q = u - 2.0 * w * vxu + 2.0 * v.cross(vxu);
  const double rho2 = q.x() * q.x() + q.y() * q.y();
  if (!(rho2 > 0.0) || !q.allFinite()) return false;

  Eigen::Map<Eigen::Vector2d> r(residuals);
  r = whitening_ * Eigen::Vector2d(WrapAngleRad(AzimuthRad(q) - beam_az_rad_),
                                   ElevationRad(q) - beam_el_rad_);
  if (jacobians == nullptr) return true;

  const Eigen::Matrix<double, 2, 3> WJ = whitening_ * AzElJacobian(q);
  if (jacobians[0] != nullptr) {
    Eigen::Matrix<double, 3, 4> dq_dquat;
    dq_dquat.leftCols<3>() =
        2.0 * w * Skew(u) +
        2.0 * (v.dot(u) * Eigen::Matrix3d::Identity() + v * u.transpose() - 2.0 * u * v.transpose());
    dq_dquat.col(3) = -2.0 * vxu;
    Eigen::Map<Eigen::Matrix<double, 2, 4, Eigen::RowMajor>> J_r_quat(jacobians[0]);
    J_r_quat = WJ * dq_dquat;
  }
  if (jacobians[1] != nullptr) {
    // dq/dt = -R^T; R^T as the same quaternion formula applied to the unit axes.
    const Eigen::Quaterniond quat(w, v.x(), v.y(), v.z());
    const Eigen::Matrix3d Rt = quat.toRotationMatrix().transpose();
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> J_r_t(jacobians[1]);
    J_r_t = -WJ * Rt;
  }
  return true;
}

}  // namespace opl
