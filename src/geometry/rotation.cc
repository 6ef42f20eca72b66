#include "opl/geometry/rotation.h"

#include <algorithm>
#include <cmath>

namespace opl {

Eigen::Matrix3d RotationX(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, c, -s, 0, s, c;
  return R;
}

Eigen::Matrix3d RotationY(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d R;
  R << c, 0, s, 0, 1, 0, -s, 0, c;
  return R;
}

Eigen::Matrix3d RotationZ(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}

Eigen::Matrix3d RotationFromXyzAnglesRad(const Eigen::Vector3d& xyz) {
  return RotationX(xyz.x()) * RotationY(xyz.y()) * RotationZ(xyz.z());
}

Eigen::Vector3d XyzAnglesRadFromRotation(const Eigen::Matrix3d& R) {
  const double sb = std::clamp(R(0, 2), -1.0, 1.0);
  const double beta = std::asin(sb);
  const double cb = std::hypot(R(0, 0), R(0, 1));
  if (cb < 1e-12) {
    // Gimbal lock: R = Rx(alpha) Ry(+-pi/2) with gamma folded into alpha.
    const double alpha = std::atan2(R(2, 1), R(1, 1));
    return Eigen::Vector3d(alpha, beta, 0.0);
  }
  return Eigen::Vector3d(std::atan2(-R(1, 2), R(2, 2)), beta, std::atan2(-R(0, 1), R(0, 0)));
}

Eigen::Matrix3d XyzAnglesJacobianWrtLeftPerturbation(const Eigen::Vector3d& xyz) {
  // Spatial angular velocity of R = Rx(a) Ry(b) Rz(c):
  //   w = e_x da + Rx(a) e_y db + Rx(a) Ry(b) e_z dc  =  M (da, db, dc)
  // so d(a, b, c) / d dtheta = M^-1.
  Eigen::Matrix3d M;
  const Eigen::Matrix3d Rx = RotationX(xyz.x());
  M.col(0) = Eigen::Vector3d::UnitX();
  M.col(1) = Rx * Eigen::Vector3d::UnitY();
  M.col(2) = Rx * RotationY(xyz.y()) * Eigen::Vector3d::UnitZ();
  return M.inverse();
}

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

double RotationAngleBetweenRad(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  return Eigen::AngleAxisd(R_a.transpose() * R_b).angle();
}

}  // namespace opl
