// Coverage of u(s) on rendered photographs (issue 6: "with speckle, s within
// its reported uncertainty in at least 95% of seeded scenes, and that
// uncertainty close to what the Monte Carlo of the uncertainty issue predicts
// for the same spot noise").
//
// The scene is examples/scene_small.json (four 1024 x 768 cameras, a
// prototype-like module of two 11 x 11 grids 55 mm apart on a wall 2 m away,
// speckle contrast 0.3, shot and read noise, 8 shots). For every seed k = 1 ..
// N the same geometry is rendered with new speckle and sensor noise
// (scene.seed = k), measured from the images with the exact calibration
// (MeasureScaleFromImages), and the TRUE scale of the measured frame is found
// independently of the pipeline: the similarity (Umeyama) that maps the
// identified 3D spots onto their true points (the renderer's truth). Then
//   z_k = (s_k - s_true,k) / u(s_k)
// should be a standard normal draw when u(s) is right.
//
// The Monte Carlo comparison: the uncertainty module's Monte Carlo
// (RunMeasurementMonteCarlo) of the same module and wall, with the spot
// noise really present, modelled independently of the front end: each spot
// triangulated by the scene's four true cameras with one isotropic pixel
// noise sigma_px, whose covariance sigma_px^2 (sum_k J_k^T J_k)^-1 (J_k the
// projection Jacobian of camera k) is long along the line of sight; sigma_px
// is fitted to the scatter of the measured spots about their true points.
// (One covariance for every spot, as a design's spot_noise_mm gives, cannot
// say that the lines of sight, from cameras near the module, run nearly
// along the beams, where a spot's error cannot move its source's origin:
// with the median reported covariance it predicts u(s) ~17 % too high; it
// is printed for contrast.) And a Monte Carlo of our own with every spot's
// own reported covariance (scene 1: the true points perturbed by each
// spot's covariance, then MeasureScale with the spots assigned).
//
// N = 20 scenes by default (about 4 s each in Release on 2 cores);
// OPL_COVERAGE_SCENES=<N> runs more by hand. Everything is seeded.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "opl/core/format.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/pipeline/measure.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "opl/sim/random.h"
#include "opl/uncertainty/monte_carlo.h"
#include "opl/vision/camera_model.h"
#include "support/scene_images.h"

