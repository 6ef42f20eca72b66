// AzElCostFunction: the spherical-angle residual of one spot of a located
// source, with analytic Jacobians, for Ceres.
//
// Parameters: scene_from_source rotation as a unit quaternion in Eigen's memory
// order (x, y, z, w), used with ceres::EigenQuaternionManifold, and the origin
// t (3, scene units). With u = p - t and the source-frame point
//   q = R^T u = u - 2 w (v x u) + 2 v x (v x u)        (v = (x, y, z))
// the residual is
//   r = W [ wrap(az(q) - az_beam),  el(q) - el_beam ]
// and its Jacobians are, by the chain rule,
//   dr/dquat = W J_azel(q) [ 2 w [u]x + 2 ((v.u) I + v u^T - 2 u v^T)  |  -2 v x u ]
//   dr/dt    = -W J_azel(q) R^T
// with J_azel from geometry/spherical.h. Checked against automatic
// differentiation and ceres::GradientChecker in tests/locate.
#pragma once

#include <ceres/sized_cost_function.h>
#include <Eigen/Core>

namespace opl {

class AzElCostFunction final : public ceres::SizedCostFunction<2, 4, 3> {
 public:
  // `whitening` W (2x2, upper triangular or full) maps the angular residual to
  // standard deviations; identity for an unweighted residual in radians.
  AzElCostFunction(const Eigen::Vector3d& point_in_scene, double beam_az_rad,
                   double beam_el_rad, const Eigen::Matrix2d& whitening);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  // The unwhitened residual (az, el) in radians at a pose.
  static Eigen::Vector2d AngularResidual(const Eigen::Matrix3d& scene_from_source_R,
                                         const Eigen::Vector3d& origin,
                                         const Eigen::Vector3d& point_in_scene, double beam_az,
                                         double beam_el);

 private:
  Eigen::Vector3d point_in_scene_;
  double beam_az_rad_;
  double beam_el_rad_;
  Eigen::Matrix2d whitening_;
};

}  // namespace opl
