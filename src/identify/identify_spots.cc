#include "opl/identify/identify_spots.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <thread>
#include <tuple>

#include <Eigen/LU>

#include "opl/core/format.h"
#include "opl/geometry/rotation.h"
#include "opl/locate/locate_source.h"
#include "opl/locate/p3p.h"
#include "opl/locate/pose_normal_equations.h"

namespace opl {
namespace {

// The 8 symmetries of the square lattice, g = [[a, b], [c, d]] acting on
// (col, row) offsets: (a x + b y, c x + d y). The first four are rolls
// (0, 90, 180, 270 deg), the last four mirrors.
constexpr std::array<std::array<int, 4>, 8> kSymmetries = {{{1, 0, 0, 1},
                                                             {0, -1, 1, 0},
                                                             {-1, 0, 0, -1},
                                                             {0, 1, -1, 0},
                                                             {1, 0, 0, -1},
                                                             {-1, 0, 0, 1},
                                                             {0, 1, 1, 0},
                                                             {0, -1, -1, 0}}};

inline Eigen::Vector2i Apply(int g, const Eigen::Vector2i& o) {
  const auto& m = kSymmetries[g];
  return Eigen::Vector2i(m[0] * o.x() + m[1] * o.y(), m[2] * o.x() + m[3] * o.y());
}

// A pattern's lattice, and an affine model of it that extrapolates beyond the
// pattern: model coordinates c(q) = (atan(y/x), atan(z/x)) (exact for the
// equal-angle model) or (y, z) / |q| (direction cosines, exact for a
// grating), c = c0 + M (col, row). Whichever fits the beams better is used.
struct PatternIndex {
  const BeamPattern* pattern = nullptr;
  int n = 0;
  std::vector<char> exists;             // by node = id - 1 = row * n + col
  std::vector<Eigen::Vector3d> dir;     // by node, unit, source frame
  bool cosines = false;
  Eigen::Vector2d c0 = Eigen::Vector2d::Zero();
  Eigen::Matrix2d Minv = Eigen::Matrix2d::Identity();
  double spacing_rad = 0.0;  // median angle between lattice neighbours
  Eigen::Vector2i ref = Eigen::Vector2i::Zero();  // reference node (col, row) with +col, +row neighbours
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();  // unit, mean of the beams
  double cone_chord = 4.0;  // largest chord from `axis` to a beam
  // Minv's row sums of |.| times FastAtan's error bound are far below the
  // 1e-6 rounding margin (always for a usable lattice; checked).
  bool fast_margin_ok = false;
  double model_error = 0.0;     // worst |lattice position - node| at the beams, steps
  double min_x = 1.0;           // smallest X component of a beam direction
  double minv_norm_inf = 0.0;   // max row sum of |Minv|

  bool Has(int col, int row) const {
    return col >= 0 && row >= 0 && col < n && row < n && exists[row * n + col];
  }
  int Id(int col, int row) const { return row * n + col + 1; }
  const Eigen::Vector3d& Dir(int col, int row) const { return dir[row * n + col]; }

  static Eigen::Vector2d Coords(bool cos_model, const Eigen::Vector3d& q) {
    if (cos_model) return Eigen::Vector2d(q.y(), q.z()) / q.norm();
    return Eigen::Vector2d(std::atan2(q.y(), q.x()), std::atan2(q.z(), q.x()));
  }
  // Continuous (col, row) of a direction with q.x() > 0.
  Eigen::Vector2d Lattice(const Eigen::Vector3d& q) const { return Minv * (Coords(cosines, q) - c0); }

  // std::lround for |x| < 1e6, inline: x - trunc(x) is exact.
  static int RoundHalfAway(double x) {
    const int t = static_cast<int>(x);
    const double f = x - t;
    return f >= 0.5 ? t + 1 : (f <= -0.5 ? t - 1 : t);
  }

  // False only when every beam is farther than `gate` (chord) from the
  // direction of q (q.x() > 0), so that Nearest's angle is >= gate: the
  // chord is a metric, |u - d| >= |u - axis| - |d - axis|. The margin keeps
  // the test conservative under rounding.
  bool MayBeWithin(const Eigen::Vector3d& q, double gate) const {
    const double reach = cone_chord + gate + 1e-9;
    return (q - q.norm() * axis).squaredNorm() <= reach * reach * q.squaredNorm();
  }

  // atan(t) for |t| < 1e3, absolute error below 3e-10 (measured against
  // std::atan2 over 2e7 values: worst 2.3e-10, at |t| ~ 1e3): two half-angle
  // reductions, atan(t) = 2 atan(t / (1 + sqrt(1 + t^2))), leave
  // |b| < tan(pi / 8) = 0.415, then the alternating series to b^21
  // (truncation < 0.415^23 / 23 = 7e-11, times 4).
  static constexpr double kInvOdd[11] = {1.0,        1.0 / 3.0,  1.0 / 5.0,  1.0 / 7.0,
                                         1.0 / 9.0,  1.0 / 11.0, 1.0 / 13.0, 1.0 / 15.0,
                                         1.0 / 17.0, 1.0 / 19.0, 1.0 / 21.0};
  static double FastAtan(double t) {
    const double a = t / (1.0 + std::sqrt(1.0 + t * t));
    // |t| <= tan(pi / 8): one reduction already leaves |a| <= tan(pi / 16).
    if (std::abs(t) <= 0.41) {
      const double a2 = a * a;
      double p = kInvOdd[10];
      for (int k = 9; k >= 0; --k) p = kInvOdd[k] - a2 * p;
      return 2.0 * a * p;
    }
    const double b = a / (1.0 + std::sqrt(1.0 + a * a));
    const double b2 = b * b;
    double p = kInvOdd[10];
    for (int k = 9; k >= 0; --k) p = kInvOdd[k] - b2 * p;
    return 4.0 * b * p;
  }

  // The continuous lattice position of q (q.x() > 0) to within 1e-7 steps:
  // with FastAtan for the tangent model where that is accurate, else exact;
  // false when out of range (as Window).
  bool Position(const Eigen::Vector3d& q, Eigen::Vector2d* l) const {
    if (!cosines && fast_margin_ok) {
      const double inv_x = 1.0 / q.x();
      const double ty = q.y() * inv_x, tz = q.z() * inv_x;
      if (std::abs(ty) < 1e3 && std::abs(tz) < 1e3) {
        *l = Minv * (Eigen::Vector2d(FastAtan(ty), FastAtan(tz)) - c0);
        return std::abs(l->x()) < 1e5 && std::abs(l->y()) < 1e5;
      }
    }
    *l = Lattice(q);
    return std::abs(l->x()) < 1e5 && std::abs(l->y()) < 1e5;
  }

  // The 3 x 3 window of Nearest: the node (col, row) nearest the lattice
  // position of q (q.x() > 0), rounded half away from zero exactly as with
  // the atan2 model; false when the position is out of range. For the
  // tangent model the position is first computed with FastAtan; its error
  // (< 3e-10 rad, i.e. < 1e-7 lattice steps: fast_margin_ok) cannot
  // change the rounding unless the position lies within 1e-6 of a half
  // integer, and then the exact path is taken.
  bool Window(const Eigen::Vector3d& q, int* col, int* row) const {
    if (!cosines) {
      const double inv_x = 1.0 / q.x();
      const double ty = q.y() * inv_x, tz = q.z() * inv_x;
      if (std::abs(ty) < 1e3 && std::abs(tz) < 1e3) {
        const Eigen::Vector2d l = Minv * (Eigen::Vector2d(FastAtan(ty), FastAtan(tz)) - c0);
        if (std::abs(l.x()) < 1e5 && std::abs(l.y()) < 1e5 && fast_margin_ok) {
          const double fx = std::abs(l.x() - std::floor(l.x()) - 0.5);
          const double fy = std::abs(l.y() - std::floor(l.y()) - 0.5);
          if (fx > 1e-6 && fy > 1e-6) {
            *col = RoundHalfAway(l.x());
            *row = RoundHalfAway(l.y());
            return true;
          }
        }
      }
    }
    const Eigen::Vector2d l = Lattice(q);
    if (!(std::abs(l.x()) < 1e6 && std::abs(l.y()) < 1e6)) return false;
    *col = RoundHalfAway(l.x());
    *row = RoundHalfAway(l.y());
    return true;
  }

  // How far (in lattice steps, per component) the lattice position of a
  // direction can lie from a node whose beam is within `gate` (chord) of it:
  // the model's worst residual at the beams, plus the largest change of the
  // position along the chord. The model coordinates change by at most
  // chord / (min_x - gate) (tangent angles: |grad atan2(v_y, v_x)| =
  // 1 / |(v_x, v_y)| <= 1 / v_x, and v_x >= min_x - gate on the chord) or
  // by the chord (direction cosines), the position by |Minv|_inf times
  // that; 1e-6 covers the fast arctangent and rounding. Infinity when the
  // bound does not hold (gate >= min_x).
  double PositionReach(double gate) const {
    const double per_chord = cosines ? 1.0 : (min_x > gate ? 1.0 / (min_x - gate) : -1.0);
    if (per_chord < 0.0) return std::numeric_limits<double>::infinity();
    return model_error + minv_norm_inf * per_chord * gate + 1e-6;
  }

  // Nearest(q, &angle) >= 0 && angle < gate, without finding the nearest:
  // true as soon as one node of the same 3 x 3 window is within the gate
  // (sqrt is monotonic, so min sqrt(d2) < gate iff some sqrt(d2) < gate).
  // `reach` = PositionReach(gate): when below 1/2, only the rounded node
  // can be within the gate, and only when the position is within `reach` of
  // it in both components (the same answer, fewer nodes looked at).
  bool AnyWithin(const Eigen::Vector3d& q, double gate, double reach) const {
    if (reach < 0.5) {
      Eigen::Vector2d l;
      if (!Position(q, &l)) return false;
      const int c = RoundHalfAway(l.x()), r = RoundHalfAway(l.y());
      if (std::abs(l.x() - c) >= reach || std::abs(l.y() - r) >= reach || !Has(c, r)) return false;
      const double d2 = (q.normalized() - Dir(c, r)).squaredNorm();
      const double lo = gate * gate * (1.0 - 1e-12), hi = gate * gate * (1.0 + 1e-12);
      if (d2 < lo) return true;
      if (d2 > hi) return false;
      return std::sqrt(d2) < gate;
    }
    int c0i, r0i;
    if (!Window(q, &c0i, &r0i)) return false;
    const Eigen::Vector3d u = q.normalized();
    // sqrt(d2) < gate decided without the sqrt away from the boundary.
    const double lo = gate * gate * (1.0 - 1e-12), hi = gate * gate * (1.0 + 1e-12);
    auto within = [&](int c, int r) {
      if (!Has(c, r)) return false;
      const double d2 = (u - Dir(c, r)).squaredNorm();
      if (d2 < lo) return true;
      if (d2 > hi) return false;
      return std::sqrt(d2) < gate;
    };
    // The central node first (the likeliest), then the other eight.
    if (within(c0i, r0i)) return true;
    for (int r = r0i - 1; r <= r0i + 1; ++r) {
      for (int c = c0i - 1; c <= c0i + 1; ++c) {
        if ((r != r0i || c != c0i) && within(c, r)) return true;
      }
    }
    return false;
  }