namespace opl {
namespace {

using test::SourceDir;

int SceneCount() {
  const char* n = std::getenv("OPL_COVERAGE_SCENES");
  if (n == nullptr) return 20;
  const int value = std::atoi(n);
  return value >= 2 ? value : 20;
}

// One measured scene.
struct SceneOutcome {
  uint64_t seed = 0;
  double s = 0.0;       // measured scale factor
  double u = 0.0;       // its reported u(s)
  double s_true = 0.0;  // scale of the truth fit
  double z = 0.0;       // (s - s_true) / u
  int points = 0;       // identified spots in the truth fit
  double fit_rms_mm = 0.0;
  double spot_variance_factor = 0.0;   // front end, first adjustment
  double spot_extra_sigma_px = 0.0;
  double tag_variance_factor = 0.0, tag_extra_sigma_px = 0.0;
  std::vector<double> locate_variance_factor;  // per located source
  double u_shared = 0.0;  // part of u shared by the spots (cameras, datum)
  double final_variance_factor = 0.0;  // front end: final adjustment (tags and spots)
  double seconds = 0.0;                // render + measure
  // Per identified spot, in the design frame, mm: residual of the truth fit
  // (fitted measured point - true point) and the reported covariance moved
  // there (A C A^T, A the fit's scaled rotation); its true point.
  std::vector<Eigen::Vector3d> residual_mm;
  std::vector<Eigen::Matrix3d> covariance_mm2;
  std::vector<Eigen::Vector3d> true_point_mm;
  std::vector<std::pair<std::string, int>> beam;  // (source, beam id)
  std::vector<int> views;  // images each spot was measured in
};

// Renders scene `seed` into a temp dir, measures it, fits to the truth.
SceneOutcome MeasureSeed(const Scene& base, uint64_t seed) {
  const auto start = std::chrono::steady_clock::now();
  SceneOutcome out;
  out.seed = seed;
  Scene scene = base;
  scene.seed = seed;
  const std::filesystem::path dir = test::FreshTempDir("images_coverage_" + std::to_string(seed));
  Result<SceneRenderer> renderer = test::RenderShotsTo(scene, dir, 2);
  EXPECT_TRUE(renderer.ok()) << renderer.status().ToString();
  if (!renderer.ok()) return out;
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  EXPECT_TRUE(calibration.ok()) << calibration.status().ToString();
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  if (std::getenv("OPL_COVERAGE_PROGRESS") != nullptr) {
    options.front_end.progress = [start, seed](const std::string& stage, int done, int total) {
      std::cerr << "seed " << seed << " "
                << FormatNumber(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 4)
                << " s: " << stage << " " << done << "/" << total << "\n";
    };
  }
  Result<ImageMeasureReport> report =
      MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  std::filesystem::remove_all(dir);
  EXPECT_TRUE(report.ok()) << "seed " << seed << ": " << report.status().ToString();
  if (!report.ok()) return out;

  // Truth fit (as tests/pipeline/measure_images_test.cc): identified spots
  // matched to their true points by (source, beam).
  std::map<std::pair<std::string, int>, Eigen::Vector3d> true_point;
  for (const SceneSpotTruth& t : renderer->spots()) true_point[{t.source, t.beam}] = t.point_in_scene;
  std::vector<const Spot*> used;
  std::vector<Eigen::Vector3d> truths;
  for (size_t k = 0; k < report->spots.size(); ++k) {
    const Spot& spot = report->spots[k];
    if (!spot.assigned()) continue;
    const auto found = true_point.find({spot.source, spot.observation.beam_id});
    if (found == true_point.end()) continue;
    used.push_back(&spot);
    truths.push_back(found->second);
    out.views.push_back(static_cast<int>(report->front_end.spots[k].views.size()));
  }
  out.points = static_cast<int>(used.size());
  EXPECT_GE(out.points, 200) << "seed " << seed;
  if (out.points < 4) return out;
  Eigen::Matrix3Xd src(3, out.points), dst(3, out.points);
  for (int i = 0; i < out.points; ++i) {
    src.col(i) = used[static_cast<size_t>(i)]->observation.point_in_scene;
    dst.col(i) = truths[static_cast<size_t>(i)];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
  const Eigen::Matrix3d a = t.topLeftCorner<3, 3>();
  out.s_true = a.col(0).norm();
  double sum = 0.0;
  for (int i = 0; i < out.points; ++i) {
    const Spot& spot = *used[static_cast<size_t>(i)];
    const Eigen::Vector3d r = a * src.col(i) + t.topRightCorner<3, 1>() - dst.col(i);
    sum += r.squaredNorm();
    out.residual_mm.push_back(r);
    out.covariance_mm2.push_back(a * spot.observation.cov_in_scene.value_or(Eigen::Matrix3d::Zero()) *
                                 a.transpose());
    out.true_point_mm.push_back(dst.col(i));
    out.beam.emplace_back(spot.source, spot.observation.beam_id);
  }
  out.fit_rms_mm = std::sqrt(sum / out.points);
  out.s = report->measure.scale.scale_factor;
  out.u = report->measure.scale.u_scale_factor;
  out.z = (out.s - out.s_true) / out.u;
  out.spot_variance_factor = report->front_end.spot_variance_factor;
  out.spot_extra_sigma_px = report->front_end.spot_extra_sigma_px;
  out.final_variance_factor = report->front_end.variance_factor;
  out.tag_variance_factor = report->front_end.tag_variance_factor;
  out.u_shared = report->u_scale_factor_shared;
  for (const auto& [name, located] : report->measure.sources) {
    out.locate_variance_factor.push_back(located.variance_factor);
  }
  out.tag_extra_sigma_px = report->front_end.tag_extra_sigma_px;
  out.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

// The N scenes, measured once for both tests.
const std::vector<SceneOutcome>& Outcomes() {
  static const std::vector<SceneOutcome> outcomes = [] {
    std::vector<SceneOutcome> all;
    Result<Scene> scene = ReadSceneJson(SourceDir() + "/examples/scene_small.json");
    EXPECT_TRUE(scene.ok()) << scene.status().ToString();
    if (!scene.ok()) return all;
    const int n = SceneCount();
    const char* first_seed = std::getenv("OPL_COVERAGE_FIRST_SEED");  // by hand: rerun one seed
    const int first = first_seed != nullptr ? std::max(1, std::atoi(first_seed)) : 1;
    for (int k = first; k < first + n; ++k) {
      all.push_back(MeasureSeed(*scene, static_cast<uint64_t>(k)));
      const SceneOutcome& o = all.back();
      std::cout << "seed " << k << ": s " << FormatNumber(o.s, 9) << " +- "
                << FormatNumber(o.u, 3) << " (shared " << FormatNumber(o.u_shared, 3) << "), s_true " << FormatNumber(o.s_true, 9) << ", z "
                << FormatNumber(o.z, 3) << ", " << o.points << " spots, fit rms "
                << FormatNumber(o.fit_rms_mm, 3) << " mm, spot variance factor "
                << FormatNumber(o.spot_variance_factor, 3) << " (extra sigma px "
                << FormatNumber(o.spot_extra_sigma_px, 3) << "; tags " << FormatNumber(o.tag_variance_factor, 3) << ", extra "
                << FormatNumber(o.tag_extra_sigma_px, 3) << " px; locate chi2/dof";
      for (double v : o.locate_variance_factor) std::cout << " " << FormatNumber(v, 3);
      std::cout << "; final adjustment "
                << FormatNumber(o.final_variance_factor, 3) << "), " << FormatNumber(o.seconds, 3)
                << " s\n";
    }
    return all;
  }();
  return outcomes;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The design whose Monte Carlo uses spot covariance `c` (mm^2, design frame).
ModuleDesign WithSpotCovariance(ModuleDesign design, const Eigen::Matrix3d& c) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (c + c.transpose()));
  Eigen::Matrix3d r = eig.eigenvectors();
  if (r.determinant() < 0) r.col(2) = -r.col(2);
  design.spot_noise_mm = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  design.noise_frame_rotation = r;
  return design;
}

// The covariance of a point triangulated by `cameras` (those that see it)
// with 1 px isotropic noise per image: (sum_k J_k^T J_k)^-1, J_k = d pixel /
// d point of camera k by central differences (mm^2 per px^2).
Eigen::Matrix3d TriangulationCovarianceAt1Px(const std::vector<Camera>& cameras,
                                              const Eigen::Vector3d& point) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const Camera& camera : cameras) {
    Eigen::Vector2d centre;
    if (!camera.Project(point, &centre) || !camera.InImage(centre)) continue;
    Eigen::Matrix<double, 2, 3> j;
    const double h = 1e-3;  // mm
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector2d plus, minus;
      camera.Project(point + h * Eigen::Vector3d::Unit(a), &plus);
      camera.Project(point - h * Eigen::Vector3d::Unit(a), &minus);
      j.col(a) = (plus - minus) / (2.0 * h);
    }
    information += j.transpose() * j;
  }
  return information.inverse();
}

