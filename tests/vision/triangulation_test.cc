// Triangulation against known truth: noise-free views reproduce the point to
// 1e-9 m, the first-order covariance matches the closed form of two
// orthogonal pinhole cameras and the scatter of a Monte Carlo, residuals
// match OpenCV's projectPoints, and every error case names what is wrong.
#include "opl/vision/triangulation.h"

#include <cmath>
#include <cstdlib>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "opl/core/format.h"
#include <opencv2/calib3d.hpp>

namespace opl {
namespace {

CameraIntrinsics Intrinsics(double f, bool distorted) {
  CameraIntrinsics c;
  c.width_px = 1024;
  c.height_px = 768;
  c.fx_px = f;
  c.fy_px = f * 1.001;
  c.cx_px = 511.7;
  c.cy_px = 384.2;
  if (distorted) {
    c.k1 = -0.11;
    c.k2 = 0.08;
    c.k3 = -0.015;
    c.p1 = 3e-4;
    c.p2 = -2e-4;
  }
  return c;
}

// A camera at `center` looking at `target`, X right, Y down (scene Z up).
Camera LookAt(const std::string& name, const Eigen::Vector3d& center, const Eigen::Vector3d& target,
              const CameraIntrinsics& intrinsics) {
  Camera c;
  c.name = name;
  c.intrinsics = intrinsics;
  c.cam_from_scene = *CamFromSceneLookingAt(center, target);
  return c;
}

Eigen::Vector2d Pixel(const Camera& c, const Eigen::Vector3d& X) {
  Eigen::Vector2d px;
  EXPECT_TRUE(c.Project(X, &px));
  return px;
}

int MonteCarloTrials(int default_trials) {
  const char* env = std::getenv("OPL_VISION_MC");
  if (env == nullptr) return default_trials;
  const int n = std::atoi(env);
  return n > 0 ? n : default_trials;
}

TEST(Triangulation, NoiseFreeTwoViewsAreExact) {
  const Eigen::Vector3d X(0.31, -0.22, 0.47);
  for (bool distorted : {false, true}) {
    const Camera a = LookAt("a", Eigen::Vector3d(-1.2, -2.5, 0.9), Eigen::Vector3d(0, 0, 0.4),
                            Intrinsics(900.0, distorted));
    const Camera b = LookAt("b", Eigen::Vector3d(1.6, -2.1, 1.3), Eigen::Vector3d(0, 0, 0.5),
                            Intrinsics(950.0, distorted));
    const std::vector<PointObservation> obs = {{&a, Pixel(a, X), Eigen::Matrix2d::Identity()},
                                               {&b, Pixel(b, X), Eigen::Matrix2d::Identity()}};
    const auto r = TriangulatePoint(obs);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    EXPECT_LT((r->point_in_scene - X).norm(), 1e-9) << r->ToText();
    for (const Eigen::Vector2d& res : r->residuals_px) EXPECT_LT(res.norm(), 1e-8);
    // Angle between the rays, computed from the camera centres directly.
    const Eigen::Vector3d da = (X - a.CenterInScene()).normalized();
    const Eigen::Vector3d db = (X - b.CenterInScene()).normalized();
    EXPECT_NEAR(r->triangulation_angle_deg, std::acos(da.dot(db)) * 180.0 / kPi, 1e-9);
  }
}

TEST(Triangulation, CovarianceOfTwoOrthogonalPinholeCamerasIsClosedForm) {
  // Camera a on -Y looking +Y sees scene X and Z; camera b on +X looking -X
  // sees scene Y and Z. At distance d with focal f and pixel sigma s, each
  // seen coordinate has sigma s d / f per camera, so
  //   var(x) = (s d / f)^2, var(y) = (s d / f)^2, var(z) = (s d / f)^2 / 2.
  const double d = 2.0, f = 1000.0, s = 0.3;
  const Camera a = LookAt("a", Eigen::Vector3d(0, -d, 0), Eigen::Vector3d::Zero(), Intrinsics(f, false));
  const Camera b = LookAt("b", Eigen::Vector3d(d, 0, 0), Eigen::Vector3d::Zero(), Intrinsics(f, false));
  Camera a2 = a, b2 = b;
  a2.intrinsics.fy_px = f;
  b2.intrinsics.fy_px = f;
  const Eigen::Matrix2d cov = s * s * Eigen::Matrix2d::Identity();
  const Eigen::Vector3d X = Eigen::Vector3d::Zero();
  const auto r = TriangulatePoint({{&a2, Pixel(a2, X), cov}, {&b2, Pixel(b2, X), cov}});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const double v = std::pow(s * d / f, 2);
  EXPECT_NEAR(r->covariance(0, 0), v, 1e-12 * v + 1e-20);
  EXPECT_NEAR(r->covariance(1, 1), v, 1e-12 * v + 1e-20);
  EXPECT_NEAR(r->covariance(2, 2), v / 2.0, 1e-9 * v);
  EXPECT_NEAR(r->covariance(0, 1), 0.0, 1e-12 * v);
  EXPECT_NEAR(r->triangulation_angle_deg, 90.0, 1e-9);
}

TEST(Triangulation, CovarianceMatchesMonteCarloScatter) {
  const Eigen::Vector3d X(0.2, 0.1, 0.6);
  std::vector<Camera> cams = {
      LookAt("a", Eigen::Vector3d(-1.5, -2.4, 1.2), Eigen::Vector3d(0, 0, 0.5), Intrinsics(900, true)),
      LookAt("b", Eigen::Vector3d(0.3, -2.8, 1.6), Eigen::Vector3d(0, 0, 0.5), Intrinsics(1000, true)),
      LookAt("c", Eigen::Vector3d(1.9, -1.9, 0.7), Eigen::Vector3d(0, 0, 0.5), Intrinsics(950, true))};
  // Anisotropic, correlated pixel covariances.
  std::vector<Eigen::Matrix2d> covs(3);
  covs[0] << 0.04, 0.01, 0.01, 0.02;
  covs[1] << 0.01, -0.004, -0.004, 0.03;
  covs[2] << 0.09, 0.0, 0.0, 0.01;
  std::vector<Eigen::Vector2d> clean;
  for (const Camera& c : cams) clean.push_back(Pixel(c, X));
  std::vector<PointObservation> obs;
  for (size_t i = 0; i < cams.size(); ++i) obs.push_back({&cams[i], clean[i], covs[i]});
  const auto predicted = TriangulatePoint(obs);
  ASSERT_TRUE(predicted.ok());

  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int trials = 10 * MonteCarloTrials(200);  // cheap: 10 per BA solve
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  double chi2 = 0.0;
  const Eigen::Matrix3d info = predicted->covariance.inverse();
  double var_factor_sum = 0.0;
  for (int t = 0; t < trials; ++t) {
    for (size_t i = 0; i < cams.size(); ++i) {
      const Eigen::Matrix2d L = covs[i].llt().matrixL();
      obs[i].pixel_px = clean[i] + L * Eigen::Vector2d(n01(rng), n01(rng));
    }
    const auto r = TriangulatePoint(obs);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const Eigen::Vector3d e = r->point_in_scene - X;
    scatter += e * e.transpose();
    chi2 += e.dot(info * e);
    var_factor_sum += r->variance_factor;
  }
  scatter /= trials;
  for (int k = 0; k < 3; ++k) {
    const double ratio = std::sqrt(scatter(k, k) / predicted->covariance(k, k));
    EXPECT_GT(ratio, 0.9) << "axis " << k;
    EXPECT_LT(ratio, 1.1) << "axis " << k;
  }
  // Mean Mahalanobis chi^2 of the errors: 3 for the right covariance.
  EXPECT_NEAR(chi2 / trials, 3.0, 0.3);
  // Residual chi^2 / (2n - 3) averages 1 for correct pixel covariances.
  EXPECT_NEAR(var_factor_sum / trials, 1.0, 0.15);
}

TEST(Triangulation, ResidualsMatchOpenCvProjection) {
  const Eigen::Vector3d X(-0.1, 0.3, 0.2);
  std::vector<Camera> cams = {
      LookAt("a", Eigen::Vector3d(-1.5, -2.4, 1.2), Eigen::Vector3d(0, 0, 0.5), Intrinsics(900, true)),
      LookAt("b", Eigen::Vector3d(1.3, -2.8, 1.6), Eigen::Vector3d(0, 0, 0.5), Intrinsics(1000, true)),
      LookAt("c", Eigen::Vector3d(1.9, -0.9, 0.7), Eigen::Vector3d(0, 0, 0.5), Intrinsics(950, true))};
  std::vector<PointObservation> obs;
  const Eigen::Vector2d offsets[3] = {{0.4, -0.2}, {-0.3, 0.5}, {0.1, 0.2}};
  for (size_t i = 0; i < cams.size(); ++i) {
    obs.push_back({&cams[i], Pixel(cams[i], X) + offsets[i], Eigen::Matrix2d::Identity()});
  }
  const auto r = TriangulatePoint(obs);
  ASSERT_TRUE(r.ok());
  double sum_sq = 0.0;
  for (size_t i = 0; i < cams.size(); ++i) {
    const Camera& c = cams[i];
    const Eigen::Matrix3d R = c.cam_from_scene.RotationMatrix();
    cv::Matx33d Rcv;
    for (int u = 0; u < 3; ++u)
      for (int v = 0; v < 3; ++v) Rcv(u, v) = R(u, v);
    cv::Vec3d rvec;
    cv::Rodrigues(Rcv, rvec);
    const Eigen::Vector3d& t = c.cam_from_scene.translation;
    const CameraIntrinsics& k = c.intrinsics;
    const cv::Matx33d K(k.fx_px, 0, k.cx_px, 0, k.fy_px, k.cy_px, 0, 0, 1);
    const cv::Vec<double, 5> dist(k.k1, k.k2, k.p1, k.p2, k.k3);
    std::vector<cv::Point3d> object = {{r->point_in_scene.x(), r->point_in_scene.y(),
                                        r->point_in_scene.z()}};
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, rvec, cv::Vec3d(t.x(), t.y(), t.z()), K, dist, image);
    EXPECT_NEAR(r->residuals_px[i].x(), image[0].x - obs[i].pixel_px.x(), 1e-7);
    EXPECT_NEAR(r->residuals_px[i].y(), image[0].y - obs[i].pixel_px.y(), 1e-7);
    sum_sq += r->residuals_px[i].squaredNorm();
  }
  EXPECT_NEAR(r->rms_residual_px, std::sqrt(sum_sq / 6.0), 1e-12);
  EXPECT_NEAR(r->chi2, sum_sq, 1e-9);
  // At the minimum the whitened residuals are orthogonal to the Jacobian:
  // moving the point along any axis cannot lower the chi^2.
  for (int axis = 0; axis < 3; ++axis) {
    for (double h : {-1e-5, 1e-5}) {
      Eigen::Vector3d Y = r->point_in_scene;
      Y(axis) += h;
      double c2 = 0.0;
      for (size_t i = 0; i < cams.size(); ++i) c2 += (Pixel(cams[i], Y) - obs[i].pixel_px).squaredNorm();
      EXPECT_GE(c2, r->chi2 - 1e-12);
    }
  }
}

TEST(Triangulation, Errors) {
  const Camera a = LookAt("a", Eigen::Vector3d(0, -3, 0), Eigen::Vector3d::Zero(), Intrinsics(900, false));
  const Camera b = LookAt("b", Eigen::Vector3d(2, -2, 0), Eigen::Vector3d::Zero(), Intrinsics(900, false));
  const Eigen::Vector3d X(0.05, 0.0, 0.02);
  {
    const auto r = TriangulatePoint({{&a, Pixel(a, X), Eigen::Matrix2d::Identity()}});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("at least 2"), std::string::npos);
  }
  {
    // Nearly parallel: a second camera 1 mm beside the first.
    Camera a_near = LookAt("a2", Eigen::Vector3d(0.001, -3, 0), Eigen::Vector3d::Zero(), Intrinsics(900, false));
    const auto r = TriangulatePoint({{&a, Pixel(a, X), Eigen::Matrix2d::Identity()},
                                     {&a_near, Pixel(a_near, X), Eigen::Matrix2d::Identity()}});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
    EXPECT_NE(r.status().message().find("nearly parallel"), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("angle 0.019"), std::string::npos) << r.status().message();
    TriangulationOptions loose;
    loose.min_triangulation_angle_deg = 0.01;
    EXPECT_TRUE(TriangulatePoint({{&a, Pixel(a, X), Eigen::Matrix2d::Identity()},
                                  {&a_near, Pixel(a_near, X), Eigen::Matrix2d::Identity()}},
                                 loose)
                    .ok());
  }
  {
    // Two cameras looking away from each other at their own pixels: the rays
    // meet behind camera c.
    const Camera c = LookAt("c", Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0, -4, 0), Intrinsics(900, false));
    const Camera d = LookAt("d", Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, 0), Intrinsics(900, false));
    const Eigen::Vector3d Y(0, 0, 0);  // behind c, in front of d
    Eigen::Vector2d pc;
    EXPECT_FALSE(c.Project(Y, &pc));
    // A pixel of c whose ray, extended backwards, passes through Y: the
    // image centre (c looks along -Y, Y lies on its axis behind it).
    const auto r = TriangulatePoint({{&c, Eigen::Vector2d(c.intrinsics.cx_px, c.intrinsics.cy_px),
                                      Eigen::Matrix2d::Identity()},
                                     {&d, Pixel(d, Eigen::Vector3d(0, 0.0, 0.0)), Eigen::Matrix2d::Identity()}});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
    EXPECT_NE(r.status().message().find("behind camera of view 0 ('c')"), std::string::npos)
        << r.status().message();
  }
  {
    const auto r = TriangulatePoint({{&a, Pixel(a, X), Eigen::Matrix2d::Identity()},
                                     {&b, Eigen::Vector2d(NAN, 1.0), Eigen::Matrix2d::Identity()}});
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("view 1: pixel is not finite"), std::string::npos);
  }
  {
    Eigen::Matrix2d bad;
    bad << 1.0, 2.0, 2.0, 1.0;  // indefinite
    const auto r = TriangulatePoint({{&a, Pixel(a, X), Eigen::Matrix2d::Identity()},
                                     {&b, Pixel(b, X), bad}});
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("view 1: pixel covariance is not positive definite"),
              std::string::npos);
  }
  {
    TriangulationOptions o;
    o.max_iterations = 0;
    const auto r = TriangulatePoint({{&a, Pixel(a, X)}, {&b, Pixel(b, X)}}, o);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("max_iterations = 0"), std::string::npos);
  }
  {
    const auto r = TriangulatePoint({{nullptr, Pixel(a, X)}, {&b, Pixel(b, X)}});
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("view 0: camera is null"), std::string::npos);
  }
}

}  // namespace
}  // namespace opl
