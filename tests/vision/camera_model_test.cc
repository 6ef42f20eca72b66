// The camera model against OpenCV's own projectPoints/undistortPoints (an
// independent implementation of the same Brown-Conrady model), and under
// ceres::Jet against numeric differentiation.
#include "opl/vision/camera_model.h"

#include "opl/core/format.h"

#include <random>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

namespace opl {
namespace {

CameraIntrinsics TestIntrinsics() {
  CameraIntrinsics c;
  c.width_px = 5472;
  c.height_px = 3648;
  c.fx_px = 4800.0;
  c.fy_px = 4795.0;
  c.cx_px = 2741.3;
  c.cy_px = 1818.9;
  c.k1 = -0.12;
  c.k2 = 0.09;
  c.k3 = -0.02;
  c.p1 = 4e-4;
  c.p2 = -2.5e-4;
  return c;
}

TEST(CameraModel, ProjectionMatchesOpenCvProjectPoints) {
  const CameraIntrinsics c = TestIntrinsics();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lateral(-0.55, 0.55);
  std::uniform_real_distribution<double> depth(0.5, 5.0);
  std::vector<cv::Point3d> object;
  std::vector<Eigen::Vector2d> ours;
  for (int i = 0; i < 200; ++i) {
    const double z = depth(rng);
    const Eigen::Vector3d p(lateral(rng) * z, lateral(rng) * z * 0.7, z);
    object.emplace_back(p.x(), p.y(), p.z());
    Eigen::Vector2d px;
    ASSERT_TRUE(ProjectToPixel(c, p, &px));
    ours.push_back(px);
  }
  const cv::Matx33d K(c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1);
  const cv::Vec<double, 5> dist(c.k1, c.k2, c.p1, c.p2, c.k3);
  std::vector<cv::Point2d> theirs;
  cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, dist, theirs);
  for (size_t i = 0; i < theirs.size(); ++i) {
    EXPECT_NEAR(ours[i].x(), theirs[i].x, 1e-9);
    EXPECT_NEAR(ours[i].y(), theirs[i].y, 1e-9);
  }
}

TEST(CameraModel, PointBehindCameraDoesNotProject) {
  Eigen::Vector2d px(1, 2);
  EXPECT_FALSE(ProjectToPixel(TestIntrinsics(), Eigen::Vector3d(0.1, 0.1, -1.0), &px));
  EXPECT_FALSE(ProjectToPixel(TestIntrinsics(), Eigen::Vector3d(0.1, 0.1, 0.0), &px));
}

TEST(CameraModel, UndistortInvertsProjectionAndMatchesOpenCv) {
  const CameraIntrinsics c = TestIntrinsics();
  const cv::Matx33d K(c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1);
  const cv::Vec<double, 5> dist(c.k1, c.k2, c.p1, c.p2, c.k3);
  for (double u = 0.0; u < c.width_px; u += 547.0) {
    for (double v = 0.0; v < c.height_px; v += 364.0) {
      const auto xy = UndistortPixel(c, Eigen::Vector2d(u, v));
      ASSERT_TRUE(xy.ok()) << xy.status().ToString();
      Eigen::Vector2d back;
      ASSERT_TRUE(ProjectToPixel(c, Eigen::Vector3d(xy->x(), xy->y(), 1.0), &back));
      EXPECT_NEAR(back.x(), u, 1e-7);
      EXPECT_NEAR(back.y(), v, 1e-7);
      // OpenCV's iterative undistortion (fixed-point, fewer iterations) agrees
      // to its own accuracy.
      std::vector<cv::Point2d> in{{u, v}}, out;
      cv::undistortPoints(in, out, K, dist, cv::noArray(), cv::noArray(),
                          cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                           200, 1e-14));
      EXPECT_NEAR(xy->x(), out[0].x, 1e-6);
      EXPECT_NEAR(xy->y(), out[0].y, 1e-6);
    }
  }
}

TEST(CameraModel, JetDerivativesMatchCentralDifferences) {
  using Jet = ceres::Jet<double, kNumCameraParameters + 3>;
  const CameraIntrinsics c = TestIntrinsics();
  const auto packed = c.Packed();
  const Eigen::Vector3d point(0.31, -0.22, 1.7);
  Jet pj[kNumCameraParameters], xj[3], uv[2];
  for (int i = 0; i < kNumCameraParameters; ++i) pj[i] = Jet(packed[i], i);
  for (int i = 0; i < 3; ++i) xj[i] = Jet(point[i], kNumCameraParameters + i);
  ASSERT_TRUE(ProjectPointInCamera(pj, xj, uv));
  for (int k = 0; k < kNumCameraParameters + 3; ++k) {
    auto perturbed = [&](double h, int axis) {
      auto p = packed;
      Eigen::Vector3d x = point;
      if (k < kNumCameraParameters) {
        p[k] += h;
      } else {
        x[k - kNumCameraParameters] += h;
      }
      double out[2];
      EXPECT_TRUE(ProjectPointInCamera(p.data(), x.data(), out));
      return out[axis];
    };
    const double h = k < 4 ? 1e-3 : 1e-6;
    for (int axis = 0; axis < 2; ++axis) {
      const double numeric = (perturbed(h, axis) - perturbed(-h, axis)) / (2 * h);
      EXPECT_NEAR(uv[axis].v[k], numeric, 1e-5 * (1.0 + std::abs(numeric)))
          << "parameter " << k << " axis " << axis;
    }
  }
}

