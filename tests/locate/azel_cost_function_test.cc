#include "opl/locate/azel_cost_function.h"

#include <random>

#include <ceres/autodiff_cost_function.h>
#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include "opl/geometry/spherical.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

// The same residual written generically, for automatic differentiation.
struct AzElFunctor {
  Eigen::Vector3d p;
  double az, el;
  Eigen::Matrix2d W;
  template <typename T>
  bool operator()(const T* quat_xyzw, const T* origin, T* residuals) const {
    const Eigen::Map<const Eigen::Quaternion<T>> quat(quat_xyzw);
    const Eigen::Matrix<T, 3, 1> u = p.cast<T>() - Eigen::Map<const Eigen::Matrix<T, 3, 1>>(origin);
    const Eigen::Matrix<T, 3, 1> q = quat.conjugate() * u;
    const Eigen::Matrix<T, 2, 1> r(WrapAngleRad(AzimuthRad(q) - T(az)), ElevationRad(q) - T(el));
    Eigen::Map<Eigen::Matrix<T, 2, 1>> out(residuals);
    out = W.cast<T>() * r;
    return true;
  }
};

TEST(AzElCostFunction, AnalyticalVersusAutoDiff) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Quaterniond q = test::RandomRotation(rng);
    const Eigen::Vector3d t(u(rng) * 100, u(rng) * 100, u(rng) * 100);
    const Eigen::Vector3d dir = Eigen::Vector3d(1.0, 0.3 * u(rng), 0.3 * u(rng)).normalized();
    const Eigen::Vector3d p = q * (800.0 * dir) + t + Eigen::Vector3d(u(rng), u(rng), u(rng));
    Eigen::Matrix2d W;
    W << 2.0 + u(rng), 0.5 * u(rng), 0.0, 1.5 + u(rng);
    const double az = AzimuthRad(dir) + 0.01 * u(rng), el = ElevationRad(dir) + 0.01 * u(rng);

    AzElCostFunction analytic(p, az, el, W);
    ceres::AutoDiffCostFunction<AzElFunctor, 2, 4, 3> autodiff(new AzElFunctor{p, az, el, W});
    double quat[4] = {q.x(), q.y(), q.z(), q.w()};
    double origin[3] = {t.x(), t.y(), t.z()};
    const double* params[2] = {quat, origin};
    double r_a[2], r_b[2], Jq_a[8], Jq_b[8], Jt_a[6], Jt_b[6];
    double* J_a[2] = {Jq_a, Jt_a};
    double* J_b[2] = {Jq_b, Jt_b};
    ASSERT_TRUE(analytic.Evaluate(params, r_a, J_a));
    ASSERT_TRUE(autodiff.Evaluate(params, r_b, J_b));
    for (int i = 0; i < 2; ++i) EXPECT_NEAR(r_a[i], r_b[i], 1e-14);
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(Jq_a[i], Jq_b[i], 1e-12 * (1 + std::abs(Jq_b[i])));
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(Jt_a[i], Jt_b[i], 1e-15 * (1 + std::abs(Jt_b[i])) + 1e-18);
  }
}

TEST(AzElCostFunction, GradientCheckerOnTheManifold) {
  std::mt19937_64 rng(22);
  const Eigen::Quaterniond q = test::RandomRotation(rng);
  const Eigen::Vector3d t(10, -20, 30);
  const Eigen::Vector3d p = q * Eigen::Vector3d(900, 120, -80) + t;
  AzElCostFunction cost(p, 0.1, -0.05, Eigen::Matrix2d::Identity() * 1e3);
  ceres::EigenQuaternionManifold quat_manifold;
  std::vector<const ceres::Manifold*> manifolds = {&quat_manifold, nullptr};
  ceres::NumericDiffOptions numeric_options;
  ceres::GradientChecker checker(&cost, &manifolds, numeric_options);
  double quat[4] = {q.x(), q.y(), q.z(), q.w()};
  double origin[3] = {t.x(), t.y(), t.z()};
  const double* params[2] = {quat, origin};
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params, 1e-7, &results)) << results.error_log;
}

TEST(AzElCostFunction, ResidualIsZeroOnTheBeam) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const Eigen::Vector3d t(1, 2, 3);
  const double az = 0.2, el = -0.1;
  const Eigen::Vector3d p = q * (1234.0 * DirectionFromAzElRad(az, el)) + t;
  AzElCostFunction cost(p, az, el, Eigen::Matrix2d::Identity());
  double quat[4] = {q.x(), q.y(), q.z(), q.w()};
  double origin[3] = {t.x(), t.y(), t.z()};
  const double* params[2] = {quat, origin};
  double r[2];
  ASSERT_TRUE(cost.Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], 0.0, 1e-15);
  EXPECT_NEAR(r[1], 0.0, 1e-15);
}

}  // namespace
}  // namespace opl
