// The harder virtual lab of examples/scene_clutter.json, shared by the
// integration tests and studies that render it (docs/images.md, "The harder
// lab (200 scenes)").
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "opl/io/scene_json.h"
#include "opl/lab/scene.h"
#include "support/scene_images.h"

namespace opl::test {

inline Scene ClutterScene() {
  Result<Scene> scene = ReadSceneJson(SourceDir() + "/examples/scene_clutter.json");
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  return scene.ok() ? *scene : Scene();
}

// The scene without speckle and sensor noise (everything else kept).
inline Scene NoiseFree(Scene scene) {
  scene.spots.speckle_contrast = 0.0;
  scene.image.read_noise = 0.0;
  scene.image.gain_e_per_dn = 0.0;
  return scene;
}

// The module moved rigidly for seed k: up to +-40 mm across the beams (y, z),
// +-2 deg of yaw and pitch, +-10 deg of roll. Why: JPEG's error on a spot
// centre is a fixed function of where the spot falls on the 8 x 8 blocks and
// the 2 x 2 chroma grid, so with one placement every seed repeats the same
// compression error and s shows it as a bias (the 200 scenes of one
// placement had mean z +0.31). Over placements that error is random and
// u(s) covers it (docs/images.md, "The harder lab", and
// tests/integration/jpeg_spot_offsets_test.cc).
inline void PlaceModuleForSeed(Scene& scene, uint64_t seed) {
  std::mt19937_64 rng(0x9e3779b97f4a7c15ULL ^ seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const double deg = M_PI / 180.0;
  const Eigen::Matrix3d r =
      (Eigen::AngleAxisd(2.0 * deg * uniform(rng), Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(2.0 * deg * uniform(rng), Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(10.0 * deg * uniform(rng), Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const double dy = 40.0 * uniform(rng), dz = 40.0 * uniform(rng);
  const Rigid3d moved(r, Eigen::Vector3d(0.0, dy, dz));
  for (SourceDesign& source : scene.module->sources) {
    source.scene_from_source = moved * source.scene_from_source;
  }
}

}  // namespace opl::test
