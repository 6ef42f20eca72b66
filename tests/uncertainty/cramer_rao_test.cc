// The Cramer-Rao bound of a source's pose (cramer_rao.h), checked against two
// independent computations: the Fisher information of the full model (pose
// and every spot's distance t_k, Jacobian by central differences of the 3D
// spot model, inverted as one dense matrix), and the covariance LocateSource
// reports for efficiently weighted spots (angular residuals: a different
// derivation). Then the Monte Carlo: the efficient weighting reaches the bound,
// the unweighted solve does not, on a design with anisotropic spot noise.
#include "opl/uncertainty/cramer_rao.h"

#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/locate/locate_source.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_spots.h"
#include "opl/uncertainty/monte_carlo.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// A design whose spot noise is strongly anisotropic and oblique: 0.30 mm along
// an axis 35 deg from the viewing direction, 0.04 mm across it. Spots far from
// the centre see much of the long axis across their ray, central spots little.
ModuleDesign AnisotropicDesign() {
  ModuleDesign d = test::Prototype();
  d.sources = {test::Source("A", {0, 19.5, 0}, {0.02, -0.03, 0.05}),
               test::Source("B", {-39, -19.5, 0}, {-0.01, 0.02, -0.04})};
  d.spot_noise_mm = Eigen::Vector3d(0.30, 0.04, 0.04);
  d.noise_frame_rotation = RotationZ(35.0 * M_PI / 180.0) * RotationX(0.4);
  return d;
}

// Noise-free spots of source `index`, each with the design's covariance.
SourceSpotGeometry GeometryOf(const ModuleDesign& design, size_t index,
                              std::vector<SpotObservation>* observations) {
  SpotSimulationOptions exact;
  exact.attach_covariance = false;
  Result<std::vector<SimulatedSpot>> spots = SimulateSpots(design, exact);
  EXPECT_TRUE(spots.ok()) << spots.status().message();
  SourceSpotGeometry g;
  g.scene_from_source = design.sources[index].scene_from_source;
  const Eigen::Matrix3d sigma = design.SpotCovarianceMm2();
  for (const SimulatedSpot& s : *spots) {
    if (s.spot.source != design.sources[index].name) continue;
    g.points_in_scene.push_back(s.true_point_in_scene);
    g.covariances.push_back(sigma);
    if (observations != nullptr) {
      SpotObservation o;
      o.beam_id = s.spot.observation.beam_id;
      o.point_in_scene = s.true_point_in_scene;
      o.cov_in_scene = sigma;
      observations->push_back(o);
    }
  }
  return g;
}

// The full Fisher information J^T Sigma^-1 J of the parameters
// (dtheta, do, t_1 .. t_N), J by central differences of
//   p_k = o + t_k Exp(dtheta) R d_k,
// inverted densely; returns the pose block.
Matrix6d BruteForceBound(const SourceSpotGeometry& g) {
  const int n = static_cast<int>(g.points_in_scene.size());
  const Eigen::Matrix3d r = g.scene_from_source.RotationMatrix();
  const Eigen::Vector3d o = g.scene_from_source.translation;
  std::vector<Eigen::Vector3d> d_in_source(n);
  std::vector<double> t(n);
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d v = g.points_in_scene[k] - o;
    t[k] = v.norm();
    d_in_source[k] = r.transpose() * v / t[k];
  }
  const int m = 6 + n;
  auto model = [&](const Eigen::VectorXd& x) {
    Eigen::VectorXd p(3 * n);
    const Eigen::Matrix3d rx = ExpSO3(x.head<3>()) * r;
    for (int k = 0; k < n; ++k) {
      p.segment<3>(3 * k) = o + x.segment<3>(3) + (t[k] + x[6 + k]) * rx * d_in_source[k];
    }
    return p;
  };
  Eigen::MatrixXd jacobian(3 * n, m);
  const double h = 1e-6;
  for (int j = 0; j < m; ++j) {
    Eigen::VectorXd plus = Eigen::VectorXd::Zero(m), minus = Eigen::VectorXd::Zero(m);
    plus[j] = h;
    minus[j] = -h;
    jacobian.col(j) = (model(plus) - model(minus)) / (2.0 * h);
  }
  Eigen::MatrixXd weight = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int k = 0; k < n; ++k) weight.block<3, 3>(3 * k, 3 * k) = g.covariances[k].inverse();
  const Eigen::MatrixXd information = jacobian.transpose() * weight * jacobian;
  const Eigen::MatrixXd inverse = information.ldlt().solve(Eigen::MatrixXd::Identity(m, m));
  return inverse.topLeftCorner<6, 6>();
}

