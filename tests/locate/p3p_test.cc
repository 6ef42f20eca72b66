#include "opl/locate/p3p.h"

#include <random>

#include <gtest/gtest.h>

#include "support/synthetic_source.h"

namespace opl {
namespace {

// Random triples of scene points seen from a random pose: one of the returned
// solutions is the true pose, to near machine precision.
TEST(P3P, RecoversTruePoseAmongSolutions) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int found = 0, trials = 2000;
  double worst = 0.0;
  for (int trial = 0; trial < trials; ++trial) {
    const Eigen::Matrix3d R = test::RandomRotation(rng).toRotationMatrix();
    const Eigen::Vector3d t(u(rng) * 500, u(rng) * 500, u(rng) * 500);
    std::array<Eigen::Vector3d, 3> f, X;
    for (int i = 0; i < 3; ++i) {
      // Points in the source frame within a 60 deg cone of +X, 0.5-2 m away.
      const Eigen::Vector3d q = (0.5 + 0.75 * (u(rng) + 1.0)) *
                                Eigen::Vector3d(1.0, 0.5 * u(rng), 0.5 * u(rng)).normalized();
      f[i] = q.normalized();
      X[i] = R.transpose() * (q - t);  // scene point with q = R X + t
    }
    std::array<PoseRt, 4> sols;
    const int n = SolveP3P(f, X, &sols);
    double best = 1e300;
    for (int s = 0; s < n; ++s) {
      best = std::min(best, (sols[s].R - R).norm() + (sols[s].t - t).norm() / 1000.0);
    }
    if (best < 1e-6) ++found;
    worst = std::max(worst, std::min(best, 1.0));
  }
  // Near-degenerate random triples may lose precision; almost all must be exact.
  EXPECT_GE(found, trials * 999 / 1000) << "worst " << worst;
}

TEST(P3P, EverySolutionReprojectsExactly) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    std::array<Eigen::Vector3d, 3> f, X;
    for (int i = 0; i < 3; ++i) {
      f[i] = Eigen::Vector3d(1.0, 0.4 * u(rng), 0.4 * u(rng)).normalized();
      X[i] = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 300.0;
    }
    std::array<PoseRt, 4> sols;
    const int n = SolveP3P(f, X, &sols);
    for (int s = 0; s < n; ++s) {
      EXPECT_NEAR((sols[s].R.transpose() * sols[s].R - Eigen::Matrix3d::Identity()).norm(), 0, 1e-12);
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d q = sols[s].R * X[i] + sols[s].t;
        EXPECT_GT(q.dot(f[i]), 0.0);
        EXPECT_LT(q.normalized().cross(f[i]).norm(), 1e-8);
      }
    }
  }
}

TEST(P3P, CollinearPointsGiveNoSolution) {
  std::array<Eigen::Vector3d, 3> f = {Eigen::Vector3d(1, 0.1, 0).normalized(),
                                      Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, -0.1, 0).normalized()};
  std::array<Eigen::Vector3d, 3> X = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1),
                                      Eigen::Vector3d(2, 2, 2)};
  std::array<PoseRt, 4> sols;
  EXPECT_EQ(SolveP3P(f, X, &sols), 0);
}

}  // namespace
}  // namespace opl
