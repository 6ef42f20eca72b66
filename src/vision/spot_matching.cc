#include "opl/vision/spot_matching.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <unordered_set>
#include <utility>

#include <ceres/jet.h>
#include <Eigen/Dense>

#include "opl/core/format.h"

namespace opl {
namespace {

using Jet3 = ceres::Jet<double, 3>;
using Jet2 = ceres::Jet<double, 2>;

double LargestEigenvalue(const Eigen::Matrix2d& S) {
  const double tr = 0.5 * (S(0, 0) + S(1, 1));
  const double det = S(0, 0) * S(1, 1) - S(0, 1) * S(1, 0);
  return tr + std::sqrt(std::max(0.0, tr * tr - det));
}

// Bucket grid over 2D points: cells of side `cell`, items stored by cell.
class Grid {
 public:
  void Build(const std::vector<Eigen::Vector2d>& points, const std::vector<char>& usable,
             double cell) {
    x0_ = y0_ = std::numeric_limits<double>::infinity();
    x1_ = y1_ = -std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < points.size(); ++k) {
      if (!usable[k]) continue;
      x0_ = std::min(x0_, points[k].x());
      y0_ = std::min(y0_, points[k].y());
      x1_ = std::max(x1_, points[k].x());
      y1_ = std::max(y1_, points[k].y());
    }
    nx_ = ny_ = 0;
    start_.assign(1, 0);
    items_.clear();
    if (!(x0_ <= x1_)) return;
    cell_ = cell;
    // Keep the grid at most ~1M cells whatever the spread of the points.
    while ((x1_ - x0_) / cell_ * (y1_ - y0_) / cell_ > 1.0e6) cell_ *= 2.0;
    nx_ = static_cast<int>((x1_ - x0_) / cell_) + 1;
    ny_ = static_cast<int>((y1_ - y0_) / cell_) + 1;
    std::vector<int> count(static_cast<size_t>(nx_) * static_cast<size_t>(ny_) + 1, 0);
    std::vector<int> cell_of(points.size(), -1);
    for (size_t k = 0; k < points.size(); ++k) {
      if (!usable[k]) continue;
      const int ix = std::min(nx_ - 1, static_cast<int>((points[k].x() - x0_) / cell_));
      const int iy = std::min(ny_ - 1, static_cast<int>((points[k].y() - y0_) / cell_));
      cell_of[k] = iy * nx_ + ix;
      ++count[static_cast<size_t>(cell_of[k]) + 1];
    }
    for (size_t c = 1; c < count.size(); ++c) count[c] += count[c - 1];
    start_ = count;
    items_.assign(static_cast<size_t>(count.back()), 0);
    for (size_t k = 0; k < points.size(); ++k) {
      if (cell_of[k] < 0) continue;
      items_[static_cast<size_t>(count[static_cast<size_t>(cell_of[k])]++)] = static_cast<int>(k);
    }
  }

  int num_cells() const { return nx_ * ny_; }
  double cell() const { return cell_; }
  bool empty() const { return nx_ == 0; }
  double x0() const { return x0_; }
  double y0() const { return y0_; }
  double x1() const { return x1_; }
  double y1() const { return y1_; }

  // Calls f(cell index) for every cell meeting the box.
  template <typename F>
  void ForEachCell(double xa, double ya, double xb, double yb, F&& f) const {
    if (empty() || xb < x0_ || yb < y0_ || xa > x1_ || ya > y1_) return;
    const int ix0 = std::max(0, static_cast<int>(std::floor((xa - x0_) / cell_)));
    const int iy0 = std::max(0, static_cast<int>(std::floor((ya - y0_) / cell_)));
    const int ix1 = std::min(nx_ - 1, static_cast<int>(std::floor((xb - x0_) / cell_)));
    const int iy1 = std::min(ny_ - 1, static_cast<int>(std::floor((yb - y0_) / cell_)));
    for (int iy = iy0; iy <= iy1; ++iy) {
      for (int ix = ix0; ix <= ix1; ++ix) f(iy * nx_ + ix);
    }
  }
  template <typename F>
  void ForEachInCell(int c, F&& f) const {
    for (int k = start_[static_cast<size_t>(c)]; k < start_[static_cast<size_t>(c) + 1]; ++k) {
      f(items_[static_cast<size_t>(k)]);
    }
  }

