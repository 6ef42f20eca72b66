// The three-point scene frame against a hand-computed case and its defining
// properties, TransformScene against the cameras' own projections, and
// ScaleFromArtifact against its closed form and a Monte Carlo.
#include "opl/vision/scene_frame.h"

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "opl/core/format.h"

namespace opl {
namespace {

Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
}

TEST(SceneFrame, HandComputedFrame) {
  // X along +Y_old, C above A: Z = X x (C - A) = (0,1,0) x (0,0,5) = (5,0,0)/5,
  // Y = Z x X = (1,0,0) x (0,1,0) = (0,0,1).
  const Eigen::Vector3d a(1, 2, 3), b(1, 4, 3), c(1, 2, 8);
  const auto f = SceneFromThreePoints(a, b, c);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  Eigen::Matrix3d expected;
  expected << 0, 1, 0, 0, 0, 1, 1, 0, 0;
  EXPECT_LT((f->RotationMatrix() - expected).norm(), 1e-15);
  EXPECT_LT((*f * a).norm(), 1e-15);
  EXPECT_LT((*f * b - Eigen::Vector3d(2, 0, 0)).norm(), 1e-15);
  EXPECT_LT((*f * c - Eigen::Vector3d(0, 5, 0)).norm(), 1e-15);
}

TEST(SceneFrame, DefiningPropertiesAndInvarianceToTheOldFrame) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)),
        c(u(rng), u(rng), u(rng)), p(u(rng), u(rng), u(rng));
    const auto f = SceneFromThreePoints(a, b, c);
    ASSERT_TRUE(f.ok()) << f.status().ToString();
    const Eigen::Vector3d a2 = *f * a, b2 = *f * b, c2 = *f * c;
    EXPECT_LT(a2.norm(), 1e-12);
    EXPECT_NEAR(b2.x(), (b - a).norm(), 1e-12);
    EXPECT_NEAR(b2.y(), 0.0, 1e-12);
    EXPECT_NEAR(b2.z(), 0.0, 1e-12);
    EXPECT_GT(c2.y(), 0.0);
    EXPECT_NEAR(c2.z(), 0.0, 1e-12);
    EXPECT_NEAR(f->RotationMatrix().determinant(), 1.0, 1e-12);
    // Moving all four points by any rigid motion leaves their coordinates in
    // the new frame unchanged.
    const Rigid3d m(RandomRotation(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)));
    const auto g = SceneFromThreePoints(m * a, m * b, m * c);
    ASSERT_TRUE(g.ok());
    EXPECT_LT((*g * (m * p) - *f * p).norm(), 1e-12);
  }
}

TEST(SceneFrame, CoincidentAndCollinearTargetsAreErrors) {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0);
  {
    const auto f = SceneFromThreePoints(a, a, Eigen::Vector3d(0, 1, 0));
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.status().message().find("A and B coincide"), std::string::npos);
  }
  {
    const auto f = SceneFromThreePoints(a, b, b);
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.status().message().find("C coincides with B"), std::string::npos);
  }
  {
    // C 0.2 deg off the line AB seen from A (0.4 deg seen from B).
    const double ang = 0.2 * kPi / 180.0;
    const Eigen::Vector3d c(2.0, 2.0 * std::tan(ang), 0.0);
    const auto f = SceneFromThreePoints(a, b, c);
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.status().message().find("collinear"), std::string::npos) << f.status().message();
    EXPECT_NE(f.status().message().find("0.2 deg"), std::string::npos) << f.status().message();
    SceneFrameOptions o;
    o.min_angle_deg = 0.1;
    EXPECT_TRUE(SceneFromThreePoints(a, b, c, o).ok());
  }
  {
    SceneFrameOptions o;
    o.min_angle_deg = 0.0;
    const auto f = SceneFromThreePoints(a, b, Eigen::Vector3d(0, 1, 0), o);
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.status().message().find("min_angle_deg = 0"), std::string::npos);
  }
  EXPECT_FALSE(SceneFromThreePoints(a, b, Eigen::Vector3d(0, NAN, 0)).ok());
}

