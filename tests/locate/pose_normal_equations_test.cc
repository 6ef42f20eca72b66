// PoseNormalEquations and SolvePoseLevenbergMarquardt (the fast path of
// LocateSource's refinement) against the reference: SourcePoseCostFunction's
// residuals and Jacobian, and ceres::TinySolver on it.
#include "opl/locate/pose_normal_equations.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <random>

#include <ceres/tiny_solver.h>
#include <ceres/tiny_solver_cost_function_adapter.h>
#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "opl/locate/locate_source.h"
#include "opl/locate/source_pose_cost_function.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

using Matrix6 = PoseNormalEquations::Matrix6;
using Vector6 = PoseNormalEquations::Vector6;

struct Problem {
  std::vector<Eigen::Vector3d> points, beams;
  std::vector<Eigen::Matrix2d> W;
  Eigen::Matrix3d R0;
  Eigen::Vector3d t0;
  double D = 1.0;

  std::vector<SourcePoseCostFunction::Spot> Spots() const {
    std::vector<SourcePoseCostFunction::Spot> spots;
    for (size_t i = 0; i < points.size(); ++i) spots.push_back({points[i], beams[i], W[i]});
    return spots;
  }
  SourcePoseCostFunction Reference() const { return SourcePoseCostFunction(Spots(), R0, t0, D); }
  PoseNormalEquations Fast() const { return PoseNormalEquations(points, beams, W, R0, t0, D); }
};

enum class Whitening { kIdentity, kLowerTriangular, kGeneral };

// n spots about 900 away in random directions, each slightly off its beam;
// every `far`-th one far off (0.3 rad: outside the small-angle range).
Problem MakeProblem(std::mt19937_64& rng, int n, Whitening whitening, double D, int far = 0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Problem p;
  p.R0 = test::RandomRotation(rng).toRotationMatrix();
  p.t0 = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 300.0;
  p.D = D;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(1.0, 0.4 * u(rng), 0.4 * u(rng)).normalized();
    const double off = (far > 0 && i % far == 0) ? 0.3 : 0.01;
    p.beams.push_back(
        DirectionFromAzElRad(AzimuthRad(d) + off * u(rng), ElevationRad(d) + off * u(rng)));
    p.points.push_back(p.R0 * (900.0 * d) + p.t0 + 5.0 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    Eigen::Matrix2d W = Eigen::Matrix2d::Identity();
    if (whitening != Whitening::kIdentity) {
      W << 1e3 * (2.0 + u(rng)), 0.0, 1e2 * u(rng), 1e3 * (1.5 + u(rng));
      if (whitening == Whitening::kGeneral) W(0, 1) = 1e2 * u(rng);
    }
    p.W.push_back(W);
  }
  return p;
}

// |a - b| <= tol * scale entry by entry, with the scale of J^T J entry (i, j)
// sqrt(B_ii B_jj) (the Cauchy-Schwarz bound of |B_ij|).
void ExpectNormalMatrixNear(const Matrix6& A, const Matrix6& B, double tol) {
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(A(i, j), B(i, j), tol * std::sqrt(B(i, i) * B(j, j))) << i << "," << j;
    }
  }
}

