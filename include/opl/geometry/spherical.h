// Spherical pointing angles of a direction in a source frame (method.md).
//
// For a vector q = (x, y, z) in a source frame (+X along the central beam, +Z up,
// +Y to the left looking out along +X), as MATLAB's cart2sph:
//   azimuth    az = atan2(y, x)               in (-pi, pi]
//   elevation  el = atan2(z, hypot(x, y))     in [-pi/2, pi/2]
// The central beam is az = el = 0. All angles are radians.
//
// Every function is templated so that it compiles for double and ceres::Jet.
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace opl {

template <typename T>
T AzimuthRad(const Eigen::Matrix<T, 3, 1>& q) {
  using std::atan2;
  return atan2(q.y(), q.x());
}

template <typename T>
T ElevationRad(const Eigen::Matrix<T, 3, 1>& q) {
  using std::atan2;
  using std::sqrt;
  return atan2(q.z(), sqrt(q.x() * q.x() + q.y() * q.y()));
}

// Unit vector pointing at (az, el): (cos el cos az, cos el sin az, sin el).
template <typename T>
Eigen::Matrix<T, 3, 1> DirectionFromAzElRad(const T& az_rad, const T& el_rad) {
  using std::cos;
  using std::sin;
  return Eigen::Matrix<T, 3, 1>(cos(el_rad) * cos(az_rad), cos(el_rad) * sin(az_rad),
                                sin(el_rad));
}

// Wraps an angle difference into (-pi, pi].
template <typename T>
T WrapAngleRad(T a) {
  constexpr double kPi = 3.14159265358979323846;
  // Only branch on the value; the derivative of a wrap is 1.
  while (a > T(kPi)) a -= T(2.0 * kPi);
  while (a <= T(-kPi)) a += T(2.0 * kPi);
  return a;
}

// atan2(s, c) for the angle differences of the solvers, which are small: for
// c > 0 and |s| <= c / 8 it sums the odd series of atan(s / c) to 10 terms
// (truncation below 1e-18 relative, i.e. exact in double precision; checked
// against std::atan2 in tests/geometry), and calls std::atan2 otherwise. About
// four times faster than glibc's atan2 on these arguments.
inline double SmallAngleAtan2(double s, double c) {
  if (c > 0.0 && std::abs(s) <= 0.125 * c) {
    const double t = s / c;
    const double t2 = t * t;
    // atan t = t (1 - t^2/3 + t^4/5 - ... - t^18/19), Horner form.
    double p = -1.0 / 19.0;
    p = p * t2 + 1.0 / 17.0;
    p = p * t2 - 1.0 / 15.0;
    p = p * t2 + 1.0 / 13.0;
    p = p * t2 - 1.0 / 11.0;
    p = p * t2 + 1.0 / 9.0;
    p = p * t2 - 1.0 / 7.0;
    p = p * t2 + 1.0 / 5.0;
    p = p * t2 - 1.0 / 3.0;
    p = p * t2 + 1.0;
    return t * p;
  }
  return std::atan2(s, c);
}

// J_azel_q: the 2x3 Jacobian of (az, el) with respect to q, in closed form:
//   d az / dq = (-y, x, 0) / rho^2
//   d el / dq = (-x z, -y z, rho^2) / (rho r^2),   rho = hypot(x, y), r = |q|.
// Undefined on the Z axis (rho = 0), which no beam of a grid points along.
inline Eigen::Matrix<double, 2, 3> AzElJacobian(const Eigen::Vector3d& q) {
  const double rho2 = q.x() * q.x() + q.y() * q.y();
  const double rho = std::sqrt(rho2);
  const double r2 = rho2 + q.z() * q.z();
  Eigen::Matrix<double, 2, 3> J;
  J(0, 0) = -q.y() / rho2;
  J(0, 1) = q.x() / rho2;
  J(0, 2) = 0.0;
  const double k = q.z() / (rho * r2);
  J(1, 0) = -q.x() * k;
  J(1, 1) = -q.y() * k;
  J(1, 2) = rho / r2;
  return J;
}

}  // namespace opl