 private:
  double x0_ = 0.0, y0_ = 0.0, x1_ = 0.0, y1_ = 0.0, cell_ = 1.0;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_;
  std::vector<int> items_;
};

struct View {
  const Camera* camera = nullptr;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  std::array<double, kNumCameraParameters> packed{};
  double focal = 1.0;  // mean of fx, fy [px]
  std::vector<Eigen::Vector2d> pixel;      // real pixels
  std::vector<Eigen::Vector2d> ideal;      // distortion-free pixels
  std::vector<Eigen::Vector3d> ray;        // unit direction in the scene
  std::vector<Eigen::Matrix2d> cov;        // real pixels [px^2]
  std::vector<Eigen::Matrix2d> cov_ideal;  // ideal pixels [px^2]
  std::vector<Eigen::Matrix2d> weight;     // cov^-1
  std::vector<Eigen::Matrix2d> eff_weight; // (cov + tau^2 I)^-1
  std::vector<char> usable;
  // Search radii use a robust "largest" variance: the 90th percentile of the
  // view's detections (largest eigenvalue), not the maximum, so that one
  // detection with a huge covariance (a poor fit) does not widen every
  // epipolar band to the whole image (the search then costs O(S^2) seeds).
  // A detection whose covariance exceeds it can still be matched, by the
  // seeds of its other views, within its own gate.
  double search_var_real = 0.0;
  double search_var_ideal = 0.0;
  Grid grid_ideal;
  Grid grid_real;
};

// Pixel of `X` in view `v` and its 2x3 Jacobian; false behind the camera.
bool ProjectWithJacobian(const View& v, const Eigen::Vector3d& X, Eigen::Vector2d* pixel,
                         Eigen::Matrix<double, 2, 3>* J) {
  Jet3 packed[kNumCameraParameters];
  for (int i = 0; i < kNumCameraParameters; ++i) packed[i] = Jet3(v.packed[static_cast<size_t>(i)]);
  // X_cam = R X + t; d X_cam / d X = R.
  const Eigen::Vector3d xc = v.R * X + v.t;
  Jet3 Xc[3];
  for (int r = 0; r < 3; ++r) {
    Xc[r] = Jet3(xc(r));
    Xc[r].v = v.R.row(r).transpose();
  }
  Jet3 px[2];
  if (!ProjectPointInCamera(packed, Xc, px)) return false;
  for (int r = 0; r < 2; ++r) {
    (*pixel)(r) = px[r].a;
    J->row(r) = px[r].v.transpose();
  }
  return true;
}

double RayAngleDeg(const Eigen::Vector3d& X, const Eigen::Vector3d& ca, const Eigen::Vector3d& cb) {
  const Eigen::Vector3d da = (X - ca).normalized();
  const Eigen::Vector3d db = (X - cb).normalized();
  return std::atan2(da.cross(db).norm(), da.dot(db)) * 180.0 / kPi;
}

// Unit normal (a, b) and offset c of the epipolar line, in view `to`'s ideal
// pixels, of the ray from `from`'s centre along `ray`: a u + b v + c = 0.
bool EpipolarLine(const View& from, const Eigen::Vector3d& ray, const View& to,
                  Eigen::Vector3d* line) {
  const Eigen::Vector3d A = to.R * from.center + to.t;
  const Eigen::Vector3d D = to.R * ray;
  const Eigen::Vector3d ln = A.cross(D);
  const double fx = to.camera->intrinsics.fx_px, fy = to.camera->intrinsics.fy_px;
  const double cx = to.camera->intrinsics.cx_px, cy = to.camera->intrinsics.cy_px;
  Eigen::Vector3d lp(ln(0) / fx, ln(1) / fy, ln(2) - cx * ln(0) / fx - cy * ln(1) / fy);
  const double norm = std::hypot(lp(0), lp(1));
  if (!(norm > 1e-15 * lp.norm()) || !std::isfinite(norm)) return false;
  *line = lp / norm;
  return true;
}

struct Hypothesis {
  std::vector<SpotRef> spots;  // by increasing view
  TriangulatedPoint point;
  double chi2 = 0.0;  // ranking chi^2
  // chi2 + sum_i ln det(Sigma_i + tau^2 I): twice the negative
  // log-likelihood (up to a constant), which orders and compares the
  // hypotheses. chi2 alone favoured a hypothesis holding a detection with a
  // degenerate covariance (it adds ~0 to chi2 wherever it lies) over the
  // true one, and the two were refused as ambiguous.
  double nll = 0.0;
  // kLive: may be accepted; kContested: lost a detection to an ambiguity but
  // still explains its others (a competitor); kDead: accepted, or explained
  // away by an accepted track.
  enum { kLive, kContested, kDead } status = kLive;
  bool live() const { return status == kLive; }
};

class Matcher {
 public:
  Matcher(std::vector<View>* views, const SpotMatchOptions& options, int min_views,
          SpotMatchResult* result)
      : views_(*views), options_(options), min_views_(min_views), result_(result) {
    offset_.assign(views_.size() + 1, 0);
    for (size_t v = 0; v < views_.size(); ++v) {
      offset_[v + 1] = offset_[v] + static_cast<int>(views_[v].pixel.size());
    }
    state_.assign(static_cast<size_t>(offset_.back()), kFree);
    for (size_t v = 0; v < views_.size(); ++v) {
      for (size_t s = 0; s < views_[v].pixel.size(); ++s) {
        if (!views_[v].usable[s]) {
          state_[static_cast<size_t>(Flat(static_cast<int>(v), static_cast<int>(s)))] = kUnusable;
        }
      }
    }
    hyps_of_spot_.resize(static_cast<size_t>(offset_.back()));
    g2_ = options.gate_sigmas * options.gate_sigmas;
    tau2_ = std::pow(options.pose_tolerance_px / options.gate_sigmas, 2);
    tol2_ = options.pose_tolerance_px * options.pose_tolerance_px;
  }

