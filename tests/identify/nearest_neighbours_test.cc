// The exact k nearest neighbours of identify's seed search
// (src/identify/nearest_neighbours.h): the grid and the sweep against a
// brute-force sort of every pair, on the point sets identification meets
// (a plane grid with clutter, a sphere, a box corner, exact duplicates, a
// thin line, widely spread clusters).
#include "identify/nearest_neighbours.h"

#include <algorithm>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace opl::identify_internal {
namespace {

using Knn = std::vector<std::pair<double, int>>;

Knn BruteForce(const std::vector<Eigen::Vector3d>& p, int i, int k) {
  Knn all;
  for (int j = 0; j < static_cast<int>(p.size()); ++j) {
    if (j != i) all.push_back({(p[j] - p[i]).squaredNorm(), j});
  }
  std::sort(all.begin(), all.end());
  all.resize(std::min<size_t>(all.size(), static_cast<size_t>(k)));
  return all;
}

void ExpectExact(const std::vector<Eigen::Vector3d>& p, int k, const char* what) {
  const NearestNeighbours grid(p, k, NearestNeighbours::Method::kGrid);
  const NearestNeighbours sweep(p, k, NearestNeighbours::Method::kSweep);
  ASSERT_EQ(grid.method(), NearestNeighbours::Method::kGrid);
  Knn a, b;
  int mismatches = 0;
  for (int i = 0; i < static_cast<int>(p.size()); ++i) {
    const Knn truth = BruteForce(p, i, k);
    grid.Find(i, &a);
    sweep.Find(i, &b);
    mismatches += (a != truth) + (b != truth);
  }
  EXPECT_EQ(mismatches, 0) << what;
}

std::vector<Eigen::Vector3d> PlaneGridWithClutter(std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> u(-1.0, 41.0);
  std::vector<Eigen::Vector3d> p;
  for (int r = 0; r < 40; ++r) {
    for (int c = 0; c < 40; ++c) {
      p.emplace_back(1000.0 + noise(rng), c + 0.01 * r + noise(rng), r + noise(rng));
    }
  }
  for (int s = 0; s < 300; ++s) p.emplace_back(1000.0 + noise(rng), u(rng), u(rng));
  return p;
}

TEST(NearestNeighbours, GridAndSweepEqualBruteForce) {
  std::mt19937_64 rng(3);
  ExpectExact(PlaneGridWithClutter(rng), 16, "plane grid with clutter");

  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Eigen::Vector3d> sphere;
  for (int s = 0; s < 1500; ++s) sphere.push_back(Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized() * 500.0);
  ExpectExact(sphere, 16, "sphere");

  std::uniform_real_distribution<double> u(0.0, 100.0);
  std::vector<Eigen::Vector3d> corner;
  for (int s = 0; s < 1500; ++s) {
    const int face = s % 3;
    Eigen::Vector3d q(u(rng), u(rng), u(rng));
    q[face] = 0.0;
    corner.push_back(q);
  }
  ExpectExact(corner, 16, "box corner");

  // Exact duplicates: ties in distance, broken by index alike.
  std::vector<Eigen::Vector3d> dup;
  for (int s = 0; s < 400; ++s) dup.push_back(Eigen::Vector3d(s % 7, (s / 7) % 5, 0.0));
  ExpectExact(dup, 16, "duplicates");

  // Every point on one line (the grid's cells are degenerate on two axes).
  std::vector<Eigen::Vector3d> line;
  for (int s = 0; s < 800; ++s) line.push_back(Eigen::Vector3d(u(rng), 0.0, 0.0));
  ExpectExact(line, 16, "line");

  // Clusters far apart (the k-th neighbour of a small cluster lies in
  // another: the search crosses many empty cells).
  std::vector<Eigen::Vector3d> clusters;
  for (int s = 0; s < 600; ++s) {
    const double off = (s % 4 == 0) ? 1e5 : 0.0;
    clusters.push_back(Eigen::Vector3d(off + 0.1 * g(rng), 0.1 * g(rng), 0.1 * g(rng)));
  }
  clusters.push_back(Eigen::Vector3d(5e4, 0.0, 0.0));  // alone in the middle
  ExpectExact(clusters, 16, "clusters");

  // Fewer points than k + 1.
  std::vector<Eigen::Vector3d> few = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 2, 0)};
  ExpectExact(few, 16, "three points");
}

TEST(NearestNeighbours, AutoTakesTheGridAboveFourThousandPoints) {
  std::vector<Eigen::Vector3d> p(4096, Eigen::Vector3d::Zero());
  for (size_t i = 0; i < p.size(); ++i) p[i].x() = static_cast<double>(i);
  EXPECT_EQ(NearestNeighbours(p, 16).method(), NearestNeighbours::Method::kSweep);
  p.emplace_back(5000.0, 0.0, 0.0);
  EXPECT_EQ(NearestNeighbours(p, 16).method(), NearestNeighbours::Method::kGrid);
}

}  // namespace
}  // namespace opl::identify_internal
