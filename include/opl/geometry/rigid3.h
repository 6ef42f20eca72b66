// Rigid3d: a rigid transform between two frames, named b_from_a, such that
//   x_in_b = rotation * x_in_a + translation.
// A source pose is scene_from_source: p_scene = R p_source + t, where t is the
// source's projection origin in the scene frame (method.md).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace opl {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // unit quaternion
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& q, const Eigen::Vector3d& t)
      : rotation(q.normalized()), translation(t) {}
  Rigid3d(const Eigen::Matrix3d& R, const Eigen::Vector3d& t)
      : rotation(Eigen::Quaterniond(R).normalized()), translation(t) {}

  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& x_in_a) const {
    return rotation * x_in_a + translation;
  }
  // a_from_b
  Rigid3d Inverse() const {
    const Eigen::Quaterniond q_inv = rotation.conjugate();
    return Rigid3d(q_inv, -(q_inv * translation));
  }
  // c_from_a = c_from_b * b_from_a
  Rigid3d operator*(const Rigid3d& b_from_a) const {
    return Rigid3d(rotation * b_from_a.rotation, rotation * b_from_a.translation + translation);
  }
};

}  // namespace opl