  void GenerateSeeds() {
    const int nv = static_cast<int>(views_.size());
    std::vector<int> stamp;
    int stamp_value = 0;
    for (int i = 0; i < nv; ++i) {
      for (int j = i + 1; j < nv; ++j) {
        const View& vi = views_[static_cast<size_t>(i)];
        const View& vj = views_[static_cast<size_t>(j)];
        if (vj.grid_ideal.empty()) continue;
        stamp.assign(static_cast<size_t>(vj.grid_ideal.num_cells()), -1);
        const double ratio = vj.focal / vi.focal;
        for (int a = 0; a < static_cast<int>(vi.pixel.size()); ++a) {
          if (!vi.usable[static_cast<size_t>(a)]) continue;
          Eigen::Vector3d line;
          if (!EpipolarLine(vi, vi.ray[static_cast<size_t>(a)], vj, &line)) continue;
          const double var_a = std::min(LargestEigenvalue(vi.cov_ideal[static_cast<size_t>(a)]),
                                        vi.search_var_ideal);
          const double band = std::sqrt(
              g2_ * (vj.search_var_ideal + 16.0 * ratio * ratio * var_a) + tol2_);
          ++stamp_value;
          WalkLine(vj.grid_ideal, line, band, &stamp, stamp_value, [&](int b) {
            const Eigen::Vector2d& q = vj.ideal[static_cast<size_t>(b)];
            if (std::abs(line(0) * q.x() + line(1) * q.y() + line(2)) <= band) {
              TrySeed(i, a, j, b, line);
            }
          });
        }
      }
    }
  }

  void Accept() {
    std::set<std::tuple<int, double, int>> queue;
    for (size_t h = 0; h < hyps_.size(); ++h) {
      if (hyps_[h].live()) queue.insert(Key(static_cast<int>(h)));
    }
    while (!queue.empty()) {
      const int h = std::get<2>(*queue.begin());
      queue.erase(queue.begin());
      if (!hyps_[static_cast<size_t>(h)].live()) continue;
      const int c = BestCompetitor(h);
      const Hypothesis& H = hyps_[static_cast<size_t>(h)];
      std::vector<int> newly;
      bool accepted = false;
      if (c >= 0 && (hyps_[static_cast<size_t>(c)].spots.size() > H.spots.size() ||
                     hyps_[static_cast<size_t>(c)].nll - H.nll < options_.ambiguity_chi2)) {
        const Hypothesis& C = hyps_[static_cast<size_t>(c)];
        SpotAmbiguity amb;
        amb.best = H.spots;
        amb.second = C.spots;
        amb.best_chi2 = H.chi2;
        amb.second_chi2 = C.chi2;
        amb.best_nll = H.nll;
        amb.second_nll = C.nll;
        std::vector<SpotRef> shared;
        for (const SpotRef& r : H.spots) {
          if (Contains(C.spots, r)) shared.push_back(r);
        }
        if (shared.size() >= 2) {
          for (const SpotRef& r : H.spots) if (!Contains(shared, r)) amb.blocked.push_back(r);
          for (const SpotRef& r : C.spots) if (!Contains(shared, r)) amb.blocked.push_back(r);
        } else {
          amb.blocked = shared;
        }
        for (const SpotRef& r : amb.blocked) {
          if (state_[static_cast<size_t>(Flat(r))] != kFree) continue;
          state_[static_cast<size_t>(Flat(r))] = kBlocked;
          newly.push_back(Flat(r));
        }
        result_->ambiguities.push_back(std::move(amb));
        // h holds a blocked detection (h is not a subset of c): the
        // reduction below makes it contested.
      } else {
        accepted = true;
        SpotTrack track;
        track.spots = H.spots;
        track.point = H.point;
        track.ranking_chi2 = H.chi2;
        result_->tracks.push_back(std::move(track));
        hyps_[static_cast<size_t>(h)].status = Hypothesis::kDead;
        for (const SpotRef& r : H.spots) {
          state_[static_cast<size_t>(Flat(r))] = kUsed;
          newly.push_back(Flat(r));
        }
      }
      // Every live hypothesis holding a removed detection is reduced: it is
      // dead when an accepted track took the detection, contested when an
      // ambiguity blocked it. A contested one holding a detection now taken
      // is dead (explained away).
      const size_t before = hyps_.size();
      for (int s : newly) {
        const std::vector<int> holders = hyps_of_spot_[static_cast<size_t>(s)];
        for (int o : holders) {
          Hypothesis& O = hyps_[static_cast<size_t>(o)];
          if (O.status == Hypothesis::kDead) continue;
          const bool was_live = O.live();
          O.status = accepted ? Hypothesis::kDead : Hypothesis::kContested;
          if (!was_live) continue;
          std::vector<SpotRef> rest;
          for (const SpotRef& r : O.spots) {
            if (state_[static_cast<size_t>(Flat(r))] == kFree) rest.push_back(r);
          }
          if (static_cast<int>(rest.size()) >= min_views_) AddHypothesis(rest);
        }
      }
      for (size_t n = before; n < hyps_.size(); ++n) {
        if (hyps_[n].live()) queue.insert(Key(static_cast<int>(n)));
      }
    }
  }

