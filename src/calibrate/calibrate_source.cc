#include "opl/calibrate/calibrate_source.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <set>

#include <ceres/ceres.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>

#include "opl/calibrate/beam_ray_cost_function.h"
#include "opl/calibrate/level_row_manifold.h"
#include "opl/core/format.h"
#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"

namespace opl {

Status CalibrateOptions::Validate() const {
  auto bad = [](const std::string& field, double v, const std::string& rule) {
    return Status::InvalidArgument("calibrate option " + field + " = " + FormatNumber(v) +
                                   ": " + rule);
  };
  if (!(std::isfinite(loss_scale) && loss_scale > 0.0)) return bad("loss_scale", loss_scale, "must be finite and > 0");
  if (!(std::isfinite(loss_scale_unweighted_rad) && loss_scale_unweighted_rad > 0.0)) {
    return bad("loss_scale_unweighted_rad", loss_scale_unweighted_rad, "must be finite and > 0");
  }
  if (max_robust_rounds < 1) return bad("max_robust_rounds", max_robust_rounds, "must be >= 1");
  if (!(std::isfinite(outlier_threshold) && outlier_threshold > 0.0)) {
    return bad("outlier_threshold", outlier_threshold, "must be finite and > 0");
  }
  if (!(std::isfinite(min_unweighted_sigma_rad) && min_unweighted_sigma_rad > 0.0)) {
    return bad("min_unweighted_sigma_rad", min_unweighted_sigma_rad, "must be finite and > 0");
  }
  if (max_flagging_rounds < 1) return bad("max_flagging_rounds", max_flagging_rounds, "must be >= 1");
  if (min_samples_per_beam < 2) return bad("min_samples_per_beam", min_samples_per_beam, "must be >= 2");
  if (!(std::isfinite(init_inlier_distance_mm) && init_inlier_distance_mm > 0.0)) {
    return bad("init_inlier_distance_mm", init_inlier_distance_mm, "must be finite and > 0");
  }
  if (max_iterations < 1) return bad("max_iterations", max_iterations, "must be >= 1");
  if (!(std::isfinite(parameter_tolerance) && parameter_tolerance > 0.0)) {
    return bad("parameter_tolerance", parameter_tolerance, "must be finite and > 0");
  }
  if (!(std::isfinite(function_tolerance) && function_tolerance > 0.0)) {
    return bad("function_tolerance", function_tolerance, "must be finite and > 0");
  }
  return Status::Ok();
}

namespace {

using Layout = BeamRayCostFunction::Layout;

// One beam of the solve and its samples (indices into the input).
struct BeamState {
  int id = 0;
  int row = 0;
  int col = 0;
  Layout layout = Layout::kFreeBeam;
  std::vector<int> samples;
  double az = 0.0;  // current estimate, source frame
  double el = 0.0;
  int row_index = -1;      // kCentralRowBeam: its entry j in row_
  int param_offset = -1;   // column of its first e-parameter in the Jacobian
  bool active = true;
};

// Robust 3D line through points: least median of squares over pairs, then a
// least-squares (principal axis) refit of the inliers. Returns false when
// fewer than two distinct points are inliers.
bool FitLine(const std::vector<Eigen::Vector3d>& pts, double min_inlier_mm, Eigen::Vector3d* c,
             Eigen::Vector3d* d, std::vector<char>* inlier) {
  const int n = static_cast<int>(pts.size());
  if (n < 2) return false;
  auto dist2 = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& u, const Eigen::Vector3d& p) {
    const Eigen::Vector3d v = p - a;
    return (v - v.dot(u) * u).squaredNorm();
  };
  // Principal axis of the points in `inlier` (all when empty).
  auto principal_axis = [&](const std::vector<char>& use) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int count = 0;
    for (int k = 0; k < n; ++k) {
      if (use[k]) {
        mean += pts[k];
        ++count;
      }
    }
    mean /= count;
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int k = 0; k < n; ++k) {
      if (use[k]) scatter += (pts[k] - mean) * (pts[k] - mean).transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
    *c = mean;
    *d = eig.eigenvectors().col(2);
    return count >= 2 && eig.eigenvalues()(2) > 0.0;
  };
  // Clean data (the usual case): every point within min_inlier_mm of the
  // least-squares line, and no need for the robust search.
  inlier->assign(n, 1);
  if (principal_axis(*inlier)) {
    bool all_close = true;
    for (int k = 0; k < n && all_close; ++k) {
      all_close = dist2(*c, *d, pts[k]) <= min_inlier_mm * min_inlier_mm;
    }
    if (all_close) return true;
  }
  double best_med = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_a = pts[0], best_u = Eigen::Vector3d::UnitX();
  std::vector<double> d2(n);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      Eigen::Vector3d u = pts[j] - pts[i];
      const double len = u.norm();
      if (!(len > 0.0)) continue;
      u /= len;
      for (int k = 0; k < n; ++k) d2[k] = dist2(pts[i], u, pts[k]);
      const int mid = n / 2;  // upper median for even n: tolerates < half wrong
      std::nth_element(d2.begin(), d2.begin() + mid, d2.end());
      if (d2[mid] < best_med) {
        best_med = d2[mid];
        best_a = pts[i];
        best_u = u;
      }
    }
  }
  if (!std::isfinite(best_med)) return false;
  const double robust_sigma = 1.4826 * std::sqrt(best_med);
  const double threshold = std::max(min_inlier_mm, 5.0 * robust_sigma);
  int count = 0;
  for (int k = 0; k < n; ++k) {
    (*inlier)[k] = dist2(best_a, best_u, pts[k]) <= threshold * threshold;
    count += (*inlier)[k];
  }
  return count >= 2 && principal_axis(*inlier);
}

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