double RelativeDifference(const Matrix6d& a, const Matrix6d& b) {
  return (a - b).norm() / b.norm();
}

TEST(CramerRaoTest, MatchesTheFullFisherInformation) {
  const ModuleDesign design = AnisotropicDesign();
  for (size_t s = 0; s < design.sources.size(); ++s) {
    const SourceSpotGeometry g = GeometryOf(design, s, nullptr);
    ASSERT_EQ(g.points_in_scene.size(), 121u);
    Result<Matrix6d> bound = PoseCramerRaoBound(g);
    ASSERT_TRUE(bound.ok()) << bound.status().message();
    EXPECT_LT(RelativeDifference(*bound, BruteForceBound(g)), 1e-6) << "source " << s;
  }
}

// The efficient weighting's first-order covariance is the bound (an identity
// of projectors), and LocateSource's own covariance for spots carrying Sigma,
// from whitened angular residuals, is that too.
TEST(CramerRaoTest, EfficientWeightingReachesTheBound) {
  const ModuleDesign design = AnisotropicDesign();
  std::vector<SpotObservation> observations;
  const SourceSpotGeometry g = GeometryOf(design, 0, &observations);
  Result<Matrix6d> bound = PoseCramerRaoBound(g);
  Result<Matrix6d> efficient = PoseFirstOrderCovariance(g, SpotWeighting::kEfficient);
  ASSERT_TRUE(bound.ok() && efficient.ok());
  EXPECT_LT(RelativeDifference(*efficient, *bound), 1e-9);

  Result<ModuleCalibration> calibration = ExactCalibration(design);
  ASSERT_TRUE(calibration.ok());
  LocateOptions options;
  options.initial_scene_from_source = g.scene_from_source;
  Result<LocateResult> located = LocateSource(calibration->sources[0].pattern, observations, options);
  ASSERT_TRUE(located.ok()) << located.status().message();
  EXPECT_LT(RelativeDifference(located->covariance, *bound), 1e-6);
}

// Unweighted: the sandwich covariance is above the bound (C_W - CRB positive
// semi-definite) and, with this noise, the length std clearly so.
TEST(CramerRaoTest, UnweightedIsAboveTheBound) {
  const ModuleDesign design = AnisotropicDesign();
  const SourceSpotGeometry g = GeometryOf(design, 0, nullptr);
  Result<Matrix6d> bound = PoseCramerRaoBound(g);
  Result<Matrix6d> unweighted = PoseFirstOrderCovariance(g, SpotWeighting::kUnweighted);
  ASSERT_TRUE(bound.ok() && unweighted.ok());
  Eigen::SelfAdjointEigenSolver<Matrix6d> eig(*unweighted - *bound);
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-12 * bound->norm());
  EXPECT_GT(std::sqrt((*unweighted)(4, 4)), 1.05 * std::sqrt((*bound)(4, 4)));
}

TEST(CramerRaoTest, LengthStdClosedForm) {
  // L along x: only the xx variances count.
  const Eigen::Matrix3d ci = Eigen::Vector3d(0.04, 9.0, 9.0).asDiagonal();
  const Eigen::Matrix3d cj = Eigen::Vector3d(0.05, 7.0, 1.0).asDiagonal();
  EXPECT_NEAR(LengthStd({0, 0, 0}, ci, {55, 0, 0}, cj), 0.3, 1e-15);
  EXPECT_EQ(LengthStd({1, 2, 3}, ci, {1, 2, 3}, cj), 0.0);
}

