// BeamRayCostFunction: the spherical-angle residuals of every sample of one
// beam in a calibration session (method.md, "Calibrating a source"), as one
// ceres::CostFunction with analytic Jacobians.
//
// A calibration sample is a measured point p_i (scene frame, mm) of a beam of
// direction (az_b, el_b) in the source frame. With the source pose
// scene_from_source = (R, t), seen from the projection origin:
//   q_i = R^T (p_i - t)
//   r_i = sqrt(w_i) W_i [ wrap(az(q_i) - az_b),  el(q_i) - el_b ]   (2 residuals)
// W_i whitens the angular residual (identity: radians) and w_i is a weight
// (1, an IRLS robust weight, or 0 for a flagged sample).
//
// Parameter blocks (all plain Euclidean, no manifold needed for the pose):
//   theta (3)  the rotation as a left perturbation of a reference R0:
//              R = Exp(theta) R0 (scene frame, rad); exact Jacobian
//              dq/dtheta = [q]x R0^T J_l(-theta) at any theta;
//   t (3)      the projection origin, mm;
//   then, by the beam's role in the gauge (method.md: the central beam is
//   az = el = 0 and the central row has mean elevation 0):
//   kFreeBeam        azel (2): the beam's (az_b, el_b);
//   kCentralRowBeam  row (2m): (az_1..az_m, el_1..el_m) of all m non-central
//                    beams of the central row (one block on LevelRowManifold,
//                    which holds the roll gauge), of which this beam is entry
//                    `row_index` (az = row[j], el = row[m + j]);
//   kCentralBeam     no beam block: az_b = el_b = 0.
// Checked against automatic differentiation in tests/calibrate.
#pragma once

#include <vector>

#include <ceres/cost_function.h>
#include <Eigen/Core>

namespace opl {

class BeamRayCostFunction final : public ceres::CostFunction {
 public:
  enum class Layout { kFreeBeam, kCentralRowBeam, kCentralBeam };

  struct Sample {
    Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();
    Eigen::Matrix2d whitening = Eigen::Matrix2d::Identity();  // W_i
    double weight = 1.0;                                       // w_i >= 0
  };

  // row_size (m) and row_index (j) are used by kCentralRowBeam only.
  BeamRayCostFunction(std::vector<Sample> samples, const Eigen::Matrix3d& R0, Layout layout,
                      int row_size = 0, int row_index = 0);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  // The unweighted, unwhitened angular residual (az, el) of sample i, rad,
  // for the given parameter blocks (as passed to Evaluate).
  Eigen::Vector2d AngularResidual(double const* const* parameters, int i) const;

  int num_samples() const { return static_cast<int>(samples_.size()); }

 private:
  void BeamAngles(double const* const* parameters, double* az, double* el) const;

  std::vector<Sample> samples_;
  Eigen::Matrix3d R0_;
  Layout layout_;
  int row_size_;
  int row_index_;
};

}  // namespace opl