double RobustWeight(RobustLoss loss, double s2, double a) {
  switch (loss) {
    case RobustLoss::kNone:
      return 1.0;
    case RobustLoss::kHuber:
      return s2 <= a * a ? 1.0 : a / std::sqrt(s2);
    case RobustLoss::kCauchy:
      return 1.0 / (1.0 + s2 / (a * a));
  }
  return 1.0;
}

class Calibrator {
 public:
  Calibrator(std::string name, int n, const std::vector<CalibrationSample>& samples,
             const CalibrateOptions& options)
      : name_(std::move(name)), n_(n), samples_(samples), options_(options) {}

  Result<SourceCalibrationResult> Run();

 private:
  Status Error(StatusCode code, const std::string& what) const {
    return Status(code, "source '" + name_ + "': " + what);
  }
  Status CheckInput();
  Status Initialise();
  Status UpdateWhitening();
  Status Solve();
  // Normalised residual norms (and raw residuals) of every sample at the
  // current estimate.
  void EvaluateResiduals();
  double SigmaForFlagging() const;
  // Drops beams with too few unflagged samples; error when the gauge beams or
  // too many beams are lost.
  Status DropThinBeams();
  Status Covariance(SourceCalibrationResult* result);
  void FillResult(SourceCalibrationResult* result) const;

  int CentralId() const { return (n_ * n_ + 1) / 2; }
  int CentralRow() const { return (n_ - 1) / 2; }
  std::vector<BeamState*> ActiveBeams();
  Eigen::Matrix3d Rotation() const { return ExpSO3(Eigen::Map<const Eigen::Vector3d>(theta_)) * R0_; }
  Eigen::Vector3d Origin() const { return Eigen::Map<const Eigen::Vector3d>(t_); }
  // Assigns row indices to the active central-row beams and refills row_
  // from their current directions, projected onto the level constraint.
  void RebuildRow();
  int RowSize() const { return static_cast<int>(row_.size()) / 2; }

  std::string name_;
  int n_;
  const std::vector<CalibrationSample>& samples_;
  CalibrateOptions options_;