  bool IsUsed(int view, int spot) const {
    return state_[static_cast<size_t>(Flat(view, spot))] == kUsed;
  }
  int num_hypotheses() const { return static_cast<int>(hyps_.size()); }

 private:
  enum State : char { kFree = 0, kUsed, kBlocked, kUnusable };

  int Flat(int view, int spot) const { return offset_[static_cast<size_t>(view)] + spot; }
  int Flat(const SpotRef& r) const { return Flat(r.view, r.spot); }
  static std::int64_t PairKey(int x, int y) {
    return static_cast<std::int64_t>(std::min(x, y)) * (std::int64_t{1} << 32) + std::max(x, y);
  }
  static bool Contains(const std::vector<SpotRef>& v, const SpotRef& r) {
    return std::find(v.begin(), v.end(), r) != v.end();
  }
  std::tuple<int, double, int> Key(int h) const {
    const Hypothesis& H = hyps_[static_cast<size_t>(h)];
    return {-static_cast<int>(H.spots.size()), H.nll, h};
  }

  // Calls f(item) once for each item of a cell within `band` of the line.
  template <typename F>
  void WalkLine(const Grid& grid, const Eigen::Vector3d& line, double band,
                std::vector<int>* stamp, int stamp_value, F&& f) {
    const Eigen::Vector2d n(line(0), line(1));
    const Eigen::Vector2d dir(-n.y(), n.x());
    // A band wider than the grid's box (search variances set by detections
    // with degenerate covariances) holds every cell: visit each once rather
    // than walk a line of length ~2 band in steps of one cell (which, with
    // bands of 1e6 px and more, did not end).
    if (band >= std::hypot(grid.x1() - grid.x0(), grid.y1() - grid.y0())) {
      for (int c = 0; c < grid.num_cells(); ++c) {
        if ((*stamp)[static_cast<size_t>(c)] == stamp_value) continue;
        (*stamp)[static_cast<size_t>(c)] = stamp_value;
        grid.ForEachInCell(c, f);
      }
      return;
    }
    const Eigen::Vector2d centre(0.5 * (grid.x0() + grid.x1()), 0.5 * (grid.y0() + grid.y1()));
    const Eigen::Vector2d p0 = centre - (n.dot(centre) + line(2)) * n;
    // Clip the line to the grid's box widened by the band (slab method).
    double s_min = -std::numeric_limits<double>::infinity();
    double s_max = std::numeric_limits<double>::infinity();
    const double lo[2] = {grid.x0() - band, grid.y0() - band};
    const double hi[2] = {grid.x1() + band, grid.y1() + band};
    for (int k = 0; k < 2; ++k) {
      if (std::abs(dir(k)) < 1e-12) {
        if (p0(k) < lo[k] || p0(k) > hi[k]) return;
        continue;
      }
      double s0 = (lo[k] - p0(k)) / dir(k), s1 = (hi[k] - p0(k)) / dir(k);
      if (s0 > s1) std::swap(s0, s1);
      s_min = std::max(s_min, s0);
      s_max = std::min(s_max, s1);
    }
    if (!(s_min <= s_max)) return;
    const double step = grid.cell();
    const double half = band + 0.5 * step;
    for (double s = s_min; s <= s_max + step; s += step) {
      const Eigen::Vector2d p = p0 + std::min(s, s_max) * dir;
      grid.ForEachCell(p.x() - half, p.y() - half, p.x() + half, p.y() + half, [&](int c) {
        if ((*stamp)[static_cast<size_t>(c)] == stamp_value) return;
        (*stamp)[static_cast<size_t>(c)] = stamp_value;
        grid.ForEachInCell(c, f);
      });
    }
  }

  // Gauss-Newton from `X` on the whitened residuals of `refs`; the
  // covariance (J^T W J)^-1 in *cov. False behind a camera.
  bool Refine(const std::vector<SpotRef>& refs, Eigen::Vector3d* X, Eigen::Matrix3d* cov) const {
    for (int iter = 0; iter < 3; ++iter) {
      Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      for (const SpotRef& r : refs) {
        const View& v = views_[static_cast<size_t>(r.view)];
        Eigen::Vector2d px;
        Eigen::Matrix<double, 2, 3> J;
        if (!ProjectWithJacobian(v, *X, &px, &J)) return false;
        const Eigen::Matrix2d& W = v.weight[static_cast<size_t>(r.spot)];
        H += J.transpose() * W * J;
        g += J.transpose() * W * (px - v.pixel[static_cast<size_t>(r.spot)]);
      }
      Eigen::LDLT<Eigen::Matrix3d> ldlt(H);
      if (iter == 2) {
        *cov = ldlt.solve(Eigen::Matrix3d::Identity());
        return cov->allFinite();
      }
      const Eigen::Vector3d step = -ldlt.solve(g);
      if (!step.allFinite()) return false;
      *X += step;
    }
    return false;
  }

