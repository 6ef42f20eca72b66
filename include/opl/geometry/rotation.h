// Rotations: the (alpha, beta, gamma) angles of files and reports, and the
// small helpers the solvers share.
//
// File/report convention (method.md): R = Rx(alpha) * Ry(beta) * Rz(gamma),
// as MATLAB's makehgtform('xrotate',a,'yrotate',b,'zrotate',c) composes.
//   beta  = asin(R(0,2))                  in [-pi/2, pi/2]
//   alpha = atan2(-R(1,2), R(2,2)),  gamma = atan2(-R(0,1), R(0,0))
// At beta = +-pi/2 (gimbal lock) alpha and gamma are not separable; we return
// gamma = 0 there and the rotation matrix is still exact.
//
// Tangent convention for covariances: a rotation R is perturbed on the left,
//   R = Exp(dtheta) * R_hat,   dtheta in radians, expressed in the scene frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace opl {

Eigen::Matrix3d RotationX(double angle_rad);
Eigen::Matrix3d RotationY(double angle_rad);
Eigen::Matrix3d RotationZ(double angle_rad);

// R = Rx(a) Ry(b) Rz(c) from (a, b, c) in radians.
Eigen::Matrix3d RotationFromXyzAnglesRad(const Eigen::Vector3d& xyz_rad);
// Inverse of RotationFromXyzAnglesRad (see the gimbal-lock note above).
Eigen::Vector3d XyzAnglesRadFromRotation(const Eigen::Matrix3d& R);

// J_xyz_dtheta: 3x3 Jacobian of (alpha, beta, gamma) with respect to the left
// perturbation dtheta of R (see above). Singular at gimbal lock.
Eigen::Matrix3d XyzAnglesJacobianWrtLeftPerturbation(const Eigen::Vector3d& xyz_rad);

// Skew-symmetric matrix [v]x such that [v]x w = v x w.
inline Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

// Exp map of so(3): rotation by |w| radians about w / |w|.
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& w_rad);
// Log map: the rotation vector (radians) of R.
Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R);

// Angle (radians) of the rotation R_a^T R_b.
double RotationAngleBetweenRad(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b);

}  // namespace opl
