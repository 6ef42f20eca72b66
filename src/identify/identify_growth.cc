// Step 1b of IdentifySpots for large point sets (opl/identify/identify_spots.h):
// a seed's lattice patch grown over its grid (GrowSeed), so that the patch
// pose of step 2 holds over the whole grid instead of only near the seed.
//
// Why. A seed's patch spans +-2 nodes; the pose fitted to it places spots
// to a fraction of the spacing only a few nodes away. On a grid of 71 x 71
// beams, hypotheses scored with such a pose find a fifth of the grid, no
// refinement is clear, and dozens of seeds fail before one near the grid's
// centre succeeds (issue 19 item 8: 27 seeds and 75 derived crosses at
// n = 71). Grown first, the patch covers the grid and its pose, fitted
// outwards stage by stage (Identifier::PatchPose), scores the grid whole.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "identify/identify_spots_internal.h"

namespace opl {
namespace identify_internal {

namespace {

uint64_t PackCell(int64_t x, int64_t y, int64_t z) {
  constexpr int64_t kMask = (int64_t{1} << 21) - 1;
  return (static_cast<uint64_t>(x & kMask) << 42) | (static_cast<uint64_t>(y & kMask) << 21) |
         static_cast<uint64_t>(z & kMask);
}

uint64_t PackNode(const Eigen::Vector2i& node) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(node.x())) << 32) |
         static_cast<uint64_t>(static_cast<uint32_t>(node.y()));
}

}  // namespace

