// Bundle adjustment against simulations with known truth: the issue-6 figure
// (four 18 MP cameras at ~3 m, ~100 targets, 0.04 px noise: RMS 3D error at
// most 1e-5 of the scene size), point covariances against ceres::Covariance
// and against a Monte Carlo of noisy solves, the cost functor's automatic
// derivatives against numeric differentiation and its residual against
// OpenCV's projectPoints, shared intrinsics refined, a robust loss, errors.
#include "opl/vision/bundle_adjustment.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "opl/core/format.h"
#include <opencv2/calib3d.hpp>

#include "opl/vision/scene_frame.h"

namespace opl {
namespace {

int MonteCarloTrials(int default_trials) {
  const char* env = std::getenv("OPL_VISION_MC");
  if (env == nullptr) return default_trials;
  const int n = std::atoi(env);
  return n > 0 ? n : default_trials;
}

struct Scene {
  BundleData truth;            // true poses and points, noise-free pixels
  std::vector<Eigen::Vector2d> clean_px;
  double size = 0.0;           // largest distance between two points
  std::array<int, 3> datum = {-1, -1, -1};
  std::array<int, 2> artifact = {-1, -1};
};

// The issue-6 scene analogue: a floor (z = 0) and a back wall (y = 2 m) of a
// 2 m room corner, targets on both; four cameras 3 m from the scene centre on
// an arc of 80 deg (the extreme views 80 deg apart), at 1.3-2.0 m height,
// each its own calibrated physical camera (constant intrinsics).
Scene MakeScene(int num_targets, int width, int height, double focal, uint64_t seed,
                double spread_deg = 80.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  Scene s;
  const Eigen::Vector3d center(0.0, 1.2, 0.6);
  const double azimuth_deg[4] = {-90.0 - spread_deg / 2.0, -90.0 - spread_deg / 6.0,
                                 -90.0 + spread_deg / 6.0, -90.0 + spread_deg / 2.0};
  const double heights[4] = {1.6, 2.0, 1.3, 1.8};
  for (int i = 0; i < 4; ++i) {
    BundleIntrinsics k;
    k.name = "cam" + std::to_string(i);
    k.intrinsics.width_px = width;
    k.intrinsics.height_px = height;
    k.intrinsics.fx_px = focal * (1.0 + 0.02 * i);
    k.intrinsics.fy_px = k.intrinsics.fx_px * 1.0003;
    k.intrinsics.cx_px = width / 2.0 + 7.3 * (i - 1.5);
    k.intrinsics.cy_px = height / 2.0 - 5.1 * (i - 1.5);
    k.intrinsics.k1 = -0.09 + 0.01 * i;
    k.intrinsics.k2 = 0.11;
    k.intrinsics.k3 = -0.03;
    k.intrinsics.p1 = 2e-4;
    k.intrinsics.p2 = -1.5e-4;
    k.constant = true;
    s.truth.intrinsics.push_back(k);
    const double az = azimuth_deg[i] * kPi / 180.0;
    const double horizontal = std::sqrt(9.0 - std::pow(heights[i] - center.z(), 2));
    const Eigen::Vector3d c = center + Eigen::Vector3d(horizontal * std::cos(az),
                                                       horizontal * std::sin(az),
                                                       heights[i] - center.z());
    BundleCamera cam;
    cam.name = k.name;
    cam.intrinsics_index = i;
    cam.cam_from_scene = *CamFromSceneLookingAt(c, center, 0.02 * (i - 1.5));
    s.truth.cameras.push_back(cam);
  }
  // Targets: half on the floor, half on the wall, uniformly spread; keep
  // those seen by at least 3 cameras inside the image.
  int made = 0;
  while (made < num_targets) {
    Eigen::Vector3d p;
    if (made % 2 == 0) {
      p = Eigen::Vector3d(-1.0 + 2.0 * u01(rng), 0.2 + 1.8 * u01(rng), 0.0);
    } else {
      p = Eigen::Vector3d(-1.0 + 2.0 * u01(rng), 2.0, 0.05 + 1.45 * u01(rng));
    }
    std::vector<std::pair<int, Eigen::Vector2d>> seen;
    for (int i = 0; i < 4; ++i) {
      const Camera c = s.truth.CameraAt(i);
      Eigen::Vector2d px;
      if (c.Project(p, &px) && c.InImage(px, 20.0)) seen.emplace_back(i, px);
    }
    if (seen.size() < 3) continue;
    BundlePoint bp;
    bp.point_in_scene = p;
    s.truth.points.push_back(bp);
    for (const auto& [i, px] : seen) {
      BundleObservation o;
      o.camera = i;
      o.point = made;
      o.pixel_px = px;
      s.truth.observations.push_back(o);
      s.clean_px.push_back(px);
    }
    ++made;
  }
  // Scene size: the largest distance between two targets.
  for (const auto& a : s.truth.points)
    for (const auto& b : s.truth.points)
      s.size = std::max(s.size, (a.point_in_scene - b.point_in_scene).norm());
  // Datum: A the front-left floor target, B the front-right one, C the
  // highest wall target; artifact: the two wall targets farthest apart in x.
  auto nearest = [&](const Eigen::Vector3d& q) {
    int best = 0;
    for (size_t j = 0; j < s.truth.points.size(); ++j) {
      if ((s.truth.points[j].point_in_scene - q).norm() <
          (s.truth.points[static_cast<size_t>(best)].point_in_scene - q).norm()) {
        best = static_cast<int>(j);
      }
    }
    return best;
  };
  s.datum = {nearest({-1.0, 0.2, 0.0}), nearest({1.0, 0.2, 0.0}), nearest({0.0, 2.0, 1.5})};
  s.artifact = {nearest({-1.0, 2.0, 0.75}), nearest({1.0, 2.0, 0.75})};
  return s;
}

// Noisy copy of the scene's observations with the given sigma.
BundleData Noisy(const Scene& s, double sigma_px, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, sigma_px);
  BundleData d = s.truth;
  for (size_t o = 0; o < d.observations.size(); ++o) {
    d.observations[o].pixel_px = s.clean_px[o] + Eigen::Vector2d(n(rng), n(rng));
    d.observations[o].covariance_px2 = sigma_px * sigma_px * Eigen::Matrix2d::Identity();
  }
  return d;
}

void Perturb(BundleData* d, double rot_deg, double trans_m, double point_m, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  for (BundleCamera& c : d->cameras) {
    const Eigen::Vector3d w(n(rng), n(rng), n(rng));
    const Eigen::Quaterniond dq(Eigen::AngleAxisd(rot_deg * kPi / 180.0, w.normalized()));
    c.cam_from_scene = Rigid3d(dq * c.cam_from_scene.rotation,
                               c.cam_from_scene.translation +
                                   trans_m * Eigen::Vector3d(n(rng), n(rng), n(rng)));
  }
  for (BundlePoint& p : d->points) p.point_in_scene += point_m * Eigen::Vector3d(n(rng), n(rng), n(rng));
}

std::vector<Eigen::Vector3d> Points(const BundleData& d) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : d.points) out.push_back(p.point_in_scene);
  return out;
}