  bool weighted_ = false;
  std::vector<BeamState> beams_;       // by id
  std::vector<double> weight_;         // per sample: 0 = left out
  std::vector<char> flagged_;          // per sample
  std::vector<char> in_dropped_beam_;  // per sample
  std::vector<Eigen::Matrix2d> whitening_;
  std::vector<Eigen::Vector2d> raw_residual_;
  std::vector<double> normalized_;
  std::vector<int> dropped_beam_ids_;
  int num_slices_ = 0;
  int iterations_ = 0;

  Eigen::Matrix3d R0_ = Eigen::Matrix3d::Identity();
  double theta_[3] = {0.0, 0.0, 0.0};
  double t_[3] = {0.0, 0.0, 0.0};
  std::vector<double> row_;  // (az_1..az_m, el_1..el_m) of the central row
};

std::vector<BeamState*> Calibrator::ActiveBeams() {
  std::vector<BeamState*> out;
  for (BeamState& b : beams_) {
    if (b.active) out.push_back(&b);
  }
  return out;
}

Status Calibrator::CheckInput() {
  if (Status st = CheckBeamsPerSide(n_); !st.ok()) {
    return Error(StatusCode::kInvalidArgument, st.message());
  }
  std::map<int, std::map<int, int>> seen;  // beam -> slice -> sample index
  std::set<int> slices;
  std::map<int, int> index_of_beam;
  bool any_cov = false, all_cov = true;
  for (size_t i = 0; i < samples_.size(); ++i) {
    const CalibrationSample& s = samples_[i];
    const std::string which = "sample " + std::to_string(i) + " (beam " +
                              std::to_string(s.beam_id) + ", slice " + std::to_string(s.slice) + ")";
    if (s.beam_id < 1 || s.beam_id > n_ * n_) {
      return Error(StatusCode::kInvalidArgument,
                   which + ": beam id outside 1.." + std::to_string(n_ * n_));
    }
    if (!s.point_mm.allFinite()) return Error(StatusCode::kInvalidArgument, which + ": point not finite");
    if (s.cov_mm2) {
      any_cov = true;
      const Eigen::Matrix3d& C = *s.cov_mm2;
      if (!C.allFinite() || (C - C.transpose()).cwiseAbs().maxCoeff() > 1e-12 * C.cwiseAbs().maxCoeff()) {
        return Error(StatusCode::kInvalidArgument, which + ": covariance not finite or not symmetric");
      }
    } else {
      all_cov = false;
    }
    auto [it, inserted] = seen[s.beam_id].emplace(s.slice, static_cast<int>(i));
    if (!inserted) {
      return Error(StatusCode::kInvalidArgument,
                   which + ": a second sample of beam " + std::to_string(s.beam_id) +
                       " in slice " + std::to_string(s.slice) + " (also sample " +
                       std::to_string(it->second) + ")");
    }
    slices.insert(s.slice);
    auto [b, added] = index_of_beam.emplace(s.beam_id, static_cast<int>(beams_.size()));
    if (added) {
      BeamState beam;
      beam.id = s.beam_id;
      beam.row = BeamRow(s.beam_id, n_);
      beam.col = BeamCol(s.beam_id, n_);
      beam.layout = s.beam_id == CentralId()       ? Layout::kCentralBeam
                    : beam.row == CentralRow() ? Layout::kCentralRowBeam
                                               : Layout::kFreeBeam;
      beams_.push_back(beam);
    }
    beams_[b->second].samples.push_back(static_cast<int>(i));
  }
  if (any_cov && !all_cov) {
    return Error(StatusCode::kInvalidArgument,
                 "some samples have covariances and some do not: give all or none");
  }
  weighted_ = all_cov && !samples_.empty();
  num_slices_ = static_cast<int>(slices.size());
  if (num_slices_ < 2) {
    return Error(StatusCode::kNoSolution,
                 slices.empty() ? std::string("no samples")
                                : "all samples come from one slice (" +
                                      std::to_string(*slices.begin()) +
                                      "): a calibration needs the screen at two depths or more");
  }
  std::sort(beams_.begin(), beams_.end(),
            [](const BeamState& a, const BeamState& b) { return a.id < b.id; });
  return Status::Ok();
}

