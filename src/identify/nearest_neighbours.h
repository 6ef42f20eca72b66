// Private to src/identify: neighbour queries over a fixed point set, exact:
// the k nearest neighbours of each of its points (FindSeeds,
// identify_seeds.cc) and the points within a radius of any position
// (GrowSeed, identify_growth.cc). One index serves both.
//
// The k nearest of point i are the k smallest pairs (squared distance to i,
// index) over the other points, ascending: the keys are unique, so the
// result does not depend on the method. The points within a radius are
// those whose computed squared distance is at most the radius squared, by
// ascending index: the same for either method. Two methods:
//  - a sweep along the axis of the largest extent (the points sorted along
//    it; a point's search runs outwards and stops on a side once the gap
//    alone exceeds the k-th distance so far; a radius query passes the
//    points whose coordinate along it is within the radius): no set-up, but
//    on a surface of N points each search passes a slab of ~sqrt(N) points;
//  - a uniform grid of cells about the typical k-th neighbour distance
//    (measured on a sample), tabulated densely or, in a box of many empty
//    cells, as a hash map of the occupied ones: a k-nearest search visits
//    shells of cells around the point's own until no unvisited cell can
//    hold a nearer point; a radius query visits the block of cells that
//    covers the ball. Either falls back to passing every point when that is
//    fewer cells (a point far from the others, a radius of many cells).
// kAuto takes the sweep up to 4096 points and the grid above.
#pragma once

#include <cstdint>
#include <functional>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace opl {
namespace identify_internal {

class NearestNeighbours {
 public:
  enum class Method { kSweep, kGrid, kAuto };

  // `points` must outlive the object. k >= 1: the neighbours Find returns
  // (the grid's cells are sized for them).
  NearestNeighbours(const std::vector<Eigen::Vector3d>& points, int k, Method method = Method::kAuto);

  // The min(k, size - 1) nearest of point i: (squared distance, index),
  // ascending. `knn` is resized.
  void Find(int i, std::vector<std::pair<double, int>>* knn) const;

  // The indices of the points within `radius` of `centre` (squared distance
  // at most radius^2), ascending, except those `skip` (when given) returns
  // true for; `skip` is asked only about points within the radius. Any
  // centre (outside the points' box: whatever lies within reach), radius 0
  // (the points equal to centre); none for a negative or NaN radius or a
  // non-finite centre. `within` is overwritten.
  void Within(const Eigen::Vector3d& centre, double radius, std::vector<int>* within,
              const std::function<bool(int)>& skip = nullptr) const;

  int k() const { return k_; }
  Method method() const { return method_; }
  // The grid's cells tabulated densely (false: a hash map of the occupied
  // ones, or the sweep).
  bool dense_cells() const { return !dense_start_.empty(); }

 private:
  void FindBySweep(int i, std::vector<std::pair<double, int>>* knn) const;
  void FindByGrid(int i, std::vector<std::pair<double, int>>* knn) const;
  // The points of one cell: [first, last) of point indices, ascending.
  std::pair<const int*, const int*> CellPoints(const Eigen::Vector3i& c) const;
  Eigen::Vector3i CellOf(const Eigen::Vector3d& p) const;
  static uint64_t Key(const Eigen::Vector3i& c);
  size_t DenseIndex(const Eigen::Vector3i& c) const;

  const std::vector<Eigen::Vector3d>& points_;
  int k_;
  Method method_;
  // Sweep.
  int sweep_axis_ = 0;
  std::vector<int> order_, rank_;
  // Grid.
  Eigen::Vector3d lo_ = Eigen::Vector3d::Zero();
  double cell_ = 1.0;
  Eigen::Vector3i cells_ = Eigen::Vector3i::Ones();  // cells a side, per axis
  size_t occupied_cells_ = 0;
  // Sparse boxes: the occupied cells by a hash map.
  std::vector<int> by_cell_;                                 // point indices by cell
  std::unordered_map<uint64_t, std::pair<int, int>> range_;  // cell -> [begin, end) of by_cell_
  std::vector<int> dense_start_;   // by DenseIndex: [start, next start) of dense_points_; empty: not dense
  std::vector<int> dense_points_;  // point indices by cell
};

}  // namespace identify_internal
}  // namespace opl