// The truth expressed in the scene frame of its own datum points.
std::vector<Eigen::Vector3d> TruthInDatum(const Scene& s) {
  std::vector<Eigen::Vector3d> pts = Points(s.truth);
  const auto f = SceneFromThreePoints(pts[static_cast<size_t>(s.datum[0])], pts[static_cast<size_t>(s.datum[1])],
                                      pts[static_cast<size_t>(s.datum[2])]);
  EXPECT_TRUE(f.ok());
  EXPECT_TRUE(TransformScene(*f, 1.0, nullptr, &pts).ok());
  return pts;
}

double Rms3d(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double sum = 0.0;
  for (size_t j = 0; j < a.size(); ++j) sum += (a[j] - b[j]).squaredNorm();
  return std::sqrt(sum / static_cast<double>(a.size()));
}

struct FigureResult {
  double scene_size = 0.0;
  int targets = 0;
  double rms_similarity = 0.0;     // RMS over realizations of the per-solve RMS 3D error (vector norm)
  double rms_datum = 0.0;          // same, three-point datum + artifact scale
  double predicted_datum = 0.0;    // RMS sqrt(trace) of the datum covariances
  double rms_reprojection_px = 0.0;
  double variance_factor = 0.0;
};

// `realizations` noisy solves of the issue-6 scene, each from perturbed poses
// (0.5 deg, 2 cm) and points (1 cm), all four cameras and all targets free
// (the 7-dof gauge floats), intrinsics known; then the scene frame from three
// targets. The estimate is compared with the truth (1) after a 7-dof
// similarity (Umeyama, Eigen's own) over all targets: the unscaled shape;
// (2) in the three-point datum of the estimated targets, scaled by an
// artifact (two wall targets ~2 m apart, their true distance as calibrated
// length): the frame a user gets.
FigureResult RunFigure(double focal_px, double sigma_px, double spread_deg, int realizations) {
  const Scene s = MakeScene(100, 5472, 3648, focal_px, 17, spread_deg);
  const std::vector<Eigen::Vector3d> truth = TruthInDatum(s);
  std::mt19937_64 rng(23);
  FigureResult out;
  out.scene_size = s.size;
  out.targets = static_cast<int>(truth.size());
  for (int t = 0; t < realizations; ++t) {
    BundleData start = Noisy(s, sigma_px, rng);
    Perturb(&start, 0.5, 0.02, 0.01, rng);
    BundleOptions options;
    options.gauge = BundleGauge::kThreePointDatum;
    options.datum_points = s.datum;
    options.compute_point_covariances = (t == 0);
    const auto r = BundleAdjust(start, options);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) return out;
    if (t == 0) {
      const std::string report = r->Report();
      std::printf("%s", report.c_str());
      EXPECT_NE(report.find("gauge: three-point datum (points " + std::to_string(s.datum[0])),
                std::string::npos);
      EXPECT_NE(report.find("camera 3 'cam3'"), std::string::npos);
      EXPECT_EQ(r->linear_solver, "SPARSE_SCHUR (SUITE_SPARSE)");
      double tr = 0.0;
      for (const auto& c : r->point_covariances) tr += c.trace();
      out.predicted_datum = std::sqrt(tr / static_cast<double>(truth.size()));
      // The datum points land where the frame says.
      const auto& p = r->data.points;
      EXPECT_LT(p[static_cast<size_t>(s.datum[0])].point_in_scene.norm(), 1e-12);
      EXPECT_LT(p[static_cast<size_t>(s.datum[1])].point_in_scene.tail<2>().norm(), 1e-12);
      EXPECT_LT(std::abs(p[static_cast<size_t>(s.datum[2])].point_in_scene.z()), 1e-12);
    }
    out.rms_reprojection_px += r->rms_reprojection_px / realizations;
    out.variance_factor += r->variance_factor / realizations;
    const std::vector<Eigen::Vector3d> est = Points(r->data);
    Eigen::Matrix3Xd src(3, est.size()), dst(3, est.size());
    for (size_t j = 0; j < est.size(); ++j) {
      src.col(static_cast<Eigen::Index>(j)) = est[j];
      dst.col(static_cast<Eigen::Index>(j)) = truth[j];
    }
    const Eigen::Matrix4d sim = Eigen::umeyama(src, dst, true);
    std::vector<Eigen::Vector3d> aligned;
    for (const auto& p : est) aligned.push_back(sim.topLeftCorner<3, 3>() * p + sim.topRightCorner<3, 1>());
    const size_t i1 = static_cast<size_t>(s.artifact[0]), i2 = static_cast<size_t>(s.artifact[1]);
    const auto scale = ScaleFromArtifact(est[i1], est[i2], (truth[i2] - truth[i1]).norm());
    EXPECT_TRUE(scale.ok());
    std::vector<Eigen::Vector3d> scaled;
    for (const auto& p : est) scaled.push_back(scale->scale * p);
    out.rms_similarity += std::pow(Rms3d(aligned, truth), 2) / realizations;
    out.rms_datum += std::pow(Rms3d(scaled, truth), 2) / realizations;
  }
  out.rms_similarity = std::sqrt(out.rms_similarity);
  out.rms_datum = std::sqrt(out.rms_datum);
  std::printf(
      "issue-6 figure: 4 cameras 5472x3648 px, f = %.0f px, 3 m from the scene centre, extreme "
      "views %.0f deg apart, %d targets, noise %.3f px, scene size %.3f m (largest target "
      "distance), %d noisy solves\n"
      "  RMS 3D error after 7-dof similarity: %.2f um = %.2e of the scene size "
      "(per coordinate %.2e)\n"
      "  RMS 3D error, three-point datum + artifact scale: %.2f um = %.2e "
      "(first-order prediction in the datum, |AB| held: %.2f um)\n"
      "  mean variance factor %.3f, RMS reprojection %.4f px\n",
      focal_px, spread_deg, out.targets, sigma_px, s.size, realizations, out.rms_similarity * 1e6,
      out.rms_similarity / s.size, out.rms_similarity / std::sqrt(3.0) / s.size,
      out.rms_datum * 1e6, out.rms_datum / s.size, out.predicted_datum * 1e6,
      out.variance_factor, out.rms_reprojection_px);
  return out;
}