TEST(CameraModel, CameraPoseAndBounds) {
  Camera cam;
  cam.intrinsics = TestIntrinsics();
  // Camera 3 m from the scene origin on -Z, looking along +Z of the scene.
  cam.cam_from_scene = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 3.0));
  EXPECT_TRUE(cam.CenterInScene().isApprox(Eigen::Vector3d(0, 0, -3.0)));
  Eigen::Vector2d px;
  ASSERT_TRUE(cam.Project(Eigen::Vector3d::Zero(), &px));
  EXPECT_NEAR(px.x(), cam.intrinsics.cx_px, 1e-12);
  EXPECT_TRUE(cam.InImage(px));
  EXPECT_FALSE(cam.InImage(Eigen::Vector2d(-0.6, 10)));
  EXPECT_TRUE(cam.InImage(Eigen::Vector2d(-0.4, 10)));
  EXPECT_FALSE(cam.InImage(Eigen::Vector2d(5471.6, 10)));
}

TEST(CameraModel, LookingAtPlacesTheTargetOnTheAxisImageUpIsSceneUp) {
  Camera cam;
  cam.intrinsics = TestIntrinsics();
  const Eigen::Vector3d center(1.0, -3.0, 1.5), target(0.2, 0.4, 0.3);
  auto pose = CamFromSceneLookingAt(center, target);
  ASSERT_TRUE(pose.ok()) << pose.status().ToString();
  cam.cam_from_scene = *pose;
  EXPECT_LT((cam.CenterInScene() - center).norm(), 1e-12);
  const Eigen::Vector3d t_cam = cam.cam_from_scene * target;
  EXPECT_NEAR(t_cam.x(), 0.0, 1e-12);
  EXPECT_NEAR(t_cam.y(), 0.0, 1e-12);
  EXPECT_NEAR(t_cam.z(), (target - center).norm(), 1e-12);
  // A point straight above the target appears above it in the image.
  Eigen::Vector2d px_target, px_above;
  ASSERT_TRUE(cam.Project(target, &px_target));
  ASSERT_TRUE(cam.Project(target + Eigen::Vector3d(0, 0, 0.1), &px_above));
  EXPECT_LT(px_above.y(), px_target.y() - 10.0);
  EXPECT_NEAR(px_above.x(), px_target.x(), 1e-6 * cam.intrinsics.fx_px);
  // Rolled by +90 deg the picture turns clockwise: "up" in the scene is now
  // along +u (to the right) in the image.
  cam.cam_from_scene = *CamFromSceneLookingAt(center, target, kPi / 2);
  ASSERT_TRUE(cam.Project(target, &px_target));
  ASSERT_TRUE(cam.Project(target + Eigen::Vector3d(0, 0, 0.1), &px_above));
  EXPECT_GT(px_above.x(), px_target.x() + 10.0);
  EXPECT_NEAR(px_above.y(), px_target.y(), 1e-6 * cam.intrinsics.fy_px);
  // Straight down: defined (scene Y as up), target on the axis.
  auto down = CamFromSceneLookingAt(Eigen::Vector3d(0, 0, 3), Eigen::Vector3d::Zero());
  ASSERT_TRUE(down.ok());
  EXPECT_LT((*down * Eigen::Vector3d::Zero()).head<2>().norm(), 1e-12);
  EXPECT_FALSE(CamFromSceneLookingAt(center, center).ok());
}

TEST(CameraModel, ValidateNamesTheField) {
  CameraIntrinsics c = TestIntrinsics();
  EXPECT_TRUE(c.Validate().ok());
  c.fy_px = -1;
  EXPECT_NE(c.Validate().message().find("fy"), std::string::npos);
  c = TestIntrinsics();
  c.k2 = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(c.Validate().message().find("'k2'"), std::string::npos);
  c = TestIntrinsics();
  c.width_px = 0;
  EXPECT_NE(c.Validate().message().find("image size"), std::string::npos);
}

}  // namespace
}  // namespace opl
