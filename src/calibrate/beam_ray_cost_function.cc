#include "opl/calibrate/beam_ray_cost_function.h"

#include <cmath>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "opl/locate/source_pose_cost_function.h"  // LeftJacobianSO3

namespace opl {

BeamRayCostFunction::BeamRayCostFunction(std::vector<Sample> samples, const Eigen::Matrix3d& R0,
                                         Layout layout, int row_size, int row_index)
    : samples_(std::move(samples)),
      R0_(R0),
      layout_(layout),
      row_size_(row_size),
      row_index_(row_index) {
  set_num_residuals(2 * static_cast<int>(samples_.size()));
  std::vector<int32_t>* sizes = mutable_parameter_block_sizes();
  sizes->assign({3, 3});
  if (layout_ == Layout::kFreeBeam) sizes->push_back(2);
  if (layout_ == Layout::kCentralRowBeam) sizes->push_back(2 * row_size_);
}

void BeamRayCostFunction::BeamAngles(double const* const* parameters, double* az,
                                     double* el) const {
  switch (layout_) {
    case Layout::kFreeBeam:
      *az = parameters[2][0];
      *el = parameters[2][1];
      return;
    case Layout::kCentralRowBeam:
      *az = parameters[2][row_index_];
      *el = parameters[2][row_size_ + row_index_];
      return;
    case Layout::kCentralBeam:
      *az = 0.0;
      *el = 0.0;
      return;
  }
}

Eigen::Vector2d BeamRayCostFunction::AngularResidual(double const* const* parameters,
                                                     int i) const {
  const Eigen::Map<const Eigen::Vector3d> theta(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
  double az_b, el_b;
  BeamAngles(parameters, &az_b, &el_b);
  const Eigen::Matrix3d R = ExpSO3(theta) * R0_;
  const Eigen::Vector3d q = R.transpose() * (samples_[i].point_in_scene - t);
  return {WrapAngleRad(AzimuthRad(q) - az_b), ElevationRad(q) - el_b};
}

bool BeamRayCostFunction::Evaluate(double const* const* parameters, double* residuals,
                                   double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> theta(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
  double az_b, el_b;
  BeamAngles(parameters, &az_b, &el_b);
  const Eigen::Matrix3d R = ExpSO3(theta) * R0_;
  const Eigen::Matrix3d Rt = R.transpose();
  // dq/dtheta = [q]x R0^T J_l(-theta): the part after [q]x is shared.
  const Eigen::Matrix3d R0t_Jl = (jacobians != nullptr && jacobians[0] != nullptr)
                                     ? Eigen::Matrix3d(R0_.transpose() * LeftJacobianSO3(-theta))
                                     : Eigen::Matrix3d::Zero();
  using RowMajor23 = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;
  const int n = num_samples();
  for (int i = 0; i < n; ++i) {
    const Sample& s = samples_[i];
    const Eigen::Vector3d q = Rt * (s.point_in_scene - t);
    if (!(q.x() * q.x() + q.y() * q.y() > 0.0)) return false;  // on the source's Z axis
    const Eigen::Vector2d raw(WrapAngleRad(AzimuthRad(q) - az_b), ElevationRad(q) - el_b);
    const double sw = std::sqrt(s.weight);
    const Eigen::Matrix2d Ws = sw * s.whitening;
    Eigen::Map<Eigen::Vector2d>(residuals + 2 * i) = Ws * raw;
    if (jacobians == nullptr) continue;
    const Eigen::Matrix<double, 2, 3> WA = Ws * AzElJacobian(q);
    if (jacobians[0] != nullptr) {
      Eigen::Map<RowMajor23>(jacobians[0] + 6 * i) = WA * Skew(q) * R0t_Jl;
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<RowMajor23>(jacobians[1] + 6 * i) = -WA * Rt;
    }
    if (layout_ == Layout::kFreeBeam && jacobians[2] != nullptr) {
      // d r / d(az_b, el_b) = -Ws.
      Eigen::Map<Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(jacobians[2] + 4 * i) = -Ws;
    }
    if (layout_ == Layout::kCentralRowBeam && jacobians[2] != nullptr) {
      const int width = 2 * row_size_;
      double* row0 = jacobians[2] + (2 * i) * width;
      double* row1 = row0 + width;
      for (int k = 0; k < width; ++k) row0[k] = row1[k] = 0.0;
      row0[row_index_] = -Ws(0, 0);
      row1[row_index_] = -Ws(1, 0);
      row0[row_size_ + row_index_] = -Ws(0, 1);
      row1[row_size_ + row_index_] = -Ws(1, 1);
    }
  }
  return true;
}

}  // namespace opl
