// Internal to src/locate: loops over spots shared by PoseNormalEquations and
// LocateSource. The arrays a loop reads and writes never overlap; saying so
// (OPL_RESTRICT) lets the compiler vectorise the loops (without it GCC gives
// up on the run-time overlap checks of this many arrays).
#pragma once

#include <cmath>

#include <Eigen/Core>

#include "opl/geometry/spherical.h"
#include "opl/locate/pose_normal_equations.h"

#define OPL_RESTRICT __restrict

namespace opl::locate_internal {

// q = Rt (p - t) and rho^2 = q_x^2 + q_y^2 of spots i < n (Rt = R^T: the
// spots in the source frame of the pose (R, t)).
inline void SourceFramePoints(int n, const double* OPL_RESTRICT px,
                              const double* OPL_RESTRICT py, const double* OPL_RESTRICT pz,
                              const Eigen::Matrix3d& Rt, const Eigen::Vector3d& t,
                              double* OPL_RESTRICT qx, double* OPL_RESTRICT qy,
                              double* OPL_RESTRICT qz, double* OPL_RESTRICT rho2) {
  const double r00 = Rt(0, 0), r01 = Rt(0, 1), r02 = Rt(0, 2);
  const double r10 = Rt(1, 0), r11 = Rt(1, 1), r12 = Rt(1, 2);
  const double r20 = Rt(2, 0), r21 = Rt(2, 1), r22 = Rt(2, 2);
  const double tx = t.x(), ty = t.y(), tz = t.z();
  for (int i = 0; i < n; ++i) {
    const double dx = px[i] - tx, dy = py[i] - ty, dz = pz[i] - tz;
    const double X = r00 * dx + r01 * dy + r02 * dz;
    const double Y = r10 * dx + r11 * dy + r12 * dz;
    const double Z = r20 * dx + r21 * dy + r22 * dz;
    qx[i] = X;
    qy[i] = Y;
    qz[i] = Z;
    rho2[i] = X * X + Y * Y;
  }
}

// SmallAngleAtan2's test (geometry/spherical.h): its series applies.
inline bool SmallAngleApplies(double s, double c) { return c > 0.0 && std::abs(s) <= 0.125 * c; }

// (az, el) of q minus those of the beam, as the angles of q rotated by the
// beam's (-az, -el) (SourcePoseCostFunction's form), one spot.
inline Eigen::Vector2d AngleDifference(const Eigen::Vector3d& q, const BeamAngles& b) {
  const double rho = std::sqrt(q.x() * q.x() + q.y() * q.y());
  return Eigen::Vector2d(
      SmallAngleAtan2(q.y() * b.cos_az - q.x() * b.sin_az, q.x() * b.cos_az + q.y() * b.sin_az),
      SmallAngleAtan2(q.z() * b.cos_el - rho * b.sin_el, rho * b.cos_el + q.z() * b.sin_el));
}

// B^T H B for B = diag(A, C) (3 x 3 blocks).
inline Eigen::Matrix<double, 6, 6> CongruenceBlockDiagonal(const Eigen::Matrix<double, 6, 6>& H,
                                                           const Eigen::Matrix3d& A,
                                                           const Eigen::Matrix3d& C) {
  Eigen::Matrix<double, 6, 6> out;
  out.topLeftCorner<3, 3>() = A.transpose() * H.topLeftCorner<3, 3>() * A;
  out.topRightCorner<3, 3>() = A.transpose() * H.topRightCorner<3, 3>() * C;
  out.bottomLeftCorner<3, 3>() = out.topRightCorner<3, 3>().transpose();
  out.bottomRightCorner<3, 3>() = C.transpose() * H.bottomRightCorner<3, 3>() * C;
  return out;
}

}  // namespace opl::locate_internal
