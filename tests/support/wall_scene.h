// Test helper: a small scene of the virtual lab for renderer tests.
#pragma once

#include <Eigen/Geometry>

#include "opl/lab/scene.h"
#include "opl/vision/camera_model.h"

namespace opl::test {

// A camera at the origin looking along +X at a wall x = 1000 mm; four tags
// around a 5 x 5 grid of source A (10 deg full angle) on the wall.
inline Scene WallScene(int width = 640, int height = 480) {
  Scene s;
  SceneCamera cam;
  cam.name = "cam0";
  CameraIntrinsics& in = cam.intrinsics;
  in.width_px = width;
  in.height_px = height;
  in.fx_px = 600.0;
  in.fy_px = 601.0;
  in.cx_px = 0.5 * (width - 1) + 2.5;
  in.cy_px = 0.5 * (height - 1) - 1.5;
  in.k1 = -0.05;
  in.k2 = 0.01;
  in.p1 = 2e-4;
  in.p2 = -1e-4;
  cam.cam_from_scene = *CamFromSceneLookingAt(Eigen::Vector3d::Zero(), Eigen::Vector3d(1000, 0, 0), 0.05);
  s.cameras.push_back(cam);
  s.tags.size_mm = 100.0;
  const double yz[4][2] = {{300, 250}, {-300, 250}, {300, -250}, {-300, -250}};
  for (int k = 0; k < 4; ++k) {
    SceneTag tag;
    tag.id = 10 + k;
    // Tag frame: x = -Y (right for a viewer looking along +X), y = -Z (down), z = +X (into the wall).
    Eigen::Matrix3d R;
    R.col(0) = -Eigen::Vector3d::UnitY();
    R.col(1) = -Eigen::Vector3d::UnitZ();
    R.col(2) = Eigen::Vector3d::UnitX();
    tag.scene_from_tag = Rigid3d(R, Eigen::Vector3d(1000.0, yz[k][0], yz[k][1]));
    s.tags.tags.push_back(tag);
  }
  ModuleDesign module;
  SourceDesign a;
  a.name = "A";
  a.beams_per_side = 5;
  a.full_angle_deg = 10.0;
  a.scene_from_source = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 40.0, -30.0));
  module.sources.push_back(a);
  module.surface = PlaneSurface{Eigen::Vector3d(1000.0, 0.0, 0.0), -Eigen::Vector3d::UnitX()};
  s.module = module;
  s.spots.diameter_mm = 8.0;
  s.spots.peak_fraction = 0.5;
  s.image.bit_depth = 16;
  s.image.blur_sigma_px = 0.6;
  s.shots.push_back({"cam0", "a.png", {"A"}, 0});
  return s;
}

}  // namespace opl::test