Status Calibrator::Initialise() {
  const int num = static_cast<int>(samples_.size());
  weight_.assign(num, 0.0);
  flagged_.assign(num, 0);
  in_dropped_beam_.assign(num, 0);
  // Line of every beam.
  struct Line {
    BeamState* beam;
    Eigen::Vector3d c, d;
  };
  std::vector<Line> lines;
  for (BeamState& b : beams_) {
    std::vector<Eigen::Vector3d> pts;
    for (int i : b.samples) pts.push_back(samples_[i].point_mm);
    Eigen::Vector3d c, d;
    std::vector<char> inlier;
    int inliers = 0;
    if (FitLine(pts, options_.init_inlier_distance_mm, &c, &d, &inlier)) {
      for (size_t k = 0; k < inlier.size(); ++k) {
        weight_[b.samples[k]] = inlier[k] ? 1.0 : 0.0;
        inliers += inlier[k];
      }
    }
    if (inliers < options_.min_samples_per_beam) {
      b.active = false;
      continue;
    }
    lines.push_back({&b, c, d});
  }
  // The origin: the point nearest to all lines, with one round that leaves
  // out lines far from the first estimate.
  std::vector<char> use(lines.size(), 1);
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  for (int round = 0; round < 2; ++round) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    int used = 0;
    for (size_t k = 0; k < lines.size(); ++k) {
      if (!use[k]) continue;
      const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - lines[k].d * lines[k].d.transpose();
      A += P;
      rhs += P * lines[k].c;
      ++used;
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
    if (used < 2 || !(eig.eigenvalues()(0) > 1e-6 * eig.eigenvalues()(2))) {
      return Error(StatusCode::kNoSolution,
                   "the beams' sample lines are (nearly) parallel: the projection origin is "
                   "undetermined (" + std::to_string(used) + " usable beams)");
    }
    origin = A.ldlt().solve(rhs);
    if (round == 1) break;
    std::vector<double> dist(lines.size());
    for (size_t k = 0; k < lines.size(); ++k) {
      const Eigen::Vector3d v = origin - lines[k].c;
      dist[k] = (v - v.dot(lines[k].d) * lines[k].d).norm();
    }
    std::vector<double> sorted = dist;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double limit =
        std::max(5.0 * 1.4826 * sorted[sorted.size() / 2], 10.0 * options_.init_inlier_distance_mm);
    for (size_t k = 0; k < lines.size(); ++k) use[k] = dist[k] <= limit;
  }
  // Orient every line away from the origin.
  for (Line& l : lines) {
    if ((l.c - origin).dot(l.d) < 0.0) l.d = -l.d;
  }
  // The pose: X along the central beam; Y along the columns (col 0 has the
  // smallest Y), Z against the rows (row 0 is the top).
  const Line* central = nullptr;
  for (const Line& l : lines) {
    if (l.beam->layout == Layout::kCentralBeam) central = &l;
  }
  if (central == nullptr) {
    return Error(StatusCode::kNoSolution,
                 "the central beam " + std::to_string(CentralId()) +
                     " has fewer than " + std::to_string(options_.min_samples_per_beam) +
                     " usable samples: the gauge (central beam az = el = 0) cannot be fixed");
  }
  const Eigen::Vector3d x = central->d;
  const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - x * x.transpose();
  Eigen::Vector3d y_grad = Eigen::Vector3d::Zero(), z_grad = Eigen::Vector3d::Zero();
  const double mid = 0.5 * (n_ - 1);
  for (const Line& l : lines) {
    y_grad += (l.beam->col - mid) * (P * l.d);
    z_grad -= (l.beam->row - mid) * (P * l.d);
  }
  Eigen::Vector3d y, z;
  if (y_grad.norm() >= z_grad.norm()) {
    y = y_grad.normalized();
    z = x.cross(y);
  } else {
    z = z_grad.normalized();
    y = z.cross(x);
  }
  // Both gradients must agree with a right-handed frame: a mirror image of
  // the grid (rows or columns numbered the other way) cannot be a pose.
  if (std::min(y_grad.norm(), z_grad.norm()) > 0.1 * std::max(y_grad.norm(), z_grad.norm()) &&
      (y.dot(y_grad) < 0.0 || z.dot(z_grad) < 0.0)) {
    return Error(StatusCode::kNoSolution,
                 "the beam numbering looks mirrored: with column 0 on the right (smallest Y), "
                 "row 0 is at the bottom, not the top (method.md, beam numbering)");
  }
  if (!(y.allFinite() && z.allFinite() && y.norm() > 0.5)) {
    return Error(StatusCode::kNoSolution,
                 "the beams do not span a grid around the central beam: the roll is undetermined");
  }
  R0_.col(0) = x;
  R0_.col(1) = y;
  R0_.col(2) = z;
  for (int k = 0; k < 3; ++k) {
    theta_[k] = 0.0;
    t_[k] = origin[k];
  }
  for (const Line& l : lines) {
    const Eigen::Vector3d q = R0_.transpose() * l.d;
    l.beam->az = AzimuthRad(q);
    l.beam->el = ElevationRad(q);
  }
  // Samples of beams that could not be fitted are out from the start.
  for (BeamState& b : beams_) {
    if (!b.active) {
      dropped_beam_ids_.push_back(b.id);
      for (int i : b.samples) {
        in_dropped_beam_[i] = 1;
        weight_[i] = 0.0;
      }
    }
  }
  RebuildRow();
  return Status::Ok();
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

Status Calibrator::Covariance(SourceCalibrationResult* result) {
  // Rebuild the final problem (weights 1/0) and take its tangent-space
  // Jacobian at the solution.
  ceres::Problem::Options po;
  ceres::Problem problem(po);
  problem.AddParameterBlock(theta_, 3);
  problem.AddParameterBlock(t_, 3);
  const int m = RowSize();
  std::vector<double*> blocks = {theta_, t_};
  if (m >= 1) {
    problem.AddParameterBlock(row_.data(), 2 * m, new LevelRowManifold(m));
    blocks.push_back(row_.data());
  }
  const int nf = 6 + (m >= 1 ? 2 * m - 1 : 0);
  std::vector<BeamState*> active = ActiveBeams();
  std::vector<double> beam_params(2 * active.size());
  int column = nf;
  for (size_t k = 0; k < active.size(); ++k) {
    BeamState& b = *active[k];
    std::vector<BeamRayCostFunction::Sample> s;
    for (int i : b.samples) s.push_back({samples_[i].point_mm, whitening_[i], weight_[i]});
    double* p = &beam_params[2 * k];
    p[0] = b.az;
    p[1] = b.el;
    if (b.layout == Layout::kFreeBeam) {
      problem.AddResidualBlock(new BeamRayCostFunction(std::move(s), R0_, b.layout), nullptr,
                               theta_, t_, p);
      problem.AddParameterBlock(p, 2);
      blocks.push_back(p);
      b.param_offset = column;
      column += 2;
    } else if (b.layout == Layout::kCentralRowBeam) {
      problem.AddResidualBlock(
          new BeamRayCostFunction(std::move(s), R0_, b.layout, m, b.row_index), nullptr, theta_,
          t_, row_.data());
      b.param_offset = -1;  // in the row block (an f-block)
    } else {
      problem.AddResidualBlock(new BeamRayCostFunction(std::move(s), R0_, b.layout), nullptr,
                               theta_, t_);
      b.param_offset = -1;
    }
  }
  const int np = column;
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  eo.num_threads = 1;
  double cost = 0.0;
  std::vector<double> residuals;
  ceres::CRSMatrix crs;
  if (!problem.Evaluate(eo, &cost, &residuals, nullptr, &crs) || crs.num_cols != np) {
    return Error(StatusCode::kNoSolution, "could not evaluate the Jacobian at the solution");
  }
  Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor>> J(
      crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()), crs.rows.data(),
      crs.cols.data(), crs.values.data());
  const Eigen::MatrixXd N = Eigen::MatrixXd(Eigen::SparseMatrix<double>(J.transpose() * J));

  // chi^2 / dof.
  int used = 0;
  for (size_t i = 0; i < samples_.size(); ++i) used += weight_[i] > 0.0;
  const int dof = 2 * used - np;
  const double chi2 = 2.0 * cost;
  if (dof > 0) {
    result->variance_factor = chi2 / dof;
  } else if (!weighted_) {
    return Error(StatusCode::kNoSolution,
                 "too few samples (" + std::to_string(used) + ") for " + std::to_string(np) +
                     " unknowns: no redundancy to estimate the noise without sample sigmas");
  }

  // Schur complement on the beam parameters: only the pose/row block and each
  // beam's own block (and its cross terms with the pose) are needed.
  Eigen::MatrixXd S = N.topLeftCorner(nf, nf);
  struct BeamBlock {
    BeamState* beam;
    int offset, size;
    Eigen::MatrixXd Nbb_inv, Nfb;
  };
  std::vector<BeamBlock> bb;
  for (BeamState* b : active) {
    if (b->param_offset < 0) continue;
    const int size = 2;
    BeamBlock blk{b, b->param_offset, size, {}, {}};
    const Eigen::MatrixXd Nbb = N.block(blk.offset, blk.offset, size, size);
    Eigen::LLT<Eigen::MatrixXd> llt(Nbb);
    if (llt.info() != Eigen::Success) {
      return Error(StatusCode::kNoSolution,
                   "beam " + std::to_string(b->id) + ": its direction is undetermined");
    }
    blk.Nbb_inv = llt.solve(Eigen::MatrixXd::Identity(size, size));
    blk.Nfb = N.block(0, blk.offset, nf, size);
    S -= blk.Nfb * blk.Nbb_inv * blk.Nfb.transpose();
    bb.push_back(std::move(blk));
  }
  Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(S);
  if (ldlt.info() != Eigen::Success || !(eig.eigenvalues()(0) > 1e-12 * eig.eigenvalues()(nf - 1))) {
    return Error(StatusCode::kNoSolution,
                 "the pose is undetermined by these samples (singular normal equations): are the "
                 "slices at distinct depths?");
  }
  const double scale = (!weighted_ && dof > 0) ? result->variance_factor : 1.0;
  result->covariance_scaled = !weighted_;
  const Eigen::MatrixXd Cff = scale * ldlt.solve(Eigen::MatrixXd::Identity(nf, nf));
  result->pose_covariance = Cff.topLeftCorner(6, 6);

  std::map<int, Eigen::Matrix2d> beam_cov;
  for (const BeamBlock& blk : bb) {
    // C_bb = s Nbb^-1 + Nbb^-1 Nbf Cff Nfb Nbb^-1.
    const Eigen::MatrixXd K = blk.Nfb * blk.Nbb_inv;  // nf x 2
    const Eigen::Matrix2d C = scale * blk.Nbb_inv + K.transpose() * Cff * K;
    beam_cov[blk.beam->id] = 0.5 * (C + C.transpose());
  }
  // The central row, from the tangent covariance of its block:
  // (az, el) = row0 + P delta, P = d Plus / d delta.
  if (m >= 1) {
    const Eigen::MatrixXd P = LevelRowManifold(m).PlusJacobianAt(row_.data());
    const Eigen::MatrixXd Crow = P * Cff.block(6, 6, 2 * m - 1, 2 * m - 1) * P.transpose();
    for (BeamState* b : active) {
      if (b->layout != Layout::kCentralRowBeam) continue;
      const int j = b->row_index;
      Eigen::Matrix2d C;
      C << Crow(j, j), Crow(j, m + j), Crow(m + j, j), Crow(m + j, m + j);
      beam_cov[b->id] = 0.5 * (C + C.transpose());
    }
  }
  for (BeamState* b : active) {
    if (!beam_cov.count(b->id)) beam_cov[b->id] = Eigen::Matrix2d::Zero();
  }
  // Fill the pattern.
  std::vector<Beam> beams;
  for (BeamState* b : active) {
    Beam beam;
    beam.id = b->id;
    beam.az_rad = b->az;
    beam.el_rad = b->el;
    beam.cov_azel_rad2 = beam_cov[b->id];
    beams.push_back(beam);
  }
  Result<BeamPattern> pattern = BeamPattern::Create(n_, std::move(beams));
  if (!pattern.ok()) return Error(StatusCode::kNoSolution, pattern.status().message());
  result->calibration.pattern = std::move(*pattern);
  return Status::Ok();
}

