// The fast path of LocateSource's refinement: the problem of
// SourcePoseCostFunction, evaluated straight into its 6 x 6 normal equations,
// and a Levenberg-Marquardt solver on them that makes the same steps and stops
// by the same rules as ceres::TinySolver does on SourcePoseCostFunction.
//
// SourcePoseCostFunction (source_pose_cost_function.h) stays the reference
// definition of the residuals and their Jacobian (checked against automatic
// differentiation and ceres::GradientChecker). PoseNormalEquations evaluates
// the same residuals r(x) and, instead of the 2N x 6 Jacobian J = dr/dx, sums
// J^T J and J^T r spot by spot: per spot, the two whitened rows of dr with
// respect to a perturbation of the pose in the source frame have a short closed
// form (below), and the map to x = (D dtheta, dt) is one 6 x 6 block-diagonal
// matrix per evaluation, applied to the sums once. The loops run across spots
// (structure of arrays) so that the compiler vectorises them, and nothing is
// allocated per evaluation once the object has held as many spots.
//
// With u = p - t, q = R^T u, rho = |(q_x, q_y)|, r = |q|, k = q_z / (rho r^2),
// the unwhitened rows of d(az, el) with respect to (dphi, dt'), where
// q = Exp(-dphi) q - dt' to first order (dphi, dt' in the source frame), are
//   d az = [ q_x q_z / rho^2,  q_y q_z / rho^2,  -1,  q_y / rho^2,  -q_x / rho^2,  0 ]
//   d el = [ -q_y / rho,       q_x / rho,         0,  q_x k,         q_y k,       -rho / r^2 ]
// (the rows g^T of d(az, el)/dq give g^T [q]x = (g x q)^T and -g^T), and
//   dr/dx = W [d az; d el] diag(R0^T J_l(-dtheta) / D, R^T),
// the same chain as SourcePoseCostFunction's [q]x R0^T J_l(-dtheta) / D and -R^T.
//
// Same numbers to rounding, not to the bit: the sums run in another order, and
// the arctangent series of SmallAngleAtan2 (geometry/spherical.h) is cut where
// every spot's angle makes the rest smaller than 1e-18 relative (near a
// solution, where the angles are residuals, 3 terms instead of 10).
// tests/locate/pose_normal_equations_test.cc checks residuals, J^T J, J^T r and
// whole solves against SourcePoseCostFunction and ceres::TinySolver to 1e-12.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

namespace opl {

// cos and sin of a beam's azimuth and elevation, as the residual uses them.
struct BeamAngles {
  double cos_az = 1.0, sin_az = 0.0, cos_el = 1.0, sin_el = 0.0;
  // From the beam's unit direction d: cos el = |(d_x, d_y)|, sin el = d_z,
  // cos az = d_x / cos el, sin az = d_y / cos el (as SourcePoseCostFunction).
  static BeamAngles FromDirection(const Eigen::Vector3d& d);
};

class PoseNormalEquations {
 public:
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;

  // Move-only (the storage is uninitialised until written).
  PoseNormalEquations() = default;
  PoseNormalEquations(PoseNormalEquations&&) = default;
  PoseNormalEquations& operator=(PoseNormalEquations&&) = default;
  // The problem of SourcePoseCostFunction(spots, R0, t0, length_per_radian).
  PoseNormalEquations(const std::vector<Eigen::Vector3d>& points_in_scene,
                      const std::vector<Eigen::Vector3d>& beam_directions_in_source,
                      const std::vector<Eigen::Matrix2d>& whitening, const Eigen::Matrix3d& R0,
                      const Eigen::Vector3d& t0, double length_per_radian = 1.0);

  // Removes every spot (keeping the storage) and sets the reference pose.
  void Reset(const Eigen::Matrix3d& R0, const Eigen::Vector3d& t0, double length_per_radian);
  // Room for num_spots spots.
  void Reserve(int num_spots);
  // Appends a spot: its scene point, its beam, its whitening W.
  void AddSpot(const Eigen::Vector3d& point_in_scene, const BeamAngles& beam,
               const Eigen::Matrix2d& whitening) {
    if (n_ == capacity_) Reserve(capacity_ < 8 ? 16 : 2 * capacity_);
    double* s = spots_.get() + n_;
    const size_t c = static_cast<size_t>(capacity_);
    s[kPx * c] = point_in_scene.x();
    s[kPy * c] = point_in_scene.y();
    s[kPz * c] = point_in_scene.z();
    s[kCosAz * c] = beam.cos_az;
    s[kSinAz * c] = beam.sin_az;
    s[kCosEl * c] = beam.cos_el;
    s[kSinEl * c] = beam.sin_el;
    s[kW00 * c] = whitening(0, 0);
    s[kW01 * c] = whitening(0, 1);
    s[kW10 * c] = whitening(1, 0);
    s[kW11 * c] = whitening(1, 1);
    any_w01_ = any_w01_ || whitening(0, 1) != 0.0;
    ++n_;
  }

