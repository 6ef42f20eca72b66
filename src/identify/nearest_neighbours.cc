// Neighbour queries over a point set, exact: the k nearest of its points and
// the points within a radius (nearest_neighbours.h).
#include "identify/nearest_neighbours.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace opl {
namespace identify_internal {

namespace {

// Above this many points kAuto takes the grid.
constexpr size_t kGridAbove = 4096;
// Points whose k-th neighbour distance sets the grid's cell size.
constexpr size_t kCellSample = 32;
// The grid's cells are tabulated densely up to this many per point.
constexpr double kDenseCellsPerPoint = 16.0;

// Inserts key into the ascending array knn[0, *size) of capacity k, keeping
// the k smallest.
inline void Insert(const std::pair<double, int>& key, int k, int* size, std::vector<std::pair<double, int>>* knn) {
  std::vector<std::pair<double, int>>& a = *knn;
  if (*size == k && !(key < a[k - 1])) return;
  int pos = *size < k ? (*size)++ : k - 1;
  while (pos > 0 && key < a[pos - 1]) {
    a[pos] = a[pos - 1];
    --pos;
  }
  a[pos] = key;
}

}  // namespace

NearestNeighbours::NearestNeighbours(const std::vector<Eigen::Vector3d>& points, int k, Method method)
    : points_(points), k_(k), method_(method) {
  const size_t n = points.size();
  if (method_ == Method::kAuto) method_ = n > kGridAbove ? Method::kGrid : Method::kSweep;
  if (n == 0) return;
  Eigen::Vector3d hi = points[0];
  lo_ = points[0];
  for (const Eigen::Vector3d& p : points) lo_ = lo_.cwiseMin(p), hi = hi.cwiseMax(p);
  if (method_ == Method::kSweep) {
    (hi - lo_).maxCoeff(&sweep_axis_);
    order_.resize(n);
    rank_.resize(n);
    for (size_t i = 0; i < n; ++i) order_[i] = static_cast<int>(i);
    std::sort(order_.begin(), order_.end(), [&](int a, int b) {
      const double xa = points[a][sweep_axis_], xb = points[b][sweep_axis_];
      return xa < xb || (xa == xb && a < b);
    });
    for (size_t r = 0; r < n; ++r) rank_[order_[r]] = static_cast<int>(r);
    return;
  }
  // The cell: the median k-th neighbour distance of an even sample, so that
  // a search mostly ends after the first shell of cells.
  const int kk = std::min<int>(k_, static_cast<int>(n) - 1);
  std::vector<double> kth;
  std::vector<double> d2(n);
  const size_t stride = std::max<size_t>(1, n / kCellSample);
  for (size_t s = 0; s < n && kk > 0; s += stride) {
    for (size_t j = 0; j < n; ++j) d2[j] = (points[j] - points[s]).squaredNorm();
    std::nth_element(d2.begin(), d2.begin() + kk, d2.end());  // d2[0] is the point itself
    kth.push_back(std::sqrt(d2[kk]));
  }
  const double extent = (hi - lo_).maxCoeff();
  cell_ = 0.0;
  if (!kth.empty()) {
    std::nth_element(kth.begin(), kth.begin() + kth.size() / 2, kth.end());
    cell_ = kth[kth.size() / 2];
  }
  // Duplicates or a degenerate sample: cells of a plain density guess. At
  // most 2^20 cells a side (the key packs 21 bits an axis).
  if (!(cell_ > 0.0)) cell_ = extent / std::cbrt(static_cast<double>(n));
  cell_ = std::max({cell_, extent / double(1 << 20), std::numeric_limits<double>::min()});
  for (int a = 0; a < 3; ++a) {
    cells_[a] = static_cast<int>(std::floor((hi[a] - lo_[a]) / cell_)) + 1;
  }
  // A dense table of the cells' points when the box holds few enough cells
  // (kDenseCellsPerPoint per point): an empty cell then costs one load;
  // otherwise a hash map of the occupied cells.
  const double total = double(cells_.x()) * cells_.y() * cells_.z();
  if (total <= kDenseCellsPerPoint * static_cast<double>(n)) {
    dense_start_.assign(static_cast<size_t>(total) + 1, 0);
    // Count, then prefix-sum: dense_start_[cell] .. dense_start_[cell + 1].
    for (size_t i = 0; i < n; ++i) ++dense_start_[DenseIndex(CellOf(points[i])) + 1];
    for (size_t c = 1; c < dense_start_.size(); ++c) dense_start_[c] += dense_start_[c - 1];
    dense_points_.resize(n);
    std::vector<int> fill(dense_start_.begin(), dense_start_.end() - 1);
    for (size_t i = 0; i < n; ++i) dense_points_[fill[DenseIndex(CellOf(points[i]))]++] = static_cast<int>(i);
    for (size_t c = 0; c + 1 < dense_start_.size(); ++c) occupied_cells_ += dense_start_[c + 1] > dense_start_[c];
    return;
  }
  std::vector<std::pair<uint64_t, int>> keyed(n);
  for (size_t i = 0; i < n; ++i) keyed[i] = {Key(CellOf(points[i])), static_cast<int>(i)};
  std::sort(keyed.begin(), keyed.end());
  by_cell_.resize(n);
  for (size_t q = 0; q < n; ++q) {
    by_cell_[q] = keyed[q].second;
    if (q == 0 || keyed[q].first != keyed[q - 1].first) range_[keyed[q].first] = {static_cast<int>(q), 0};
    range_[keyed[q].first].second = static_cast<int>(q) + 1;
  }
  occupied_cells_ = range_.size();
}

size_t NearestNeighbours::DenseIndex(const Eigen::Vector3i& c) const {
  return (static_cast<size_t>(c.x()) * cells_.y() + c.y()) * cells_.z() + c.z();
}

Eigen::Vector3i NearestNeighbours::CellOf(const Eigen::Vector3d& p) const {
  Eigen::Vector3i c;
  for (int a = 0; a < 3; ++a) {
    c[a] = std::clamp(static_cast<int>(std::floor((p[a] - lo_[a]) / cell_)), 0, cells_[a] - 1);
  }
  return c;
}

uint64_t NearestNeighbours::Key(const Eigen::Vector3i& c) {
  return (static_cast<uint64_t>(c.x()) << 42) | (static_cast<uint64_t>(c.y()) << 21) |
         static_cast<uint64_t>(c.z());
}

std::pair<const int*, const int*> NearestNeighbours::CellPoints(const Eigen::Vector3i& c) const {
  if (!dense_start_.empty()) {
    const size_t d = DenseIndex(c);
    return {dense_points_.data() + dense_start_[d], dense_points_.data() + dense_start_[d + 1]};
  }
  const auto it = range_.find(Key(c));
  if (it == range_.end()) return {nullptr, nullptr};
  return {by_cell_.data() + it->second.first, by_cell_.data() + it->second.second};
}

void NearestNeighbours::Find(int i, std::vector<std::pair<double, int>>* knn) const {
  if (method_ == Method::kGrid) {
    FindByGrid(i, knn);
  } else {
    FindBySweep(i, knn);
  }
}

void NearestNeighbours::FindBySweep(int i, std::vector<std::pair<double, int>>* knn) const {
  const int n = static_cast<int>(points_.size());
  const int k = std::min(k_, n - 1);
  knn->resize(std::max(k, 0));
  if (k <= 0) return;
  int size = 0;
  const Eigen::Vector3d pi0 = points_[i];
  const double xi = pi0[sweep_axis_];
  auto visit = [&](int j) { Insert({(points_[j] - pi0).squaredNorm(), j}, k, &size, knn); };
  // A side is done when its next point's gap squared exceeds the k-th
  // smallest so far (every later point on it is at least as far).
  auto done = [&](int j) {
    if (size < k) return false;
    const double gap = points_[j][sweep_axis_] - xi;
    return gap * gap > (*knn)[k - 1].first;
  };
  int down = rank_[i] - 1, up = rank_[i] + 1;
  while (down >= 0 || up < n) {
    if (down >= 0) {
      if (done(order_[down])) {
        down = -1;
      } else {
        visit(order_[down--]);
      }
    }
    if (up < n) {
      if (done(order_[up])) {
        up = n;
      } else {
        visit(order_[up++]);
      }
    }
  }
}

void NearestNeighbours::FindByGrid(int i, std::vector<std::pair<double, int>>* knn) const {
  const int n = static_cast<int>(points_.size());
  const int k = std::min(k_, n - 1);
  knn->resize(std::max(k, 0));
  if (k <= 0) return;
  int size = 0;
  const Eigen::Vector3d p = points_[i];
  const Eigen::Vector3i c = CellOf(p);
  auto visit_cell = [&](const Eigen::Vector3i& cell) {
    const auto [first, last] = CellPoints(cell);
    for (const int* q = first; q != last; ++q) {
      if (*q != i) Insert({(points_[*q] - p).squaredNorm(), *q}, k, &size, knn);
    }
  };
  for (int r = 0;; ++r) {
    // A point far from the others (its k-th neighbour many cells away):
    // once a shell would hold more cells than are occupied, every point is
    // visited instead.
    const double shell_cells = std::pow(2.0 * r + 1.0, 3.0) - std::pow(std::max(0.0, 2.0 * r - 1.0), 3.0);
    if (r > 1 && shell_cells > static_cast<double>(occupied_cells_)) {
      size = 0;
      for (int j = 0; j < n; ++j) {
        if (j != i) Insert({(points_[j] - p).squaredNorm(), j}, k, &size, knn);
      }
      return;
    }
    // The shell of cells at Chebyshev distance r from c, inside the grid.
    const Eigen::Vector3i lo = (c.array() - r).cwiseMax(0);
    const Eigen::Vector3i hi = (c.array() + r).cwiseMin(cells_.array() - 1);
    for (int x = lo.x(); x <= hi.x(); ++x) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        const bool side = std::abs(x - c.x()) == r || std::abs(y - c.y()) == r;
        for (int z = lo.z(); z <= hi.z(); ++z) {
          if (!side && std::abs(z - c.z()) != r) {
            // Inside the shell: jump to its far face.
            if (z < c.z() + r) z = c.z() + r - 1;
            continue;
          }
          visit_cell(Eigen::Vector3i(x, y, z));
        }
      }
    }
    // Every point outside the block [c - r, c + r] is at least `bound` from
    // p (its distance to the block's faces that have cells beyond them).
    double bound = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      if (c[a] - r > 0) bound = std::min(bound, p[a] - (lo_[a] + (c[a] - r) * cell_));
      if (c[a] + r < cells_[a] - 1) bound = std::min(bound, lo_[a] + (c[a] + r + 1) * cell_ - p[a]);
    }
    if (!std::isfinite(bound)) return;  // every cell visited
    // The margin covers the rounding of the cell index and of the bound.
    bound -= 1e-9 * cell_ + 1e-12 * p.cwiseAbs().maxCoeff();
    if (size == k && bound > 0.0 && (*knn)[k - 1].first < bound * bound) return;
  }
}