  // Nearest(q, &angle) when that node is within `gate`, else -1 (angle
  // unset). `reach` = PositionReach(gate): when below 1/2 only the rounded
  // node can be within the gate (AnyWithin), and it is then the nearest of
  // the window (every other node is at least `gate` away).
  int NearestWithin(const Eigen::Vector3d& q, double gate, double reach, double* angle) const {
    if (reach < 0.5) {
      Eigen::Vector2d l;
      if (!Position(q, &l)) return -1;
      const int c = RoundHalfAway(l.x()), r = RoundHalfAway(l.y());
      if (std::abs(l.x() - c) >= reach || std::abs(l.y() - r) >= reach || !Has(c, r)) return -1;
      const double a = std::sqrt((q.normalized() - Dir(c, r)).squaredNorm());
      if (!(a < gate)) return -1;
      *angle = a;
      return r * n + c;
    }
    double a = 0.0;
    const int node = Nearest(q, &a);
    if (node < 0 || !(a < gate)) return -1;
    *angle = a;
    return node;
  }

  // Nearest beam to the direction of q (q.x() > 0) among the 3 x 3 nodes
  // around its lattice position; returns the node index (-1 when none) and
  // the angle (chord of unit vectors, ~ the angle for small angles).
  int Nearest(const Eigen::Vector3d& q, double* angle) const {
    int c0i, r0i;
    if (!Window(q, &c0i, &r0i)) return -1;
    const Eigen::Vector3d u = q.normalized();
    int best = -1;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (int r = r0i - 1; r <= r0i + 1; ++r) {
      for (int c = c0i - 1; c <= c0i + 1; ++c) {
        if (!Has(c, r)) continue;
        const double d2 = (u - Dir(c, r)).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best = r * n + c;
        }
      }
    }
    *angle = std::sqrt(best_d2);
    return best;
  }
};

PatternIndex BuildIndex(const BeamPattern& pattern) {
  PatternIndex index;
  index.pattern = &pattern;
  const int n = pattern.beams_per_side();
  index.n = n;
  index.exists.assign(static_cast<size_t>(n) * n, 0);
  index.dir.assign(static_cast<size_t>(n) * n, Eigen::Vector3d::UnitX());
  for (const Beam& b : pattern.beams()) {
    index.exists[b.id - 1] = 1;
    index.dir[b.id - 1] = pattern.DirectionInSource(b.id);
  }
  // Affine fits of both models; keep the one with the smaller worst residual
  // (in lattice steps).
  double best_worst = std::numeric_limits<double>::infinity();
  for (int model = 0; model < 2; ++model) {
    const bool cos_model = model == 1;
    const int m = static_cast<int>(pattern.beams().size());
    Eigen::MatrixXd A(m, 3);
    Eigen::MatrixXd B(m, 2);
    for (int i = 0; i < m; ++i) {
      const Beam& b = pattern.beams()[i];
      A(i, 0) = 1.0;
      A(i, 1) = BeamCol(b.id, n);
      A(i, 2) = BeamRow(b.id, n);
      B.row(i) = PatternIndex::Coords(cos_model, index.dir[b.id - 1]).transpose();
    }
    const Eigen::MatrixXd X = (A.transpose() * A).ldlt().solve(A.transpose() * B);  // 3 x 2
    Eigen::Matrix2d M;
    M << X(1, 0), X(2, 0), X(1, 1), X(2, 1);
    if (!(std::abs(M.determinant()) > 0.0) || !X.allFinite()) continue;
    const Eigen::Matrix2d Minv = M.inverse();
    const Eigen::Vector2d c0(X(0, 0), X(0, 1));
    double worst = 0.0;
    for (int i = 0; i < m; ++i) {
      const Eigen::Vector2d l = Minv * (B.row(i).transpose() - c0);
      worst = std::max(worst, (l - A.row(i).tail<2>().transpose()).cwiseAbs().maxCoeff());
    }
    if (worst < best_worst) {
      best_worst = worst;
      index.model_error = worst;
      index.cosines = cos_model;
      index.c0 = c0;
      index.Minv = Minv;
    }
  }
  {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const Beam& b : pattern.beams()) sum += index.dir[b.id - 1];
    if (sum.norm() > 0.0) {
      index.axis = sum.normalized();
      double reach = 0.0;
      for (const Beam& b : pattern.beams()) reach = std::max(reach, (index.dir[b.id - 1] - index.axis).norm());
      index.cone_chord = reach;
    }
  }
  index.fast_margin_ok = index.Minv.cwiseAbs().rowwise().sum().maxCoeff() * 3e-10 < 1e-7;
  index.minv_norm_inf = index.Minv.cwiseAbs().rowwise().sum().maxCoeff();
  for (const Beam& b : pattern.beams()) index.min_x = std::min(index.min_x, index.dir[b.id - 1].x());
  // Spacing: median angle between lattice neighbours.
  std::vector<double> angles;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      if (!index.Has(c, r)) continue;
      if (index.Has(c + 1, r)) angles.push_back((index.Dir(c, r) - index.Dir(c + 1, r)).norm());
      if (index.Has(c, r + 1)) angles.push_back((index.Dir(c, r) - index.Dir(c, r + 1)).norm());
    }
  }
  if (!angles.empty()) {
    std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
    index.spacing_rad = angles[angles.size() / 2];
  }
  // Reference node: the one nearest the centre with both +col and +row
  // neighbours.
  const int m = (n - 1) / 2;
  int best_d = std::numeric_limits<int>::max();
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      if (!index.Has(c, r) || !index.Has(c + 1, r) || !index.Has(c, r + 1)) continue;
      const int d = std::abs(c - m) + std::abs(r - m);
      if (d < best_d) {
        best_d = d;
        index.ref = Eigen::Vector2i(c, r);
      }
    }
  }
  if (best_d == std::numeric_limits<int>::max()) index.spacing_rad = 0.0;  // no usable lattice
  return index;
}

// The points to identify.
struct Pool {
  std::vector<Eigen::Vector3d> p;   // scene
  std::vector<int> spot;            // input index
  std::vector<int> only_source;     // -1: any source
  std::vector<char> taken;          // assigned to a found source
  std::vector<char> blocked;        // not to be used as a seed point any more
  int size() const { return static_cast<int>(p.size()); }
};

struct Seed {
  int p0 = 0, pa = 0, pb = 0;
  double quality = 0.0;  // smaller is better
  // The seed's lattice patch: points and their (col, row) offsets from p0
  // along (a, b): p0, p0 +- a, p0 +- b and the supported p0 +- a +- b,
  // p0 +- 2a, p0 +- 2b.
  std::vector<std::pair<int, Eigen::Vector2i>> patch;
};