void Calibrator::FillResult(SourceCalibrationResult* result) const {
  const Eigen::Matrix3d R = Rotation();
  const Eigen::Vector3d t = Origin();
  result->calibration.name = name_;
  result->calibration.calibration_from_source = Rigid3d(R, t);
  result->weighted = weighted_;
  result->num_slices = num_slices_;
  result->solver_iterations = iterations_;
  result->dropped_beam_ids = dropped_beam_ids_;
  result->residuals.resize(samples_.size());
  SourceCalibrationQuality quality;
  quality.slices = num_slices_;
  quality.beams_dropped = static_cast<int>(dropped_beam_ids_.size());
  double sum_dist = 0.0, sum_r2 = 0.0;
  for (const BeamState& b : beams_) {
    const Eigen::Vector3d d = R * DirectionFromAzElRad(b.az, b.el);
    BeamCalibrationQuality bq;
    bq.beam_id = b.id;
    double beam_r2 = 0.0;
    for (int i : b.samples) {
      CalibrationSampleResidual& r = result->residuals[i];
      r.beam_id = b.id;
      r.slice = samples_[i].slice;
      r.residual_rad = raw_residual_[i];
      r.normalized = normalized_[i];
      const Eigen::Vector3d v = samples_[i].point_mm - t;
      r.point_to_ray_mm = (v - v.dot(d) * d).norm();
      r.outlier = flagged_[i] != 0;
      r.beam_dropped = in_dropped_beam_[i] != 0;
      if (r.beam_dropped) continue;
      if (r.outlier) {
        ++bq.samples_flagged;
        ++quality.samples_flagged;
        continue;
      }
      ++bq.samples_used;
      bq.mean_point_to_ray_mm += r.point_to_ray_mm;
      bq.max_point_to_ray_mm = std::max(bq.max_point_to_ray_mm, r.point_to_ray_mm);
      beam_r2 += r.residual_rad.squaredNorm();
      sum_dist += r.point_to_ray_mm;
      quality.max_point_to_ray_mm = std::max(quality.max_point_to_ray_mm, r.point_to_ray_mm);
    }
    if (!b.active) continue;
    quality.samples_used += bq.samples_used;
    sum_r2 += beam_r2;
    bq.mean_point_to_ray_mm /= bq.samples_used;
    bq.rms_residual_rad = std::sqrt(beam_r2 / (2.0 * bq.samples_used));
    result->beams.push_back(bq);
  }
  quality.mean_point_to_ray_mm = quality.samples_used > 0 ? sum_dist / quality.samples_used : 0.0;
  quality.rms_residual_urad =
      quality.samples_used > 0 ? 1e6 * std::sqrt(sum_r2 / (2.0 * quality.samples_used)) : 0.0;
  quality.variance_factor = result->variance_factor;
  quality.origin_cov_mm2 = result->pose_covariance.bottomRightCorner<3, 3>();
  const Eigen::Vector3d angles = XyzAnglesRadFromRotation(R);
  const Eigen::Matrix3d Ja = XyzAnglesJacobianWrtLeftPerturbation(angles);
  quality.rotation_xyz_cov_rad2 = Ja * result->pose_covariance.topLeftCorner<3, 3>() * Ja.transpose();
  result->calibration.quality = quality;
}

