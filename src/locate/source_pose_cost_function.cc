#include "opl/locate/source_pose_cost_function.h"

#include <cmath>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"

namespace opl {

Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& w) {
  const double a2 = w.squaredNorm();
  const Eigen::Matrix3d W = Skew(w);
  double c1, c2;
  if (a2 < 1e-8) {
    c1 = 0.5 - a2 / 24.0;
    c2 = 1.0 / 6.0 - a2 / 120.0;
  } else {
    const double a = std::sqrt(a2);
    c1 = (1.0 - std::cos(a)) / a2;
    c2 = (a - std::sin(a)) / (a2 * a);
  }
  return Eigen::Matrix3d::Identity() + c1 * W + c2 * W * W;
}

SourcePoseCostFunction::SourcePoseCostFunction(std::vector<Spot> spots, const Eigen::Matrix3d& R0,
                                               const Eigen::Vector3d& t0, double length_per_radian)
    : R0_(R0), t0_(t0), length_per_radian_(length_per_radian) {
  spots_.reserve(spots.size());
  for (const Spot& s : spots) {
    // cos/sin of the beam's az, el from its unit direction d:
    // cos el = hypot(dx, dy), sin el = dz, cos az = dx / cos el, sin az = dy / cos el.
    const Eigen::Vector3d& d = s.beam_direction_in_source;
    const double cos_el = std::hypot(d.x(), d.y());
    spots_.push_back({s.point_in_scene, d.x() / cos_el, d.y() / cos_el, cos_el, d.z(),
                      s.whitening});
  }
  set_num_residuals(2 * static_cast<int>(spots_.size()));
  mutable_parameter_block_sizes()->assign(1, 6);
}

Eigen::Matrix3d SourcePoseCostFunction::Rotation(const double* x) const {
  return ExpSO3(Eigen::Vector3d(x[0], x[1], x[2]) / length_per_radian_) * R0_;
}

Eigen::Vector3d SourcePoseCostFunction::Origin(const double* x) const {
  return t0_ + Eigen::Vector3d(x[3], x[4], x[5]);
}

bool SourcePoseCostFunction::Evaluate(double const* const* parameters, double* residuals,
                                      double** jacobians) const {
  const double* x = parameters[0];
  const Eigen::Vector3d dtheta = Eigen::Vector3d(x[0], x[1], x[2]) / length_per_radian_;
  const Eigen::Matrix3d Rt = Rotation(x).transpose();
  const Eigen::Vector3d t = Origin(x);
  double* J = (jacobians != nullptr) ? jacobians[0] : nullptr;
  Eigen::Matrix3d M;  // R0^T J_l(-dtheta) / D
  if (J != nullptr) M = R0_.transpose() * LeftJacobianSO3(-dtheta) / length_per_radian_;

  const int n = static_cast<int>(spots_.size());
  for (int i = 0; i < n; ++i) {
    const Prepared& s = spots_[i];
    const Eigen::Vector3d q = Rt * (s.p - t);
    const double rho2 = q.x() * q.x() + q.y() * q.y();
    if (!(rho2 > 0.0)) return false;
    const double rho = std::sqrt(rho2);
    // Angles of q relative to the beam: rotate (x, y) by -az, (rho, z) by -el.
    const double daz = SmallAngleAtan2(q.y() * s.cos_az - q.x() * s.sin_az,
                                       q.x() * s.cos_az + q.y() * s.sin_az);
    const double del = SmallAngleAtan2(q.z() * s.cos_el - rho * s.sin_el,
                                       rho * s.cos_el + q.z() * s.sin_el);
    const Eigen::Vector2d r = s.W * Eigen::Vector2d(daz, del);
    residuals[2 * i] = r(0);
    residuals[2 * i + 1] = r(1);
    if (J == nullptr) continue;
    // d(az, el)/dq (geometry/spherical.h), whitened; two divisions shared:
    // 1/rho = rho / rho^2.
    const double inv_rho2 = 1.0 / rho2;
    const double inv_r2 = 1.0 / (rho2 + q.z() * q.z());
    const double k = q.z() * inv_r2 * rho * inv_rho2;
    Eigen::Matrix<double, 2, 3> G;
    G << -q.y() * inv_rho2, q.x() * inv_rho2, 0.0, -q.x() * k, -q.y() * k, rho * inv_r2;
    G = s.W * G;
    // Rows of G [q]x: g^T [q]x = (g x q)^T.
    Eigen::Matrix<double, 2, 3> Gq;
    Gq.row(0) = Eigen::Vector3d(G.row(0).transpose()).cross(q).transpose();
    Gq.row(1) = Eigen::Vector3d(G.row(1).transpose()).cross(q).transpose();
    Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>> Ji(J + 12 * i);
    Ji.leftCols<3>() = Gq * M;
    Ji.rightCols<3>() = -G * Rt;
  }
  return true;
}

}  // namespace opl