TEST(PoseNormalEquations, ResidualsAndNormalEquationsMatchTheCostFunction) {
  std::mt19937_64 rng(51);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int trial = 0;
  for (Whitening whitening : {Whitening::kIdentity, Whitening::kLowerTriangular, Whitening::kGeneral}) {
    for (int n : {4, 9, 40, 121}) {  // odd and even counts (the evaluation pads to even)
      for (double D : {1.0, 900.0}) {
        const Problem p = MakeProblem(rng, n, whitening, D, trial % 3 == 0 ? 5 : 0);
        const SourcePoseCostFunction reference = p.Reference();
        const PoseNormalEquations fast = p.Fast();
        ASSERT_EQ(fast.num_spots(), n);
        // At zero and away from it (exact Jacobians are needed everywhere).
        for (int at = 0; at < 2; ++at) {
          Vector6 x = Vector6::Zero();
          if (at == 1) x << 0.2 * D * u(rng), 0.2 * D * u(rng), 0.2 * D * u(rng), u(rng), u(rng), u(rng);
          const int m = 2 * n;
          Eigen::VectorXd r(m);
          Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor> J(m, 6);
          const double* params[1] = {x.data()};
          double* jacobians[1] = {J.data()};
          ASSERT_TRUE(reference.Evaluate(params, r.data(), jacobians));

          Eigen::VectorXd r_fast(m);
          ASSERT_TRUE(fast.Residuals(x.data(), r_fast.data()));
          const double r_scale = r.cwiseAbs().maxCoeff();
          for (int i = 0; i < m; ++i) EXPECT_NEAR(r_fast(i), r(i), 1e-12 * r_scale) << i;

          double cost = 0.0;
          Matrix6 JtJ;
          Vector6 Jtr;
          Eigen::VectorXd angles(m);
          ASSERT_TRUE(fast.Evaluate(x.data(), &cost, &JtJ, &Jtr, angles.data()));
          EXPECT_NEAR(cost, 0.5 * r.squaredNorm(), 1e-12 * r.squaredNorm());
          const Matrix6 JtJ_ref = J.transpose() * J;
          const Vector6 Jtr_ref = J.transpose() * r;
          ExpectNormalMatrixNear(JtJ, JtJ_ref, 1e-12);
          for (int k = 0; k < 6; ++k) {
            EXPECT_NEAR(Jtr(k), Jtr_ref(k), 1e-12 * std::sqrt(JtJ_ref(k, k)) * r.norm()) << k;
          }
          // The unwhitened angle differences, whitened, are the residuals.
          for (int i = 0; i < n; ++i) {
            const Eigen::Vector2d w = p.W[i] * angles.segment<2>(2 * i);
            EXPECT_NEAR(w(0), r(2 * i), 1e-12 * r_scale);
            EXPECT_NEAR(w(1), r(2 * i + 1), 1e-12 * r_scale);
          }
          // The residuals alone.
          double cost_only = 0.0;
          ASSERT_TRUE(fast.Evaluate(x.data(), &cost_only, nullptr, nullptr));
          EXPECT_NEAR(cost_only, cost, 1e-13 * cost);
          // The pose accessors.
          EXPECT_LT((fast.Rotation(x.data()) - reference.Rotation(x.data())).norm(), 1e-15);
          EXPECT_LT((fast.Origin(x.data()) - reference.Origin(x.data())).norm(), 1e-12);
        }
        ++trial;
      }
    }
  }
}

TEST(PoseNormalEquations, ResetKeepsNothingOfTheOldSpots) {
  std::mt19937_64 rng(52);
  const Problem a = MakeProblem(rng, 30, Whitening::kGeneral, 900.0);
  const Problem b = MakeProblem(rng, 7, Whitening::kLowerTriangular, 900.0);
  PoseNormalEquations reused = a.Fast();
  reused.Reset(b.R0, b.t0, b.D);
  for (size_t i = 0; i < b.points.size(); ++i) {
    reused.AddSpot(b.points[i], BeamAngles::FromDirection(b.beams[i]), b.W[i]);
  }
  const PoseNormalEquations fresh = b.Fast();
  Vector6 x;
  x << 3.0, -2.0, 1.0, 0.5, 0.2, -0.1;
  double c1 = 0.0, c2 = 0.0;
  Matrix6 H1, H2;
  Vector6 g1, g2;
  ASSERT_TRUE(reused.Evaluate(x.data(), &c1, &H1, &g1));
  ASSERT_TRUE(fresh.Evaluate(x.data(), &c2, &H2, &g2));
  EXPECT_EQ(c1, c2);
  EXPECT_EQ(H1, H2);
  EXPECT_EQ(g1, g2);
}

