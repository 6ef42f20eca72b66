// Step 1 of IdentifySpots (opl/identify/identify_spots.h): the seeds, local
// crosses of a lattice among the scene points (FindSeeds), and the crosses
// derived from a seed that may mix two interleaved grids (DerivedSeeds).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <thread>
#include <utility>
#include <vector>

#include "identify/identify_spots_internal.h"
#include "identify/nearest_neighbours.h"

namespace opl {
namespace identify_internal {

// Seeds: points with two pairs of opposite neighbours (a local lattice cross).
// Every point's seed depends on the pool only, so the points are split into
// `threads` contiguous ranges worked in parallel; the seeds are merged in
// point order, so the result does not depend on the number of threads.
std::vector<Seed> FindSeeds(const Pool& pool, const NearestNeighbours& neighbours, int threads) {
  const int n = pool.size();
  std::vector<Seed> seeds;
  if (n < 5) return seeds;
  // The k nearest neighbours of every point (exact: nearest_neighbours.h).
  const int k = std::min(neighbours.k(), n - 1);
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
    neighbours.Find(i, &knn);
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

}  // namespace identify_internal
}  // namespace opl
