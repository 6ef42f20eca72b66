// Benchmarks of the multi-view geometry (issue 6): bundle adjustment of the
// four-camera scene (four 18 MP cameras, f = 5000 px, 3 m from a 2 m room
// corner, extreme views 80 deg apart) with 100 coded targets (seen by 3-4
// cameras) and 500 laser spots (seen by 2-4 cameras), 0.04 px noise, from
// perturbed poses (0.5 deg, 2 cm) and points (1 cm); gauge by the three-point
// datum. The reference in the same run: triangulating every point from the
// true poses without bundle adjustment (TriangulatePoint, 600 points).
// Counters: rms3d_um (RMS 3D error after a 7-dof similarity, all points),
// iterations. Run with --benchmark_repetitions=10
// --benchmark_report_aggregates_only=true for medians.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#include <Eigen/Geometry>

#include "opl/core/format.h"
#include "opl/vision/bundle_adjustment.h"
#include "opl/vision/triangulation.h"

namespace {

using opl::BundleData;

struct BenchScene {
  BundleData truth;
  BundleData start;  // noisy pixels, perturbed poses and points
  std::array<int, 3> datum = {0, 1, 2};
};

const BenchScene& Scene() {
  static const BenchScene scene = [] {
    BenchScene s;
    std::mt19937_64 rng(41);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    std::normal_distribution<double> n01(0.0, 1.0);
    const Eigen::Vector3d center(0.0, 1.2, 0.6);
    const double azimuth_deg[4] = {-130.0, -103.33, -76.67, -50.0};
    const double heights[4] = {1.6, 2.0, 1.3, 1.8};
    for (int i = 0; i < 4; ++i) {
      opl::BundleIntrinsics k;
      k.name = "cam" + std::to_string(i);
      k.intrinsics.width_px = 5472;
      k.intrinsics.height_px = 3648;
      k.intrinsics.fx_px = 5000.0 * (1.0 + 0.02 * i);
      k.intrinsics.fy_px = k.intrinsics.fx_px;
      k.intrinsics.cx_px = 2736.0 + 5.0 * i;
      k.intrinsics.cy_px = 1824.0 - 4.0 * i;
      k.intrinsics.k1 = -0.09;
      k.intrinsics.k2 = 0.11;
      k.intrinsics.k3 = -0.03;
      k.intrinsics.p1 = 2e-4;
      k.intrinsics.p2 = -1.5e-4;
      s.truth.intrinsics.push_back(k);
      const double az = azimuth_deg[i] * opl::kPi / 180.0;
      const double h = std::sqrt(9.0 - std::pow(heights[i] - center.z(), 2));
      opl::BundleCamera c;
      c.name = k.name;
      c.intrinsics_index = i;
      c.cam_from_scene = *opl::CamFromSceneLookingAt(
          center + Eigen::Vector3d(h * std::cos(az), h * std::sin(az), heights[i] - center.z()), center);
      s.truth.cameras.push_back(c);
    }
    // 100 targets seen by >= 3 cameras, then 500 spots seen by >= 2.
    int made = 0;
    while (made < 600) {
      const bool target = made < 100;
      Eigen::Vector3d p = (made % 2 == 0)
                              ? Eigen::Vector3d(-1.0 + 2.0 * u01(rng), 0.2 + 1.8 * u01(rng), 0.0)
                              : Eigen::Vector3d(-1.0 + 2.0 * u01(rng), 2.0, 0.05 + 1.45 * u01(rng));
      std::vector<opl::BundleObservation> seen;
      for (int i = 0; i < 4; ++i) {
        opl::BundleObservation o;
        const opl::Camera c = s.truth.CameraAt(i);
        if (c.Project(p, &o.pixel_px) && c.InImage(o.pixel_px, 20.0)) {
          o.camera = i;
          o.point = made;
          o.covariance_px2 = 0.04 * 0.04 * Eigen::Matrix2d::Identity();
          seen.push_back(o);
        }
      }
      if (seen.size() < (target ? 3u : 2u)) continue;
      opl::BundlePoint bp;
      bp.point_in_scene = p;
      s.truth.points.push_back(bp);
      for (const auto& o : seen) s.truth.observations.push_back(o);
      ++made;
    }
    s.start = s.truth;
    for (auto& o : s.start.observations) o.pixel_px += 0.04 * Eigen::Vector2d(n01(rng), n01(rng));
    for (auto& c : s.start.cameras) {
      const Eigen::Vector3d w(n01(rng), n01(rng), n01(rng));
      c.cam_from_scene = opl::Rigid3d(
          Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * opl::kPi / 180.0, w.normalized())) *
              c.cam_from_scene.rotation,
          c.cam_from_scene.translation + 0.02 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)));
    }
    for (auto& p : s.start.points) p.point_in_scene += 0.01 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
    // Datum among the first targets: the pair farthest apart and the point
    // farthest from their line.
    double best = 0.0;
    for (int a = 0; a < 100; ++a)
      for (int b = a + 1; b < 100; ++b) {
        const double d = (s.truth.points[a].point_in_scene - s.truth.points[b].point_in_scene).norm();
        if (d > best) {
          best = d;
          s.datum[0] = a;
          s.datum[1] = b;
        }
      }
    const Eigen::Vector3d A = s.truth.points[s.datum[0]].point_in_scene;
    const Eigen::Vector3d X = (s.truth.points[s.datum[1]].point_in_scene - A).normalized();
    best = 0.0;
    for (int c = 0; c < 100; ++c) {
      const double d = X.cross(s.truth.points[c].point_in_scene - A).norm();
      if (d > best) {
        best = d;
        s.datum[2] = c;
      }
    }
    return s;
  }();
  return scene;
}