TEST(BundleAdjustment, IssueSixFigureFourEighteenMegapixelCamerasAtThreeMetres) {
  const int realizations = 5;
  // The issue's figure, at the favourable end of the stated ranges: f = 5500
  // px, AprilTag-corner noise 0.03 px, extreme views 90 deg apart.
  const FigureResult best = RunFigure(5500.0, 0.03, 90.0, realizations);
  EXPECT_LE(best.rms_similarity, 1e-5 * best.scene_size);
  EXPECT_LE(best.rms_datum, 1.5e-5 * best.scene_size);
  // chi^2 / dof ~ 1: the solve reached the minimum the noise allows.
  EXPECT_NEAR(best.variance_factor, 1.0, 0.2);
  // The middle of the ranges (f = 5000 px, 0.04 px, 80 deg) does NOT reach
  // 1e-5 as a 3D vector norm (about 1.5e-5); it does per coordinate. Held
  // here as a regression bound, and reported (docs/multiview.md).
  const FigureResult mid = RunFigure(5000.0, 0.04, 80.0, realizations);
  EXPECT_LE(mid.rms_similarity, 1.7e-5 * mid.scene_size);
  EXPECT_LE(mid.rms_similarity / std::sqrt(3.0), 1e-5 * mid.scene_size);
  EXPECT_LE(mid.rms_datum, 2.5e-5 * mid.scene_size);
}

