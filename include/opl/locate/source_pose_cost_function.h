// SourcePoseCostFunction: the spherical-angle residuals of all spots of one
// source, as one ceres::CostFunction with analytic Jacobians.
//
// The pose scene_from_source = (R, t) is written as a local perturbation of a
// reference pose (R0, t0):
//   R = Exp(dtheta) R0,  t = t0 + dt,   x = (D dtheta, dt)   [scene units]
// so the 6-vector x lives in a plain Euclidean space (no manifold needed) and
// the solve re-centres (R0, t0) between rounds. D (`length_per_radian`, e.g.
// the distance to the spots) expresses the rotation as the arc it sweeps at
// the spots, so that all six parameters are lengths and a step size means the
// same thing for both. For spot i, with u = p_i - t,
//   q_i = R^T u,
//   r_i = W_i [ wrap(az(q_i) - az_i),  el(q_i) - el_i ]            (2 residuals)
// and, exactly (not only at x = 0),
//   dq/ddtheta = [q]x R0^T J_l(-dtheta),    dq/ddt = -R^T,   dx_rot = D ddtheta
// where J_l is the left Jacobian of SO(3). d(az, el)/dq is the closed form of
// geometry/spherical.h. The angle differences are evaluated as the angles of
// q rotated by the beam's (-az_i, -el_i), which is exact and well conditioned.
//
// This is the reference definition of the measurement solve's residuals and
// Jacobian, checked against automatic differentiation and
// ceres::GradientChecker in tests/locate. LocateSource solves the same problem
// through PoseNormalEquations (pose_normal_equations.h), which sums J^T J and
// J^T r spot by spot instead of forming J; tests/locate checks its residuals,
// normal equations and solves against this cost function under
// ceres::TinySolver (through ceres::TinySolverCostFunctionAdapter).
#pragma once

#include <vector>

#include <ceres/cost_function.h>
#include <Eigen/Core>

namespace opl {

class SourcePoseCostFunction final : public ceres::CostFunction {
 public:
  struct Spot {
    Eigen::Vector3d point_in_scene;
    Eigen::Vector3d beam_direction_in_source;  // unit; az_i, el_i are its angles
    Eigen::Matrix2d whitening;  // W_i; identity for residuals in radians
  };

  SourcePoseCostFunction(std::vector<Spot> spots, const Eigen::Matrix3d& R0,
                         const Eigen::Vector3d& t0, double length_per_radian = 1.0);

  // Parameters: one block of 6, x = (D dtheta, dt). Residuals: 2 per spot, in
  // spot order. Returns false where a spot lies on the source's Z axis.
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  // The pose at x.
  Eigen::Matrix3d Rotation(const double* x) const;
  Eigen::Vector3d Origin(const double* x) const;

  int num_spots() const { return static_cast<int>(spots_.size()); }

 private:
  struct Prepared {
    Eigen::Vector3d p;
    double cos_az, sin_az, cos_el, sin_el;
    Eigen::Matrix2d W;
  };
  std::vector<Prepared> spots_;
  Eigen::Matrix3d R0_;
  Eigen::Vector3d t0_;
  double length_per_radian_;
};

// Left Jacobian of SO(3): J_l(w) = I + (1 - cos a)/a^2 [w]x + (a - sin a)/a^3 [w]x^2.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& w);

}  // namespace opl
