// P3P for bearing vectors: the minimal closed-form pose from three spots.
//
// Given three unit bearing vectors f_i in a source frame and the three scene
// points X_i they point at, find every source_from_scene = (R, t) with
//   lambda_i f_i = R X_i + t,   lambda_i > 0.
// The three distances lambda_i satisfy
//   lambda_i^2 + lambda_j^2 - 2 (f_i . f_j) lambda_i lambda_j = |X_i - X_j|^2.
// Following the idea of Lambda Twist (Persson & Nordberg, ECCV 2018), two of
// these quadrics are combined into a degenerate conic D1 + gamma D2 (one root
// of a cubic), which factors into two planes through the origin; each plane
// reduces the system to a quadratic. Up to four solutions, each polished by
// Newton steps on the three distance equations.
#pragma once

#include <array>

#include <Eigen/Core>

namespace opl {

struct PoseRt {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // source_from_scene rotation
  Eigen::Vector3d t = Eigen::Vector3d::Zero();      // source_from_scene translation
};

// Returns the number of solutions written to `solutions` (0 to 4). Degenerate
// input (collinear scene points, parallel bearings) gives 0 or spurious poses;
// callers score every solution against more spots.
int SolveP3P(const std::array<Eigen::Vector3d, 3>& bearings_in_source,
             const std::array<Eigen::Vector3d, 3>& points_in_scene,
             std::array<PoseRt, 4>* solutions);

}  // namespace opl