  // At x = (D dtheta, dt): cost = |r|^2 / 2 and, when JtJ and Jtr are given,
  // J^T J and J^T r (J = dr/dx) of SourcePoseCostFunction's residuals r; when
  // `angle_differences` is given, the unwhitened (az, el) differences of every
  // spot, 2 per spot in spot order. Returns false where a spot lies on the
  // source's Z axis (as the reference). Uses scratch storage of this object:
  // one object must not be evaluated from two threads at once.
  bool Evaluate(const double* x, double* cost, Matrix6* JtJ, Vector6* Jtr,
                double* angle_differences = nullptr) const;
  // The residuals themselves, 2 per spot in spot order (for tests).
  bool Residuals(const double* x, double* residuals) const;

  // The pose at x, as SourcePoseCostFunction::Rotation / Origin.
  Eigen::Matrix3d Rotation(const double* x) const;
  Eigen::Vector3d Origin(const double* x) const;

  int num_spots() const { return n_; }

 private:
  // Spots as structure of arrays (the evaluation loops run across spots):
  // kFields arrays of capacity_ doubles each.
  enum Field { kPx, kPy, kPz, kCosAz, kSinAz, kCosEl, kSinEl, kW00, kW01, kW10, kW11, kFields };
  const double* field(int f) const { return spots_.get() + static_cast<size_t>(f) * capacity_; }
  double* field(int f) { return spots_.get() + static_cast<size_t>(f) * capacity_; }
  int n_ = 0;
  int capacity_ = 0;
  bool any_w01_ = false;  // some W is not lower triangular
  // Uninitialised storage (every entry is written before it is read): the
  // object is move-only.
  std::unique_ptr<double[]> spots_;
  mutable std::unique_ptr<double[]> work_;  // per-evaluation arrays
  mutable size_t work_size_ = 0;
  Eigen::Matrix3d R0_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t0_ = Eigen::Vector3d::Zero();
  double length_per_radian_ = 1.0;
};

// Levenberg-Marquardt on PoseNormalEquations, step for step the algorithm of
// ceres::TinySolver (Jacobi scaling fixed at the start, the same damping
// schedule, the same stopping tests on the gradient, the step, the cost change
// and the cost), with the option names and defaults of
// ceres::TinySolver::Options. Each trial point is evaluated once, residuals and
// normal equations together; TinySolver evaluates the residuals and, when the
// step is accepted, evaluates again with the Jacobian. A failed evaluation (a
// spot on the Z axis) rejects the step; at the start it ends the solve with
// `evaluation_failed` and a NaN cost.
struct PoseSolverOptions {
  int max_num_iterations = 50;
  double gradient_tolerance = 1e-10;   // on the max-norm of the scaled gradient
  double parameter_tolerance = 1e-8;   // |dx| < tol (|x| + tol)
  double function_tolerance = 1e-6;    // |cost change| (of 2 cost)
  double cost_threshold = 2.220446049250313e-16;
  double initial_trust_region_radius = 1e4;
};

struct PoseSolverSummary {
  enum Status {
    kGradientTooSmall,
    kRelativeStepSizeTooSmall,
    kCostTooSmall,
    kHitMaxIterations,
    kCostChangeTooSmall,
  };
  double initial_cost = -1.0;
  double final_cost = -1.0;
  double gradient_max_norm = -1.0;
  int iterations = -1;  // counted as TinySolver's Summary::iterations
  int rejected_steps = 0;  // steps that did not lower the cost (the damping grew)
  Status status = kHitMaxIterations;
  bool evaluation_failed = false;
};

PoseSolverSummary SolvePoseLevenbergMarquardt(const PoseNormalEquations& problem,
                                              const PoseSolverOptions& options,
                                              Eigen::Matrix<double, 6, 1>* x);

}  // namespace opl