TEST(PoseNormalEquations, FailsLikeTheReferenceOnTheZAxis) {
  std::mt19937_64 rng(53);
  Problem p = MakeProblem(rng, 6, Whitening::kIdentity, 1.0);
  // At x = 0 with R0 = I, spot 3 has q = (0, 0, 500) exactly.
  p.R0.setIdentity();
  p.points[3] = p.t0 + Eigen::Vector3d(0.0, 0.0, 500.0);
  const SourcePoseCostFunction reference = p.Reference();
  const PoseNormalEquations fast = p.Fast();
  const Vector6 x = Vector6::Zero();
  std::vector<double> r(12);
  const double* params[1] = {x.data()};
  EXPECT_FALSE(reference.Evaluate(params, r.data(), nullptr));
  double cost = 0.0;
  Matrix6 H;
  Vector6 g;
  EXPECT_FALSE(fast.Evaluate(x.data(), &cost, &H, &g));
  EXPECT_FALSE(fast.Evaluate(x.data(), &cost, nullptr, nullptr));
  EXPECT_FALSE(fast.Residuals(x.data(), r.data()));
}

// A located source's noisy spots (0.1 mm at ~1 m), with the whitening of
// LocateSource (W^T W = (J_p Sigma J_p^T)^-1 at the starting pose) or none,
// posed as LocateSource's refinement does: around a starting pose off the
// truth, rotation as arc length at D, the origin counted from a point D away.
struct RefineSetup {
  Problem problem;
  Vector6 x0;
};

RefineSetup MakeRefineSetup(std::mt19937_64& rng, bool weighted, double start_error_rad) {
  const BeamPattern pattern = test::TangentLatticePattern(11, 29.0 * M_PI / 180.0);
  const Rigid3d truth(test::RandomRotation(rng), Eigen::Vector3d(120.0, -40.0, 300.0));
  const double sigma = 0.1;
  const auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.2, sigma, rng);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Matrix3d R =
      ExpSO3(start_error_rad * Eigen::Vector3d(g(rng), g(rng), g(rng))) * truth.RotationMatrix();
  const Eigen::Vector3d t = truth.translation + 1000.0 * start_error_rad * Eigen::Vector3d(g(rng), g(rng), g(rng));
  RefineSetup s;
  Problem& p = s.problem;
  double D = 0.0;
  for (const SpotObservation& o : spots) {
    p.points.push_back(o.point_in_scene);
    p.beams.push_back(pattern.DirectionInSource(o.beam_id));
    Eigen::Matrix2d W = Eigen::Matrix2d::Identity();
    if (weighted) {
      const Eigen::Vector3d q = R.transpose() * (o.point_in_scene - t);
      const Eigen::Matrix<double, 2, 3> Jp = AzElJacobian(q) * R.transpose();
      const Eigen::Matrix2d C = Jp * (*o.cov_in_scene) * Jp.transpose();
      W = Eigen::Matrix2d(C.llt().matrixL()).inverse();
    }
    p.W.push_back(W);
    D += (o.point_in_scene - t).norm();
  }
  D /= static_cast<double>(spots.size());
  p.R0 = R;
  p.t0 = t - Eigen::Vector3d(D, 0.0, 0.0);
  p.D = D;
  s.x0 << 0.0, 0.0, 0.0, D, 0.0, 0.0;
  return s;
}

// LocateSource's solver settings: the step test only, starting near Gauss-Newton.
PoseSolverOptions LocateLikeOptions() {
  PoseSolverOptions o;
  o.max_num_iterations = 50;
  o.function_tolerance = std::numeric_limits<double>::min();
  o.gradient_tolerance = 0.0;
  o.parameter_tolerance = 1e-8;
  o.cost_threshold = 0.0;
  o.initial_trust_region_radius = 1e12;
  return o;
}

double max_x_difference = 0.0;
int rejected_steps = 0;