// A small scene (1024 x 768 px, f = 1000 px: the same field of view) for the
// tests that solve many times.
Scene SmallScene(int targets, uint64_t seed) { return MakeScene(targets, 1024, 768, 1000.0, seed); }

TEST(BundleAdjustment, FixedGaugeCovarianceMatchesCeresCovariance) {
  const Scene s = SmallScene(24, 5);
  std::mt19937_64 rng(1);
  const double sigma = 0.1;
  BundleData d = Noisy(s, sigma, rng);
  d.cameras[0].pose_constant = true;  // a calibrated rig of two cameras holds
  d.cameras[1].pose_constant = true;  // all 7 gauge degrees (and more)
  Perturb(&d, 0.0, 0.0, 0.005, rng);
  BundleOptions options;
  options.compute_point_covariances = true;
  const auto r = BundleAdjust(d, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->point_covariances.size(), d.points.size()) << r->covariance_method;

  // Independent: ceres::Covariance (dense SVD) on the same problem at the
  // solution, built here with its own blocks.
  BundleData sol = r->data;
  std::vector<std::array<double, 4>> q(4);
  std::vector<std::array<double, 3>> t(4);
  std::vector<std::array<double, kNumCameraParameters>> k(4);
  std::vector<std::array<double, 3>> x(sol.points.size());
  ceres::Problem problem;
  for (size_t i = 0; i < 4; ++i) {
    const auto& c = sol.cameras[i].cam_from_scene;
    q[i] = {c.rotation.x(), c.rotation.y(), c.rotation.z(), c.rotation.w()};
    t[i] = {c.translation.x(), c.translation.y(), c.translation.z()};
    k[i] = sol.intrinsics[i].intrinsics.Packed();
  }
  for (size_t j = 0; j < x.size(); ++j) {
    x[j] = {sol.points[j].point_in_scene.x(), sol.points[j].point_in_scene.y(),
            sol.points[j].point_in_scene.z()};
  }
  for (const BundleObservation& o : sol.observations) {
    const size_t i = static_cast<size_t>(o.camera);
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<ReprojectionCostFunctor, 2, 4, 3, kNumCameraParameters, 3>(
            new ReprojectionCostFunctor(o.pixel_px, Eigen::Matrix2d::Identity() / sigma)),
        nullptr, q[i].data(), t[i].data(), k[i].data(), x[static_cast<size_t>(o.point)].data());
  }
  for (size_t i = 0; i < 4; ++i) {
    problem.SetManifold(q[i].data(), new ceres::EigenQuaternionManifold);
    problem.SetParameterBlockConstant(k[i].data());
    if (i < 2) {
      problem.SetParameterBlockConstant(q[i].data());
      problem.SetParameterBlockConstant(t[i].data());
    }
  }
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (const auto& p : x) blocks.emplace_back(p.data(), p.data());
  for (size_t j = 1; j < x.size(); ++j) blocks.emplace_back(x[0].data(), x[j].data());
  ASSERT_TRUE(cov.Compute(blocks, &problem));
  ASSERT_EQ(r->point_own_covariances.size(), x.size());
  ASSERT_EQ(r->point_shared_factors.size(), x.size());
  double worst = 0.0, worst_split = 0.0, worst_cross = 0.0;
  for (size_t j = 0; j < x.size(); ++j) {
    Eigen::Matrix3d c;
    cov.GetCovarianceBlock(x[j].data(), x[j].data(), c.data());
    worst = std::max(worst, (c - r->point_covariances[j]).norm() / c.norm());
    // The own / shared split adds up to the same covariance...
    const Eigen::MatrixXd& K = r->point_shared_factors[j];
    const Eigen::Matrix3d sum = r->point_own_covariances[j] + K * K.transpose();
    worst_split = std::max(worst_split, (c - sum).norm() / c.norm());
    // ... and its shared part is the cross-covariance with another point.
    if (j > 0) {
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor> cross;  // Ceres writes row-major
      cov.GetCovarianceBlock(x[0].data(), x[j].data(), cross.data());
      const Eigen::Matrix3d predicted = r->point_shared_factors[0] * K.transpose();
      worst_cross = std::max(worst_cross, (cross - predicted).norm() / c.norm());
    }
  }
  std::printf("Schur covariance vs ceres::Covariance (DENSE_SVD): worst relative difference %.2e; "
              "own + shared %.2e; cross-covariances %.2e (of the point's covariance)\n",
              worst, worst_split, worst_cross);
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(worst_split, 1e-6);
  EXPECT_LT(worst_cross, 1e-6);
}

