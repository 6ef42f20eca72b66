// The exact neighbour queries of identify's seed search and seed growth
// (src/identify/nearest_neighbours.h): the k nearest neighbours and the
// points within a radius, by the grid and by the sweep, against brute force
// over every pair, on the point sets identification meets (a plane grid
// with clutter, a sphere, a box corner, exact duplicates, a thin line,
// widely spread clusters) and on points lying on the cells' boundaries.
#include "identify/nearest_neighbours.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
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

// The indices of the points within `radius` of `centre`, ascending, that
// `skip` does not exclude: every point tested.
std::vector<int> BruteForceWithin(const std::vector<Eigen::Vector3d>& p, const Eigen::Vector3d& centre, double radius,
                                  const std::function<bool(int)>& skip) {
  std::vector<int> within;
  for (int j = 0; j < static_cast<int>(p.size()); ++j) {
    if ((p[j] - centre).squaredNorm() <= radius * radius && !(skip && skip(j))) within.push_back(j);
  }
  return within;
}

// Within by the grid and by the sweep equals brute force for every centre
// and radius given, with and without a predicate (odd indices skipped);
// returns the number of points found by brute force (without the
// predicate), so that a caller can check the queries were not all empty.
int ExpectWithinExact(const std::vector<Eigen::Vector3d>& p, int k, const std::vector<Eigen::Vector3d>& centres,
                      const std::vector<double>& radii, const char* what) {
  const NearestNeighbours grid(p, k, NearestNeighbours::Method::kGrid);
  const NearestNeighbours sweep(p, k, NearestNeighbours::Method::kSweep);
  const std::function<bool(int)> odd = [](int j) { return j % 2 == 1; };
  std::vector<int> a, b;
  int mismatches = 0, found = 0;
  for (const Eigen::Vector3d& c : centres) {
    for (double r : radii) {
      for (const std::function<bool(int)>& skip : {std::function<bool(int)>(), odd}) {
        const std::vector<int> truth = BruteForceWithin(p, c, r, skip);
        if (!skip) found += static_cast<int>(truth.size());
        grid.Within(c, r, &a, skip);
        sweep.Within(c, r, &b, skip);
        mismatches += (a != truth) + (b != truth);
      }
    }
  }
  EXPECT_EQ(mismatches, 0) << what;
  return found;
}

