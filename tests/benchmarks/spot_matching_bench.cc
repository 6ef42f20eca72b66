// Benchmark of spot matching across views (issue 6): two overlapping 11 x 11
// laser grids (242 points, 42 and 50 mm spacing: 15-20 px apart) on a wall
// 2.5-3 m from 4 or 8 calibrated 1024 x 768 cameras (f ~ 1000 px, mild
// Brown-Conrady distortion), 0.05 px noise, 15% of the detections dropped,
// 5% spurious ones per view (half on an epipolar line of a real spot), lists
// shuffled. The 4-view case is the real use (one shot group); 8 views shows
// the growth with V. Counters: tracks, recall (points seen in >= 3 views that
// were matched), wrong (tracks mixing points or holding a spurious detection;
// must be 0), ambiguities. Run with --benchmark_repetitions=10
// --benchmark_report_aggregates_only=true for medians.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <Eigen/Dense>

#include "opl/core/format.h"
#include "opl/vision/spot_matching.h"

namespace {

struct BenchScene {
  std::vector<opl::Camera> cameras;
  std::vector<std::vector<opl::SpotInView>> spots;
  std::vector<std::vector<int>> truth;  // point index, -1 spurious
  int points_3plus = 0;
};

BenchScene MakeScene(int num_views) {
  BenchScene s;
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Eigen::Vector3d target(0.0, 0.0, 1.2);
  for (int i = 0; i < num_views; ++i) {
    // Around the wall's normal, 2.5-3 m away, 20-40 deg apart.
    const double az = opl::kPi / 2.0 + (i % 2 == 0 ? -1.0 : 1.0) * (0.2 + 0.09 * (i / 2));
    const double range = 2.5 + 0.5 * u01(rng);
    const Eigen::Vector3d center(range * std::cos(az), -range * std::sin(az),
                                 1.2 + (i % 4 < 2 ? 0.5 : -0.5) * (0.6 + 0.4 * u01(rng)));
    opl::Camera c;
    c.name = "cam" + std::to_string(i);
    c.intrinsics.width_px = 1024;
    c.intrinsics.height_px = 768;
    c.intrinsics.fx_px = 1000.0 + 10.0 * i;
    c.intrinsics.fy_px = c.intrinsics.fx_px;
    c.intrinsics.cx_px = 511.5;
    c.intrinsics.cy_px = 383.5;
    c.intrinsics.k1 = -0.08;
    c.intrinsics.k2 = 0.05;
    c.intrinsics.p1 = 1e-4;
    c.intrinsics.p2 = -1e-4;
    c.cam_from_scene = *opl::CamFromSceneLookingAt(center, target, 0.1 * (u01(rng) - 0.5));
    s.cameras.push_back(c);
  }
  std::vector<Eigen::Vector3d> points;
  const double grids[2][4] = {{-0.08, 1.18, 0.042, 0.17}, {0.1, 1.27, 0.050, -0.12}};
  for (const auto& g : grids) {
    for (int r = -5; r <= 5; ++r) {
      for (int c = -5; c <= 5; ++c) {
        const double a = c * g[2], b = r * g[2];
        points.emplace_back(g[0] + std::cos(g[3]) * a - std::sin(g[3]) * b, 0.0,
                            g[1] + std::sin(g[3]) * a + std::cos(g[3]) * b);
      }
    }
  }
  s.spots.resize(static_cast<size_t>(num_views));
  s.truth.resize(static_cast<size_t>(num_views));
  std::vector<int> views_of(points.size(), 0);
  for (int v = 0; v < num_views; ++v) {
    const opl::Camera& cam = s.cameras[static_cast<size_t>(v)];
    auto& spots = s.spots[static_cast<size_t>(v)];
    auto& truth = s.truth[static_cast<size_t>(v)];
    for (size_t p = 0; p < points.size(); ++p) {
      Eigen::Vector2d px;
      if (!cam.Project(points[p], &px) || !cam.InImage(px, 5.0) || u01(rng) < 0.15) continue;
      opl::SpotInView d;
      d.pixel_px = px + 0.05 * Eigen::Vector2d(n01(rng), n01(rng));
      d.covariance_px2 = 0.05 * 0.05 * Eigen::Matrix2d::Identity();
      spots.push_back(d);
      truth.push_back(static_cast<int>(p));
      ++views_of[p];
    }
    const size_t real = spots.size();
    const int spurious = static_cast<int>(std::lround(0.05 * static_cast<double>(real)));
    for (int k = 0; k < spurious; ++k) {
      opl::SpotInView d;
      d.covariance_px2 = 0.05 * 0.05 * Eigen::Matrix2d::Identity();
      if (k % 2 == 0) {
        // On another view's ray through a point, 5-25% off in depth.
        const opl::Camera& other = s.cameras[static_cast<size_t>((v + 1) % num_views)];
        const Eigen::Vector3d& P = points[static_cast<size_t>(u01(rng) * 242.0)];
        const Eigen::Vector3d C = other.CenterInScene();
        const double f = 1.0 + (0.05 + 0.2 * u01(rng)) * (u01(rng) < 0.5 ? -1.0 : 1.0);
        if (!cam.Project(C + f * (P - C), &d.pixel_px) || !cam.InImage(d.pixel_px, 5.0)) continue;
      } else {
        d.pixel_px = Eigen::Vector2d(5.0 + 1014.0 * u01(rng), 5.0 + 758.0 * u01(rng));
      }
      spots.push_back(d);
      truth.push_back(-1);
    }
    std::vector<size_t> perm(spots.size());
    std::iota(perm.begin(), perm.end(), size_t{0});
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<opl::SpotInView> shuffled;
    std::vector<int> shuffled_truth;
    for (size_t k : perm) {
      shuffled.push_back(spots[k]);
      shuffled_truth.push_back(truth[k]);
    }
    spots = shuffled;
    truth = shuffled_truth;
  }
  for (int n : views_of) s.points_3plus += n >= 3 ? 1 : 0;
  return s;
}

void BM_MatchSpots(benchmark::State& state) {
  const BenchScene scene = MakeScene(static_cast<int>(state.range(0)));
  opl::SpotMatchResult result;
  for (auto _ : state) {
    auto r = opl::MatchSpots(scene.cameras, scene.spots);
    if (!r.ok()) {
      state.SkipWithError(r.status().ToString().c_str());
      return;
    }
    result = std::move(r).value();
    benchmark::DoNotOptimize(result.tracks.data());
  }
  int wrong = 0;
  for (const opl::SpotTrack& t : result.tracks) {
    const auto& first = t.spots[0];
    const int p = scene.truth[static_cast<size_t>(first.view)][static_cast<size_t>(first.spot)];
    bool ok = p >= 0;
    for (const opl::SpotRef& ref : t.spots) {
      ok = ok && scene.truth[static_cast<size_t>(ref.view)][static_cast<size_t>(ref.spot)] == p;
    }
    wrong += ok ? 0 : 1;
  }
  const int good = static_cast<int>(result.tracks.size()) - wrong;
  state.counters["tracks"] = static_cast<double>(result.tracks.size());
  state.counters["recall"] =
      scene.points_3plus > 0 ? static_cast<double>(good) / scene.points_3plus : 0.0;
  state.counters["wrong"] = wrong;
  state.counters["ambiguities"] = static_cast<double>(result.ambiguities.size());
}
BENCHMARK(BM_MatchSpots)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);

}  // namespace
