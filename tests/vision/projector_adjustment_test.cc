// The projector adjustment's spot residual: analytic Jacobians against
// automatic differentiation of the same model, at random poses, beams,
// depths and distorted cameras; and the errors of bad input.
#include "opl/vision/projector_adjustment.h"

#include <random>

#include <ceres/autodiff_cost_function.h>
#include <gtest/gtest.h>

#include "opl/vision/projector_spot_cost_function.h"

namespace opl {
namespace {

Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
}

TEST(ProjectorSpotCostFunction, AnalyticVersusAutoDiff) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int checked = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 200; ++trial) {
    CameraIntrinsics K;
    K.width_px = 4000;
    K.height_px = 3000;
    K.fx_px = 3000 + 500 * u(rng);
    K.fy_px = K.fx_px * (1.0 + 0.01 * u(rng));
    K.cx_px = 2000 + 50 * u(rng);
    K.cy_px = 1500 + 50 * u(rng);
    K.k1 = 0.1 * u(rng);
    K.k2 = 0.05 * u(rng);
    K.k3 = 0.01 * u(rng);
    K.p1 = 0.002 * u(rng);
    K.p2 = 0.002 * u(rng);
    // A module somewhere, a spot 1-2 m out along a beam; a camera 2 m from
    // the spot looking at it.
    const Eigen::Quaterniond q_module = RandomRotation(rng);
    const Eigen::Vector3d t_module(500 * u(rng), 500 * u(rng), 500 * u(rng));
    const Eigen::Quaterniond q_source =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()));
    const Eigen::Vector3d origin(27.5 * u(rng), 27.5, 3 * u(rng));
    const double lambda = 1.0 + 1e-3 * u(rng);
    const double az = 0.25 * u(rng), el = 0.25 * u(rng);
    const double depth = 1500 + 500 * u(rng);
    const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    const Eigen::Vector3d spot = q_module * (q_source * (depth * d) + lambda * origin) + t_module;
    const Eigen::Vector3d look = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d centre = spot + 2000.0 * look;
    Result<Rigid3d> cam = CamFromSceneLookingAt(centre, spot + 100 * Eigen::Vector3d(u(rng), u(rng), u(rng)), u(rng));
    ASSERT_TRUE(cam.ok());
    const Eigen::Quaterniond q_cam = cam->rotation;
    const Eigen::Vector3d t_cam = cam->translation;
    const Eigen::Vector2d pixel(2000 + 100 * u(rng), 1500 + 100 * u(rng));
    Eigen::Matrix2d cov;
    cov << 0.04, 0.01, 0.01, 0.09;
    const Eigen::Matrix2d W = ReprojectionCostFunctor::WhiteningOf(cov);

    std::array<double, 4> qc = {q_cam.x(), q_cam.y(), q_cam.z(), q_cam.w()};
    std::array<double, 3> tc = {t_cam.x(), t_cam.y(), t_cam.z()};
    std::array<double, 4> qm = {q_module.x(), q_module.y(), q_module.z(), q_module.w()};
    std::array<double, 3> tm = {t_module.x(), t_module.y(), t_module.z()};
    double lam = lambda;
    std::array<double, 4> qs = {q_source.x(), q_source.y(), q_source.z(), q_source.w()};
    std::array<double, 2> beam = {az, el};
    double dep = depth;
    const double* params[] = {qc.data(), tc.data(), qm.data(), tm.data(), &lam, qs.data(), beam.data(), &dep};
    const int sizes[] = {4, 3, 4, 3, 1, 4, 2, 1};

    const ProjectorSpotCostFunction analytic(K, pixel, W, origin);
    ceres::AutoDiffCostFunction<ProjectorSpotFunctor, 2, 4, 3, 4, 3, 1, 4, 2, 1> autodiff(
        new ProjectorSpotFunctor(K, pixel, W, origin));
    std::array<std::vector<double>, 8> ja, jd;
    double* pa[8];
    double* pd[8];
    for (int b = 0; b < 8; ++b) {
      ja[static_cast<size_t>(b)].assign(static_cast<size_t>(2 * sizes[b]), 0.0);
      jd[static_cast<size_t>(b)].assign(static_cast<size_t>(2 * sizes[b]), 0.0);
      pa[b] = ja[static_cast<size_t>(b)].data();
      pd[b] = jd[static_cast<size_t>(b)].data();
    }
    double ra[2], rd[2];
    const bool ok_a = analytic.Evaluate(params, ra, pa);
    const bool ok_d = autodiff.Evaluate(params, rd, pd);
    ASSERT_EQ(ok_a, ok_d);
    if (!ok_a) continue;
    EXPECT_NEAR(ra[0], rd[0], 1e-9 * (1.0 + std::abs(rd[0])));
    EXPECT_NEAR(ra[1], rd[1], 1e-9 * (1.0 + std::abs(rd[1])));
    for (int b = 0; b < 8; ++b) {
      double scale = 0.0, diff = 0.0;
      for (size_t e = 0; e < ja[static_cast<size_t>(b)].size(); ++e) {
        scale = std::max(scale, std::abs(jd[static_cast<size_t>(b)][e]));
        diff = std::max(diff, std::abs(ja[static_cast<size_t>(b)][e] - jd[static_cast<size_t>(b)][e]));
      }
      ASSERT_GT(scale, 0.0) << "block " << b;
      worst = std::max(worst, diff / scale);
      EXPECT_LT(diff / scale, 1e-9) << "trial " << trial << " block " << b;
    }
    ++checked;
  }
  EXPECT_GT(checked, 190);
  std::cout << "worst relative Jacobian difference over " << checked << " trials: " << worst << "\n";
}

TEST(RotatedVectorJacobianWrtQuaternion, MatchesCentralDifferences) {
  std::mt19937_64 rng(3);
  const Eigen::Quaterniond q = RandomRotation(rng);
  const Eigen::Vector3d v(0.3, -1.2, 2.0);
  const Eigen::Matrix<double, 3, 4> J = RotatedVectorJacobianWrtQuaternion(q, v);
  for (int k = 0; k < 4; ++k) {
    Eigen::Vector4d c = q.coeffs();
    const double h = 1e-6;
    c(k) += h;
    const Eigen::Vector3d up = Eigen::Quaterniond(c) * v;  // Eigen: not normalised, as differentiated
    c(k) -= 2 * h;
    const Eigen::Vector3d down = Eigen::Quaterniond(c) * v;
    EXPECT_LT(((up - down) / (2 * h) - J.col(k)).norm(), 1e-8) << k;
  }
}

TEST(ProjectorAdjust, BadInputNamesTheField) {
  ProjectorAdjustmentData data;
  ProjectorAdjustmentOptions options;
  Result<ProjectorAdjustmentResult> r = ProjectorAdjust(data, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("datum_point_sets[0] is empty"), std::string::npos)
      << r.status().message();
  options.datum_point_sets = {std::vector<int>{0}, {1}, {2}};
  options.unscaled_datum_length = -1.0;
  r = ProjectorAdjust(data, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("unscaled_datum_length"), std::string::npos);
  options.unscaled_datum_length = 1.0;
  options.num_threads = 0;
  r = ProjectorAdjust(data, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("num_threads = 0"), std::string::npos);
}

}  // namespace
}  // namespace opl