  void TrySeed(int i, int a, int j, int b, const Eigen::Vector3d& line) {
    const View& vi = views_[static_cast<size_t>(i)];
    const View& vj = views_[static_cast<size_t>(j)];
    const size_t ua = static_cast<size_t>(a), ub = static_cast<size_t>(b);
    const double d = line.dot(Eigen::Vector3d(vj.ideal[ub].x(), vj.ideal[ub].y(), 1.0));
    // Midpoint of the two rays.
    const Eigen::Vector3d& d1 = vi.ray[ua];
    const Eigen::Vector3d& d2 = vj.ray[ub];
    const Eigen::Vector3d w0 = vi.center - vj.center;
    const double bb = d1.dot(d2), dd = d1.dot(w0), ee = d2.dot(w0);
    const double den = 1.0 - bb * bb;
    if (!(den > 1e-12)) return;
    const double s1 = (bb * ee - dd) / den, s2 = (ee - bb * dd) / den;
    if (!(s1 > 0.0 && s2 > 0.0)) return;
    Eigen::Vector3d X = 0.5 * (vi.center + s1 * d1 + vj.center + s2 * d2);
    const double zi = (vi.R * X + vi.t).z(), zj = (vj.R * X + vj.t).z();
    if (!(zi > 0.0 && zj > 0.0)) return;
    Eigen::Vector3d line_i;
    if (!EpipolarLine(vj, d2, vi, &line_i)) return;
    const double transfer = (vj.focal * zi) / (vi.focal * zj);
    const Eigen::Vector2d n(line(0), line(1)), na(line_i(0), line_i(1));
    const double var = n.dot(vj.cov_ideal[ub] * n) +
                       transfer * transfer * na.dot(vi.cov_ideal[ua] * na);
    if (d * d > g2_ * var + tol2_) return;
    ++result_->candidate_pairs;
    // A pair inside a stored hypothesis (seeded by another pair of its
    // views) would only find that hypothesis again.
    if (seen_pairs_.count(PairKey(Flat(i, a), Flat(j, b))) > 0) return;
    if (RayAngleDeg(X, vi.center, vj.center) < options_.min_triangulation_angle_deg) {
      ++result_->rejected_geometry;
      return;
    }
    std::vector<SpotRef> support = {{i, a}, {j, b}};
    Eigen::Matrix3d C;
    if (!Refine(support, &X, &C)) {
      ++result_->rejected_geometry;
      return;
    }
    for (int k = 0; k < static_cast<int>(views_.size()); ++k) {
      if (k == i || k == j) continue;
      const View& vk = views_[static_cast<size_t>(k)];
      if (vk.grid_real.empty()) continue;
      Eigen::Vector2d px;
      Eigen::Matrix<double, 2, 3> J;
      if (!ProjectWithJacobian(vk, X, &px, &J) || !px.allFinite()) continue;
      const Eigen::Matrix2d S_pred = J * C * J.transpose() + tau2_ * Eigen::Matrix2d::Identity();
      const double radius = std::sqrt(g2_ * (LargestEigenvalue(S_pred) + vk.search_var_real));
      if (!(radius < 1e4)) continue;  // the point is barely determined
      // Within the gate (m2 <= g^2), the most likely detection: the lowest
      // m2 + ln det S (the Gaussian's negative log-likelihood, doubled). The
      // lowest m2 alone preferred a detection with a degenerate covariance
      // (the detector's poor fits of non-spot blobs: 1e6 px^2 and more),
      // whose m2 is ~0 wherever it lies, to the true detection beside it.
      int best = -1;
      double best_nll = std::numeric_limits<double>::infinity();
      vk.grid_real.ForEachCell(px.x() - radius, px.y() - radius, px.x() + radius,
                               px.y() + radius, [&](int cell) {
        vk.grid_real.ForEachInCell(cell, [&](int s) {
          const Eigen::Vector2d r = vk.pixel[static_cast<size_t>(s)] - px;
          if (r.squaredNorm() > radius * radius) return;
          const Eigen::Matrix2d S = S_pred + vk.cov[static_cast<size_t>(s)];
          const double m2 = r.dot(S.inverse() * r);
          if (!(m2 <= g2_)) return;
          const double nll = m2 + std::log(S.determinant());
          if (nll < best_nll) {
            best_nll = nll;
            best = s;
          }
        });
      });
      if (best >= 0) support.push_back({k, best});
    }
    if (static_cast<int>(support.size()) < min_views_) return;
    std::sort(support.begin(), support.end(),
              [](const SpotRef& x, const SpotRef& y) { return x.view < y.view; });
    AddHypothesis(support);
  }

