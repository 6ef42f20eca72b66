// The lattice model of a beam pattern (PatternIndex, pattern_index.h): how
// BuildIndex fits it to a pattern's calibrated directions.
#include "identify/pattern_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Dense>

namespace opl {
namespace identify_internal {

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

}  // namespace identify_internal
}  // namespace opl