TEST(BundleAdjustment, DatumCovarianceMatchesMonteCarlo) {
  const Scene s = SmallScene(20, 8);
  const double sigma = 0.05;
  BundleOptions options;
  options.gauge = BundleGauge::kThreePointDatum;
  options.datum_points = s.datum;
  options.compute_point_covariances = true;
  std::mt19937_64 rng(2);
  // Predicted at the truth: noise-free pixels with the noise's covariance.
  BundleData clean = Noisy(s, sigma, rng);
  for (size_t o = 0; o < clean.observations.size(); ++o) clean.observations[o].pixel_px = s.clean_px[o];
  const auto predicted = BundleAdjust(clean, options);
  ASSERT_TRUE(predicted.ok()) << predicted.status().ToString();
  ASSERT_EQ(predicted->point_covariances.size(), s.truth.points.size()) << predicted->covariance_method;

  const std::vector<Eigen::Vector3d> truth = TruthInDatum(s);
  const size_t ia = static_cast<size_t>(s.datum[0]), ib = static_cast<size_t>(s.datum[1]);
  const double d0 = (truth[ib] - truth[ia]).norm();
  const int trials = MonteCarloTrials(200);
  const size_t np = truth.size();
  std::vector<Eigen::Matrix3d> scatter(np, Eigen::Matrix3d::Zero());
  // Pairs of points: the spread of their difference needs the
  // cross-covariance, Cov(X_i - X_j) = C_i + C_j - K_i K_j^T - K_j K_i^T.
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t j = 1; j < np; j += 3) pairs.emplace_back(j - 1, j);
  std::vector<Eigen::Matrix3d> pair_scatter(pairs.size(), Eigen::Matrix3d::Zero());
  for (int t = 0; t < trials; ++t) {
    const BundleData noisy = Noisy(s, sigma, rng);
    BundleOptions o = options;
    o.compute_point_covariances = false;
    const auto r = BundleAdjust(noisy, o);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    std::vector<Eigen::Vector3d> est = Points(r->data);
    // The covariance holds |AB|: scale the unscaled solve to it.
    const double k = d0 / (est[ib] - est[ia]).norm();
    for (size_t j = 0; j < np; ++j) {
      const Eigen::Vector3d e = k * est[j] - truth[j];
      scatter[j] += e * e.transpose() / trials;
    }
    for (size_t q = 0; q < pairs.size(); ++q) {
      const auto [a, b] = pairs[q];
      const Eigen::Vector3d e = k * (est[a] - est[b]) - (truth[a] - truth[b]);
      pair_scatter[q] += e * e.transpose() / trials;
    }
  }
  // Pooled over the pairs: predicted with the split, and as if independent.
  double pair_ratio2 = 0.0, independent_ratio2 = 0.0;
  for (size_t q = 0; q < pairs.size(); ++q) {
    const auto [a, b] = pairs[q];
    const Eigen::MatrixXd& Ka = predicted->point_shared_factors[a];
    const Eigen::MatrixXd& Kb = predicted->point_shared_factors[b];
    const Eigen::Matrix3d independent = predicted->point_covariances[a] + predicted->point_covariances[b];
    const Eigen::Matrix3d with_cross =
        independent - Ka * Kb.transpose() - Kb * Ka.transpose();
    pair_ratio2 += pair_scatter[q].trace() / with_cross.trace();
    independent_ratio2 += pair_scatter[q].trace() / independent.trace();
  }
  const double pair_ratio = std::sqrt(pair_ratio2 / static_cast<double>(pairs.size()));
  const double independent_ratio = std::sqrt(independent_ratio2 / static_cast<double>(pairs.size()));
  std::printf("differences of %zu point pairs: Monte Carlo / predicted sigma %.3f with the "
              "cross-covariances, %.3f as if independent\n",
              pairs.size(), pair_ratio, independent_ratio);
  EXPECT_GT(pair_ratio, 0.85);
  EXPECT_LT(pair_ratio, 1.18);
  double sum_ratio2 = 0.0;
  int n = 0;
  double worst_point = 1.0;
  for (size_t j = 0; j < np; ++j) {
    const Eigen::Matrix3d& c = predicted->point_covariances[j];
    for (int a = 0; a < 3; ++a) {
      if (c(a, a) < 1e-24) {  // datum-fixed coordinates: zero both ways
        EXPECT_LT(scatter[j](a, a), 1e-20) << "point " << j << " axis " << a;
        continue;
      }
      sum_ratio2 += scatter[j](a, a) / c(a, a);
      ++n;
    }
    if (c.trace() > 1e-24) {
      const double ratio = std::sqrt(scatter[j].trace() / c.trace());
      if (std::abs(std::log(ratio)) > std::abs(std::log(worst_point))) worst_point = ratio;
    }
  }
  const double pooled = std::sqrt(sum_ratio2 / n);
  std::printf("datum covariance vs %d-solve Monte Carlo: pooled sigma ratio %.3f over %d "
              "coordinates, worst point %.3f\n", trials, pooled, n, worst_point);
  EXPECT_GT(pooled, 0.8);
  EXPECT_LT(pooled, 1.25);
  EXPECT_GT(worst_point, 0.6);
  EXPECT_LT(worst_point, 1.6);
}

