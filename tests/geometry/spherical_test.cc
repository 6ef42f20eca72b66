#include "opl/geometry/spherical.h"

#include <random>

#include <ceres/jet.h>
#include <gtest/gtest.h>

namespace opl {
namespace {

TEST(Spherical, ConventionMatchesCart2sph) {
  // MATLAB: [az, el] = cart2sph(1, 1, 1) -> az = pi/4, el = atan(1/sqrt(2)).
  const Eigen::Vector3d q(1.0, 1.0, 1.0);
  EXPECT_DOUBLE_EQ(AzimuthRad(q), M_PI / 4);
  EXPECT_DOUBLE_EQ(ElevationRad(q), std::atan(1.0 / std::sqrt(2.0)));
  // +Y is to the left: positive azimuth; +Z up: positive elevation.
  EXPECT_GT(AzimuthRad(Eigen::Vector3d(1, 0.1, 0)), 0.0);
  EXPECT_GT(ElevationRad(Eigen::Vector3d(1, 0, 0.1)), 0.0);
  EXPECT_EQ(AzimuthRad(Eigen::Vector3d(1, 0, 0)), 0.0);
}

TEST(Spherical, DirectionRoundTrip) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> az(-3.1, 3.1), el(-1.5, 1.5);
  for (int i = 0; i < 1000; ++i) {
    const double a = az(rng), e = el(rng);
    const Eigen::Vector3d d = DirectionFromAzElRad(a, e);
    EXPECT_NEAR(d.norm(), 1.0, 1e-15);
    EXPECT_NEAR(AzimuthRad(d), a, 1e-13);
    EXPECT_NEAR(ElevationRad(d), e, 1e-13);
  }
}

TEST(Spherical, AnalyticJacobianMatchesAutoDiff) {
  using Jet = ceres::Jet<double, 3>;
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d q(u(rng) + 2.5, u(rng), u(rng));
    Eigen::Matrix<Jet, 3, 1> qj;
    for (int k = 0; k < 3; ++k) qj(k) = Jet(q(k), k);
    const Jet az = AzimuthRad(qj), el = ElevationRad(qj);
    const Eigen::Matrix<double, 2, 3> J = AzElJacobian(q);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(J(0, k), az.v(k), 1e-13 * (1 + std::abs(az.v(k))));
      EXPECT_NEAR(J(1, k), el.v(k), 1e-13 * (1 + std::abs(el.v(k))));
    }
  }
}

TEST(Spherical, SmallAngleAtan2MatchesStdAtan2) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst = 0.0;
  for (int i = 0; i < 200000; ++i) {
    // Ratios across the series' range and beyond it (the fallback).
    const double c = std::exp(6.0 * u(rng)) * (i % 17 == 0 ? -1.0 : 1.0);
    const double s = c * 0.2 * u(rng) * std::pow(10.0, 4.0 * u(rng) - 2.0);
    const double ref = std::atan2(s, c);
    const double got = SmallAngleAtan2(s, c);
    worst = std::max(worst, std::abs(got - ref) / std::max(std::abs(ref), 1e-300));
  }
  EXPECT_LT(worst, 4e-16);
  EXPECT_EQ(SmallAngleAtan2(0.0, 1.0), 0.0);
  EXPECT_DOUBLE_EQ(SmallAngleAtan2(1.0, -1.0), std::atan2(1.0, -1.0));
}

TEST(Spherical, WrapAngle) {
  EXPECT_NEAR(WrapAngleRad(3 * M_PI / 2), -M_PI / 2, 1e-15);
  EXPECT_NEAR(WrapAngleRad(-3 * M_PI / 2), M_PI / 2, 1e-15);
  EXPECT_DOUBLE_EQ(WrapAngleRad(-M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngleRad(0.25), 0.25);
}

}  // namespace
}  // namespace opl