TEST(NearestNeighbours, WithinEqualsBruteForce) {
  std::mt19937_64 rng(5);
  const std::vector<double> radii = {0.0, 0.1, 0.25, 0.5, 1.0, 1.5, 3.0, 7.0};

  // A plane grid with clutter (dense cells): centres at every 7th point and
  // at random places in and beyond the points' box.
  const std::vector<Eigen::Vector3d> plane = PlaneGridWithClutter(rng);
  std::vector<Eigen::Vector3d> centres;
  for (size_t i = 0; i < plane.size(); i += 7) centres.push_back(plane[i]);
  std::uniform_real_distribution<double> u(-5.0, 45.0);
  for (int s = 0; s < 100; ++s) centres.emplace_back(1000.0 + 0.1 * u(rng), u(rng), u(rng));
  EXPECT_GT(ExpectWithinExact(plane, 16, centres, radii, "plane grid with clutter"), 20000);
  EXPECT_TRUE(NearestNeighbours(plane, 16, NearestNeighbours::Method::kGrid).dense_cells());

  // Exact duplicates (7 x 5 positions, about 11 points each); radius 0 at a
  // position finds all its copies, between positions none.
  std::vector<Eigen::Vector3d> dup;
  for (int s = 0; s < 400; ++s) dup.push_back(Eigen::Vector3d(s % 7, (s / 7) % 5, 0.0));
  const std::vector<Eigen::Vector3d> dup_centres = {Eigen::Vector3d(3, 2, 0), Eigen::Vector3d(0, 0, 0),
                                                    Eigen::Vector3d(6, 4, 0), Eigen::Vector3d(2.5, 2, 0)};
  EXPECT_GT(ExpectWithinExact(dup, 16, dup_centres, radii, "duplicates"), 2000);
  const NearestNeighbours dup_grid(dup, 16, NearestNeighbours::Method::kGrid);
  std::vector<int> within;
  dup_grid.Within(Eigen::Vector3d(3, 2, 0), 0.0, &within);
  EXPECT_EQ(within.size(), BruteForceWithin(dup, Eigen::Vector3d(3, 2, 0), 0.0, nullptr).size());
  EXPECT_GE(within.size(), 11u);
  dup_grid.Within(Eigen::Vector3d(2.5, 2, 0), 0.0, &within);
  EXPECT_TRUE(within.empty());

  // An integer lattice whose 6th neighbours are at distance 1: cells of
  // 1, so every point lies on cells' boundaries, and integer radii put
  // points exactly on the ball's surface (they count: distance <= radius).
  std::vector<Eigen::Vector3d> lattice;
  for (int x = 0; x < 12; ++x) {
    for (int y = 0; y < 12; ++y) {
      for (int z = 0; z < 12; ++z) lattice.emplace_back(x, y, z);
    }
  }
  const std::vector<Eigen::Vector3d> lattice_centres = {
      Eigen::Vector3d(5, 5, 5),  Eigen::Vector3d(0, 0, 0),       Eigen::Vector3d(11, 11, 11),
      Eigen::Vector3d(5.5, 5, 5), Eigen::Vector3d(3, 7.5, 11.5), Eigen::Vector3d(-1, 5, 5),
      Eigen::Vector3d(12, 12, 12)};
  const std::vector<double> integer_radii = {0.0, 1.0, 2.0, 3.0, std::sqrt(2.0), 0.5};
  EXPECT_GT(ExpectWithinExact(lattice, 6, lattice_centres, integer_radii, "lattice on cell boundaries"), 500);
  NearestNeighbours(lattice, 6, NearestNeighbours::Method::kGrid).Within(Eigen::Vector3d(5, 5, 5), 1.0, &within);
  EXPECT_EQ(within.size(), 7u);  // the centre and its 6 neighbours at exactly 1
  NearestNeighbours(lattice, 6, NearestNeighbours::Method::kGrid).Within(Eigen::Vector3d(-1, 5, 5), 1.0, &within);
  ASSERT_EQ(within.size(), 1u);  // from outside the box: (0, 5, 5) on the ball's surface
  EXPECT_EQ(lattice[within[0]], Eigen::Vector3d(0, 5, 5));

  // Queries outside the points' box: nothing near, then a radius reaching
  // into the box, then one holding every point (more cells than occupied:
  // every point passed).
  const std::vector<Eigen::Vector3d> outside = {Eigen::Vector3d(1000.0, -200.0, 20.0),
                                                Eigen::Vector3d(-1e6, 1e6, 1e6)};
  EXPECT_GT(ExpectWithinExact(plane, 16, outside, {0.0, 1.0, 195.0, 210.0, 3e6}, "outside the box"), 2 * 1900);

  // Clusters far apart (a box of mostly empty cells: the hash map of
  // occupied cells), a lone point between them.
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Eigen::Vector3d> clusters;
  for (int s = 0; s < 600; ++s) {
    const double off = (s % 4 == 0) ? 1e5 : 0.0;
    clusters.push_back(Eigen::Vector3d(off + 0.1 * g(rng), 0.1 * g(rng), 0.1 * g(rng)));
  }
  clusters.push_back(Eigen::Vector3d(5e4, 0.0, 0.0));
  EXPECT_FALSE(NearestNeighbours(clusters, 16, NearestNeighbours::Method::kGrid).dense_cells());
  std::vector<Eigen::Vector3d> cluster_centres = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1e5, 0.05, 0),
                                                  Eigen::Vector3d(5e4, 0, 0), Eigen::Vector3d(7e4, 0, 0)};
  for (int s = 0; s < 600; s += 13) cluster_centres.push_back(clusters[s]);
  EXPECT_GT(ExpectWithinExact(clusters, 16, cluster_centres, {0.0, 0.05, 0.1, 0.3, 2e4, 6e4}, "clusters"), 5000);

  // No point for a negative or NaN radius or a non-finite centre.
  const NearestNeighbours plane_grid(plane, 16, NearestNeighbours::Method::kGrid);
  for (const double r : {-1.0, std::numeric_limits<double>::quiet_NaN()}) {
    plane_grid.Within(plane[0], r, &within);
    EXPECT_TRUE(within.empty()) << r;
  }
  plane_grid.Within(Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0), 1.0, &within);
  EXPECT_TRUE(within.empty());
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