// Seeds: points with two pairs of opposite neighbours (a local lattice cross).
// Every point's seed depends on the pool only, so the points are split into
// `threads` contiguous ranges worked in parallel; the seeds are merged in
// point order, so the result does not depend on the number of threads.
std::vector<Seed> FindSeeds(const Pool& pool, int k, int threads) {
  const int n = pool.size();
  std::vector<Seed> seeds;
  if (n < 5) return seeds;
  k = std::min(k, n - 1);

  // The k nearest neighbours of every point, by a sweep along the axis of
  // the largest extent: the points sorted along it, each point's search
  // runs outwards in that order and stops on a side once the coordinate gap
  // alone exceeds the k-th smallest squared distance found.
  int sweep_axis = 0;
  {
    Eigen::Vector3d lo = pool.p[0], hi = pool.p[0];
    for (const Eigen::Vector3d& p : pool.p) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    (hi - lo).maxCoeff(&sweep_axis);
  }
  std::vector<int> order(n), rank(n);
  for (int i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const double xa = pool.p[a][sweep_axis], xb = pool.p[b][sweep_axis];
    return xa < xb || (xa == xb && a < b);
  });
  for (int r = 0; r < n; ++r) rank[order[r]] = r;
  struct Axis {
    int plus, minus;
    Eigen::Vector3d a;      // half the step from minus to plus
    Eigen::Vector3d bend;   // (plus + minus) / 2 - p0: the second-order term
    double err;
    double norm;
  };
  auto seeds_of_range = [&](int i_begin, int i_end, std::vector<Seed>* out) {
  std::vector<int> nb(k);
  std::vector<Eigen::Vector3d> nbp(k);  // the neighbours' points, contiguous
  std::vector<double> nbd(k);           // their distances, ascending
  std::vector<Axis> axes;
  // The k smallest (squared distance, index) pairs so far, ascending (an
  // insertion-sorted array: k is small).
  std::vector<std::pair<double, int>> knn(k);
  for (int i = i_begin; i < i_end; ++i) {
    // The keys are unique, so the result is exactly the k first of all pairs
    // sorted.
    int size = 0;
    const Eigen::Vector3d pi0 = pool.p[i];
    const double xi = pi0[sweep_axis];
    auto visit = [&](int j) {
      const std::pair<double, int> key((pool.p[j] - pi0).squaredNorm(), j);
      if (size == k && !(key < knn[k - 1])) return;
      int pos = size < k ? size++ : k - 1;
      while (pos > 0 && key < knn[pos - 1]) {
        knn[pos] = knn[pos - 1];
        --pos;
      }
      knn[pos] = key;
    };
    // A side is done when its next point's gap squared exceeds the k-th
    // smallest so far (every later point on it is at least as far).
    auto done = [&](int j) {
      if (size < k) return false;
      const double gap = pool.p[j][sweep_axis] - xi;
      return gap * gap > knn[k - 1].first;
    };
    int down = rank[i] - 1, up = rank[i] + 1;
    while (down >= 0 || up < n) {
      if (down >= 0) {
        if (done(order[down])) {
          down = -1;
        } else {
          visit(order[down--]);
        }
      }
      if (up < n) {
        if (done(order[up])) {
          up = n;
        } else {
          visit(order[up++]);
        }
      }
    }
    for (int j = 0; j < k; ++j) nb[j] = knn[j].second;
    for (int j = 0; j < k; ++j) nbp[j] = pool.p[nb[j]];
    for (int j = 0; j < k; ++j) nbd[j] = std::sqrt(knn[j].first);
    const Eigen::Vector3d pi = pool.p[i];
    const double nearest = std::sqrt(knn[0].first);
    axes.clear();
    for (int a = 0; a < k; ++a) {
      const Eigen::Vector3d va = pool.p[nb[a]] - pool.p[i];
      const double la = va.norm();
      for (int b = a + 1; b < k; ++b) {
        const Eigen::Vector3d vb = pool.p[nb[b]] - pool.p[i];
        const double lb = vb.norm();
        const double lmax = std::max(la, lb);
        // The neighbours come by ascending distance (la <= lb): once b is
        // twice as far as a, every later b is too.
        if (std::min(la, lb) < 0.5 * lmax) break;
        const double err = (va + vb).norm() / lmax;
        if (err > 0.35) continue;
        axes.push_back({nb[a], nb[b], 0.5 * (va - vb), 0.5 * (va + vb), err, 0.0});
      }
    }
    double best = std::numeric_limits<double>::infinity();
    Seed seed;
    for (Axis& x : axes) x.norm = x.a.norm();
    for (size_t a = 0; a < axes.size(); ++a) {
      for (size_t b = a + 1; b < axes.size(); ++b) {
        const double na = axes[a].norm, nbn = axes[b].norm;
        // Prefer crosses with the most lattice support, then short and
        // regular ones (the true lattice steps are the shortest axes):
        // q = -support + shape. The support is at most 8, so a cross whose
        // -8 + shape is not below the best q cannot win (rounding is
        // monotonic: fl(-8 + shape) <= fl(-support + shape)).
        const double shape = 0.5 * (na + nbn) / nearest * (1.0 + axes[a].err + axes[b].err);
        if (!(-8 + shape < best)) continue;
        const double c = axes[a].a.dot(axes[b].a) / (na * nbn);
        if (std::abs(c) > 0.8) continue;
        // Lattice support: how many of the 8 further nodes p0 +- a +- b,
        // p0 +- 2a, p0 +- 2b hold a point (within 20% of the shorter step).
        // The nodes are predicted to second order along each axis,
        // x(i, j) = i a + j b + i^2 ea + j^2 eb (ea, eb: the axes' bends),
        // which follows a smoothly curved or foreshortened grid and does
        // not support a cross that mixes two interleaved grids (its bend
        // alternates in sign from node to node: p0 +- 2a lie 4 ea away).
        const Eigen::Vector3d& va = axes[a].a;
        const Eigen::Vector3d& vb = axes[b].a;
        const Eigen::Vector3d eab = axes[a].bend + axes[b].bend;
        const std::array<Eigen::Vector3d, 8> predicted = {
            va + vb + eab,  va - vb + eab,  -va + vb + eab, -va - vb + eab, 2.0 * va + 4.0 * axes[a].bend,
            -2.0 * va + 4.0 * axes[a].bend, 2.0 * vb + 4.0 * axes[b].bend, -2.0 * vb + 4.0 * axes[b].bend};
        const double tol2 = 0.04 * std::min(na, nbn) * std::min(na, nbn);
        static const std::array<Eigen::Vector2i, 8> kOffsets = {
            Eigen::Vector2i(1, 1),  Eigen::Vector2i(1, -1), Eigen::Vector2i(-1, 1), Eigen::Vector2i(-1, -1),
            Eigen::Vector2i(2, 0),  Eigen::Vector2i(-2, 0), Eigen::Vector2i(0, 2),  Eigen::Vector2i(0, -2)};
        int support = 0;
        std::array<int, 8> found;
        bool hopeless = false;
        for (int o = 0; o < 8; ++o) {
          // Even with every remaining node supported, q would not be below
          // the best: this cross cannot win (monotonic rounding as above).
          if (!(-(support + 8 - o) + shape < best)) {
            hopeless = true;
            break;
          }
          const Eigen::Vector3d target = pi + predicted[o];
          found[o] = -1;
          // A neighbour within tol of the target is within tol of its
          // distance (triangle inequality): only those are scanned, in the
          // same order (the margin covers rounding).
          const double dt = predicted[o].norm();
          const double tol = std::sqrt(tol2) * (1.0 + 1e-9) + 1e-12 * dt;
          const int j0 = static_cast<int>(std::lower_bound(nbd.begin(), nbd.end(), dt - tol) - nbd.begin());
          for (int j = j0; j < k && nbd[j] <= dt + tol; ++j) {
            if ((nbp[j] - target).squaredNorm() < tol2) {
              ++support;
              found[o] = nb[j];
              break;
            }
          }
        }
        if (hopeless) continue;
        const double q = -support + shape;
        if (q < best) {
          best = q;
          seed.p0 = i;
          seed.pa = axes[a].plus;
          seed.pb = axes[b].plus;
          seed.quality = q;
          seed.patch = {{i, Eigen::Vector2i(0, 0)},
                        {axes[a].plus, Eigen::Vector2i(1, 0)},
                        {axes[a].minus, Eigen::Vector2i(-1, 0)},
                        {axes[b].plus, Eigen::Vector2i(0, 1)},
                        {axes[b].minus, Eigen::Vector2i(0, -1)}};
          for (int o = 0; o < 8; ++o) {
            if (found[o] >= 0) seed.patch.push_back({found[o], kOffsets[o]});
          }
        }
      }
    }
    if (std::isfinite(best)) out->push_back(seed);
  }
  };
  threads = std::clamp(threads, 1, std::max(1, n / 64));
  if (threads == 1) {
    seeds_of_range(0, n, &seeds);
  } else {
    std::vector<std::vector<Seed>> parts(static_cast<size_t>(threads));
    std::vector<std::thread> pool_threads;
    for (int t = 1; t < threads; ++t) {
      pool_threads.emplace_back(seeds_of_range, n * t / threads, n * (t + 1) / threads,
                                &parts[static_cast<size_t>(t)]);
    }
    seeds_of_range(0, n / threads, &parts[0]);
    for (std::thread& th : pool_threads) th.join();
    for (std::vector<Seed>& part : parts) {
      for (Seed& seed : part) seeds.push_back(std::move(seed));
    }
  }
  std::stable_sort(seeds.begin(), seeds.end(),
                   [](const Seed& a, const Seed& b) { return a.quality < b.quality; });
  return seeds;
}

// The crosses derived from a seed whose own cross may mix two interleaved
// grids: with the cross's steps a, b, the crosses (2a, b), (a, 2b) and
// (a + b, a - b), each with the seed's patch points that fall on its
// lattice (offsets re-expressed in the new steps). Two grids of one pattern
// translated by about half a pitch along a (the prototype's side-by-side
// sources on a wall) make a point set whose shortest crosses alternate
// between the grids along a; (2a, b) is then a cross of one grid. A
// translation by half a pitch along both steps makes a centred lattice whose
// shortest crosses run along the diagonals of the grids; (a + b, a - b) is
// then a cross of one grid. Crosses without their two step points, or with
// fewer than 6 patch points, are left out.
std::vector<Seed> DerivedSeeds(const Seed& seed) {
  // New steps (a', b') in the seed's offsets: a' = (m[0], m[1]), b' = (m[2], m[3]).
  static constexpr std::array<std::array<int, 4>, 3> kSteps = {{{2, 0, 0, 1}, {1, 0, 0, 2}, {1, 1, 1, -1}}};
  std::vector<Seed> out;
  for (const auto& m : kSteps) {
    const int det = m[0] * m[3] - m[2] * m[1];
    Seed d;
    d.p0 = seed.p0;
    d.pa = -1;
    d.pb = -1;
    d.quality = seed.quality;
    for (const auto& [i, o] : seed.patch) {
      // o = x a' + y b': (x, y) = adj(m) o / det, kept when integral.
      const int nx = m[3] * o.x() - m[2] * o.y(), ny = -m[1] * o.x() + m[0] * o.y();
      if (nx % det != 0 || ny % det != 0) continue;
      const Eigen::Vector2i l(nx / det, ny / det);
      if (l == Eigen::Vector2i(1, 0)) d.pa = i;
      if (l == Eigen::Vector2i(0, 1)) d.pb = i;
      d.patch.push_back({i, l});
    }
    if (d.pa >= 0 && d.pb >= 0 && d.patch.size() >= 6) out.push_back(std::move(d));
  }
  return out;
}

// One refined explanation of some points by one source.
struct Detection {
  int source = -1;
  Rigid3d scene_from_source;
  double sigma = 0.0;  // robust per-component angular noise, rad
  std::vector<int> point;   // pool indices
  std::vector<int> beam;    // beam ids, parallel
  std::vector<double> residual;  // angles, rad, parallel
  double cost = 0.0;        // truncated chi^2 over the pool (set by the caller)
  int conflicts = 0;
};

struct Candidate {
  int source = -1;
  PoseRt pose;  // source_from_scene
  int score = 0;
  // Lattice node (col, row) of the seed point; refinement grows from it when
  // `grow` (a pose from three neighbouring spots is right only near them).
  Eigen::Vector2i node = Eigen::Vector2i::Zero();
  bool grow = false;
};

class Identifier {
 public:
  Identifier(const ModuleCalibration& calibration, const IdentifyOptions& options, Pool* pool,
             const std::vector<std::vector<char>>& beam_reserved)
      : calibration_(calibration), options_(options), pool_(*pool), reserved_(beam_reserved) {
    for (const SourceCalibration& s : calibration.sources) index_.push_back(BuildIndex(s.pattern));
  }

  const PatternIndex& index(int s) const { return index_[s]; }

  bool Eligible(int i, int s) const {
    return !pool_.taken[i] && (pool_.only_source[i] < 0 || pool_.only_source[i] == s);
  }

  // A hypothesis of step 2: the seed point at lattice node L0 of source s,
  // its patch's offsets mapped by symmetry g; `count` estimates how many
  // points it explains (the histogram).
  struct Hypothesis {
    int source, g;
    Eigen::Vector2i L0;
    int count;
  };