double SimilarityRms(const std::vector<Eigen::Vector3d>& est, const std::vector<Eigen::Vector3d>& truth) {
  Eigen::Matrix3Xd src(3, est.size()), dst(3, est.size());
  for (size_t j = 0; j < est.size(); ++j) {
    src.col(static_cast<Eigen::Index>(j)) = est[j];
    dst.col(static_cast<Eigen::Index>(j)) = truth[j];
  }
  const Eigen::Matrix4d sim = Eigen::umeyama(src, dst, true);
  double sum = 0.0;
  for (size_t j = 0; j < est.size(); ++j) {
    sum += (sim.topLeftCorner<3, 3>() * est[j] + sim.topRightCorner<3, 1>() - truth[j]).squaredNorm();
  }
  return std::sqrt(sum / static_cast<double>(est.size()));
}

std::vector<Eigen::Vector3d> TruthPoints() {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : Scene().truth.points) out.push_back(p.point_in_scene);
  return out;
}

void BM_BundleAdjustFourCameras(benchmark::State& state) {
  const BenchScene& s = Scene();
  opl::BundleOptions options;
  options.gauge = opl::BundleGauge::kThreePointDatum;
  options.datum_points = s.datum;
  options.compute_point_covariances = state.range(0) != 0;
  double rms = 0.0;
  int iterations = 0;
  for (auto _ : state) {
    auto r = opl::BundleAdjust(s.start, options);
    if (!r.ok()) {
      state.SkipWithError(r.status().message().c_str());
      return;
    }
    std::vector<Eigen::Vector3d> est;
    for (const auto& p : r->data.points) est.push_back(p.point_in_scene);
    rms = SimilarityRms(est, TruthPoints());
    iterations = r->iterations;
    benchmark::DoNotOptimize(r);
  }
  state.counters["points"] = static_cast<double>(s.truth.points.size());
  state.counters["observations"] = static_cast<double>(s.truth.observations.size());
  state.counters["rms3d_um"] = rms * 1e6;
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_BundleAdjustFourCameras)->Arg(0)->Arg(1)->ArgName("covariances")->Unit(benchmark::kMillisecond);

// Reference: every point triangulated from the TRUE poses (no bundle
// adjustment), the noisy pixels of the same run.
void BM_TriangulateAllFromTruePoses(benchmark::State& state) {
  const BenchScene& s = Scene();
  std::vector<opl::Camera> cams;
  for (int i = 0; i < 4; ++i) cams.push_back(s.truth.CameraAt(i));
  std::vector<std::vector<opl::PointObservation>> per_point(s.truth.points.size());
  for (const auto& o : s.start.observations) {
    per_point[static_cast<size_t>(o.point)].push_back({&cams[static_cast<size_t>(o.camera)], o.pixel_px, o.covariance_px2});
  }
  double rms = 0.0;
  for (auto _ : state) {
    std::vector<Eigen::Vector3d> est;
    est.reserve(per_point.size());
    for (const auto& obs : per_point) {
      auto r = opl::TriangulatePoint(obs);
      if (!r.ok()) {
        state.SkipWithError(r.status().message().c_str());
        return;
      }
      est.push_back(r->point_in_scene);
    }
    rms = SimilarityRms(est, TruthPoints());
    benchmark::DoNotOptimize(est);
  }
  state.counters["rms3d_um"] = rms * 1e6;
}
BENCHMARK(BM_TriangulateAllFromTruePoses)->Unit(benchmark::kMillisecond);

}  // namespace