// A point seen only from one position (two images of one camera that stood
// still, as a camera shooting both grids; COLMAP's models place such images a
// little apart): its depth is free. The 3x3 block still factors, but its
// inverse has no digits and made the reduced camera matrix indefinite
// (smallest eigenvalue -0.35 of the largest on a COLMAP model; refused as
// "5 near-zero eigenvalues, 7 expected"). Now the point is named.
TEST(BundleAdjustment, PointSeenFromOnePositionIsNamed) {
  const Scene s = SmallScene(20, 8);
  BundleData d = s.truth;
  // Image 4: camera 0 again, 1e-7 of the scene away, turned a little.
  BundleCamera twin = d.cameras[0];
  twin.name = "cam0 again";
  const Eigen::Vector3d centre = twin.cam_from_scene.Inverse().translation;
  const Eigen::Vector3d target = d.points[0].point_in_scene;
  twin.cam_from_scene = *CamFromSceneLookingAt(centre + Eigen::Vector3d(1e-7 * s.size, 0.0, 0.0),
                                               target + Eigen::Vector3d(0.0, 0.0, 0.01), 0.03);
  d.cameras.push_back(twin);
  const int twin_index = static_cast<int>(d.cameras.size()) - 1;
  const std::vector<BundleObservation> observations = d.observations;
  for (const BundleObservation& o : observations) {
    if (o.camera != 0) continue;
    BundleObservation t = o;
    t.camera = twin_index;
    ASSERT_TRUE(d.CameraAt(twin_index).Project(d.points[static_cast<size_t>(o.point)].point_in_scene, &t.pixel_px));
    d.observations.push_back(t);
  }
  // The extra point, 1.5 m in front of camera 0, seen by camera 0 and its twin only.
  BundlePoint extra;
  extra.point_in_scene = d.cameras[0].cam_from_scene.Inverse() * Eigen::Vector3d(0.1, -0.05, 1.5);
  d.points.push_back(extra);
  const int extra_index = static_cast<int>(d.points.size()) - 1;
  for (int camera : {0, twin_index}) {
    BundleObservation o;
    o.camera = camera;
    o.point = extra_index;
    ASSERT_TRUE(d.CameraAt(camera).Project(extra.point_in_scene, &o.pixel_px));
    d.observations.push_back(o);
  }
  BundleOptions options;
  options.gauge = BundleGauge::kThreePointDatum;
  options.datum_points = s.datum;
  options.compute_point_covariances = true;
  const auto r = BundleAdjust(d, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->point_covariances.empty());
  EXPECT_NE(r->covariance_method.find("point " + std::to_string(extra_index) +
                                      " is not determined (its 3x3 block has condition number"),
            std::string::npos)
      << r->covariance_method;
  // Without the extra point the same network has its covariances.
  d.points.pop_back();
  d.observations.resize(d.observations.size() - 2);
  const auto fine = BundleAdjust(d, options);
  ASSERT_TRUE(fine.ok()) << fine.status().ToString();
  EXPECT_EQ(fine->point_covariances.size(), d.points.size()) << fine->covariance_method;
}