  // The hypotheses of source s from a seed (header comment, step 2): for each
  // symmetry g, up to 6 nodes L0 with the highest histogram counts (at least
  // min_spots), appended to `out`.
  void Hypotheses(int s, const Seed& seed, std::vector<Hypothesis>* out) const {
    const PatternIndex& idx = index_[s];
    if (idx.spacing_rad <= 0.0) return;
    const int n = idx.n;
    const std::array<Eigen::Vector3d, 3> X = {pool_.p[seed.p0], pool_.p[seed.pa], pool_.p[seed.pb]};
    const Eigen::Vector2i L = idx.ref;
    const std::array<Eigen::Vector3d, 3> f = {idx.Dir(L.x(), L.y()), idx.Dir(L.x() + 1, L.y()),
                                              idx.Dir(L.x(), L.y() + 1)};
    std::array<PoseRt, 4> roots;
    int num_roots = SolveP3P(f, X, &roots);
    if (PatchPose(s, seed, L, 0, BestOnPatch(s, seed, L, 0, roots, num_roots), &roots[0])) num_roots = 1;
    using Hist = Hypothesis;
    std::vector<Hist>& hist = *out;
    std::vector<Eigen::Vector2i> offsets;
    std::vector<int> diff(static_cast<size_t>(n + 1) * (n + 1));
    for (int root = 0; root < num_roots; ++root) {
      const PoseRt& P = roots[root];
      if (!P.R.allFinite() || !P.t.allFinite()) continue;
      offsets.clear();
      for (int i = 0; i < pool_.size(); ++i) {
        if (!Eligible(i, s)) continue;
        const Eigen::Vector3d q = P.R * pool_.p[i] + P.t;
        if (!(q.x() > 0.0)) continue;
        const Eigen::Vector2d d = idx.Lattice(q) - L.cast<double>();
        const Eigen::Vector2d rd = d.array().round();
        if ((d - rd).cwiseAbs().maxCoeff() > 0.3 || rd.cwiseAbs().maxCoeff() > 2 * n) continue;
        offsets.push_back(rd.cast<int>());
      }
      for (int g = 0; g < 8; ++g) {
        std::fill(diff.begin(), diff.end(), 0);
        for (const Eigen::Vector2i& o : offsets) {
          const Eigen::Vector2i go = Apply(g, o);
          const int c_lo = std::max(0, -go.x()), c_hi = std::min(n - 1, n - 1 - go.x());
          const int r_lo = std::max(0, -go.y()), r_hi = std::min(n - 1, n - 1 - go.y());
          if (c_lo > c_hi || r_lo > r_hi) continue;
          diff[r_lo * (n + 1) + c_lo] += 1;
          diff[r_lo * (n + 1) + c_hi + 1] -= 1;
          diff[(r_hi + 1) * (n + 1) + c_lo] -= 1;
          diff[(r_hi + 1) * (n + 1) + c_hi + 1] += 1;
        }
        // Prefix sums in place; count at (c, r) = inclusive sum.
        for (int r = 0; r < n; ++r) {
          for (int c = 0; c < n; ++c) {
            int v = diff[r * (n + 1) + c];
            if (r > 0) v += diff[(r - 1) * (n + 1) + c];
            if (c > 0) v += diff[r * (n + 1) + c - 1];
            if (r > 0 && c > 0) v -= diff[(r - 1) * (n + 1) + c - 1];
            diff[r * (n + 1) + c] = v;
          }
        }
        // The best nodes of this (root, g): up to 6.
        std::array<Hist, 6> top;
        for (auto& t : top) t.count = -1;
        for (int r = 0; r < n; ++r) {
          for (int c = 0; c < n; ++c) {
            const int v = diff[r * (n + 1) + c];
            if (v <= top[5].count) continue;
            if (!idx.Has(c, r)) continue;
            Hist h{s, g, Eigen::Vector2i(c, r), v};
            int k = 5;
            while (k > 0 && top[k - 1].count < v) {
              top[k] = top[k - 1];
              --k;
            }
            top[k] = h;
          }
        }
        for (const auto& t : top) {
          if (t.count >= options_.min_spots) hist.push_back(t);
        }
      }
    }
  }

  // Candidate poses from the hypotheses of every source (header comment,
  // step 2), checked exactly in the order of their counts (the sources'
  // lists merged): per source, those with at least half its highest count,
  // at most 48. The counts estimate the exact scores (from above when other
  // grids overlap): once the best pose so far scores as many points as the
  // next count, or as that source's pattern has beams, the rest are not
  // expected to do better, and `clear` is asked whether it settles the seed
  // (a clear refinement; a symmetric or cross-source rival is examined in
  // step 4 regardless). When it does, the check stops there.
  template <typename ClearFn>
  void Candidates(const Seed& seed, std::vector<Hypothesis> hyps, std::vector<Candidate>* out,
                  ClearFn&& clear) const {
    if (hyps.empty()) return;
    std::stable_sort(hyps.begin(), hyps.end(),
                     [](const Hypothesis& a, const Hypothesis& b) { return a.count > b.count; });
    const int num_sources = static_cast<int>(index_.size());
    std::vector<int> max_count(num_sources, -1), checked(num_sources, 0);
    std::vector<Eigen::Matrix3Xd> eligible(num_sources);
    for (const Hypothesis& h : hyps) max_count[h.source] = std::max(max_count[h.source], h.count);
    const std::array<Eigen::Vector3d, 3> X = {pool_.p[seed.p0], pool_.p[seed.pa], pool_.p[seed.pb]};
    int best_score = -1, stop_tried = -1;
    size_t best = 0;  // index in `out` of the best-scoring candidate
    std::vector<std::tuple<int, Eigen::Vector2i, int>> seen;  // (source, L0, g) verified
    for (const Hypothesis& h : hyps) {
      const int s = h.source;
      const PatternIndex& idx = index_[s];
      const int num_beams = static_cast<int>(idx.pattern->beams().size());
      if (best_score >= std::min(h.count, num_beams) && best_score > stop_tried) {
        stop_tried = best_score;
        if (clear(out->at(best))) return;
      }
      if (h.count < 0.5 * max_count[s] || checked[s] >= 48) continue;
      bool dup = false;
      for (const auto& sv : seen) dup |= (std::get<0>(sv) == s && std::get<1>(sv) == h.L0 && std::get<2>(sv) == h.g);
      if (dup) continue;
      seen.emplace_back(s, h.L0, h.g);
      const Eigen::Vector2i e1 = Apply(h.g, Eigen::Vector2i(1, 0)), e2 = Apply(h.g, Eigen::Vector2i(0, 1));
      const Eigen::Vector2i A = h.L0 + e1, B = h.L0 + e2;
      if (!idx.Has(A.x(), A.y()) || !idx.Has(B.x(), B.y())) continue;
      ++checked[s];
      if (eligible[s].cols() == 0) {
        eligible[s].resize(3, pool_.size());
        Eigen::Index m = 0;
        for (int i = 0; i < pool_.size(); ++i) {
          if (Eligible(i, s)) eligible[s].col(m++) = pool_.p[i];
        }
        eligible[s].conservativeResize(3, m);
      }
      const double gate = options_.score_gate_fraction * idx.spacing_rad +
                          (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
      const std::array<Eigen::Vector3d, 3> fb = {idx.Dir(h.L0.x(), h.L0.y()), idx.Dir(A.x(), A.y()),
                                                 idx.Dir(B.x(), B.y())};
      std::array<PoseRt, 4> poses;
      int np = SolveP3P(fb, X, &poses);
      if (PatchPose(s, seed, h.L0, h.g, BestOnPatch(s, seed, h.L0, h.g, poses, np), &poses[0])) np = 1;
      for (int k = 0; k < np; ++k) {
        if (!poses[k].R.allFinite() || !poses[k].t.allFinite()) continue;
        const int score = Score(s, poses[k], gate, eligible[s]);
        if (score >= options_.min_spots) {
          if (score > best_score) best = out->size();
          out->push_back({s, poses[k], score, h.L0, true});
        }
        best_score = std::max(best_score, score);
      }
    }
  }

  // Of the P3P poses of the seed's cross, the one that puts the most patch
  // points near their beams L0 + g offset (chord below kGuessGateSpacings
  // spacings), when it puts at least 90% of them there: a pose to start
  // PatchPose from. nullptr when none does.
  static constexpr double kGuessGateSpacings = 0.25;
  const PoseRt* BestOnPatch(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                            const std::array<PoseRt, 4>& poses, int num_poses) const {
    const PatternIndex& idx = index_[s];
    const double gate = kGuessGateSpacings * idx.spacing_rad;
    const PoseRt* best = nullptr;
    int best_count = -1, used = 0;
    for (int k = 0; k < num_poses; ++k) {
      const PoseRt& P = poses[k];
      if (!P.R.allFinite() || !P.t.allFinite()) continue;
      int count = 0;
      used = 0;
      for (const auto& [i, o] : seed.patch) {
        const Eigen::Vector2i l = L0 + Apply(g, o);
        if (!idx.Has(l.x(), l.y()) || !Eligible(i, s)) continue;
        ++used;
        const Eigen::Vector3d q = P.R * pool_.p[i] + P.t;
        if (q.x() > 0.0 && (q.normalized() - idx.Dir(l.x(), l.y())).squaredNorm() < gate * gate) ++count;
      }
      if (count > best_count) {
        best_count = count;
        best = &P;
      }
    }
    return best != nullptr && best_count >= 0.9 * used ? best : nullptr;
  }

  // The pose of source s that maps the seed's patch onto the beams
  // L0 + g offset; false when it fails. From `guess` (BestOnPatch): a
  // least-squares fit of the patch's points that fit the guess within its
  // gate (FitPatch). Without a guess: LocateSource over the patch (RANSAC).
  bool PatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g, const PoseRt* guess,
                 PoseRt* pose) const {
    const PatternIndex& idx = index_[s];
    std::vector<SpotObservation> obs;
    for (const auto& [i, o] : seed.patch) {
      const Eigen::Vector2i l = L0 + Apply(g, o);
      if (!idx.Has(l.x(), l.y()) || !Eligible(i, s)) continue;
      SpotObservation so;
      so.beam_id = idx.Id(l.x(), l.y());
      so.point_in_scene = pool_.p[i];
      obs.push_back(so);
    }
    if (obs.size() < 6) return false;
    if (guess != nullptr) return FitPatch(idx, obs, *guess, pose);
    LocateOptions lo;
    lo.ransac_seed = options_.seed;
    // The patch's points are nearly all inliers when the hypothesis is
    // right: a few minimal samples suffice; a wrong one fails fast.
    lo.ransac_max_iterations = 20;
    // The pose only has to place the spots to a fraction of the spacing
    // (Score's gate; Refine solves again): 1e-5 of the range is plenty.
    lo.parameter_tolerance = 1e-5;
    lo.ransac_inlier_threshold_rad = 0.05 * idx.spacing_rad;
    auto located = LocateSource(*idx.pattern, obs, lo);
    if (!located.ok()) return false;
    const Eigen::Matrix3d R = located->scene_from_source.RotationMatrix();
    pose->R = R.transpose();
    pose->t = -(R.transpose() * located->scene_from_source.translation);
    return true;
  }

