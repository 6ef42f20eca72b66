// CalibrateSource's start: the input checks (Calibrator::CheckInput) and the
// initial estimate (Calibrator::Initialise): a robust 3D line through each
// beam's spots (FitLine) gives its direction in the scene; the lines'
// common point the origin, the central beam and row the source axes.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "calibrate/calibrate_source_internal.h"
#include "opl/geometry/spherical.h"
#include "opl/model/beam_pattern.h"

namespace opl {
namespace calibrate_internal {
namespace {

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

}  // namespace

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

}  // namespace calibrate_internal
}  // namespace opl
