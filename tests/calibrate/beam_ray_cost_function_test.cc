#include "opl/calibrate/beam_ray_cost_function.h"

#include <random>

#include <ceres/autodiff_cost_function.h>
#include <ceres/dynamic_autodiff_cost_function.h>
#include <ceres/gradient_checker.h>
#include <ceres/manifold_test_utils.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include "opl/calibrate/level_row_manifold.h"
#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

using Layout = BeamRayCostFunction::Layout;

// The residuals written generically for automatic differentiation, with
// Ceres' angle-axis rotation (a different route to the same numbers).
struct AutoDiffBeamRay {
  std::vector<BeamRayCostFunction::Sample> samples;
  Eigen::Matrix3d R0;
  Layout layout;
  int el_row_index = 0;
  int m = 0;
  template <typename T>
  bool operator()(T const* const* p, T* residuals) const {
    T dR[9];
    ceres::AngleAxisToRotationMatrix(p[0], ceres::ColumnMajorAdapter3x3(dR));
    const Eigen::Map<const Eigen::Matrix<T, 3, 3>> Exp(dR);
    const Eigen::Matrix<T, 3, 3> R = Exp * R0.cast<T>();
    const Eigen::Matrix<T, 3, 1> t(p[1][0], p[1][1], p[1][2]);
    T az_b(0.0), el_b(0.0);
    if (layout == Layout::kFreeBeam) {
      az_b = p[2][0];
      el_b = p[2][1];
    } else if (layout == Layout::kCentralRowBeam) {
      az_b = p[2][el_row_index];
      el_b = p[2][m + el_row_index];
    }
    for (size_t i = 0; i < samples.size(); ++i) {
      const Eigen::Matrix<T, 3, 1> q = R.transpose() * (samples[i].point_in_scene.cast<T>() - t);
      const Eigen::Matrix<T, 2, 1> d(WrapAngleRad(AzimuthRad(q) - az_b), ElevationRad(q) - el_b);
      using std::sqrt;
      const Eigen::Matrix<T, 2, 1> r = sqrt(samples[i].weight) * (samples[i].whitening.cast<T>() * d);
      residuals[2 * i] = r(0);
      residuals[2 * i + 1] = r(1);
    }
    return true;
  }
};

TEST(BeamRayCostFunction, AnalyticalVersusAutoDiffForEveryLayout) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int m = 4;  // size of the central-row elevation block
  double worst = 0.0;
  for (int trial = 0; trial < 60; ++trial) {
    const Layout layout = static_cast<Layout>(trial % 3);
    const Eigen::Matrix3d R0 = test::RandomRotation(rng).toRotationMatrix();
    const Eigen::Vector3d t0 = 300.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Vector3d beam = DirectionFromAzElRad(0.2 * u(rng), 0.2 * u(rng));
    std::vector<BeamRayCostFunction::Sample> samples;
    for (int k = 0; k < 6; ++k) {
      BeamRayCostFunction::Sample s;
      s.point_in_scene = R0 * ((700.0 + 80.0 * k) * beam) + t0 + 2.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
      s.whitening << 1e3 * (2.0 + u(rng)), 0.0, 1e2 * u(rng), 1e3 * (1.5 + u(rng));
      s.weight = 0.5 + 0.5 * u(rng) * u(rng);
      samples.push_back(s);
    }
    const int index = trial % m;
    BeamRayCostFunction analytic(samples, R0, layout, m, index);
    ceres::DynamicAutoDiffCostFunction<AutoDiffBeamRay> autodiff(
        new AutoDiffBeamRay{samples, R0, layout, index, m});
    autodiff.AddParameterBlock(3);
    autodiff.AddParameterBlock(3);
    std::vector<double> theta = {0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)};
    std::vector<double> t = {t0.x() + u(rng), t0.y() + u(rng), t0.z() + u(rng)};
    std::vector<double> azel = {AzimuthRad(beam) + 0.01 * u(rng), ElevationRad(beam) + 0.01 * u(rng)};
    std::vector<double> row(2 * m);
    for (double& e : row) e = 0.1 * u(rng);
    std::vector<double*> params = {theta.data(), t.data()};
    if (layout == Layout::kFreeBeam) {
      autodiff.AddParameterBlock(2);
      params.push_back(azel.data());
    } else if (layout == Layout::kCentralRowBeam) {
      autodiff.AddParameterBlock(2 * m);
      params.push_back(row.data());
    }
    autodiff.SetNumResiduals(analytic.num_residuals());
    ASSERT_EQ(analytic.parameter_block_sizes(), autodiff.parameter_block_sizes());
    const int nr = analytic.num_residuals();
    std::vector<std::vector<double>> ja(params.size()), jd(params.size());
    std::vector<double*> pa, pd;
    for (size_t b = 0; b < params.size(); ++b) {
      ja[b].resize(nr * analytic.parameter_block_sizes()[b]);
      jd[b].resize(ja[b].size());
      pa.push_back(ja[b].data());
      pd.push_back(jd[b].data());
    }
    std::vector<double> ra(nr), rd(nr);
    ASSERT_TRUE(analytic.Evaluate(params.data(), ra.data(), pa.data()));
    ASSERT_TRUE(autodiff.Evaluate(params.data(), rd.data(), pd.data()));
    for (int i = 0; i < nr; ++i) {
      EXPECT_NEAR(ra[i], rd[i], 1e-9 * (1.0 + std::abs(rd[i])));
      // The angular residual accessor agrees with the residuals.
    }
    for (size_t b = 0; b < params.size(); ++b) {
      for (size_t k = 0; k < ja[b].size(); ++k) {
        const double err = std::abs(ja[b][k] - jd[b][k]) / (1.0 + std::abs(jd[b][k]));
        worst = std::max(worst, err);
        ASSERT_LT(err, 1e-8) << "trial " << trial << " block " << b << " entry " << k;
      }
    }
    const Eigen::Vector2d raw = analytic.AngularResidual(params.data(), 2);
    const Eigen::Vector2d r(ra[4], ra[5]);
    EXPECT_LT((std::sqrt(samples[2].weight) * samples[2].whitening * raw - r).norm(), 1e-9);
  }
  EXPECT_LT(worst, 1e-8);
}

