// Test support: rendered calibration boards seen by a camera of known
// intrinsics (tests/pipeline/calibrate_camera_images_test.cc and
// calibrate_camera_sigma_study_test.cc): the truth camera, board poses over
// the field, and the 6 x 4 tag grid those tests use.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "opl/core/format.h"
#include "opl/geometry/rigid3.h"
#include "opl/sim/random.h"
#include "opl/vision/camera_calibration.h"
#include "opl/vision/camera_model.h"

namespace opl::test {

// An 800 x 600 camera with ~900 px focal lengths and a moderate distortion.
inline Camera BoardTruthCamera() {
  Camera camera;
  camera.name = "truth";
  CameraIntrinsics& k = camera.intrinsics;
  k.width_px = 800;
  k.height_px = 600;
  k.fx_px = 900.0;
  k.fy_px = 897.0;
  k.cx_px = 405.3;
  k.cy_px = 296.8;
  k.k1 = -0.15;
  k.k2 = 0.05;
  k.p1 = 5e-4;
  k.p2 = -3e-4;
  return camera;
}

// Board poses (cam_from_board) at ~400-480 mm, tilted 15-40 deg about varied
// axes, placed over the field; each keeps the corners of the rectangle
// [lo, hi] of the board frame 12 px inside the image.
inline std::vector<Rigid3d> BoardPoses(const Camera& camera, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                       int count, uint64_t seed) {
  const Eigen::Vector3d centre(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), 0.0);
  std::mt19937_64 rng(seed);
  std::vector<Rigid3d> poses;
  for (int tries = 0; tries < 10000 && static_cast<int>(poses.size()) < count; ++tries) {
    const double tilt = (15.0 + 25.0 * Uniform01(rng)) * kPi / 180.0;
    const double axis = 2.0 * kPi * Uniform01(rng);
    const double roll = (Uniform01(rng) - 0.5) * 0.8;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis), std::sin(axis), 0.0)) *
                               Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                                  .toRotationMatrix();
    const double depth = 400.0 + 80.0 * Uniform01(rng);
    const Eigen::Vector3d at(0.25 * (2.0 * Uniform01(rng) - 1.0) * depth, 0.18 * (2.0 * Uniform01(rng) - 1.0) * depth,
                             depth);
    const Rigid3d pose(R, at - R * centre);
    bool inside = true;
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(lo.x(), lo.y(), 0), Eigen::Vector3d(hi.x(), lo.y(), 0),
                                     Eigen::Vector3d(hi.x(), hi.y(), 0), Eigen::Vector3d(lo.x(), hi.y(), 0)}) {
      Eigen::Vector2d px;
      inside = inside && ProjectToPixel(camera.intrinsics, pose * p, &px) && camera.InImage(px, 12.0);
    }
    if (inside) poses.push_back(pose);
  }
  return poses;
}

// The tag grid of those tests: 6 x 4 tags of 30 mm, gap 7.5 mm (2 cells), ids 40..63.
inline TagBoard SixByFourTagBoard() {
  TagBoard board;
  board.columns = 6;
  board.rows = 4;
  board.tag_size = 30.0;
  board.tag_gap = 7.5;
  board.first_id = 40;
  return board;
}

// The far corner of that grid's tags in the board frame (the near one is 0, 0).
inline Eigen::Vector2d TagBoardExtent(const TagBoard& board) {
  const double pitch = board.tag_size + board.tag_gap;
  return Eigen::Vector2d(board.columns * pitch - board.tag_gap, board.rows * pitch - board.tag_gap);
}

}  // namespace opl::test
