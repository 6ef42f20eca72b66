// Poses from tags against known truth: four distorted cameras at ~2.5 m see
// ten 120 mm tags on two walls; with 0.05 px corner noise the start poses put
// every camera centre within 0.5% of its distance and every tag within 12
// mm (0.4%), in the frame of the reference tag (the truth is moved into that frame
// independently, from the true poses). Far, small tags whose IPPE solutions are
// ambiguous do not derail it; disconnected images are reported, and bad input
// names what is wrong.
#include "opl/vision/tag_poses.h"

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace opl {
namespace {

CameraIntrinsics Intrinsics() {
  CameraIntrinsics c;
  c.width_px = 1024;
  c.height_px = 768;
  c.fx_px = 1000.0;
  c.fy_px = 1000.5;
  c.cx_px = 512.3;
  c.cy_px = 383.6;
  c.k1 = -0.06;
  c.k2 = 0.03;
  c.p1 = 2e-4;
  c.p2 = -1e-4;
  return c;
}

// Tag on a wall: normal out of the wall (towards the viewer), printed upright
// (scene Z up). Tag frame: x right, y down, z into the wall.
Rigid3d TagOnWall(const Eigen::Vector3d& center, const Eigen::Vector3d& out_normal) {
  const Eigen::Vector3d z = -out_normal.normalized();
  Eigen::Vector3d y = -Eigen::Vector3d::UnitZ();
  y = (y - y.dot(z) * z).normalized();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return Rigid3d(r, center);
}

struct TagScene {
  std::vector<Camera> cameras;
  std::vector<std::pair<int, Rigid3d>> tags;  // id, scene_from_tag
  std::vector<std::vector<TagDetection>> detections;
};

TagScene MakeTagScene(double noise_px, uint64_t seed) {
  TagScene s;
  // Wall x = 3000 (normal -X) and wall y = 1500 (normal -Y), floor z = 0.
  int id = 3;
  for (double y : {-600.0, 0.0, 600.0}) {
    for (double z : {700.0, 1500.0}) {
      s.tags.emplace_back(id++, TagOnWall({3000.0, y, z}, -Eigen::Vector3d::UnitX()));
    }
  }
  for (double x : {2000.0, 2600.0}) {
    for (double z : {800.0, 1400.0}) {
      s.tags.emplace_back(id++, TagOnWall({x, 1500.0, z}, -Eigen::Vector3d::UnitY()));
    }
  }
  const Eigen::Vector3d look(2800.0, 600.0, 1100.0);
  const std::vector<Eigen::Vector3d> centers = {
      {400.0, -700.0, 1300.0}, {500.0, 500.0, 1600.0}, {800.0, -200.0, 900.0},
      {300.0, 1000.0, 1200.0}};
  for (size_t i = 0; i < centers.size(); ++i) {
    s.cameras.push_back(Camera{"c" + std::to_string(i), Intrinsics(),
                               *CamFromSceneLookingAt(centers[i], look, 0.05 * double(i))});
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px);
  const auto corners = TagCornersInTag(120.0);
  for (const Camera& c : s.cameras) {
    std::vector<TagDetection> list;
    for (const auto& [tag_id, pose] : s.tags) {
      TagDetection d;
      d.id = tag_id;
      bool visible = (c.cam_from_scene * pose.translation).z() > 0.0;
      // Facing: the tag's out-normal points towards the camera.
      visible = visible && (c.CenterInScene() - pose.translation).dot(
                               -(pose.RotationMatrix().col(2))) > 0.0;
      for (size_t k = 0; k < 4 && visible; ++k) {
        Eigen::Vector2d px;
        visible = c.Project(pose * corners[k], &px) && c.InImage(px, 2.0);
        d.corners_px[k] = px + Eigen::Vector2d(noise(rng), noise(rng));
      }
      if (visible) list.push_back(d);
    }
    s.detections.push_back(list);
  }
  return s;
}

TEST(PosesFromTagsTest, RecoversCamerasAndTagsInTheReferenceTagFrame) {
  const TagScene s = MakeTagScene(0.05, 7);
  std::vector<CameraIntrinsics> k(s.cameras.size(), Intrinsics());
  for (const auto& list : s.detections) ASSERT_GE(list.size(), 4u);
  const Result<TagPoses> poses = PosesFromTags(k, s.detections, TagPoseOptions{120.0, 2.0, 3});
  ASSERT_TRUE(poses.ok()) << poses.status().ToString();
  EXPECT_TRUE(poses->warnings.empty()) << poses->warnings.front();
  // Truth in the reference tag's frame.
  Rigid3d scene_from_ref;
  for (const auto& [tag_id, pose] : s.tags) {
    if (tag_id == poses->reference_tag) scene_from_ref = pose;
  }
  const Rigid3d ref_from_scene = scene_from_ref.Inverse();
  for (size_t i = 0; i < s.cameras.size(); ++i) {
    ASSERT_TRUE(poses->cam_from_scene[i].has_value()) << i;
    const Eigen::Vector3d true_center = ref_from_scene * s.cameras[i].CenterInScene();
    const Eigen::Vector3d center = poses->cam_from_scene[i]->Inverse().translation;
    EXPECT_LT((center - true_center).norm(), 0.005 * true_center.norm()) << "camera " << i;
    EXPECT_LT(poses->image_rms_px[i], 0.5) << "camera " << i;
  }
  for (const auto& [tag_id, pose] : s.tags) {
    const auto found = poses->scene_from_tag.find(tag_id);
    ASSERT_NE(found, poses->scene_from_tag.end()) << tag_id;
    const Eigen::Vector3d truth = ref_from_scene * pose.translation;
    EXPECT_LT((found->second.translation - truth).norm(), 12.0) << "tag " << tag_id;
    const double angle = Eigen::AngleAxisd(found->second.rotation.inverse() *
                                           (ref_from_scene.rotation * pose.rotation))
                             .angle();
    EXPECT_LT(angle, 0.02) << "tag " << tag_id;  // rad: no flipped (IPPE twin) tag
  }
}

TEST(PosesFromTagsTest, ReportsAnImageThatSeesNoConnectedTag) {
  TagScene s = MakeTagScene(0.05, 8);
  std::vector<TagDetection> lonely(1);
  lonely[0] = s.detections[0][0];
  lonely[0].id = 500;  // a tag nobody else sees
  s.detections.push_back(lonely);
  std::vector<CameraIntrinsics> k(s.detections.size(), Intrinsics());
  const Result<TagPoses> poses = PosesFromTags(k, s.detections, TagPoseOptions{120.0, 2.0, 3});
  ASSERT_TRUE(poses.ok()) << poses.status().ToString();
  EXPECT_FALSE(poses->cam_from_scene.back().has_value());
  bool reported = false;
  for (const std::string& w : poses->warnings) reported |= w == "image 4: not placed (it sees no tag connected to the others)";
  EXPECT_TRUE(reported);
}

TEST(PosesFromTagsTest, BadInputNamesTheProblem) {
  const TagScene s = MakeTagScene(0.05, 9);
  std::vector<CameraIntrinsics> k(s.cameras.size(), Intrinsics());
  Result<TagPoses> r = PosesFromTags(k, s.detections, TagPoseOptions{0.0, 2.0, 3});
  EXPECT_EQ(r.status().message(), "tag_size must be finite and > 0, got 0");
  k[2].fx_px = -1.0;
  r = PosesFromTags(k, s.detections, TagPoseOptions{120.0, 2.0, 3});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind("image 2: ", 0), 0u) << r.status().message();
  k.pop_back();
  r = PosesFromTags(k, s.detections, TagPoseOptions{120.0, 2.0, 3});
  EXPECT_EQ(r.status().message(), "PosesFromTags: 3 intrinsics but 4 tag lists");
  std::vector<std::vector<TagDetection>> one_each = {{s.detections[0][0]}, {}};
  r = PosesFromTags({Intrinsics(), Intrinsics()}, one_each, TagPoseOptions{120.0, 2.0, 3});
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
}

}  // namespace
}  // namespace opl
