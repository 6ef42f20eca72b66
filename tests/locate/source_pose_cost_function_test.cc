#include "opl/locate/source_pose_cost_function.h"

#include <random>

#include <ceres/autodiff_cost_function.h>
#include <ceres/gradient_checker.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

// The same residuals written generically for automatic differentiation, with
// Ceres' own angle-axis rotation and plain atan2 angle differences (a different
// route to the same numbers).
struct AutoDiffResiduals {
  std::vector<SourcePoseCostFunction::Spot> spots;
  Eigen::Matrix3d R0;
  Eigen::Vector3d t0;
  double D = 1.0;  // length per radian
  template <typename T>
  bool operator()(const T* x, T* residuals) const {
    T dR[9];
    const T dtheta[3] = {x[0] / D, x[1] / D, x[2] / D};
    ceres::AngleAxisToRotationMatrix(dtheta, ceres::ColumnMajorAdapter3x3(dR));
    const Eigen::Map<const Eigen::Matrix<T, 3, 3>> Exp(dR);
    const Eigen::Matrix<T, 3, 3> R = Exp * R0.cast<T>();
    const Eigen::Matrix<T, 3, 1> t = t0.cast<T>() + Eigen::Matrix<T, 3, 1>(x[3], x[4], x[5]);
    for (size_t i = 0; i < spots.size(); ++i) {
      const Eigen::Matrix<T, 3, 1> q = R.transpose() * (spots[i].point_in_scene.cast<T>() - t);
      const Eigen::Vector3d& b = spots[i].beam_direction_in_source;
      const Eigen::Matrix<T, 2, 1> d(WrapAngleRad(AzimuthRad(q) - T(AzimuthRad(b))),
                                     ElevationRad(q) - T(ElevationRad(b)));
      const Eigen::Matrix<T, 2, 1> r = spots[i].whitening.cast<T>() * d;
      residuals[2 * i] = r(0);
      residuals[2 * i + 1] = r(1);
    }
    return true;
  }
};

struct PoseProblem {
  std::vector<SourcePoseCostFunction::Spot> spots;
  Eigen::Matrix3d R0;
  Eigen::Vector3d t0;
};

PoseProblem MakePoseProblem(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PoseProblem s;
  s.R0 = test::RandomRotation(rng).toRotationMatrix();
  s.t0 = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 300.0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(1.0, 0.4 * u(rng), 0.4 * u(rng)).normalized();
    Eigen::Matrix2d W;
    W << 1e3 * (2.0 + u(rng)), 1e2 * u(rng), 0.0, 1e3 * (1.5 + u(rng));
    const Eigen::Vector3d beam =
        DirectionFromAzElRad(AzimuthRad(d) + 0.01 * u(rng), ElevationRad(d) + 0.01 * u(rng));
    s.spots.push_back({s.R0 * (900.0 * d) + s.t0 + 5.0 * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                       beam, W});
  }
  return s;
}

TEST(SourcePoseCostFunction, AnalyticalVersusAutoDiffAwayFromZero) {
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 100; ++trial) {
    const PoseProblem s = MakePoseProblem(rng, 9);
    // Half the trials with the rotation scaled to arc length at ~900 mm.
    const double D = (trial % 2 == 0) ? 1.0 : 900.0;
    SourcePoseCostFunction analytic(s.spots, s.R0, s.t0, D);
    ceres::AutoDiffCostFunction<AutoDiffResiduals, ceres::DYNAMIC, 6> autodiff(
        new AutoDiffResiduals{s.spots, s.R0, s.t0, D}, 2 * static_cast<int>(s.spots.size()));
    // Exact Jacobians are needed everywhere, not only at x = 0.
    double x[6] = {0.2 * D * u(rng), 0.2 * D * u(rng), 0.2 * D * u(rng), u(rng), u(rng), u(rng)};
    if (trial == 0) std::fill(x, x + 6, 0.0);
    const double* params[1] = {x};
    const int m = analytic.num_residuals();
    std::vector<double> r_a(m), r_b(m), J_a(6 * m), J_b(6 * m);
    double* ja[1] = {J_a.data()};
    double* jb[1] = {J_b.data()};
    ASSERT_TRUE(analytic.Evaluate(params, r_a.data(), ja));
    ASSERT_TRUE(autodiff.Evaluate(params, r_b.data(), jb));
    for (int i = 0; i < m; ++i) EXPECT_NEAR(r_a[i], r_b[i], 1e-10 * (1 + std::abs(r_b[i])));
    for (int i = 0; i < 6 * m; ++i) EXPECT_NEAR(J_a[i], J_b[i], 1e-9 * (1 + std::abs(J_b[i])));
  }
}