  // Least squares of the angle residuals (PoseNormalEquations, unweighted)
  // over the observations within the guess gate of `guess`; then, as
  // LocateSource does, the observations beyond 5 robust sigmas of the fitted
  // pose are left out and the fit repeated until that set is stable (at most
  // 6 fits). The pose only places spots to a fraction of the spacing for
  // Score and seeds Refine, which solves again: a step below 1e-5 of the
  // range ends each solve. False when fewer than 6 observations, or under
  // half of them, remain, or a solve fails.
  bool FitPatch(const PatternIndex& idx, const std::vector<SpotObservation>& obs, const PoseRt& guess,
                PoseRt* pose) const {
    Eigen::Matrix3d R = guess.R.transpose();  // scene_from_source
    Eigen::Vector3d t = -(R * guess.t);
    const int m = static_cast<int>(obs.size());
    std::vector<char> use(m), next(m);
    std::vector<double> chord(m);
    auto chords = [&]() {
      const Eigen::Matrix3d Rt = R.transpose();
      for (int k = 0; k < m; ++k) {
        const Eigen::Vector3d q = Rt * (obs[k].point_in_scene - t);
        chord[k] = q.x() > 0.0 ? (q.normalized() - idx.pattern->DirectionInSource(obs[k].beam_id)).norm()
                               : std::numeric_limits<double>::infinity();
      }
    };
    chords();
    const double guess_gate = kGuessGateSpacings * idx.spacing_rad;
    for (int k = 0; k < m; ++k) use[k] = chord[k] < guess_gate;
    std::vector<double> inlier;
    for (int round = 0; round < 6; ++round) {
      int used = 0;
      double D = 0.0;
      for (int k = 0; k < m; ++k) {
        if (use[k]) ++used, D += (obs[k].point_in_scene - t).norm();
      }
      if (used < 6 || 2 * used < m) return false;
      D /= used;
      const Eigen::Vector3d offset(D, 0.0, 0.0);
      patch_problem_.Reset(R, t - offset, D);
      for (int k = 0; k < m; ++k) {
        if (!use[k]) continue;
        patch_problem_.AddSpot(obs[k].point_in_scene,
                               BeamAngles::FromDirection(idx.pattern->DirectionInSource(obs[k].beam_id)),
                               Eigen::Matrix2d::Identity());
      }
      Eigen::Matrix<double, 6, 1> x;
      x << 0.0, 0.0, 0.0, offset;
      PoseSolverOptions so;
      so.max_num_iterations = 20;
      so.function_tolerance = std::numeric_limits<double>::min();  // step test only
      so.parameter_tolerance = 1e-5;
      so.cost_threshold = 0.0;
      so.initial_trust_region_radius = 1e12;  // close to Gauss-Newton (as LocateSource)
      const PoseSolverSummary summary = SolvePoseLevenbergMarquardt(patch_problem_, so, &x);
      if (summary.evaluation_failed || !x.allFinite() || !std::isfinite(summary.final_cost)) return false;
      R = patch_problem_.Rotation(x.data());
      t = patch_problem_.Origin(x.data());
      // Outliers as LocateSource flags them: beyond 5 robust sigmas (the
      // median chord of a 2D Gaussian is 1.1774 sigma).
      chords();
      inlier.clear();
      for (int k = 0; k < m; ++k) {
        if (use[k]) inlier.push_back(chord[k]);
      }
      std::nth_element(inlier.begin(), inlier.begin() + inlier.size() / 2, inlier.end());
      const double gate = std::max(5.0 * inlier[inlier.size() / 2] / 1.1774100225154747, 1e-7);
      for (int k = 0; k < m; ++k) next[k] = chord[k] <= gate;
      if (next == use) break;
      use = next;
    }
    pose->R = R.transpose();
    pose->t = -(R.transpose() * t);
    return pose->R.allFinite() && pose->t.allFinite();
  }

  // Points of source s whose nearest beam under `pose` is within `gate`.
  // `points`: the points eligible for s (3 x m).
  int Score(int s, const PoseRt& pose, double gate, const Eigen::Matrix3Xd& points) const {
    const PatternIndex& idx = index_[s];
    int count = 0;
    const double reach = idx.PositionReach(gate);
    const Eigen::Matrix3Xd Q = (pose.R * points).colwise() + pose.t;
    for (Eigen::Index i = 0; i < Q.cols(); ++i) {
      const Eigen::Vector3d q = Q.col(i);
      if (!(q.x() > 0.0) || !idx.MayBeWithin(q, gate)) continue;
      if (idx.AnyWithin(q, gate, reach)) ++count;
    }
    return count;
  }

  // Assigns points to beams of source s under scene_from_source within
  // `gate`; conflicts (two points in one beam's gate) resolved by the chi^2
  // margin when sigma > 0, else by the nearest.
  Detection Assign(int s, const Rigid3d& scene_from_source, double gate, double sigma,
                   const Eigen::Vector2i& centre = Eigen::Vector2i::Zero(), int radius = 1 << 20) const {
    const PatternIndex& idx = index_[s];
    const Eigen::Matrix3d Rt = scene_from_source.RotationMatrix().transpose();
    const Eigen::Vector3d t = scene_from_source.translation;
    const int nn = idx.n * idx.n;
    std::vector<int> best(nn, -1), second(nn, -1);
    std::vector<double> best_a(nn, 0.0), second_a(nn, 0.0);
    const double reach = idx.PositionReach(gate);
    for (int i = 0; i < pool_.size(); ++i) {
      if (!Eligible(i, s)) continue;
      const Eigen::Vector3d q = Rt * (pool_.p[i] - t);
      if (!(q.x() > 0.0) || !idx.MayBeWithin(q, gate)) continue;
      double angle = 0.0;
      const int node = idx.NearestWithin(q, gate, reach, &angle);
      if (node < 0 || reserved_[s][node]) continue;
      if (std::abs(node % idx.n - centre.x()) > radius || std::abs(node / idx.n - centre.y()) > radius) continue;
      if (best[node] < 0 || angle < best_a[node]) {
        second[node] = best[node];
        second_a[node] = best_a[node];
        best[node] = i;
        best_a[node] = angle;
      } else if (second[node] < 0 || angle < second_a[node]) {
        second[node] = i;
        second_a[node] = angle;
      }
    }
    Detection d;
    d.source = s;
    d.scene_from_source = scene_from_source;
    d.sigma = sigma;
    for (int node = 0; node < nn; ++node) {
      if (best[node] < 0) continue;
      if (second[node] >= 0 && sigma > 0.0) {
        const double margin = (second_a[node] * second_a[node] - best_a[node] * best_a[node]) / (sigma * sigma);
        if (margin < options_.conflict_margin_chi2) {
          ++d.conflicts;
          continue;
        }
      }
      d.point.push_back(best[node]);
      d.beam.push_back(node + 1);
      d.residual.push_back(best_a[node]);
    }
    return d;
  }

