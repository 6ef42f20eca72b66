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
#include <functional>
#include <limits>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "identify/identify_spots_internal.h"
#include "identify/nearest_neighbours.h"

namespace opl {
namespace identify_internal {

namespace {

uint64_t PackNode(const Eigen::Vector2i& node) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(node.x())) << 32) |
         static_cast<uint64_t>(static_cast<uint32_t>(node.y()));
}

}  // namespace

GrowthScale MakeGrowthScale(const std::vector<Seed>& seeds, const Pool& pool) {
  GrowthScale scale;
  if (pool.p.empty()) return scale;
  std::vector<double> steps;
  for (const Seed& s : seeds) {
    if (steps.size() >= 64) break;
    steps.push_back((pool.p[s.pa] - pool.p[s.p0]).norm());
    steps.push_back((pool.p[s.pb] - pool.p[s.p0]).norm());
  }
  double typical_step = 0.0;
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
    typical_step = steps[steps.size() / 2];
  }
  Eigen::Vector3d hi = pool.p[0];
  scale.corner = pool.p[0];
  for (const Eigen::Vector3d& p : pool.p) scale.corner = scale.corner.cwiseMin(p), hi = hi.cwiseMax(p);
  const double extent = (hi - scale.corner).maxCoeff();
  scale.cell = std::max({0.5 * typical_step, extent / double(1 << 20), std::numeric_limits<double>::min()});
  return scale;
}

bool GrowthScale::Local(const Eigen::Vector3d& centre, double radius) const {
  const Eigen::Vector3d a = ((centre - corner).array() - radius) / cell;
  const Eigen::Vector3d b = ((centre - corner).array() + radius) / cell;
  // The points' box spans at most 2^20 + 1 cells a side.
  constexpr double kMax = double(1 << 21);
  if ((b.array() < 0.0).any() || (a.array() > kMax).any()) return false;
  const Eigen::Vector3d c0 = a.cwiseMax(0.0).array().floor();
  const Eigen::Vector3d c1 = b.cwiseMin(kMax).array().floor();
  return (c1 - c0).prod() <= 4096.0;
}

// Breadth-first from the seed's patch: a node v next to a grown node u
// (along d) is predicted from the grown nodes around it, linearly along d
// (2 p(u) - p(u - d)) and by the parallelograms across d
// (p(u) + p(v + e) - p(u + e), e perpendicular to d), averaged; it takes
// the one free point within kTolerance steps of the prediction, and is
// left out (for good) when two points are there (clutter next to a spot,
// another grid). Nodes never leave [-max_extent, max_extent]^2; a node
// whose query is not a local one (GrowthScale) is not grown from there.
void GrowSeed(const Pool& pool, const NearestNeighbours& points, const GrowthScale& scale, int max_extent,
              Seed* seed) {
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
  std::vector<int> near;  // the free points near a prediction
  const std::function<bool(int)> is_used = [&](int j) { return pool.taken[j] || used.count(j) != 0; };
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
      const Eigen::Vector3d prediction = sum / count;
      if (!scale.Local(prediction, kTolerance * step)) continue;
      points.Within(prediction, kTolerance * step, &near, is_used);
      if (near.size() != 1) {
        if (near.size() > 1) failed.insert(key);
        continue;
      }
      const int found = near[0];
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