Result<SourceCalibrationResult> Calibrator::Run() {
  OPL_RETURN_IF_ERROR(options_.Validate());
  OPL_RETURN_IF_ERROR(CheckInput());
  OPL_RETURN_IF_ERROR(Initialise());
  int usable = static_cast<int>(ActiveBeams().size());
  auto too_few = [&](int count) {
    return Error(StatusCode::kNoSolution,
                 "only " + std::to_string(count) + " beam(s) have " +
                     std::to_string(options_.min_samples_per_beam) +
                     " or more usable samples: a calibration needs at least three");
  };
  if (usable < 3) return too_few(usable);
  bool has_row_beam = false;
  for (BeamState* b : ActiveBeams()) has_row_beam |= b->layout == Layout::kCentralRowBeam;
  if (!has_row_beam) {
    return Error(StatusCode::kNoSolution,
                 "no beam of the central row besides the central beam has usable samples: the "
                 "roll gauge (central row mean elevation 0) cannot be fixed");
  }

  // Robust phase: IRLS with the chosen loss, starting from the line-fit inliers.
  OPL_RETURN_IF_ERROR(UpdateWhitening());
  OPL_RETURN_IF_ERROR(Solve());
  // The robust phase only when the first solve used a sample beyond the
  // flagging threshold (samples the line fits already left out do not count:
  // they did not pull the solution; a clean session goes straight to flagging).
  EvaluateResiduals();
  bool suspicious = false;
  {
    const double limit = options_.outlier_threshold * SigmaForFlagging();
    for (size_t i = 0; i < samples_.size(); ++i) {
      suspicious |= weight_[i] > 0.0 && normalized_[i] > limit;
    }
  }
  if (options_.loss != RobustLoss::kNone && suspicious) {
    const double a = weighted_ ? options_.loss_scale : options_.loss_scale_unweighted_rad;
    for (int round = 0; round < options_.max_robust_rounds; ++round) {
      OPL_RETURN_IF_ERROR(UpdateWhitening());
      EvaluateResiduals();
      double change = 0.0;
      for (size_t i = 0; i < samples_.size(); ++i) {
        if (in_dropped_beam_[i]) continue;
        const double w = RobustWeight(options_.loss, normalized_[i] * normalized_[i], a);
        change = std::max(change, std::abs(w - weight_[i]));
        weight_[i] = w;
      }
      OPL_RETURN_IF_ERROR(Solve());
      if (change < 1e-2) break;
    }
  }
  // Flagging phase: plain least squares over the samples within the threshold.
  for (int round = 0; round < options_.max_flagging_rounds; ++round) {
    OPL_RETURN_IF_ERROR(UpdateWhitening());
    EvaluateResiduals();
    const double limit = options_.outlier_threshold * SigmaForFlagging();
    bool changed = false;
    for (size_t i = 0; i < samples_.size(); ++i) {
      if (in_dropped_beam_[i]) continue;
      const char flag = normalized_[i] > limit;
      changed |= flag != flagged_[i] || weight_[i] != (flag ? 0.0 : 1.0);
      flagged_[i] = flag;
      weight_[i] = flag ? 0.0 : 1.0;
    }
    const size_t dropped_before = dropped_beam_ids_.size();
    OPL_RETURN_IF_ERROR(DropThinBeams());
    changed |= dropped_beam_ids_.size() != dropped_before;
    usable = static_cast<int>(ActiveBeams().size());
    if (usable < 3) return too_few(usable);
    if (!changed) break;
    OPL_RETURN_IF_ERROR(Solve());
  }
  OPL_RETURN_IF_ERROR(UpdateWhitening());
  EvaluateResiduals();
  SourceCalibrationResult result;
  OPL_RETURN_IF_ERROR(Covariance(&result));
  FillResult(&result);
  return result;
}

}  // namespace

Result<SourceCalibrationResult> CalibrateSource(const std::string& name, int beams_per_side,
                                                const std::vector<CalibrationSample>& samples,
                                                const CalibrateOptions& options) {
  Calibrator calibrator(name, beams_per_side, samples, options);
  return calibrator.Run();
}

}  // namespace opl