  // Triangulates `refs` (sorted by view) and stores it unless known; drops
  // the worst observation outside its gate while min_views remain.
  void AddHypothesis(std::vector<SpotRef> refs) {
    TriangulationOptions topt;
    topt.min_triangulation_angle_deg = options_.min_triangulation_angle_deg;
    while (true) {
      std::vector<int> key;
      key.reserve(2 * refs.size());
      for (const SpotRef& r : refs) {
        key.push_back(r.view);
        key.push_back(r.spot);
      }
      if (!known_.insert(key).second) return;
      std::vector<PointObservation> obs;
      for (const SpotRef& r : refs) {
        const View& v = views_[static_cast<size_t>(r.view)];
        obs.push_back({v.camera, v.pixel[static_cast<size_t>(r.spot)],
                       v.cov[static_cast<size_t>(r.spot)]});
      }
      Result<TriangulatedPoint> tp = TriangulatePoint(obs, topt);
      if (!tp.ok()) {
        ++result_->rejected_geometry;
        return;
      }
      double chi2 = 0.0, log_det = 0.0, worst = -1.0;
      size_t worst_k = 0;
      for (size_t k = 0; k < refs.size(); ++k) {
        const View& v = views_[static_cast<size_t>(refs[k].view)];
        const Eigen::Vector2d& r = tp->residuals_px[k];
        const double m2 = r.dot(v.eff_weight[static_cast<size_t>(refs[k].spot)] * r);
        chi2 += m2;
        log_det -= std::log(v.eff_weight[static_cast<size_t>(refs[k].spot)].determinant());
        if (m2 > worst) {
          worst = m2;
          worst_k = k;
        }
      }
      if (worst > g2_) {
        if (static_cast<int>(refs.size()) - 1 < min_views_) return;
        refs.erase(refs.begin() + static_cast<std::ptrdiff_t>(worst_k));
        continue;
      }
      Hypothesis h;
      h.spots = refs;
      h.point = std::move(tp).value();
      h.chi2 = chi2;
      h.nll = chi2 + log_det;
      const int id = static_cast<int>(hyps_.size());
      for (const SpotRef& r : refs) hyps_of_spot_[static_cast<size_t>(Flat(r))].push_back(id);
      for (size_t x = 0; x < refs.size(); ++x) {
        for (size_t y = x + 1; y < refs.size(); ++y) {
          seen_pairs_.insert(PairKey(Flat(refs[x]), Flat(refs[y])));
        }
      }
      hyps_.push_back(std::move(h));
      return;
    }
  }

  // The strongest competitor of h: a live or contested hypothesis sharing a
  // detection with h, neither a subset of the other, with at least as many
  // views (most views, then lowest chi^2); -1 when none.
  int BestCompetitor(int h) const {
    const Hypothesis& H = hyps_[static_cast<size_t>(h)];
    int best = -1;
    for (const SpotRef& r : H.spots) {
      for (int c : hyps_of_spot_[static_cast<size_t>(Flat(r))]) {
        const Hypothesis& C = hyps_[static_cast<size_t>(c)];
        if (c == h || C.status == Hypothesis::kDead || C.spots.size() < H.spots.size()) continue;
        if (IsSubset(C.spots, H.spots) || IsSubset(H.spots, C.spots)) continue;
        if (best < 0 || Key(c) < Key(best)) best = c;
      }
    }
    return best;
  }
  static bool IsSubset(const std::vector<SpotRef>& a, const std::vector<SpotRef>& b) {
    for (const SpotRef& q : a) {
      if (!Contains(b, q)) return false;
    }
    return true;
  }

  std::vector<View>& views_;
  const SpotMatchOptions& options_;
  int min_views_;
  SpotMatchResult* result_;
  std::vector<int> offset_;
  std::vector<char> state_;
  std::vector<std::vector<int>> hyps_of_spot_;
  std::vector<Hypothesis> hyps_;
  std::set<std::vector<int>> known_;
  std::unordered_set<std::int64_t> seen_pairs_;
  double g2_ = 16.0, tau2_ = 0.0, tol2_ = 0.0;
};

}  // namespace