TEST(ReprojectionCostFunctor, AutoDiffVersusNumericAndOpenCv) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  CameraIntrinsics k;
  k.width_px = 1024;
  k.height_px = 768;
  k.fx_px = 950;
  k.fy_px = 955;
  k.cx_px = 515;
  k.cy_px = 380;
  k.k1 = -0.12;
  k.k2 = 0.09;
  k.k3 = -0.02;
  k.p1 = 4e-4;
  k.p2 = -2.5e-4;
  Eigen::Matrix2d cov;
  cov << 0.04, 0.01, 0.01, 0.02;
  const Eigen::Matrix2d white = ReprojectionCostFunctor::WhiteningOf(cov);
  EXPECT_LT((white.transpose() * white - cov.inverse()).norm(), 1e-9);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond q = Eigen::Quaterniond(1.0, 0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)).normalized();
    double qa[4] = {q.x(), q.y(), q.z(), q.w()};
    double t[3] = {0.1 * u(rng), 0.1 * u(rng), 2.0 + 0.5 * u(rng)};
    auto packed = k.Packed();
    double X[3] = {0.5 * u(rng), 0.4 * u(rng), 0.3 * u(rng)};
    const Eigen::Vector2d obs(500 + 100 * u(rng), 400 + 100 * u(rng));
    ceres::AutoDiffCostFunction<ReprojectionCostFunctor, 2, 4, 3, kNumCameraParameters, 3> ad(
        new ReprojectionCostFunctor(obs, white));
    ceres::NumericDiffOptions nopt;
    ceres::NumericDiffCostFunction<ReprojectionCostFunctor, ceres::RIDDERS, 2, 4, 3,
                                   kNumCameraParameters, 3>
        nd(new ReprojectionCostFunctor(obs, white), ceres::TAKE_OWNERSHIP, 2, nopt);
    const double* params[4] = {qa, t, packed.data(), X};
    double r_ad[2], r_nd[2];
    double Jq_ad[8], Jt_ad[6], Jk_ad[18], Jx_ad[6];
    double Jq_nd[8], Jt_nd[6], Jk_nd[18], Jx_nd[6];
    double* J_ad[4] = {Jq_ad, Jt_ad, Jk_ad, Jx_ad};
    double* J_nd[4] = {Jq_nd, Jt_nd, Jk_nd, Jx_nd};
    ASSERT_TRUE(ad.Evaluate(params, r_ad, J_ad));
    ASSERT_TRUE(nd.Evaluate(params, r_nd, J_nd));
    const int sizes[4] = {8, 6, 18, 6};
    for (int b = 0; b < 4; ++b) {
      for (int e = 0; e < sizes[b]; ++e) {
        EXPECT_NEAR(J_ad[b][e], J_nd[b][e], 1e-6 * (1.0 + std::abs(J_nd[b][e])))
            << "block " << b << " entry " << e;
      }
    }
    // The residual against OpenCV's projection, whitened by hand.
    cv::Matx33d Rcv;
    const Eigen::Matrix3d R = q.toRotationMatrix();
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) Rcv(a, c) = R(a, c);
    cv::Vec3d rvec;
    cv::Rodrigues(Rcv, rvec);
    std::vector<cv::Point2d> img;
    cv::projectPoints(std::vector<cv::Point3d>{{X[0], X[1], X[2]}}, rvec, cv::Vec3d(t[0], t[1], t[2]),
                      cv::Matx33d(k.fx_px, 0, k.cx_px, 0, k.fy_px, k.cy_px, 0, 0, 1),
                      cv::Vec<double, 5>(k.k1, k.k2, k.p1, k.p2, k.k3), img);
    const Eigen::Vector2d expected = white * Eigen::Vector2d(img[0].x - obs.x(), img[0].y - obs.y());
    EXPECT_NEAR(r_ad[0], expected.x(), 1e-7);
    EXPECT_NEAR(r_ad[1], expected.y(), 1e-7);
  }
  // Behind the camera: no residual.
  const ReprojectionCostFunctor f(Eigen::Vector2d(1, 1), Eigen::Matrix2d::Identity());
  const double qi[4] = {0, 0, 0, 1}, t0[3] = {0, 0, 0}, Xb[3] = {0, 0, -1};
  const auto packed = k.Packed();
  double r[2];
  EXPECT_FALSE(f(qi, t0, packed.data(), Xb, r));
}

TEST(BundleAdjustment, SharedIntrinsicsAreRefined) {
  Scene s = SmallScene(60, 12);
  // Two physical cameras, two images each: images 0, 1 by camera 0, images
  // 2, 3 by camera 1. Regenerate the pixels with the shared intrinsics.
  s.truth.intrinsics.resize(2);
  s.truth.intrinsics[1] = s.truth.intrinsics[0];
  s.truth.intrinsics[1].intrinsics.fx_px *= 1.05;
  s.truth.intrinsics[1].intrinsics.fy_px *= 1.05;
  s.truth.intrinsics[1].intrinsics.k1 = -0.05;
  for (int i = 0; i < 4; ++i) s.truth.cameras[static_cast<size_t>(i)].intrinsics_index = i / 2;
  for (size_t o = 0; o < s.truth.observations.size(); ++o) {
    const BundleObservation& ob = s.truth.observations[o];
    ASSERT_TRUE(s.truth.CameraAt(ob.camera).Project(s.truth.points[static_cast<size_t>(ob.point)].point_in_scene,
                                                    &s.clean_px[o]));
    s.truth.observations[o].pixel_px = s.clean_px[o];
  }
  BundleData d = s.truth;
  for (BundleIntrinsics& k : d.intrinsics) {
    k.constant = false;
    k.intrinsics.fx_px *= 1.01;
    k.intrinsics.fy_px *= 0.99;
    k.intrinsics.k1 += 0.02;
    k.intrinsics.cx_px += 3.0;
  }
  d.cameras[0].pose_constant = true;
  d.cameras[2].pose_constant = true;
  std::mt19937_64 rng(3);
  Perturb(&d, 0.0, 0.0, 0.003, rng);
  const auto r = BundleAdjust(d);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_LT(r->rms_reprojection_px, 1e-6) << r->Report();
  for (size_t k = 0; k < 2; ++k) {
    const auto est = r->data.intrinsics[k].intrinsics.Packed();
    const auto tru = s.truth.intrinsics[k].intrinsics.Packed();
    EXPECT_NEAR(est[0], tru[0], 1e-4);
    EXPECT_NEAR(est[1], tru[1], 1e-4);
    EXPECT_NEAR(est[2], tru[2], 1e-4);
    EXPECT_NEAR(est[4], tru[4], 1e-6);
  }
}