TEST(ImagesCoverage, ScaleFactorWithinItsUncertainty) {
  const std::vector<SceneOutcome>& outcomes = Outcomes();
  const int n = static_cast<int>(outcomes.size());
  ASSERT_GE(n, 2);
  int within = 0;
  double sum_z2 = 0.0;
  double seconds = 0.0;
  for (const SceneOutcome& o : outcomes) {
    ASSERT_GT(o.u, 0.0) << "seed " << o.seed;
    if (std::abs(o.z) <= 2.0) ++within;
    sum_z2 += o.z * o.z;
    seconds += o.seconds;
  }
  const double rms_z = std::sqrt(sum_z2 / n);
  std::cout << "coverage |z| <= 2: " << within << " / " << n << ", RMS z " << FormatNumber(rms_z, 3)
            << ", " << FormatNumber(seconds / n, 3) << " s per scene\n";
  // 95 % coverage at k = 2: for a correct u(s) (z standard normal), |z| <= 2
  // has p = 0.9545. With N = 20 we require >= 17 inside: a correct interval
  // fails that with binomial probability P(X <= 16 | 20, 0.9545) = 0.012; a
  // 2x understated u(s) (p = 0.68) passes it with probability 0.08. For
  // other N the bound is floor(0.85 N) (N = 100: >= 85, failure 1e-5).
  const int required = static_cast<int>(std::floor(0.85 * n));
  EXPECT_GE(within, required) << "coverage " << within << " / " << n;
  // RMS z: for a correct u(s), N RMS^2 is chi^2 with N degrees of freedom.
  // [0.6, 1.6] at N = 20 means chi^2_20 in [7.2, 51.2]: probability 0.004 below
  // and 0.0002 above. u(s) off by a factor 1.6 or more (either way) fails.
  EXPECT_GE(rms_z, 0.6);
  EXPECT_LE(rms_z, 1.6);
}

