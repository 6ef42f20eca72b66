// Private to src/identify: the k nearest neighbours of the points of a set,
// exactly (FindSeeds, identify_seeds.cc).
//
// The result for point i is the k smallest pairs (squared distance to i,
// index) over the other points, ascending: the keys are unique, so it does
// not depend on the method. Two methods:
//  - a sweep along the axis of the largest extent (the points sorted along
//    it; a point's search runs outwards and stops on a side once the gap
//    alone exceeds the k-th distance so far): no set-up, but on a surface of
//    N points each search passes a slab of ~sqrt(N) points;
//  - a uniform grid of cells about the typical k-th neighbour distance
//    (measured on a sample): the search visits shells of cells around the
//    point's own until no unvisited cell can hold a nearer point.
// kAuto takes the sweep up to 4096 points and the grid above.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace opl {
namespace identify_internal {

class NearestNeighbours {
 public:
  enum class Method { kSweep, kGrid, kAuto };

  // `points` must outlive the object. k >= 1.
  NearestNeighbours(const std::vector<Eigen::Vector3d>& points, int k, Method method = Method::kAuto);

  // The min(k, size - 1) nearest of point i: (squared distance, index),
  // ascending. `knn` is resized.
  void Find(int i, std::vector<std::pair<double, int>>* knn) const;

  Method method() const { return method_; }

 private:
  void FindBySweep(int i, std::vector<std::pair<double, int>>* knn) const;
  void FindByGrid(int i, std::vector<std::pair<double, int>>* knn) const;
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