TEST(CramerRaoTest, Errors) {
  SourceSpotGeometry g;
  g.points_in_scene = {{1000, 0, 0}, {1000, 10, 0}};
  g.covariances = {Eigen::Matrix3d::Identity()};
  EXPECT_EQ(PoseCramerRaoBound(g).status().code(), StatusCode::kInvalidArgument);
  g.covariances.push_back(-Eigen::Matrix3d::Identity());
  EXPECT_EQ(PoseCramerRaoBound(g).status().code(), StatusCode::kInvalidArgument);
  g.covariances[1] = Eigen::Matrix3d::Identity();
  Result<Matrix6d> two_spots = PoseCramerRaoBound(g);  // 4 equations, 6 unknowns
  EXPECT_EQ(two_spots.status().code(), StatusCode::kNoSolution);
  g.points_in_scene[1] = Eigen::Vector3d::Zero();  // at the origin
  EXPECT_EQ(PoseFirstOrderCovariance(g, SpotWeighting::kUnweighted).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(ParseSpotWeighting("efficient").value(), SpotWeighting::kEfficient);
  EXPECT_EQ(ParseSpotWeighting("unweighted").value(), SpotWeighting::kUnweighted);
  EXPECT_EQ(ParseSpotWeighting("optimal").status().message(),
            "unknown weighting 'optimal' (known: efficient, unweighted)");
}

// The Monte Carlo on the anisotropic design: with the efficient weighting the
// std of L is the bound (ratio within 10 %; the std of a std from M = 400
// draws is 3.5 %); unweighted, it is above the bound by what the sandwich
// predicts, and the report says so.
TEST(CramerRaoTest, MonteCarloAgainstTheBound) {
  const ModuleDesign design = AnisotropicDesign();
  MonteCarloOptions options;
  options.iterations = 400;
  options.seed = 3;
  options.threads = 2;
  Result<MonteCarloReport> efficient = RunMeasurementMonteCarlo(design, options);
  options.weighting = SpotWeighting::kUnweighted;
  Result<MonteCarloReport> unweighted = RunMeasurementMonteCarlo(design, options);
  ASSERT_TRUE(efficient.ok()) << efficient.status().message();
  ASSERT_TRUE(unweighted.ok()) << unweighted.status().message();
  const SampleSummary& e = efficient->lengths[0].photo_mm;
  const SampleSummary& u = unweighted->lengths[0].photo_mm;
  EXPECT_DOUBLE_EQ(e.cramer_rao_std, u.cramer_rao_std);  // a property of the design
  EXPECT_NEAR(e.first_order_std / e.cramer_rao_std, 1.0, 1e-6);
  EXPECT_NEAR(e.std_dev / e.cramer_rao_std, 1.0, 0.10);
  EXPECT_NEAR(u.std_dev / u.first_order_std, 1.0, 0.10);
  EXPECT_GT(u.first_order_std, 2.0 * u.cramer_rao_std);  // 2.34 for this design
  EXPECT_GT(u.std_dev, e.std_dev);
  std::printf("std L: efficient %.5f mm (MC/CRB %.3f), unweighted %.5f mm (MC/CRB %.3f, "
              "sandwich/CRB %.3f), CRB %.5f mm\n",
              e.std_dev, e.std_dev / e.cramer_rao_std, u.std_dev, u.std_dev / u.cramer_rao_std,
              u.first_order_std / u.cramer_rao_std, e.cramer_rao_std);
  EXPECT_NE(unweighted->ToText().find("unweighted weighting"), std::string::npos);
  EXPECT_NE(efficient->ToJson().find("\"std_over_cramer_rao\""), std::string::npos);
}

}  // namespace
}  // namespace opl