using Adapter = ceres::TinySolverCostFunctionAdapter<Eigen::Dynamic, 6>;

ceres::TinySolver<Adapter>::Summary SolveWithTinySolver(const SourcePoseCostFunction& cost,
                                                        const PoseSolverOptions& o, Vector6* x) {
  const Adapter function(cost);
  ceres::TinySolver<Adapter> solver;
  solver.options.max_num_iterations = o.max_num_iterations;
  solver.options.function_tolerance = o.function_tolerance;
  solver.options.gradient_tolerance = o.gradient_tolerance;
  solver.options.parameter_tolerance = o.parameter_tolerance;
  solver.options.cost_threshold = o.cost_threshold;
  solver.options.initial_trust_region_radius = o.initial_trust_region_radius;
  return solver.Solve(function, x);
}

void ExpectSameSolve(const RefineSetup& s, const PoseSolverOptions& o, const std::string& what,
                     int min_iterations) {
  SCOPED_TRACE(what);
  const SourcePoseCostFunction reference = s.problem.Reference();
  const PoseNormalEquations fast = s.problem.Fast();
  Vector6 x_ref = s.x0, x_fast = s.x0;
  const auto ref = SolveWithTinySolver(reference, o, &x_ref);
  const PoseSolverSummary sum = SolvePoseLevenbergMarquardt(fast, o, &x_fast);
  EXPECT_FALSE(sum.evaluation_failed);
  EXPECT_EQ(sum.iterations, ref.iterations);
  EXPECT_EQ(static_cast<int>(sum.status), static_cast<int>(ref.status));
  EXPECT_NEAR(sum.initial_cost, ref.initial_cost, 1e-12 * ref.initial_cost);
  // Cost away from the minimum (the gradient stop) moves to first order with
  // the rounding-level differences of x.
  EXPECT_NEAR(sum.final_cost, ref.final_cost, 1e-10 * ref.final_cost);
  // The final pose: x to 1e-12 of |x| (~ D), the rotation to 1e-12 rad.
  EXPECT_LT((x_fast - x_ref).norm(), 1e-12 * x_ref.norm());
  EXPECT_LT(RotationAngleBetweenRad(fast.Rotation(x_fast.data()), reference.Rotation(x_ref.data())), 1e-12);
  EXPECT_LT((fast.Origin(x_fast.data()) - reference.Origin(x_ref.data())).norm(), 1e-12 * s.problem.D);
  // And it went somewhere.
  EXPECT_GE(sum.iterations, min_iterations);
  max_x_difference = std::max(max_x_difference, (x_fast - x_ref).norm() / x_ref.norm());
  rejected_steps += sum.rejected_steps;
}

TEST(SolvePoseLevenbergMarquardt, SameStepsAndResultAsTinySolverOnNoisySpots) {
  std::mt19937_64 rng(54);
  for (int trial = 0; trial < 10; ++trial) {
    for (bool weighted : {false, true}) {
      const std::string what = "trial " + std::to_string(trial) + (weighted ? " weighted" : " unweighted");
      // As LocateSource runs it: from a RANSAC-like start ~1 mrad off.
      const RefineSetup near = MakeRefineSetup(rng, weighted, 1e-3);
      ExpectSameSolve(near, LocateLikeOptions(), what + ", locate settings", 3);
      // Further off, with TinySolver's default damping (rejected steps, the
      // damping schedule) and a gradient stop.
      const RefineSetup far = MakeRefineSetup(rng, weighted, 3e-2);
      PoseSolverOptions o = LocateLikeOptions();
      o.initial_trust_region_radius = 1e4;
      ExpectSameSolve(far, o, what + ", damped", 3);
      o.gradient_tolerance = weighted ? 1e2 : 1e-5;
      ExpectSameSolve(far, o, what + ", gradient stop", 1);
      o = PoseSolverOptions();  // TinySolver's defaults
      ExpectSameSolve(far, o, what + ", defaults", 1);
      // Far off and undamped: Gauss-Newton overshoots, steps are rejected.
      const RefineSetup very_far = MakeRefineSetup(rng, weighted, 0.3);
      ExpectSameSolve(very_far, LocateLikeOptions(), what + ", rejections", 3);
    }
  }
  EXPECT_GT(rejected_steps, 0);
  std::printf("largest |x - x_TinySolver| / |x|: %.2g\n", max_x_difference);
}