TEST(BundleAdjustment, RobustLossResistsOutliers) {
  const Scene s = SmallScene(30, 21);
  std::mt19937_64 rng(6);
  BundleData d = Noisy(s, 0.05, rng);
  d.cameras[0].pose_constant = true;
  d.cameras[1].pose_constant = true;
  const std::vector<Eigen::Vector3d> truth = Points(s.truth);
  const auto clean = BundleAdjust(d);
  ASSERT_TRUE(clean.ok());
  for (size_t o : {3u, 17u, 40u, 61u}) d.observations[o].pixel_px += Eigen::Vector2d(4.0, -3.0);
  const auto plain = BundleAdjust(d);
  BundleOptions robust;
  robust.loss = BundleLoss::kCauchy;
  robust.loss_scale_px = 0.15;
  const auto cauchy = BundleAdjust(d, robust);
  robust.loss = BundleLoss::kHuber;
  const auto huber = BundleAdjust(d, robust);
  ASSERT_TRUE(plain.ok() && cauchy.ok() && huber.ok());
  const double e_clean = Rms3d(Points(clean->data), truth);
  const double e_plain = Rms3d(Points(plain->data), truth);
  const double e_cauchy = Rms3d(Points(cauchy->data), truth);
  const double e_huber = Rms3d(Points(huber->data), truth);
  std::printf("outliers: RMS 3D error clean %.2e, plain %.2e, Cauchy %.2e, Huber %.2e\n", e_clean,
              e_plain, e_cauchy, e_huber);
  EXPECT_LT(e_cauchy, 1.5 * e_clean);
  EXPECT_GT(e_plain, 5.0 * e_cauchy);
  EXPECT_LT(e_huber, e_plain / 2.0);
}

TEST(BundleAdjustment, ErrorsNameTheInput) {
  const Scene s = SmallScene(8, 30);
  auto expect_error = [](const BundleData& d, const BundleOptions& o, const std::string& needle) {
    const auto r = BundleAdjust(d, o);
    ASSERT_FALSE(r.ok()) << needle;
    EXPECT_NE(r.status().message().find(needle), std::string::npos) << r.status().message();
  };
  BundleOptions o;
  {
    BundleData d = s.truth;
    d.observations[3].camera = 7;
    expect_error(d, o, "observation 3: camera index 7 is not in [0, 4)");
  }
  {
    BundleData d = s.truth;
    d.observations[5].point = -1;
    expect_error(d, o, "observation 5: point index -1");
  }
  {
    BundleData d = s.truth;
    d.observations[2].pixel_px.x() = NAN;
    expect_error(d, o, "observation 2: pixel is not finite");
  }
  {
    BundleData d = s.truth;
    d.observations[1].covariance_px2 << 1, 2, 2, 1;
    expect_error(d, o, "observation 1: covariance_px2 is not symmetric positive definite");
  }
  {
    BundleData d = s.truth;
    BundlePoint lonely;
    lonely.point_in_scene = Eigen::Vector3d(0, 1, 0.5);
    d.points.push_back(lonely);
    BundleObservation ob;
    ob.camera = 0;
    ob.point = static_cast<int>(d.points.size()) - 1;
    ASSERT_TRUE(d.CameraAt(0).Project(lonely.point_in_scene, &ob.pixel_px));
    d.observations.push_back(ob);
    expect_error(d, o, "point " + std::to_string(d.points.size() - 1) + " is free but seen by 1 camera(s)");
  }
  {
    BundleData d = s.truth;
    d.cameras[2].intrinsics_index = 9;
    expect_error(d, o, "camera 2 ('cam2'): intrinsics_index 9");
  }
  {
    BundleOptions bad;
    bad.gauge = BundleGauge::kThreePointDatum;
    bad.datum_points = {0, 0, 1};
    expect_error(s.truth, bad, "datum_points = (0, 0, 1)");
    bad.datum_points = {0, 1, 2};
    BundleData d = s.truth;
    d.cameras[0].pose_constant = true;
    expect_error(d, bad, "camera 0 ('cam0'): pose_constant with gauge kThreePointDatum");
  }
  {
    BundleOptions bad;
    bad.loss = BundleLoss::kHuber;
    bad.loss_scale_px = 0.0;
    expect_error(s.truth, bad, "loss_scale_px = 0");
    BundleOptions threads;
    threads.num_threads = 0;
    expect_error(s.truth, threads, "num_threads = 0");
  }
  {
    // A gauge not fixed by constant blocks: covariances unavailable, said why.
    BundleOptions cov;
    cov.compute_point_covariances = true;
    const auto r = BundleAdjust(s.truth, cov);
    ASSERT_TRUE(r.ok());
    EXPECT_TRUE(r->point_covariances.empty());
    EXPECT_NE(r->covariance_method.find("do not fix the gauge (7 near-zero"), std::string::npos)
        << r->covariance_method;
  }
}

}  // namespace
}  // namespace opl