PointHash::PointHash(const std::vector<Eigen::Vector3d>& points, double cell) : points_(points) {
  if (points.empty()) return;
  Eigen::Vector3d hi = points[0];
  lo_ = points[0];
  for (const Eigen::Vector3d& p : points) lo_ = lo_.cwiseMin(p), hi = hi.cwiseMax(p);
  // At most 2^20 cells a side (the key packs 21 bits an axis).
  const double extent = (hi - lo_).maxCoeff();
  cell_ = std::max({cell, extent / double(1 << 20), std::numeric_limits<double>::min()});
  std::vector<std::pair<uint64_t, int>> keyed(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d c = ((points[i] - lo_) / cell_).array().floor();
    keyed[i] = {PackCell(static_cast<int64_t>(c.x()), static_cast<int64_t>(c.y()), static_cast<int64_t>(c.z())),
                static_cast<int>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  order_.resize(keyed.size());
  for (size_t k = 0; k < keyed.size(); ++k) {
    order_[k] = keyed[k].second;
    if (k == 0 || keyed[k].first != keyed[k - 1].first) {
      range_[keyed[k].first] = {static_cast<int>(k), static_cast<int>(k)};
    }
    range_[keyed[k].first].second = static_cast<int>(k) + 1;
  }
}

void PointHash::Within(const Eigen::Vector3d& centre, double radius, std::vector<int>* out) const {
  out->clear();
  if (order_.empty() || !(radius >= 0.0)) return;
  const Eigen::Vector3d a = ((centre - lo_).array() - radius) / cell_;
  const Eigen::Vector3d b = ((centre - lo_).array() + radius) / cell_;
  // A query far outside the points' box (or at a huge radius) finds nothing
  // or is refused: the box spans fewer than 2^21 cells.
  constexpr double kMax = double(1 << 21);
  if ((b.array() < 0.0).any() || (a.array() > kMax).any()) return;
  const Eigen::Vector3i c0 = a.cwiseMax(0.0).array().floor().cast<int>();
  const Eigen::Vector3i c1 = b.cwiseMin(kMax).array().floor().cast<int>();
  if ((c1 - c0).prod() > 4096) return;  // not a local query
  const double r2 = radius * radius;
  for (int x = c0.x(); x <= c1.x(); ++x) {
    for (int y = c0.y(); y <= c1.y(); ++y) {
      for (int z = c0.z(); z <= c1.z(); ++z) {
        const auto it = range_.find(PackCell(x, y, z));
        if (it == range_.end()) continue;
        for (int k = it->second.first; k < it->second.second; ++k) {
          if ((points_[order_[k]] - centre).squaredNorm() <= r2) out->push_back(order_[k]);
        }
      }
    }
  }
  std::sort(out->begin(), out->end());
}

double TypicalStep(const std::vector<Seed>& seeds, const Pool& pool) {
  std::vector<double> steps;
  for (const Seed& s : seeds) {
    if (steps.size() >= 64) break;
    steps.push_back((pool.p[s.pa] - pool.p[s.p0]).norm());
    steps.push_back((pool.p[s.pb] - pool.p[s.p0]).norm());
  }
  if (steps.empty()) return 0.0;
  std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
  return steps[steps.size() / 2];
}

// Breadth-first from the seed's patch: a node v next to a grown node u
// (along d) is predicted from the grown nodes around it, linearly along d
// (2 p(u) - p(u - d)) and by the parallelograms across d
// (p(u) + p(v + e) - p(u + e), e perpendicular to d), averaged; it takes
// the one free point within kTolerance steps of the prediction, and is
// left out (for good) when two points are there (clutter next to a spot,
// another grid). Nodes never leave [-max_extent, max_extent]^2.
void GrowSeed(const Pool& pool, const PointHash& hash, int max_extent, Seed* seed) {
  constexpr double kTolerance = 0.25;  // of the local step
  constexpr size_t kRingSize = 24;     // far nodes kept per ring for the pose
  std::unordered_map<uint64_t, int> node_point;
  std::unordered_set<int> used;
  std::unordered_set<uint64_t> failed;
  std::deque<Eigen::Vector2i> queue;
  for (const auto& [i, o] : seed->patch) {
    if (node_point.emplace(PackNode(o), i).second) {
      used.insert(i);
      queue.push_back(o);
    }
  }
  auto point_at = [&](const Eigen::Vector2i& node) -> int {
    const auto it = node_point.find(PackNode(node));
    return it == node_point.end() ? -1 : it->second;
  };
  static const std::array<Eigen::Vector2i, 4> kDirs = {Eigen::Vector2i(1, 0), Eigen::Vector2i(-1, 0),
                                                       Eigen::Vector2i(0, 1), Eigen::Vector2i(0, -1)};
  std::vector<std::pair<int, Eigen::Vector2i>> grown;
  std::vector<int> near;
  while (!queue.empty()) {
    const Eigen::Vector2i u = queue.front();
    queue.pop_front();
    const int pu = point_at(u);
    for (const Eigen::Vector2i& d : kDirs) {
      const Eigen::Vector2i v = u + d;
      if (v.cwiseAbs().maxCoeff() > max_extent) continue;
      const uint64_t key = PackNode(v);
      if (node_point.count(key) != 0 || failed.count(key) != 0) continue;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      int count = 0;
      double step = 0.0;
      const int back = point_at(u - d);
      if (back >= 0) {
        sum += 2.0 * pool.p[pu] - pool.p[back];
        step = (pool.p[pu] - pool.p[back]).norm();
        ++count;
      }
      const Eigen::Vector2i e(d.y(), d.x());
      for (const Eigen::Vector2i& side : {e, Eigen::Vector2i(-e)}) {
        const int a = point_at(u + side), b = point_at(v + side);
        if (a < 0 || b < 0) continue;
        sum += pool.p[pu] + pool.p[b] - pool.p[a];
        if (step == 0.0) step = (pool.p[b] - pool.p[a]).norm();
        ++count;
      }
      if (count == 0 || !(step > 0.0)) continue;  // reached later from another side
      hash.Within(sum / count, kTolerance * step, &near);
      int found = -1, candidates = 0;
      for (int j : near) {
        if (pool.taken[j] || used.count(j) != 0) continue;
        found = j;
        ++candidates;
      }
      if (candidates != 1) {
        if (candidates > 1) failed.insert(key);
        continue;
      }
      node_point.emplace(key, found);
      used.insert(found);
      grown.push_back({found, v});
      queue.push_back(v);
    }
  }
  // The far nodes, beyond the patch's +-2, by rings of Chebyshev radius
  // (2, 4], (4, 8], (8, 16], ... (the stages of Identifier::ExtendPatchPose):
  // of each ring an even sub-lattice of at most about kRingSize nodes,
  // spread over it.
  std::vector<std::vector<std::pair<int, Eigen::Vector2i>>> rings;
  for (const auto& g : grown) {
    const int r = g.second.cwiseAbs().maxCoeff();
    if (r <= 2) continue;
    size_t ring = 0;
    while ((4 << ring) < r) ++ring;
    if (rings.size() <= ring) rings.resize(ring + 1);
    rings[ring].push_back(g);
  }
  seed->far.clear();
  for (const auto& ring : rings) {
    const int stride = std::max(1, static_cast<int>(std::ceil(std::sqrt(ring.size() / double(kRingSize)))));
    for (const auto& g : ring) {
      if (g.second.x() % stride == 0 && g.second.y() % stride == 0) seed->far.push_back(g);
    }
  }
  seed->grown = seed->patch;
  seed->grown.insert(seed->grown.end(), grown.begin(), grown.end());
}

}  // namespace identify_internal
}  // namespace opl