Status SpotMatchOptions::Validate() const {
  if (!(gate_sigmas > 0.0 && std::isfinite(gate_sigmas))) {
    return Status::InvalidArgument("SpotMatchOptions.gate_sigmas = " + FormatNumber(gate_sigmas) +
                                   ": must be positive and finite");
  }
  if (!(pose_tolerance_px >= 0.0 && std::isfinite(pose_tolerance_px))) {
    return Status::InvalidArgument("SpotMatchOptions.pose_tolerance_px = " +
                                   FormatNumber(pose_tolerance_px) +
                                   ": must be non-negative and finite");
  }
  if (min_views != 0 && min_views < 2) {
    return Status::InvalidArgument("SpotMatchOptions.min_views = " + std::to_string(min_views) +
                                   ": must be 0 (automatic) or at least 2");
  }
  if (!(min_triangulation_angle_deg >= 0.0 && min_triangulation_angle_deg < 90.0)) {
    return Status::InvalidArgument("SpotMatchOptions.min_triangulation_angle_deg = " +
                                   FormatNumber(min_triangulation_angle_deg) +
                                   ": must be in [0, 90)");
  }
  if (!(ambiguity_chi2 >= 0.0 && std::isfinite(ambiguity_chi2))) {
    return Status::InvalidArgument("SpotMatchOptions.ambiguity_chi2 = " +
                                   FormatNumber(ambiguity_chi2) +
                                   ": must be non-negative and finite");
  }
  if (!(grid_cell_px > 0.0 && std::isfinite(grid_cell_px))) {
    return Status::InvalidArgument("SpotMatchOptions.grid_cell_px = " +
                                   FormatNumber(grid_cell_px) + ": must be positive and finite");
  }
  return Status::Ok();
}

int SpotMatchResult::TracksWithViews(int n) const {
  int count = 0;
  for (const SpotTrack& t : tracks) count += t.num_views() == n ? 1 : 0;
  return count;
}

std::string SpotMatchResult::ToText() const {
  std::string s = std::to_string(tracks.size()) + " tracks (min_views " +
                  std::to_string(min_views) + "):";
  int most = 0;
  for (const SpotTrack& t : tracks) most = std::max(most, t.num_views());
  for (int n = most; n >= 2; --n) {
    s += " " + std::to_string(TracksWithViews(n)) + " with " + std::to_string(n) + " views";
    if (n > 2) s += ",";
  }
  s += "; rms reprojection " + FormatPrintf("%.4f", rms_reprojection_px) + " px\n";
  s += "unmatched per view:";
  for (size_t v = 0; v < unmatched.size(); ++v) s += " " + std::to_string(unmatched[v].size());
  s += "\n" + std::to_string(candidate_pairs) + " epipolar candidate pairs, " +
       std::to_string(hypotheses) + " hypotheses, " + std::to_string(rejected_geometry) +
       " rejected (behind a camera, narrow angle, no convergence), " +
       std::to_string(not_undistortable) + " detections not undistortable\n";
  s += std::to_string(ambiguities.size()) + " ambiguities";
  size_t blocked = 0;
  for (const SpotAmbiguity& a : ambiguities) blocked += a.blocked.size();
  s += " (" + std::to_string(blocked) + " detections left unmatched by them)";
  return s;
}