// End to end: with a good starting guess (no RANSAC) and no outliers,
// LocateSource's pose is that of TinySolver on SourcePoseCostFunction from the
// guess, whitened at the guess, as docs/locate.md describes the refinement.
TEST(SolvePoseLevenbergMarquardt, LocateSourceEqualsTinySolverOnTheReference) {
  std::mt19937_64 rng(55);
  const BeamPattern pattern = test::TangentLatticePattern(11, 29.0 * M_PI / 180.0);
  for (int trial = 0; trial < 6; ++trial) {
    const bool weighted = trial % 2 == 1;
    const Rigid3d truth(test::RandomRotation(rng), Eigen::Vector3d(120.0, -40.0, 300.0));
    auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.2, 0.1, rng);
    if (!weighted) {
      for (auto& s : spots) s.cov_in_scene.reset();
    }
    std::normal_distribution<double> g(0.0, 1.0);
    const Rigid3d guess(Eigen::Quaterniond(ExpSO3(3e-4 * Eigen::Vector3d(g(rng), g(rng), g(rng))) *
                                           truth.RotationMatrix()),
                        truth.translation + 0.3 * Eigen::Vector3d(g(rng), g(rng), g(rng)));
    LocateOptions options;
    options.initial_scene_from_source = guess;
    const auto located = LocateSource(pattern, spots, options);
    ASSERT_TRUE(located.ok()) << located.status().ToString();
    ASSERT_EQ(located->ransac_iterations, 0);
    ASSERT_EQ(located->num_inliers, located->num_spots);

    // The reference, from the guess as LocateSource reads it.
    const Rigid3d source_from_scene = guess.Inverse();
    const Eigen::Matrix3d R = source_from_scene.RotationMatrix().transpose();
    const Eigen::Vector3d t = -(R * source_from_scene.translation);
    std::vector<SourcePoseCostFunction::Spot> ref_spots;
    double D = 0.0;
    for (const SpotObservation& o : spots) {
      Eigen::Matrix2d W = Eigen::Matrix2d::Identity();
      if (weighted) {
        const Eigen::Matrix<double, 2, 3> Jp = AzElJacobian(R.transpose() * (o.point_in_scene - t)) * R.transpose();
        W = Eigen::Matrix2d((Jp * (*o.cov_in_scene) * Jp.transpose()).llt().matrixL()).inverse();
      }
      ref_spots.push_back({o.point_in_scene, pattern.DirectionInSource(o.beam_id), W});
      D += (o.point_in_scene - t).norm();
    }
    D /= static_cast<double>(spots.size());
    const SourcePoseCostFunction cost(ref_spots, R, t - Eigen::Vector3d(D, 0.0, 0.0), D);
    Vector6 x;
    x << 0.0, 0.0, 0.0, D, 0.0, 0.0;
    const auto summary = SolveWithTinySolver(cost, LocateLikeOptions(), &x);
    EXPECT_EQ(located->solver_iterations, summary.iterations) << "trial " << trial;
    const Rigid3d expected(cost.Rotation(x.data()), cost.Origin(x.data()));
    EXPECT_LT((located->scene_from_source.translation - expected.translation).norm(), 1e-12 * D)
        << "trial " << trial;
    EXPECT_LT(RotationAngleBetweenRad(located->scene_from_source.RotationMatrix(),
                                      expected.RotationMatrix()),
              1e-12)
        << "trial " << trial;
  }
}

}  // namespace
}  // namespace opl
