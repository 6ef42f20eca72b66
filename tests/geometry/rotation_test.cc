#include "opl/geometry/rotation.h"

#include <random>

#include <gtest/gtest.h>

namespace opl {
namespace {

TEST(Rotation, XyzCompositionOrderIsMakehgtform) {
  // makehgtform('xrotate',a,'yrotate',b,'zrotate',c) = Rx(a)*Ry(b)*Rz(c):
  // applied to e_z, Rz leaves it, Ry(b) tilts it to (sin b, 0, cos b), Rx(a)
  // then gives (sin b, -sin a cos b, cos a cos b).
  const double a = 0.3, b = -0.4, c = 1.1;
  const Eigen::Vector3d v = RotationFromXyzAnglesRad({a, b, c}) * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(v.x(), std::sin(b), 1e-15);
  EXPECT_NEAR(v.y(), -std::sin(a) * std::cos(b), 1e-15);
  EXPECT_NEAR(v.z(), std::cos(a) * std::cos(b), 1e-15);
}

TEST(Rotation, AnglesRoundTrip) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-M_PI, M_PI), h(-1.5, 1.5);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d xyz(u(rng), h(rng), u(rng));
    const Eigen::Vector3d back = XyzAnglesRadFromRotation(RotationFromXyzAnglesRad(xyz));
    EXPECT_NEAR((back - xyz).norm(), 0.0, 1e-12);
  }
  // Gimbal lock still reproduces the matrix.
  const Eigen::Matrix3d R = RotationFromXyzAnglesRad({0.4, M_PI / 2, 0.3});
  EXPECT_NEAR((RotationFromXyzAnglesRad(XyzAnglesRadFromRotation(R)) - R).norm(), 0.0, 1e-12);
}

TEST(Rotation, AngleJacobianMatchesFiniteDifference) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(-3.0, 3.0), h(-1.4, 1.4);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d xyz(u(rng), h(rng), u(rng));
    const Eigen::Matrix3d R = RotationFromXyzAnglesRad(xyz);
    const Eigen::Matrix3d J = XyzAnglesJacobianWrtLeftPerturbation(xyz);
    const double eps = 1e-6;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d d = eps * Eigen::Vector3d::Unit(k);
      const Eigen::Vector3d fd = (XyzAnglesRadFromRotation(ExpSO3(d) * R) -
                                  XyzAnglesRadFromRotation(ExpSO3(-d) * R)) / (2 * eps);
      EXPECT_NEAR((fd - J.col(k)).norm(), 0.0, 1e-7 * (1 + J.col(k).norm()));
    }
  }
}

TEST(Rotation, ExpLogRoundTrip) {
  const Eigen::Vector3d w(0.1, -0.7, 2.0);
  EXPECT_NEAR((LogSO3(ExpSO3(w)) - w).norm(), 0.0, 1e-14);
  EXPECT_NEAR(RotationAngleBetweenRad(ExpSO3(w), Eigen::Matrix3d::Identity()), w.norm(), 1e-14);
  EXPECT_NEAR((Skew(w) * Eigen::Vector3d(1, 2, 3) - w.cross(Eigen::Vector3d(1, 2, 3))).norm(), 0, 1e-15);
}

}  // namespace
}  // namespace opl
