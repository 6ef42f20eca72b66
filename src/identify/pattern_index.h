// Private to src/identify: the lattice of a beam pattern as IdentifySpots
// sees it (opl/identify/identify_spots.h has the algorithm): the 8 symmetries
// of the square lattice on (col, row) offsets, and PatternIndex, an affine
// model of the pattern's directions in (col, row) that finds the beam nearest
// to a direction in the source frame through its 3 x 3 window of nodes.
// Angles are chords of unit vectors, in rad; lattice positions in steps.
#pragma once

#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "opl/model/beam_pattern.h"

namespace opl {
namespace identify_internal {

// The 8 symmetries of the square lattice, g = [[a, b], [c, d]] acting on
// (col, row) offsets: (a x + b y, c x + d y). The first four are rolls
// (0, 90, 180, 270 deg), the last four mirrors.
inline constexpr std::array<std::array<int, 4>, 8> kSymmetries = {{{1, 0, 0, 1},
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

// The lattice model of `pattern` (which it points to: it must outlive the
// index): the better of the two affine models, the spacing, the reference node
// and the bounds that the fast lookups rely on. spacing_rad is 0 when the
// pattern has no node with a +col and a +row neighbour (no usable lattice).
PatternIndex BuildIndex(const BeamPattern& pattern);

}  // namespace identify_internal
}  // namespace opl