  // Largest noise sigma of an accepted detection of source s, rad.
  double MaxSigma(int s) const {
    return options_.max_sigma_fraction * index_[s].spacing_rad +
           (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
  }

  // Fewest points a detection of source s must explain.
  int MinPoints(int s) const {
    const int beams = static_cast<int>(index_[s].pattern->beams().size());
    return std::max(options_.min_spots, static_cast<int>(std::ceil(options_.min_fraction * beams)));
  }

  double Gate(double sigma, double cap) const {
    double g = options_.assign_gate_sigma * sigma;
    if (options_.directions_nominal) g = std::hypot(g, options_.nominal_tolerance_rad);
    return std::min(g, cap);
  }

  // Refines a candidate (header comment, step 3). False when the pose cannot
  // be refined or explains too few points.
  bool Refine(const Candidate& c, Detection* out) const {
    const PatternIndex& idx = index_[c.source];
    const double cap = options_.score_gate_fraction * idx.spacing_rad +
                       (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
    Rigid3d pose(Eigen::Matrix3d(c.pose.R.transpose()), Eigen::Vector3d(-(c.pose.R.transpose() * c.pose.t)));
    double sigma = 0.0;
    double gate = cap;
    // Growth: the region around the seed's node widens stage by stage.
    static constexpr int kRadii[] = {2, 3, 5, 8};
    int stage = c.grow ? 0 : 4;
    auto radius = [&stage]() { return stage < 4 ? kRadii[stage] : 1 << 20; };
    Detection d = Assign(c.source, pose, gate, sigma, c.node, radius());
    LocateOptions lo;
    lo.ransac_seed = options_.seed;
    // The assigned points are within `cap` of their beams under the initial
    // pose: with that threshold the guess is taken and RANSAC never runs.
    lo.ransac_inlier_threshold_rad = std::min(0.4, 1.01 * cap);
    lo.ransac_max_iterations = 100;
    const double max_sigma = options_.max_sigma_fraction * idx.spacing_rad +
                             (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
    // The gate shrinks from `cap` by halves to the noise gate, so that a pose
    // right only near the seed grows onto the whole grid.
    double schedule = cap;
    for (int iter = 0; iter < 16; ++iter) {
      if (static_cast<int>(d.point.size()) < (stage < 4 ? 6 : std::max(4, options_.min_spots))) return false;
      std::vector<SpotObservation> obs(d.point.size());
      for (size_t k = 0; k < d.point.size(); ++k) {
        obs[k].beam_id = d.beam[k];
        obs[k].point_in_scene = pool_.p[d.point[k]];
      }
      lo.initial_scene_from_source = pose;
      auto located = LocateSource(*idx.pattern, obs, lo);
      if (!located.ok()) return false;
      pose = located->scene_from_source;
      // Robust sigma from the inliers' angles (Rayleigh median = 1.1774 sigma).
      std::vector<double> r;
      const Eigen::Matrix3d Rt = pose.RotationMatrix().transpose();
      for (size_t k = 0; k < obs.size(); ++k) {
        if (located->residuals[k].outlier) continue;
        const Eigen::Vector3d q = (Rt * (obs[k].point_in_scene - pose.translation)).normalized();
        r.push_back((q - idx.pattern->DirectionInSource(obs[k].beam_id)).norm());
      }
      if (r.size() < 4) return false;
      std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
      sigma = std::max(r[r.size() / 2] / std::sqrt(2.0 * std::log(2.0)), options_.min_sigma_rad);
      if (sigma > 2.0 * max_sigma) return false;
      if (stage < 4) {
        ++stage;
        gate = cap;
        d = Assign(c.source, pose, gate, 0.0, c.node, radius());
        continue;
      }
      schedule *= 0.5;
      gate = std::max(Gate(sigma, cap), schedule);
      Detection next = Assign(c.source, pose, gate, sigma);
      const bool same = next.point == d.point && next.beam == d.beam;
      d = std::move(next);
      if (same && schedule <= Gate(sigma, cap)) break;
    }
    if (static_cast<int>(d.point.size()) < MinPoints(c.source)) return false;
    // A pose whose spots scatter by more than a small fraction of the beam
    // spacing is not this source's grid (another pattern, a wrong
    // correspondence of a nearly symmetric pattern).
    if (d.sigma > max_sigma) return false;
    *out = std::move(d);
    return true;
  }

  // Candidate poses for the alternatives of detection d: its points
  // relabelled by each symmetry g of the square about the pattern centre, in
  // each allowed source (d's own source without g = identity). The pose of
  // each comes from P3P on three well-spread points; it is kept only when it
  // puts at least 80% of the relabelled points within 4 max-sigma of their
  // beams (an alternative that fits no better than that cannot rival d).
  std::vector<Candidate> Alternatives(const Detection& d, const std::vector<char>& allowed) const {
    std::vector<Candidate> out;
    const int m = static_cast<int>(d.point.size());
    if (m < 4) return out;
    const int n0 = index_[d.source].n;
    std::vector<Eigen::Vector2i> lattice(m);
    for (int k = 0; k < m; ++k) lattice[k] = Eigen::Vector2i(BeamCol(d.beam[k], n0), BeamRow(d.beam[k], n0));
    // Three well-spread points (in lattice coordinates).
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& l : lattice) mean += l.cast<double>();
    mean /= m;
    int a = 0, b = 0, c = 0;
    double best = -1.0;
    for (int k = 0; k < m; ++k) {
      const double v = (lattice[k].cast<double>() - mean).squaredNorm();
      if (v > best) best = v, a = k;
    }
    best = -1.0;
    for (int k = 0; k < m; ++k) {
      const double v = (lattice[k] - lattice[a]).cast<double>().squaredNorm();
      if (v > best) best = v, b = k;
    }
    // c and c2: the largest triangles with a, b on either side of ab.
    int c2 = 0;
    double best2 = 0.0;
    best = 0.0;
    const Eigen::Vector2d ab = (lattice[b] - lattice[a]).cast<double>();
    for (int k = 0; k < m; ++k) {
      const Eigen::Vector2d ak = (lattice[k] - lattice[a]).cast<double>();
      const double v = ab.x() * ak.y() - ab.y() * ak.x();
      if (v > best) best = v, c = k;
      if (-v > best2) best2 = -v, c2 = k;
    }
    if (best <= 0.0 && best2 <= 0.0) return out;
    if (best <= 0.0) c = c2;
    if (best2 <= 0.0) c2 = c;
    // Three triples: a P3P configuration can be near-degenerate (the origin
    // near the triangle's circumscribed cylinder); the best of the three is
    // kept.
    const std::array<std::array<int, 3>, 3> triples = {{{a, b, c}, {a, b, c2}, {c, c2, a}}};
    for (int s = 0; s < static_cast<int>(index_.size()); ++s) {
      if (!allowed[s]) continue;
      const PatternIndex& idx = index_[s];
      if (idx.spacing_rad <= 0.0) continue;
      const double max_sigma = options_.max_sigma_fraction * idx.spacing_rad +
                               (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
      const double gate = 4.0 * max_sigma;
      for (int g = 0; g < 8; ++g) {
        if (s == d.source && g == 0) continue;
        // Relabel: (c, r) -> g ((c, r) - centre0) + centre.
        std::vector<int> node(m, -1);
        const Eigen::Vector2i centre0((n0 - 1) / 2, (n0 - 1) / 2), centre((idx.n - 1) / 2, (idx.n - 1) / 2);
        int valid = 0;
        for (int k = 0; k < m; ++k) {
          const Eigen::Vector2i l = Apply(g, lattice[k] - centre0) + centre;
          if (idx.Has(l.x(), l.y())) node[k] = l.y() * idx.n + l.x(), ++valid;
        }
        if (valid < MinPoints(s) || 5 * valid < 4 * m) continue;
        int best_count = -1;
        PoseRt best_pose;
        for (const auto& tri : triples) {
          if (tri[0] == tri[2] || tri[1] == tri[2] || tri[0] == tri[1]) continue;
          if (node[tri[0]] < 0 || node[tri[1]] < 0 || node[tri[2]] < 0) continue;
          const std::array<Eigen::Vector3d, 3> f = {idx.dir[node[tri[0]]], idx.dir[node[tri[1]]], idx.dir[node[tri[2]]]};
          const std::array<Eigen::Vector3d, 3> X = {pool_.p[d.point[tri[0]]], pool_.p[d.point[tri[1]]],
                                                    pool_.p[d.point[tri[2]]]};
          std::array<PoseRt, 4> poses;
          const int np = SolveP3P(f, X, &poses);
        for (int r = 0; r < np; ++r) {
          if (!poses[r].R.allFinite() || !poses[r].t.allFinite()) continue;
          int count = 0;
          for (int k = 0; k < m; ++k) {
            if (node[k] < 0) continue;
            const Eigen::Vector3d q = poses[r].R * pool_.p[d.point[k]] + poses[r].t;
            if (q.x() > 0.0 && (q.normalized() - idx.dir[node[k]]).norm() < gate) ++count;
          }
          if (count > best_count) best_count = count, best_pose = poses[r];
        }
        }
        if (best_count >= MinPoints(s) && 5 * best_count >= 4 * m) {
          out.push_back({s, best_pose, best_count, Eigen::Vector2i::Zero(), false});
        }
      }
    }
    return out;
  }

  // Angle from the direction of point p (scene) to its nearest beam of
  // source s at `scene_from_source`; infinity when none.
  double NearestAngle(int s, const Rigid3d& scene_from_source, const Eigen::Vector3d& p) const {
    const Eigen::Vector3d q = scene_from_source.rotation.conjugate() * (p - scene_from_source.translation);
    double angle = std::numeric_limits<double>::infinity();
    if (!(q.x() > 0.0) || index_[s].Nearest(q, &angle) < 0) return std::numeric_limits<double>::infinity();
    return angle;
  }

  double FinalGate(int s, double sigma) const {
    return Gate(sigma, options_.score_gate_fraction * index_[s].spacing_rad +
                           (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0));
  }

  // Truncated chi^2 of a detection's pose over every point eligible for its
  // source, with a common sigma.
  double Cost(const Detection& d, double sigma) const {
    const PatternIndex& idx = index_[d.source];
    const Eigen::Matrix3d Rt = d.scene_from_source.RotationMatrix().transpose();
    const double G2 = options_.assign_gate_sigma * options_.assign_gate_sigma;
    double cost = 0.0;
    for (int i = 0; i < pool_.size(); ++i) {
      if (pool_.taken[i]) continue;
      double c = G2;
      if (Eligible(i, d.source)) {
        const Eigen::Vector3d q = Rt * (pool_.p[i] - d.scene_from_source.translation);
        double angle = 0.0;
        const int node = q.x() > 0.0 ? idx.Nearest(q, &angle) : -1;
        if (node >= 0 && !reserved_[d.source][node]) c = std::min(G2, angle * angle / (sigma * sigma));
      }
      cost += c;
    }
    return cost;
  }

 private:
  const ModuleCalibration& calibration_;
  const IdentifyOptions& options_;
  Pool& pool_;
  const std::vector<std::vector<char>>& reserved_;
  std::vector<PatternIndex> index_;
  mutable PoseNormalEquations patch_problem_;  // FitPatch's scratch (one thread)
};

// True when a and b give (mostly) the same correspondence.
bool SameCorrespondence(const Detection& a, const Detection& b) {
  if (a.source != b.source) return false;
  std::vector<std::pair<int, int>> pa, pb;
  for (size_t k = 0; k < a.point.size(); ++k) pa.push_back({a.point[k], a.beam[k]});
  for (size_t k = 0; k < b.point.size(); ++k) pb.push_back({b.point[k], b.beam[k]});
  std::sort(pa.begin(), pa.end());
  std::sort(pb.begin(), pb.end());
  int same = 0, common = 0;
  size_t i = 0, j = 0;
  while (i < pa.size() && j < pb.size()) {
    if (pa[i].first < pb[j].first) {
      ++i;
    } else if (pb[j].first < pa[i].first) {
      ++j;
    } else {
      ++common;
      same += pa[i].second == pb[j].second;
      ++i;
      ++j;
    }
  }
  return common > 0 && 2 * same > common;
}

std::string Where(const Spot& s, size_t i) {
  return s.where.empty() ? "spot " + std::to_string(i) : s.where;
}

}  // namespace

const char* IdentifyOutcomeName(IdentifyOutcome outcome) {
  switch (outcome) {
    case IdentifyOutcome::kFound:
      return "found";
    case IdentifyOutcome::kNotFound:
      return "not found";
    case IdentifyOutcome::kAmbiguous:
      return "ambiguous";
  }
  return "?";
}

Status IdentifyOptions::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("IdentifyOptions." + field + " = " + FormatNumber(value, 6) + ": " + rule);
  };
  if (num_threads < 1 || num_threads > 256) {
    return bad("num_threads", num_threads, "must be in [1, 256]");
  }
  if (!(assign_gate_sigma > 0.0 && std::isfinite(assign_gate_sigma))) {
    return bad("assign_gate_sigma", assign_gate_sigma, "must be finite and > 0");
  }
  if (!(min_sigma_rad > 0.0 && min_sigma_rad < 0.1)) {
    return bad("min_sigma_rad", min_sigma_rad, "must be in (0, 0.1)");
  }
  if (!(score_gate_fraction > 0.0 && score_gate_fraction <= 0.5)) {
    return bad("score_gate_fraction", score_gate_fraction, "must be in (0, 0.5]");
  }
  if (!(nominal_tolerance_rad >= 0.0 && nominal_tolerance_rad < 0.1)) {
    return bad("nominal_tolerance_rad", nominal_tolerance_rad, "must be in [0, 0.1)");
  }
  if (min_spots < 4) return bad("min_spots", min_spots, "must be >= 4");
  if (!(min_fraction >= 0.0 && min_fraction <= 1.0)) return bad("min_fraction", min_fraction, "must be in [0, 1]");
  if (!(conflict_margin_chi2 >= 0.0 && std::isfinite(conflict_margin_chi2))) {
    return bad("conflict_margin_chi2", conflict_margin_chi2, "must be finite and >= 0");
  }
  if (!(ambiguity_chi2 >= 0.0 && std::isfinite(ambiguity_chi2))) {
    return bad("ambiguity_chi2", ambiguity_chi2, "must be finite and >= 0");
  }
  if (neighbours < 4 || neighbours > 64) return bad("neighbours", neighbours, "must be in [4, 64]");
  if (max_seeds < 1) return bad("max_seeds", max_seeds, "must be >= 1");
  if (!(expected_rotation_tolerance_deg > 0.0 && expected_rotation_tolerance_deg < 45.0)) {
    return bad("expected_rotation_tolerance_deg", expected_rotation_tolerance_deg,
               "must be in (0, 45) (the symmetries of a square grid are 90 deg apart)");
  }
  if (!expected_origin.empty() && !(expected_origin_tolerance > 0.0 && std::isfinite(expected_origin_tolerance))) {
    return bad("expected_origin_tolerance", expected_origin_tolerance,
               "must be finite and > 0 when expected_origin is given");
  }
  for (const auto& [name, o] : expected_origin) {
    if (!o.allFinite()) {
      return Status::InvalidArgument("IdentifyOptions.expected_origin['" + name + "']: not finite");
    }
  }
  for (const auto& [name, r] : expected_rotation) {
    if (!r.allFinite() || (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
        std::abs(r.determinant() - 1.0) > 1e-6) {
      return Status::InvalidArgument("IdentifyOptions.expected_rotation['" + name +
                                     "']: not a proper rotation");
    }
  }
  if (max_refined < 1) return bad("max_refined", max_refined, "must be >= 1");
  if (!(max_sigma_fraction > 0.0 && max_sigma_fraction <= 0.5)) {
    return bad("max_sigma_fraction", max_sigma_fraction, "must be in (0, 0.5]");
  }
  return Status::Ok();
}

int IdentifyResult::num_assigned() const {
  return static_cast<int>(std::count_if(source_index.begin(), source_index.end(), [](int s) { return s >= 0; }));
}

int IdentifyResult::num_unassigned() const {
  return static_cast<int>(source_index.size()) - num_assigned();
}

std::string IdentifyResult::ToText() const {
  std::ostringstream os;
  for (const IdentifiedSource& s : sources) {
    os << "source " << s.name << ": " << IdentifyOutcomeName(s.outcome);
    if (s.outcome == IdentifyOutcome::kFound) {
      os << ", " << s.assigned << " points, rms " << FormatNumber(s.rms_residual_rad * 1e6, 4) << " urad";
    }
    if (!s.detail.empty()) os << " (" << s.detail << ")";
    os << "\n";
  }
  os << num_assigned() << " of " << source_index.size() << " points assigned";
  if (passed_through > 0) os << " (" << passed_through << " given)";
  os << ", " << num_unassigned() << " unassigned\n";
  return os.str();
}

std::vector<Spot> AssignedSpots(const std::vector<Spot>& spots, const IdentifyResult& result) {
  std::vector<Spot> out;
  if (result.source_index.size() != spots.size() || result.beam_id.size() != spots.size()) return out;
  for (size_t i = 0; i < spots.size(); ++i) {
    const int s = result.source_index[i];
    if (s < 0 || s >= static_cast<int>(result.sources.size())) continue;
    Spot spot = spots[i];
    spot.source = result.sources[s].name;
    spot.observation.beam_id = result.beam_id[i];
    out.push_back(std::move(spot));
  }
  return out;
}

Result<IdentifyResult> IdentifySpots(const ModuleCalibration& calibration, const std::vector<Spot>& spots,
                                     const IdentifyOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  {
    Status s = calibration.Validate();
    if (!s.ok()) return Status::InvalidArgument("calibration: " + s.message());
  }
  if (calibration.sources.empty()) return Status::InvalidArgument("calibration: no sources");
  const int num_sources = static_cast<int>(calibration.sources.size());
  // The orientation prior, by source index (identity-free when absent).
  std::vector<const Eigen::Matrix3d*> expected(num_sources, nullptr);
  for (const auto& [name, r] : options.expected_rotation) {
    bool known = false;
    for (int s = 0; s < num_sources; ++s) {
      if (calibration.sources[s].name == name) {
        expected[s] = &r;
        known = true;
      }
    }
    if (!known) {
      return Status::InvalidArgument("IdentifyOptions.expected_rotation: unknown source '" + name + "'");
    }
  }
  std::vector<const Eigen::Vector3d*> expected_origin(num_sources, nullptr);
  for (const auto& [name, o] : options.expected_origin) {
    bool known = false;
    for (int s = 0; s < num_sources; ++s) {
      if (calibration.sources[s].name == name) {
        expected_origin[s] = &o;
        known = true;
      }
    }
    if (!known) {
      return Status::InvalidArgument("IdentifyOptions.expected_origin: unknown source '" + name + "'");
    }
  }
  const double prior_tolerance_rad = options.expected_rotation_tolerance_deg * kPi / 180.0;
  auto against_prior = [&](const Detection& d) {
    const bool rotation_off =
        expected[d.source] != nullptr &&
        RotationAngleBetweenRad(*expected[d.source], d.scene_from_source.RotationMatrix()) >
            prior_tolerance_rad;
    const bool origin_off =
        expected_origin[d.source] != nullptr &&
        (d.scene_from_source.translation - *expected_origin[d.source]).norm() >
            options.expected_origin_tolerance;
    return rotation_off || origin_off;
  };

  IdentifyResult result;
  result.source_index.assign(spots.size(), -1);
  result.beam_id.assign(spots.size(), 0);
  for (const SourceCalibration& s : calibration.sources) {
    IdentifiedSource is;
    is.name = s.name;
    result.sources.push_back(is);
  }
  std::vector<std::vector<char>> reserved(num_sources);
  for (int s = 0; s < num_sources; ++s) {
    const int n = calibration.sources[s].pattern.beams_per_side();
    reserved[s].assign(static_cast<size_t>(n) * n + 1, 0);
  }

  Pool pool;
  for (size_t i = 0; i < spots.size(); ++i) {
    const Spot& spot = spots[i];
    if (!spot.observation.point_in_scene.allFinite()) {
      return Status::InvalidArgument(Where(spot, i) + ": point is not finite");
    }
    if (spot.observation.beam_id < 0) {
      return Status::InvalidArgument(Where(spot, i) + ": beam id " + std::to_string(spot.observation.beam_id) +
                                     " is negative");
    }
    int source = -1;
    if (!spot.source.empty()) {
      for (int s = 0; s < num_sources; ++s) {
        if (calibration.sources[s].name == spot.source) source = s;
      }
      if (source < 0) {
        std::string names;
        for (const auto& s : calibration.sources) names += (names.empty() ? "" : ", ") + s.name;
        return Status::InvalidArgument(Where(spot, i) + ": unknown source '" + spot.source +
                                       "' (the calibration has " + names + ")");
      }
    }
    if (source >= 0 && spot.observation.beam_id > 0) {
      const BeamPattern& pattern = calibration.sources[source].pattern;
      if (pattern.Find(spot.observation.beam_id) == nullptr) {
        return Status::InvalidArgument(Where(spot, i) + ": beam " + std::to_string(spot.observation.beam_id) +
                                       " is not in the pattern of source '" + spot.source + "'");
      }
      result.source_index[i] = source;
      result.beam_id[i] = spot.observation.beam_id;
      reserved[source][spot.observation.beam_id - 1] = 1;
      ++result.passed_through;
      continue;
    }
    pool.p.push_back(spot.observation.point_in_scene);
    pool.spot.push_back(static_cast<int>(i));
    pool.only_source.push_back(source);
  }
  pool.taken.assign(pool.p.size(), 0);
  pool.blocked.assign(pool.p.size(), 0);

  Identifier identifier(calibration, options, &pool, reserved);
  std::vector<char> done(num_sources, 0);
  std::vector<std::string> ambiguity(num_sources);
  for (int s = 0; s < num_sources; ++s) {
    if (identifier.index(s).spacing_rad <= 0.0) {
      done[s] = 1;
      result.sources[s].detail = "the pattern has no lattice node with a row and a column neighbour";
    }
  }

  const std::vector<Seed> seeds = FindSeeds(pool, options.neighbours, options.num_threads);
  int tried = 0, tried_derived = 0;
  auto usable = [&](const Seed& seed) {
    bool skip = pool.taken[seed.p0] || pool.taken[seed.pa] || pool.taken[seed.pb];
    return !(skip || pool.blocked[seed.p0]);
  };
  // Adds d to `detections` unless one with the same correspondence is there
  // (the one with more points, then the lower sigma, is kept).
  auto add_to = [](std::vector<Detection>* detections, Detection d) {
    for (Detection& e : *detections) {
      if (SameCorrespondence(d, e)) {
        if (d.point.size() > e.point.size() || (d.point.size() == e.point.size() && d.sigma < e.sigma)) {
          e = std::move(d);
        }
        return;
      }
    }
    detections->push_back(std::move(d));
  };
  // The refined detections of one seed (header comment, steps 2-3).
  auto seed_detections = [&](const Seed& seed, std::vector<Detection>* out) {
    const int sp[3] = {seed.p0, seed.pa, seed.pb};
    std::vector<Identifier::Hypothesis> hypotheses;
    for (int s = 0; s < num_sources; ++s) {
      if (done[s]) continue;
      bool allowed = true;
      for (int i : sp) allowed &= pool.only_source[i] < 0 || pool.only_source[i] == s;
      if (allowed) identifier.Hypotheses(s, seed, &hypotheses);
    }
    std::vector<Candidate> candidates;
    // A candidate that refines clearly (noise well below the acceptance
    // limit) is the grid: its symmetric and cross-source alternatives are
    // examined next (step 4), so no other candidate needs refining.
    std::optional<Detection> settled;
    identifier.Candidates(seed, std::move(hypotheses), &candidates, [&](const Candidate& c) {
      Detection d;
      if (!identifier.Refine(c, &d) || d.sigma > 0.25 * identifier.MaxSigma(d.source)) return false;
      settled = std::move(d);
      return true;
    });
    if (candidates.empty()) return;
    // Best score first; among equal scores, by source, then in the order
    // each source's hypotheses were checked.
    std::stable_sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
      return a.score > b.score || (a.score == b.score && a.source < b.source);
    });
    // Distinct poses only (the same hypothesis is reached from several
    // symmetries, nodes and roots), the best-scoring first.
    std::vector<const Candidate*> distinct;
    for (const Candidate& c : candidates) {
      if (static_cast<int>(distinct.size()) >= options.max_refined) break;
      if (c.score * 2 < candidates.front().score) break;
      const Eigen::Vector3d origin = -(c.pose.R.transpose() * c.pose.t);
      const double range = (pool.p[seed.p0] - origin).norm();
      bool same = false;
      for (const Candidate* e : distinct) {
        if (e->source != c.source) continue;
        const Eigen::Vector3d eo = -(e->pose.R.transpose() * e->pose.t);
        same |= RotationAngleBetweenRad(e->pose.R, c.pose.R) < 0.02 && (eo - origin).norm() < 0.02 * range;
      }
      if (!same) distinct.push_back(&c);
    }
    auto add = [&](Detection d) { add_to(out, std::move(d)); };
    if (settled) {
      distinct.clear();
      add(std::move(*settled));
    }
    for (const Candidate* cp : distinct) {
      Detection d;
      const bool ok = identifier.Refine(*cp, &d);
      // A detection whose noise is well below the acceptance limit is the
      // grid; its symmetric and cross-source alternatives are examined next
      // (step 4), so the remaining candidates need not be refined.
      const bool clear = ok && d.sigma <= 0.25 * identifier.MaxSigma(d.source);
      if (ok) add(std::move(d));
      if (clear) break;
    }
  };
  auto clear = [&](const std::vector<Detection>& detections) {
    for (const Detection& d : detections) {
      if (d.sigma <= 0.25 * identifier.MaxSigma(d.source)) return true;
    }
    return false;
  };
  // One seed (header comment, steps 2-5): false when it explains nothing
  // (no detection survives), true when it found a source or made one
  // ambiguous. With `derived`, when the seed gives no clear detection (noise
  // well below the acceptance limit), the detections of its derived crosses
  // (DerivedSeeds; header comment, step 1) compete with its own: a cross
  // mixing two interleaved grids can fit a wrong pose to a few dozen points
  // of their union (a sheared or rotated lattice) that no other seed
  // contradicts.
  // `defer`: a decision on a detection that is not clear (noise above a
  // quarter of the acceptance limit) is put off: the seed counts as
  // explaining nothing and changes nothing (no point taken or blocked).
  bool deferred_one = false;
  auto try_seed = [&](const Seed& seed, bool derived, bool defer) -> bool {
    deferred_one = false;
    std::vector<Detection> detections;
    seed_detections(seed, &detections);
    if (derived && !clear(detections)) {
      for (const Seed& d : DerivedSeeds(seed)) {
        if (tried_derived >= options.max_seeds) break;
        if (!usable(d)) continue;
        ++tried_derived;
        seed_detections(d, &detections);
        if (clear(detections)) break;
      }
    }
    if (detections.empty()) return false;
    // Common sigma: the smallest among the detections that explain nearly as
    // many points as the most; the best detection has the lowest cost.
    auto rank = [&]() {
      size_t max_points = 0;
      for (const Detection& d : detections) max_points = std::max(max_points, d.point.size());
      double sigma = std::numeric_limits<double>::infinity();
      for (const Detection& d : detections) {
        if (d.point.size() * 5 >= max_points * 4) sigma = std::min(sigma, d.sigma);
      }
      for (Detection& d : detections) d.cost = identifier.Cost(d, sigma);
      std::stable_sort(detections.begin(), detections.end(),
                       [](const Detection& x, const Detection& y) { return x.cost < y.cost; });
    };
    rank();
    detections.resize(1);
    // The alternatives of the first detection: its points relabelled by every
    // symmetry of the square about the pattern centre, in every unfound
    // source allowed for them (header comment, step 4).
    {
      std::vector<char> allowed(num_sources, 0);
      for (int s = 0; s < num_sources; ++s) {
        bool ok = !done[s];
        for (int i : detections[0].point) ok = ok && (pool.only_source[i] < 0 || pool.only_source[i] == s);
        allowed[s] = ok;
      }
      const std::vector<Candidate> alternatives = identifier.Alternatives(detections[0], allowed);
      for (const Candidate& c : alternatives) {
        Detection d;
        if (identifier.Refine(c, &d)) add_to(&detections, std::move(d));
      }
    }
    detections.erase(std::remove_if(detections.begin(), detections.end(), against_prior),
                     detections.end());
    rank();
    if (detections.empty()) return false;
    size_t best = 0;
    for (size_t k = 1; k < detections.size(); ++k) {
      if (detections[k].cost < detections[best].cost) best = k;
    }
    const Detection& b = detections[best];
    if (defer && !(b.sigma <= 0.25 * identifier.MaxSigma(b.source))) {
      deferred_one = true;
      return false;
    }
    std::vector<size_t> rivals;
    for (size_t k = 0; k < detections.size(); ++k) {
      if (k != best && detections[k].cost - b.cost < options.ambiguity_chi2) rivals.push_back(k);
    }
    if (rivals.empty()) {
      IdentifiedSource& out = result.sources[b.source];
      out.outcome = IdentifyOutcome::kFound;
      out.detail.clear();
      out.scene_from_source = b.scene_from_source;
      out.assigned = static_cast<int>(b.point.size());
      out.sigma_rad = b.sigma;
      double ss = 0.0;
      for (size_t k = 0; k < b.point.size(); ++k) {
        const int i = b.point[k];
        pool.taken[i] = 1;
        result.source_index[pool.spot[i]] = b.source;
        result.beam_id[pool.spot[i]] = b.beam[k];
        ss += b.residual[k] * b.residual[k];
      }
      out.rms_residual_rad = std::sqrt(ss / (2.0 * std::max<size_t>(1, b.point.size())));
      done[b.source] = 1;
      return true;
    }
    // Ambiguous: say why, for every source involved.
    for (int i : b.point) pool.blocked[i] = 1;
    const Detection& r = detections[rivals.front()];
    std::ostringstream why;
    if (r.source == b.source) {
      const double angle = RotationAngleBetweenRad(b.scene_from_source.RotationMatrix(),
                                                   r.scene_from_source.RotationMatrix());
      why << b.point.size() << " points fit two correspondences as well (the other pose rotated by "
          << FormatNumber(angle * 180.0 / kPi, 4) << " deg; chi2 difference "
          << FormatNumber(r.cost - b.cost, 3) << " < " << FormatNumber(options.ambiguity_chi2, 3)
          << "): the pattern is symmetric to within the noise";
      ambiguity[b.source] = why.str();
      done[b.source] = 1;
    } else {
      why << "a grid of " << b.point.size() << " points fits sources " << calibration.sources[b.source].name
          << " and " << calibration.sources[r.source].name << " as well (chi2 difference "
          << FormatNumber(r.cost - b.cost, 3) << " < " << FormatNumber(options.ambiguity_chi2, 3) << ")";
      ambiguity[b.source] = why.str();
      ambiguity[r.source] = why.str();
    }
    return true;
  };
  auto all_done = [&done]() { return std::all_of(done.begin(), done.end(), [](char d) { return d != 0; }); };
  // A detection that is not clear is decided only after kDeferrals such
  // seeds: interleaved grids (spots of the other grid a fraction of a step
  // away) can give a wrong pose of a whole grid whose noise, far above the
  // spots', is still below the acceptance limit, while a later seed finds
  // the grid clearly.
  constexpr int kDeferrals = 16;
  int deferrals = 0;
  // The seeds of `list` in order, each counted in *counter (at most
  // max_seeds); then, when a decision was put off and sources remain, the
  // same seeds again deciding on every detection.
  auto run = [&](const std::vector<Seed>& list, int* counter) {
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {
        if (deferrals == 0 || all_done()) break;
        deferrals = kDeferrals;
        *counter = 0;
      }
      for (const Seed& seed : list) {
        if (all_done() || *counter >= options.max_seeds) break;
        if (!usable(seed)) continue;
        ++*counter;
        try_seed(seed, true, deferrals < kDeferrals);
        deferrals += deferred_one;
      }
    }
  };
  run(seeds, &tried);
  // Sources still to find after a source was found: seeds again, from the
  // points still free only (a grid interleaved with a found one: its
  // points' crosses used the found grid's points), with a budget of
  // max_seeds.
  int reseeded = 0;
  if (!all_done() && std::any_of(pool.taken.begin(), pool.taken.end(), [](char t) { return t != 0; })) {
    Pool rest;
    std::vector<int> back;
    for (int i = 0; i < pool.size(); ++i) {
      if (pool.taken[i]) continue;
      rest.p.push_back(pool.p[i]);
      back.push_back(i);
    }
    std::vector<Seed> more = FindSeeds(rest, options.neighbours, options.num_threads);
    for (Seed& seed : more) {
      seed.p0 = back[seed.p0];
      seed.pa = back[seed.pa];
      seed.pb = back[seed.pb];
      for (auto& entry : seed.patch) entry.first = back[entry.first];
    }
    deferrals = 0;
    run(more, &reseeded);
  }

  // Overlapping grids: a point assigned to one found source that also lies
  // within the gate of a beam of another found source could be either's
  // spot (e.g. a spot of one grid where the other's is missing): refuse it.
  for (int i = 0; i < pool.size(); ++i) {
    const int spot = pool.spot[i];
    const int s = result.source_index[spot];
    if (s < 0) continue;
    for (int o = 0; o < num_sources; ++o) {
      if (o == s || result.sources[o].outcome != IdentifyOutcome::kFound) continue;
      if (pool.only_source[i] >= 0 && pool.only_source[i] != o) continue;
      const double angle = identifier.NearestAngle(o, result.sources[o].scene_from_source, pool.p[i]);
      if (angle < identifier.FinalGate(o, result.sources[o].sigma_rad)) {
        const double r = identifier.NearestAngle(s, result.sources[s].scene_from_source, pool.p[i]);
        IdentifiedSource& src = result.sources[s];
        const double ss = src.rms_residual_rad * src.rms_residual_rad * 2.0 * src.assigned - r * r;
        --src.assigned;
        src.rms_residual_rad = std::sqrt(std::max(0.0, ss) / (2.0 * std::max(1, src.assigned)));
        result.source_index[spot] = -1;
        result.beam_id[spot] = 0;
        break;
      }
    }
  }

  for (int s = 0; s < num_sources; ++s) {
    IdentifiedSource& out = result.sources[s];
    if (out.outcome == IdentifyOutcome::kFound) continue;
    if (!ambiguity[s].empty()) {
      out.outcome = IdentifyOutcome::kAmbiguous;
      out.detail = ambiguity[s];
    } else if (out.detail.empty()) {
      out.outcome = IdentifyOutcome::kNotFound;
      if (pool.size() < options.min_spots) {
        out.detail = "too few points to identify: " + std::to_string(pool.size()) + " (at least " +
                     std::to_string(options.min_spots) + " needed)";
      } else if (seeds.empty()) {
        out.detail = "no lattice-like group of points (a point with two pairs of opposite neighbours)";
      } else {
        out.detail = "no pose explains at least " + std::to_string(identifier.MinPoints(s)) + " points (" +
                     std::to_string(tried) + " seeds tried, " + std::to_string(tried_derived) +
                     " derived crosses, " + std::to_string(reseeded) + " seeds of the free points)";
      }
    }
  }
  return result;
}

}  // namespace opl