Result<SpotMatchResult> MatchSpots(const std::vector<Camera>& cameras,
                                   const std::vector<std::vector<SpotInView>>& spots_per_view,
                                   const SpotMatchOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (cameras.size() != spots_per_view.size()) {
    return Status::InvalidArgument("MatchSpots: " + std::to_string(cameras.size()) +
                                   " cameras but " + std::to_string(spots_per_view.size()) +
                                   " views of spots (spots_per_view): one camera per view");
  }
  const int nv = static_cast<int>(cameras.size());
  if (nv < 2) {
    return Status::InvalidArgument("MatchSpots: " + std::to_string(nv) +
                                   " view(s) given, at least 2 are needed");
  }
  if (options.min_views > nv) {
    return Status::InvalidArgument("SpotMatchOptions.min_views = " +
                                   std::to_string(options.min_views) +
                                   ": exceeds the number of views (" + std::to_string(nv) + ")");
  }
  const int min_views = options.min_views == 0 ? std::min(3, nv) : options.min_views;
  const double tau2 = std::pow(options.pose_tolerance_px / options.gate_sigmas, 2);

  SpotMatchResult result;
  result.min_views = min_views;
  std::vector<View> views(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    const Camera& cam = cameras[static_cast<size_t>(v)];
    const std::string where = "MatchSpots: view " + std::to_string(v);
    const Status camera_ok = cam.intrinsics.Validate();
    if (!camera_ok.ok()) return Status::InvalidArgument(where + ": " + camera_ok.message());
    if (!cam.cam_from_scene.rotation.coeffs().allFinite() ||
        !cam.cam_from_scene.translation.allFinite() ||
        !(cam.cam_from_scene.rotation.norm() > 0.0)) {
      return Status::InvalidArgument(where + ": camera pose (cam_from_scene) is not finite");
    }
    View& view = views[static_cast<size_t>(v)];
    view.camera = &cam;
    view.R = cam.cam_from_scene.RotationMatrix();
    view.t = cam.cam_from_scene.translation;
    view.center = cam.CenterInScene();
    view.packed = cam.intrinsics.Packed();
    view.focal = 0.5 * (cam.intrinsics.fx_px + cam.intrinsics.fy_px);
    const std::vector<SpotInView>& spots = spots_per_view[static_cast<size_t>(v)];
    const size_t n = spots.size();
    view.pixel.resize(n);
    view.ideal.resize(n);
    view.ray.resize(n);
    view.cov.resize(n);
    view.cov_ideal.resize(n);
    view.weight.resize(n);
    view.eff_weight.resize(n);
    view.usable.assign(n, 0);
    Jet2 packed[kNumCameraParameters];
    for (int k = 0; k < kNumCameraParameters; ++k) {
      packed[k] = Jet2(view.packed[static_cast<size_t>(k)]);
    }
    const double fx = cam.intrinsics.fx_px, fy = cam.intrinsics.fy_px;
    for (size_t s = 0; s < n; ++s) {
      const std::string spot_where = where + " spot " + std::to_string(s);
      const Eigen::Vector2d& px = spots[s].pixel_px;
      const Eigen::Matrix2d& S = spots[s].covariance_px2;
      if (!px.allFinite()) return Status::InvalidArgument(spot_where + ": pixel_px is not finite");
      if (!S.allFinite() || std::abs(S(0, 1) - S(1, 0)) > 1e-12 * S.cwiseAbs().maxCoeff() ||
          !(S(0, 0) > 0.0) || !(S.determinant() > 0.0)) {
        return Status::InvalidArgument(spot_where +
                                       ": covariance_px2 is not symmetric positive definite");
      }
      view.pixel[s] = px;
      view.cov[s] = S;
      view.weight[s] = S.inverse();
      view.eff_weight[s] = (S + tau2 * Eigen::Matrix2d::Identity()).inverse();
      const Result<Eigen::Vector2d> xy = UndistortPixel(cam.intrinsics, px);
      if (!xy.ok()) {
        ++result.not_undistortable;
        continue;
      }
      view.usable[s] = 1;
      view.ideal[s] = Eigen::Vector2d(fx * xy->x() + cam.intrinsics.cx_px,
                                      fy * xy->y() + cam.intrinsics.cy_px);
      view.ray[s] = (view.R.transpose() * Eigen::Vector3d(xy->x(), xy->y(), 1.0)).normalized();
      // Covariance in ideal pixels: J^-1 S J^-T, J = d(real)/d(ideal).
      Jet2 x(xy->x(), 0), y(xy->y(), 1), xd, yd;
      DistortNormalized(packed, x, y, &xd, &yd);
      Eigen::Matrix2d J;
      J << xd.v(0), xd.v(1) * fx / fy, yd.v(0) * fy / fx, yd.v(1);
      const Eigen::Matrix2d Jinv = J.inverse();
      view.cov_ideal[s] = Jinv * S * Jinv.transpose();
      if (!view.cov_ideal[s].allFinite()) {
        view.usable[s] = 0;
        ++result.not_undistortable;
        continue;
      }
    }
    {
      std::vector<double> real, ideal;
      for (size_t s = 0; s < view.pixel.size(); ++s) {
        if (!view.usable[s]) continue;
        real.push_back(LargestEigenvalue(view.cov[s]));
        ideal.push_back(LargestEigenvalue(view.cov_ideal[s]));
      }
      auto p90 = [](std::vector<double>* values) {
        if (values->empty()) return 0.0;
        const size_t k = (values->size() * 9) / 10;
        std::nth_element(values->begin(), values->begin() + static_cast<std::ptrdiff_t>(k), values->end());
        return (*values)[k];
      };
      view.search_var_real = p90(&real);
      view.search_var_ideal = p90(&ideal);
    }
    // The epipolar walk visits ~ line length / cell cells: coarser cells
    // there (a few detections each, tested by one dot product).
    view.grid_ideal.Build(view.ideal, view.usable, 4.0 * options.grid_cell_px);
    view.grid_real.Build(view.pixel, view.usable, options.grid_cell_px);
  }

  Matcher matcher(&views, options, min_views, &result);
  matcher.GenerateSeeds();
  matcher.Accept();
  result.hypotheses = matcher.num_hypotheses();

  std::sort(result.tracks.begin(), result.tracks.end(), [](const SpotTrack& a, const SpotTrack& b) {
    return std::make_pair(a.spots.front().view, a.spots.front().spot) <
           std::make_pair(b.spots.front().view, b.spots.front().spot);
  });
  double sum_sq = 0.0;
  int count = 0;
  for (const SpotTrack& t : result.tracks) {
    for (const Eigen::Vector2d& r : t.point.residuals_px) {
      sum_sq += r.squaredNorm();
      count += 2;
    }
  }
  result.rms_reprojection_px = count > 0 ? std::sqrt(sum_sq / count) : 0.0;
  result.unmatched.resize(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    for (int s = 0; s < static_cast<int>(views[static_cast<size_t>(v)].pixel.size()); ++s) {
      if (!matcher.IsUsed(v, s)) result.unmatched[static_cast<size_t>(v)].push_back(s);
    }
  }
  return result;
}

}  // namespace opl
