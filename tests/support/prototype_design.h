// Test support: a source design at a pose, and the prototype-like module of
// method.md (two 11 x 11, 29 deg sources 55 mm apart side by side, screen
// plane 1 m ahead, spot noise 0.110 / 0.073 / 0.073 mm along the scene axes).
#pragma once

#include <string>

#include "opl/geometry/rotation.h"
#include "opl/sim/module_design.h"

namespace opl::test {

inline SourceDesign Source(const std::string& name, const Eigen::Vector3d& origin_mm,
                           const Eigen::Vector3d& xyz_rad = Eigen::Vector3d::Zero()) {
  SourceDesign s;
  s.name = name;
  s.scene_from_source = Rigid3d(RotationFromXyzAnglesRad(xyz_rad), origin_mm);
  return s;
}

inline ModuleDesign Prototype() {
  ModuleDesign d;
  d.sources = {Source("A", {0, 27.5, 0}), Source("B", {0, -27.5, 0})};
  d.surface = PlaneSurface{Eigen::Vector3d(1000, 0, 0), Eigen::Vector3d(-1, 0, 0)};
  d.spot_noise_mm = Eigen::Vector3d(0.110, 0.073, 0.073);
  return d;
}

}  // namespace opl::test