TEST(SceneFrame, TransformSceneKeepsEveryPixel) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Camera> cams(3);
  for (size_t i = 0; i < cams.size(); ++i) {
    cams[i].intrinsics.width_px = 1000;
    cams[i].intrinsics.height_px = 800;
    cams[i].intrinsics.fx_px = cams[i].intrinsics.fy_px = 800.0 + 50.0 * static_cast<double>(i);
    cams[i].intrinsics.cx_px = 500;
    cams[i].intrinsics.cy_px = 400;
    cams[i].intrinsics.k1 = -0.1;
    // Camera 4 m from the origin looking at it, random roll.
    const Eigen::Quaterniond q = RandomRotation(rng);
    cams[i].cam_from_scene = Rigid3d(q, Eigen::Vector3d(0.1 * u(rng), 0.1 * u(rng), 4.0));
  }
  std::vector<Eigen::Vector3d> pts;
  for (int j = 0; j < 20; ++j) pts.emplace_back(u(rng), u(rng), u(rng));
  std::vector<std::vector<Eigen::Vector2d>> before(cams.size());
  for (size_t i = 0; i < cams.size(); ++i) {
    for (const auto& p : pts) {
      Eigen::Vector2d px;
      ASSERT_TRUE(cams[i].Project(p, &px));
      before[i].push_back(px);
    }
  }
  const Rigid3d new_from_old(RandomRotation(rng), Eigen::Vector3d(3.0, -2.0, 0.5));
  const double scale = 1.7;
  std::vector<Eigen::Vector3d> moved = pts;
  ASSERT_TRUE(TransformScene(new_from_old, scale, &cams, &moved).ok());
  for (size_t j = 0; j < pts.size(); ++j) {
    EXPECT_LT((moved[j] - scale * (new_from_old.RotationMatrix() * pts[j] + new_from_old.translation)).norm(), 1e-12);
  }
  for (size_t i = 0; i < cams.size(); ++i) {
    for (size_t j = 0; j < pts.size(); ++j) {
      Eigen::Vector2d px;
      ASSERT_TRUE(cams[i].Project(moved[j], &px));
      EXPECT_LT((px - before[i][j]).norm(), 1e-9);
    }
  }
  const Status bad = TransformScene(new_from_old, -1.0, &cams, &moved);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("scale = -1"), std::string::npos);
}

TEST(SceneFrame, ScaleFromArtifactClosedFormAndMonteCarlo) {
  const Eigen::Vector3d p1(0.1, 0.2, 0.3), p2(1.3, 0.7, -0.1);
  Eigen::Matrix3d c1, c2;
  c1 << 4e-6, 1e-6, 0, 1e-6, 2e-6, 0, 0, 0, 1e-6;
  c2 << 1e-6, 0, 0, 0, 5e-6, -1e-6, 0, -1e-6, 3e-6;
  const double L = 1.2, sigma_L = 2e-5;
  const auto s = ScaleFromArtifact(p1, p2, L, c1, c2, sigma_L);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  const double d = (p2 - p1).norm();
  EXPECT_NEAR(s->measured_length, d, 1e-15);
  EXPECT_NEAR(s->scale, L / d, 1e-15);
  // Closed form by hand: u^T (c1 + c2) u.
  const Eigen::Vector3d u = (p2 - p1) / d;
  const double var_d = u.dot(c1 * u) + u.dot(c2 * u);
  EXPECT_NEAR(s->measured_length_sigma, std::sqrt(var_d), 1e-15);
  // Monte Carlo of s over the points only (sigma_L = 0).
  const auto s0 = ScaleFromArtifact(p1, p2, L, c1, c2);
  ASSERT_TRUE(s0.ok());
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Matrix3d l1 = c1.llt().matrixL(), l2 = c2.llt().matrixL();
  const int trials = 20000;
  double sum = 0.0, sum_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Eigen::Vector3d q1 = p1 + l1 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const Eigen::Vector3d q2 = p2 + l2 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const double si = L / (q2 - q1).norm();
    sum += si;
    sum_sq += si * si;
  }
  const double mean = sum / trials;
  const double sd = std::sqrt(sum_sq / trials - mean * mean);
  EXPECT_NEAR(sd / s0->scale_sigma, 1.0, 0.03);
  // With the calibration's own sigma the relative variances add.
  EXPECT_NEAR(std::pow(s->scale_sigma / s->scale, 2),
              std::pow(s0->scale_sigma / s0->scale, 2) + std::pow(sigma_L / L, 2), 1e-18);

  EXPECT_FALSE(ScaleFromArtifact(p1, p1, L).ok());
  const auto neg = ScaleFromArtifact(p1, p2, -1.0);
  ASSERT_FALSE(neg.ok());
  EXPECT_NE(neg.status().message().find("calibrated_length = -1"), std::string::npos);
  Eigen::Matrix3d indefinite = Eigen::Matrix3d::Identity();
  indefinite(2, 2) = -1.0;
  const auto bad = ScaleFromArtifact(p1, p2, L, indefinite);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("cov1 is not positive semi-definite"), std::string::npos);
}

}  // namespace
}  // namespace opl