void NearestNeighbours::Within(const Eigen::Vector3d& centre, double radius, std::vector<int>* within,
                               const std::function<bool(int)>& skip) const {
  within->clear();
  if (points_.empty() || !(radius >= 0.0) || !centre.allFinite()) return;
  const double r2 = radius * radius;
  auto visit = [&](int j) {
    if ((points_[j] - centre).squaredNorm() <= r2 && !(skip && skip(j))) within->push_back(j);
  };
  // Every point the distance test accepts lies within `reach` of centre
  // along each axis, whatever the rounding of that test, of centre -+ reach
  // and of the cell arithmetic (which rounds alike for points and bounds).
  const double reach =
      radius * (1.0 + 1e-9) + 1e-12 * (centre.cwiseAbs().maxCoeff() + lo_.cwiseAbs().maxCoeff());
  if (method_ == Method::kSweep) {
    const int a = sweep_axis_;
    const double x0 = centre[a] - reach, x1 = centre[a] + reach;
    auto r = std::lower_bound(order_.begin(), order_.end(), x0,
                              [&](int j, double x) { return points_[j][a] < x; });
    for (; r != order_.end() && points_[*r][a] <= x1; ++r) visit(*r);
    std::sort(within->begin(), within->end());
    return;
  }
  // The block of cells that covers the ball, within the grid.
  Eigen::Vector3i c0, c1;
  double block = 1.0;
  for (int a = 0; a < 3; ++a) {
    const double f0 = std::floor((centre[a] - reach - lo_[a]) / cell_);
    const double f1 = std::floor((centre[a] + reach - lo_[a]) / cell_);
    if (f1 < 0.0 || f0 > cells_[a] - 1.0) return;  // the ball misses the box
    c0[a] = static_cast<int>(std::max(f0, 0.0));
    c1[a] = static_cast<int>(std::min(f1, cells_[a] - 1.0));
    block *= c1[a] - c0[a] + 1.0;
  }
  // A ball of more cells than are occupied: every point instead.
  if (block > static_cast<double>(occupied_cells_)) {
    for (int j = 0; j < static_cast<int>(points_.size()); ++j) visit(j);
    return;
  }
  for (int x = c0.x(); x <= c1.x(); ++x) {
    for (int y = c0.y(); y <= c1.y(); ++y) {
      for (int z = c0.z(); z <= c1.z(); ++z) {
        const auto [first, last] = CellPoints(Eigen::Vector3i(x, y, z));
        for (const int* q = first; q != last; ++q) visit(*q);
      }
    }
  }
  std::sort(within->begin(), within->end());
}

}  // namespace identify_internal
}  // namespace opl
