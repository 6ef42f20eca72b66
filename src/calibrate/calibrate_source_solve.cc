// CalibrateSource's solve: the whitening of the samples' covariances, the
// Ceres problem over the pose and the beam directions (central row on its
// level constraint), the residuals at the estimate and the beams left with
// too few samples.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <ceres/ceres.h>

#include "calibrate/calibrate_source_internal.h"
#include "opl/calibrate/level_row_manifold.h"
#include "opl/geometry/spherical.h"

namespace opl {
namespace calibrate_internal {
namespace {

// Cholesky-based whitening W (W^T W = C^-1) of a 2x2 covariance; false when C
// is not positive definite.
bool WhiteningOf(const Eigen::Matrix2d& C, Eigen::Matrix2d* W) {
  const double a = C(0, 0) > 0.0 ? std::sqrt(C(0, 0)) : 0.0;
  const double b = a > 0.0 ? C(1, 0) / a : 0.0;
  const double c2 = C(1, 1) - b * b;
  if (!(a > 0.0 && c2 > 0.0) || !std::isfinite(a) || !std::isfinite(c2)) return false;
  const double c = std::sqrt(c2);
  *W << 1.0 / a, 0.0, -b / (a * c), 1.0 / c;
  return true;
}

}  // namespace

std::vector<BeamState*> Calibrator::ActiveBeams() {
  std::vector<BeamState*> out;
  for (BeamState& b : beams_) {
    if (b.active) out.push_back(&b);
  }
  return out;
}

void Calibrator::RebuildRow() {
  std::vector<double> az, el;
  for (BeamState* b : ActiveBeams()) {
    if (b->layout != Layout::kCentralRowBeam) continue;
    b->row_index = static_cast<int>(az.size());
    az.push_back(b->az);
    el.push_back(b->el);
  }
  const int m = static_cast<int>(az.size());
  row_ = az;
  row_.insert(row_.end(), el.begin(), el.end());
  if (m > 0) LevelRowManifold::Project(row_.data(), row_.data() + m, m);
}

Status Calibrator::UpdateWhitening() {
  whitening_.assign(samples_.size(), Eigen::Matrix2d::Identity());
  if (!weighted_) return Status::Ok();
  const Eigen::Matrix3d R = Rotation();
  const Eigen::Vector3d t = Origin();
  for (size_t i = 0; i < samples_.size(); ++i) {
    const Eigen::Vector3d q = R.transpose() * (samples_[i].point_mm - t);
    const Eigen::Matrix<double, 2, 3> Jp = AzElJacobian(q) * R.transpose();
    const Eigen::Matrix2d C = Jp * (*samples_[i].cov_mm2) * Jp.transpose();
    if (!WhiteningOf(C, &whitening_[i])) {
      return Error(StatusCode::kInvalidArgument,
                   "sample " + std::to_string(i) + " (beam " + std::to_string(samples_[i].beam_id) +
                       ", slice " + std::to_string(samples_[i].slice) +
                       "): its covariance gives no angular uncertainty (zero or singular across "
                       "the ray)");
    }
  }
  return Status::Ok();
}

Status Calibrator::Solve() {
  ceres::Problem problem;
  problem.AddParameterBlock(theta_, 3);
  problem.AddParameterBlock(t_, 3);
  const int m = RowSize();
  if (m >= 1) problem.AddParameterBlock(row_.data(), 2 * m, new LevelRowManifold(m));
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  std::vector<double> beam_params;
  std::vector<BeamState*> active = ActiveBeams();
  beam_params.resize(2 * active.size());
  for (size_t k = 0; k < active.size(); ++k) {
    BeamState& b = *active[k];
    std::vector<BeamRayCostFunction::Sample> s;
    s.reserve(b.samples.size());
    for (int i : b.samples) s.push_back({samples_[i].point_mm, whitening_[i], weight_[i]});
    double* p = &beam_params[2 * k];
    p[0] = b.az;
    p[1] = b.el;
    switch (b.layout) {
      case Layout::kFreeBeam:
        problem.AddResidualBlock(new BeamRayCostFunction(std::move(s), R0_, b.layout), nullptr,
                                 theta_, t_, p);
        ordering->AddElementToGroup(p, 0);
        break;
      case Layout::kCentralRowBeam:
        problem.AddResidualBlock(
            new BeamRayCostFunction(std::move(s), R0_, b.layout, m, b.row_index), nullptr,
            theta_, t_, row_.data());
        break;
      case Layout::kCentralBeam:
        problem.AddResidualBlock(new BeamRayCostFunction(std::move(s), R0_, b.layout), nullptr,
                                 theta_, t_);
        break;
    }
  }
  ordering->AddElementToGroup(theta_, 1);
  ordering->AddElementToGroup(t_, 1);
  if (m >= 1) ordering->AddElementToGroup(row_.data(), 1);

  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.linear_solver_ordering = ordering;
  so.num_threads = 1;
  so.max_num_iterations = options_.max_iterations;
  so.parameter_tolerance = options_.parameter_tolerance;
  so.function_tolerance = options_.function_tolerance;
  so.gradient_tolerance = 0.0;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  iterations_ += static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable()) {
    return Error(StatusCode::kNoSolution, "the solve failed: " + summary.message);
  }
  for (size_t k = 0; k < active.size(); ++k) {
    BeamState& b = *active[k];
    switch (b.layout) {
      case Layout::kFreeBeam:
        b.az = beam_params[2 * k];
        b.el = beam_params[2 * k + 1];
        break;
      case Layout::kCentralRowBeam:
        b.az = row_[b.row_index];
        b.el = row_[m + b.row_index];
        break;
      case Layout::kCentralBeam:
        b.az = b.el = 0.0;
        break;
    }
  }
  // Re-centre the rotation: R0 <- Exp(theta) R0, theta <- 0.
  R0_ = Rotation();
  for (double& v : theta_) v = 0.0;
  return Status::Ok();
}

void Calibrator::EvaluateResiduals() {
  const Eigen::Matrix3d R = Rotation();
  const Eigen::Vector3d t = Origin();
  raw_residual_.assign(samples_.size(), Eigen::Vector2d::Zero());
  normalized_.assign(samples_.size(), 0.0);
  for (const BeamState& b : beams_) {
    for (int i : b.samples) {
      const Eigen::Vector3d q = R.transpose() * (samples_[i].point_mm - t);
      raw_residual_[i] = Eigen::Vector2d(WrapAngleRad(AzimuthRad(q) - b.az), ElevationRad(q) - b.el);
      normalized_[i] = (whitening_[i] * raw_residual_[i]).norm();
    }
  }
}

double Calibrator::SigmaForFlagging() const {
  // Robust sigma of a 2D whitened residual: median norm / sqrt(2 ln 2).
  std::vector<double> r;
  for (size_t i = 0; i < samples_.size(); ++i) {
    if (!in_dropped_beam_[i] && !flagged_[i]) r.push_back(normalized_[i]);
  }
  if (r.empty()) return weighted_ ? 1.0 : options_.min_unweighted_sigma_rad;
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  const double robust = r[r.size() / 2] / std::sqrt(2.0 * std::log(2.0));
  return weighted_ ? std::max(1.0, robust) : std::max(options_.min_unweighted_sigma_rad, robust);
}

Status Calibrator::DropThinBeams() {
  bool changed = false;
  for (BeamState& b : beams_) {
    if (!b.active) continue;
    int used = 0;
    for (int i : b.samples) used += weight_[i] > 0.0;
    if (used >= options_.min_samples_per_beam) continue;
    if (b.layout == Layout::kCentralBeam) {
      return Error(StatusCode::kNoSolution,
                   "the central beam " + std::to_string(b.id) + " kept only " +
                       std::to_string(used) +
                       " good samples: the gauge (central beam az = el = 0) cannot be fixed");
    }
    b.active = false;
    changed = true;
    dropped_beam_ids_.push_back(b.id);
    for (int i : b.samples) {
      in_dropped_beam_[i] = 1;
      weight_[i] = 0.0;
    }
  }
  if (changed) {
    std::sort(dropped_beam_ids_.begin(), dropped_beam_ids_.end());
    RebuildRow();
  }
  return Status::Ok();
}

}  // namespace calibrate_internal
}  // namespace opl