TEST(ImagesCoverage, UncertaintyAgreesWithTheMonteCarlo) {
  const std::vector<SceneOutcome>& outcomes = Outcomes();
  const int n = static_cast<int>(outcomes.size());
  ASSERT_GE(n, 2);
  Result<Scene> scene = ReadSceneJson(SourceDir() + "/examples/scene_small.json");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  const ModuleDesign& design = *scene->module;
  // The scene frame of the truth is the design's (the module is placed in
  // it, examples/scene_small.json), and so are its cameras.
  std::vector<Camera> cameras;
  for (const SceneCamera& c : scene->cameras) {
    ASSERT_TRUE(c.cam_from_scene.has_value()) << c.name;
    cameras.push_back(Camera{c.name, c.intrinsics, *c.cam_from_scene});
  }

  // Relative quantities: s is mm per scene unit with s_true near 1, the
  // Monte Carlo's s is 1 on average; compare u(s)/s.
  std::vector<double> u_rel;
  double sum_d2 = 0.0, sum_d = 0.0;
  std::vector<double> c00, c01, c02, c11, c12, c22;
  // sigma_px of the camera model: r^T C1^-1 r summed over every spot (C1 the
  // triangulation covariance at 1 px), over the degrees of freedom.
  double camera_chi2 = 0.0, camera_dof = 0.0;
  for (const SceneOutcome& o : outcomes) {
    u_rel.push_back(o.u / o.s);
    const double d = o.s / o.s_true - 1.0;
    sum_d += d;
    sum_d2 += d * d;
    for (size_t i = 0; i < o.residual_mm.size(); ++i) {
      const Eigen::Matrix3d& c = o.covariance_mm2[i];
      c00.push_back(c(0, 0));
      c01.push_back(c(0, 1));
      c02.push_back(c(0, 2));
      c11.push_back(c(1, 1));
      c12.push_back(c(1, 2));
      c22.push_back(c(2, 2));
      const Eigen::Matrix3d c1 = TriangulationCovarianceAt1Px(cameras, o.true_point_mm[i]);
      camera_chi2 += o.residual_mm[i].dot(c1.ldlt().solve(o.residual_mm[i]));
    }
    camera_dof += 3.0 * o.points - 7.0;  // the similarity fit takes 7 parameters
  }
  const double sigma_px = std::sqrt(camera_chi2 / camera_dof);
  Eigen::Matrix3d median_cov;
  median_cov << Median(c00), Median(c01), Median(c02), Median(c01), Median(c11), Median(c12),
      Median(c02), Median(c12), Median(c22);
  const double median_u = Median(u_rel);
  // Empirical std of s / s_true - 1 about zero (the estimator is unbiased
  // when u(s) is right; a bias shows here too).
  const double empirical_std = std::sqrt(sum_d2 / n);
  const double mean_d = sum_d / n;

  MonteCarloOptions mc;
  mc.iterations = 1000;
  mc.seed = 20261122;
  mc.threads = 2;
  mc.spot_covariance_mm2 = [&cameras, sigma_px](const std::string&, int, const Eigen::Vector3d& point) {
    return Eigen::Matrix3d(sigma_px * sigma_px * TriangulationCovarianceAt1Px(cameras, point));
  };
  Result<MonteCarloReport> mc_cameras = RunMeasurementMonteCarlo(design, mc);
  ASSERT_TRUE(mc_cameras.ok()) << mc_cameras.status().ToString();
  mc.spot_covariance_mm2 = nullptr;
  Result<MonteCarloReport> mc_median = RunMeasurementMonteCarlo(WithSpotCovariance(design, median_cov), mc);
  ASSERT_TRUE(mc_median.ok()) << mc_median.status().ToString();

  // Our own Monte Carlo with every spot's reported covariance (scene 1): true
  // points + N(0, C_i), C_i carried by the spot, assigned, MeasureScale.
  Result<ModuleCalibration> calibration = ExactCalibration(design);
  ASSERT_TRUE(calibration.ok());
  const SceneOutcome& first = outcomes.front();
  std::vector<double> own_s;
  {
    std::mt19937_64 rng(20261123);
    NormalGenerator normal;
    std::vector<Eigen::Matrix3d> chol;
    for (const Eigen::Matrix3d& c : first.covariance_mm2) chol.push_back(c.llt().matrixL());
    for (int trial = 0; trial < 200; ++trial) {
      std::vector<Spot> spots;
      for (size_t i = 0; i < first.true_point_mm.size(); ++i) {
        Spot spot;
        spot.source = first.beam[i].first;
        spot.observation.beam_id = first.beam[i].second;
        const Eigen::Vector3d e(normal(rng), normal(rng), normal(rng));
        spot.observation.point_in_scene = first.true_point_mm[i] + chol[i] * e;
        spot.observation.cov_in_scene = first.covariance_mm2[i];
        spots.push_back(spot);
      }
      Result<MeasureReport> r = MeasureScale(*calibration, spots);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      own_s.push_back(r->scale.scale_factor);
    }
  }
  double own_mean = 0.0, own_var = 0.0;
  for (double v : own_s) own_mean += v / static_cast<double>(own_s.size());
  for (double v : own_s) own_var += (v - own_mean) * (v - own_mean) / static_cast<double>(own_s.size() - 1);
  const double own_std = std::sqrt(own_var);

  // Diagnosis of the reported spot covariances: the normalised squared
  // residual of the truth fit, r^T C^-1 r per degree of freedom (1 when C is
  // the spot's covariance), by view count and by distance from the grid's
  // centre (thirds of the largest), and its tail (beyond chi^2_3's 99 %
  // point, 11.34: 1 % expected).
  double nis_sum = 0.0, nis_dof = 0.0;
  std::map<std::string, std::pair<double, int>> by;  // label -> (sum r^T C^-1 r, spots)
  int tail = 0, total = 0;
  for (const SceneOutcome& o : outcomes) {
    std::map<std::string, Eigen::Vector3d> centre;
    std::map<std::string, int> count;
    for (size_t i = 0; i < o.true_point_mm.size(); ++i) {
      centre.try_emplace(o.beam[i].first, Eigen::Vector3d::Zero()).first->second += o.true_point_mm[i];
      ++count[o.beam[i].first];
    }
    for (auto& [name, c] : centre) c /= count[name];
    double max_radius = 0.0;
    for (size_t i = 0; i < o.true_point_mm.size(); ++i) {
      max_radius = std::max(max_radius, (o.true_point_mm[i] - centre[o.beam[i].first]).norm());
    }
    for (size_t i = 0; i < o.residual_mm.size(); ++i) {
      const double nis = o.residual_mm[i].dot(o.covariance_mm2[i].ldlt().solve(o.residual_mm[i]));
      nis_sum += nis;
      const double radius = (o.true_point_mm[i] - centre[o.beam[i].first]).norm() / max_radius;
      const int third = std::min(2, static_cast<int>(3.0 * radius));
      for (const std::string& label : {"views " + std::to_string(o.views[i]),
                                       "radius third " + std::to_string(third + 1)}) {
        by[label].first += nis;
        ++by[label].second;
      }
      tail += nis > 11.34 ? 1 : 0;
      ++total;
    }
    nis_dof += 3.0 * static_cast<double>(o.residual_mm.size()) - 7.0;
  }
  const double nis = nis_sum / nis_dof;
  std::cout << "reported spot covariances: r^T C^-1 r per dof " << FormatNumber(nis, 3) << ";";
  for (const auto& [label, v] : by) {
    std::cout << " " << label << ": " << FormatNumber(v.first / (3.0 * v.second), 3) << " ("
              << v.second << " spots);";
  }
  std::cout << " beyond chi^2_3 99 %: " << tail << " of " << total << "\n";
  std::cout << "camera model: sigma_px " << FormatNumber(sigma_px, 3)
            << " (front end: detector + added " << FormatNumber(first.spot_extra_sigma_px, 3)
            << " px)\n";
  std::cout << "u(s)/s: median reported " << FormatNumber(median_u, 3)
            << ", empirical std of s/s_true - 1 " << FormatNumber(empirical_std, 3) << " (mean "
            << FormatNumber(mean_d, 3) << "), MC (camera model) "
            << FormatNumber(mc_cameras->scale_factor.std_dev, 3) << " (first order "
            << FormatNumber(mc_cameras->scale_factor.first_order_std, 3)
            << "), own MC (scene 1 per-spot cov, M = 200) " << FormatNumber(own_std, 3)
            << " vs its reported " << FormatNumber(first.u / first.s, 3)
            << "; for contrast, MC with one (the median) covariance for every spot "
            << FormatNumber(mc_median->scale_factor.std_dev, 3) << "\n";

  // (1) First order vs our own Monte Carlo with the same per-spot
  // covariances: the std of M = 200 draws scatters by 1/sqrt(2(M-1)) = 5 %;
  // 15 % is three of those.
  EXPECT_NEAR(own_std / (first.u / first.s), 1.0, 0.15);
  // (2) The reported covariances follow the scatter about the truth on
  // average (~4700 spots: the mean is known to a few %).
  EXPECT_NEAR(nis, 1.0, 0.2);
  // (3) The observed spread of s about s_true vs the Monte Carlo of the
  // spot noise really present: the empirical std of N = 20 values scatters
  // as sqrt(chi^2_20 / 20); a factor 1.5 either way is missed with
  // probability 0.016 + 0.001 by a correct prediction.
  EXPECT_GT(empirical_std / mc_cameras->scale_factor.std_dev, 1.0 / 1.5);
  EXPECT_LT(empirical_std / mc_cameras->scale_factor.std_dev, 1.5);
  // (4) The requirement: the reported u(s) is what the Monte Carlo
  // predicts for the same spot noise; within 15 % (the median of N values
  // against M = 1000 draws, 2 % each; the camera model's one sigma_px for
  // every spot and view is an approximation of a few %).
  EXPECT_NEAR(median_u / mc_cameras->scale_factor.std_dev, 1.0, 0.15);
}

}  // namespace
}  // namespace opl