TEST(BeamRayCostFunction, GradientCheckerAgrees) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Matrix3d R0 = test::RandomRotation(rng).toRotationMatrix();
  const Eigen::Vector3d beam = DirectionFromAzElRad(0.15, -0.1);
  std::vector<BeamRayCostFunction::Sample> samples;
  for (int k = 0; k < 5; ++k) {
    BeamRayCostFunction::Sample s;
    s.point_in_scene = R0 * ((800.0 + 60.0 * k) * beam) + Eigen::Vector3d(u(rng), u(rng), u(rng));
    samples.push_back(s);
  }
  BeamRayCostFunction cost(samples, R0, Layout::kFreeBeam);
  double theta[3] = {0.01, -0.02, 0.03}, t[3] = {0.5, -0.3, 0.2}, azel[2] = {0.14, -0.09};
  const double* params[3] = {theta, t, azel};
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::NumericDiffOptions nd;
  ceres::GradientChecker checker(&cost, no_manifolds, nd);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params, 1e-6, &results)) << results.error_log;
}

TEST(LevelRowManifold, InvariantsHoldAndPlusStaysLevel) {
  for (int m : {1, 2, 4, 10}) {
    LevelRowManifold manifold(m);
    Eigen::VectorXd x(2 * m);
    for (int j = 0; j < m; ++j) {
      x(j) = 0.05 * (j - m / 2.0 + 0.3);      // azimuths, not symmetric
      x(m + j) = 0.002 * std::cos(1.0 + j);  // elevations
    }
    LevelRowManifold::Project(x.data(), x.data() + m, m);
    EXPECT_NEAR(x.head(m).dot(x.tail(m)), 0.0, 1e-18);
    Eigen::VectorXd delta(2 * m - 1);
    for (int k = 0; k < 2 * m - 1; ++k) delta(k) = 0.01 * std::sin(3.0 * k + 1.0);
    Eigen::VectorXd y(2 * m);
    ASSERT_TRUE(manifold.Plus(x.data(), delta.data(), y.data()));
    EXPECT_NEAR(y.head(m).dot(y.tail(m)), 0.0, 1e-16);
    EXPECT_GT((y - x).norm(), 1e-3);
    const Eigen::MatrixXd B = LevelRowManifold::OrthogonalBasis(x.head(m));
    EXPECT_LT((B.transpose() * B - Eigen::MatrixXd::Identity(m - 1, m - 1)).norm(), 1e-14);
    EXPECT_LT((x.head(m).transpose() * B).norm(), 1e-15);
    {
      using namespace ceres;  // the macro names ceres' helpers unqualified
      EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-10);
    }
  }
}

}  // namespace
}  // namespace opl