TEST(SourcePoseCostFunction, GradientChecker) {
  std::mt19937_64 rng(42);
  const PoseProblem s = MakePoseProblem(rng, 5);
  SourcePoseCostFunction cost(s.spots, s.R0, s.t0);
  ceres::NumericDiffOptions numeric_options;
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::GradientChecker checker(&cost, no_manifolds, numeric_options);
  double x[6] = {0.05, -0.02, 0.01, 0.3, -0.2, 0.1};
  const double* params[1] = {x};
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params, 1e-7, &results)) << results.error_log;
}

TEST(SourcePoseCostFunction, ZeroOnExactData) {
  std::mt19937_64 rng(43);
  const Eigen::Matrix3d R = test::RandomRotation(rng).toRotationMatrix();
  const Eigen::Vector3d t(1, 2, 3);
  std::vector<SourcePoseCostFunction::Spot> spots;
  for (double az : {-0.2, 0.0, 0.25}) {
    for (double el : {-0.2, 0.1}) {
      const Eigen::Vector3d d = DirectionFromAzElRad(az, el);
      spots.push_back({R * (1234.0 * d) + t, d, Eigen::Matrix2d::Identity()});
    }
  }
  SourcePoseCostFunction cost(spots, R, t);
  double x[6] = {0, 0, 0, 0, 0, 0};
  const double* params[1] = {x};
  std::vector<double> r(cost.num_residuals());
  ASSERT_TRUE(cost.Evaluate(params, r.data(), nullptr));
  for (double v : r) EXPECT_NEAR(v, 0.0, 1e-15);
  // The pose accessors apply x as documented.
  double y[6] = {0.1, 0, 0, 1, 2, 3};
  EXPECT_NEAR((cost.Rotation(y) - ExpSO3(Eigen::Vector3d(0.1, 0, 0)) * R).norm(), 0, 1e-15);
  EXPECT_NEAR((cost.Origin(y) - Eigen::Vector3d(2, 4, 6)).norm(), 0, 1e-15);
  // With D = 500 scene units per radian, x_rot = 50 is 0.1 rad.
  SourcePoseCostFunction scaled(spots, R, t, 500.0);
  double z[6] = {50.0, 0, 0, 0, 0, 0};
  EXPECT_NEAR((scaled.Rotation(z) - ExpSO3(Eigen::Vector3d(0.1, 0, 0)) * R).norm(), 0, 1e-15);
}

TEST(LeftJacobianSO3, MatchesFiniteDifferenceOfExp) {
  // Exp(w + dw) ~ Exp(J_l(w) dw) Exp(w)
  const Eigen::Vector3d w(0.3, -0.5, 0.9);
  const Eigen::Matrix3d J = LeftJacobianSO3(w);
  for (int k = 0; k < 3; ++k) {
    const double eps = 1e-6;
    const Eigen::Vector3d dw = eps * Eigen::Vector3d::Unit(k);
    const Eigen::Vector3d fd =
        (LogSO3(ExpSO3(w + dw) * ExpSO3(w).transpose()) - LogSO3(ExpSO3(w - dw) * ExpSO3(w).transpose())) / (2 * eps);
    EXPECT_NEAR((fd - J.col(k)).norm(), 0.0, 1e-8);
  }
  // J_l(w) - I ~ [w]x / 2, whose Frobenius norm is |w| / sqrt(2).
  EXPECT_NEAR((LeftJacobianSO3(Eigen::Vector3d(1e-6, 0, 0)) - Eigen::Matrix3d::Identity()).norm(), 1e-6 / std::sqrt(2.0), 1e-12);
}

}  // namespace
}  // namespace opl
