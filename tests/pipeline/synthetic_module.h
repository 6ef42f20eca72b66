// Test helper shared by tests/io, tests/pipeline and tests/apps: a small
// synthetic module (independent of the simulation module) and its exact spots.
//
// Pattern: n x n beams on a regular az/el grid, step 2.9 deg (29 deg full
// angle for n = 11): beam (row, col) at az = (col - c) * step,
// el = (c - row) * step, c = (n - 1) / 2, so that beam 1 is top right and the
// central beam is az = el = 0 (method.md numbering).
// Spots: each beam's ray from its source's calibrated pose, hit on the plane
// x = wall_x_mm, then taken into a "scene" frame that differs from the
// calibration frame by a rotation, a translation and a scale:
//   p_scene = (R_s p_cal + t_s) / true_scale,
// so that the scale factor to find (mm per scene unit) is true_scale.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/geometry/rotation.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"

namespace opl {
namespace testing_support {

inline BeamPattern GridPattern(int n, double step_deg = 2.9) {
  const double step = step_deg * M_PI / 180.0;
  const int c = (n - 1) / 2;
  std::vector<Beam> beams;
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      Beam b;
      b.id = BeamId(row, col, n);
      b.az_rad = (col - c) * step;
      b.el_rad = (c - row) * step;
      beams.push_back(b);
    }
  }
  return BeamPattern(n, beams);
}

// Sources "A", "B" (and "C" when num_sources = 3), 55 mm apart along Y (C 40 mm
// above A), slightly rotated, all separations calibrated exactly.
inline ModuleCalibration SyntheticCalibration(int num_sources = 2, int n = 11) {
  ModuleCalibration cal;
  const char* names[3] = {"A", "B", "C"};
  const Eigen::Vector3d origins[3] = {
      {0.0, 0.0, 0.0}, {0.5, 55.0, -0.25}, {0.25, 10.0, 40.0}};
  const Eigen::Vector3d angles[3] = {
      {0.0, 0.0, 0.0}, {0.01, -0.02, 0.03}, {-0.015, 0.01, -0.02}};
  for (int i = 0; i < num_sources; ++i) {
    SourceCalibration s;
    s.name = names[i];
    s.pattern = GridPattern(n);
    s.calibration_from_source = Rigid3d(RotationFromXyzAnglesRad(angles[i]), origins[i]);
    cal.sources.push_back(s);
  }
  cal.separations = ModuleCalibration::SeparationsFromOrigins(cal.sources);
  for (Separation& sep : cal.separations) sep.u_length_mm = 0.002;
  return cal;
}

struct SceneTransform {
  double true_scale = 2.0;  // mm per scene unit
  Eigen::Vector3d angles_rad = Eigen::Vector3d(0.3, -0.2, 1.1);
  Eigen::Vector3d translation_mm = Eigen::Vector3d(100.0, -250.0, 40.0);

  Eigen::Vector3d SceneFromCalibration(const Eigen::Vector3d& p_cal) const {
    return (RotationFromXyzAnglesRad(angles_rad) * p_cal + translation_mm) / true_scale;
  }
};

// Exact spots of every beam of every source on the plane x = wall_x_mm of the
// calibration frame, in the scene frame; `where` is "<file>:<line>" as if read
// from a CSV with a header on line 1.
inline std::vector<Spot> SyntheticSpots(const ModuleCalibration& cal,
                                        const SceneTransform& scene = SceneTransform(),
                                        double wall_x_mm = 1000.0,
                                        const std::string& file = "spots.csv") {
  std::vector<Spot> spots;
  for (const SourceCalibration& s : cal.sources) {
    for (const Beam& b : s.pattern.beams()) {
      const Eigen::Vector3d t = s.calibration_from_source.translation;
      const Eigen::Vector3d d = s.calibration_from_source.rotation * b.DirectionInSource();
      const Eigen::Vector3d p_cal = t + d * ((wall_x_mm - t.x()) / d.x());
      Spot spot;
      spot.source = s.name;
      spot.observation.beam_id = b.id;
      spot.observation.point_in_scene = scene.SceneFromCalibration(p_cal);
      spot.where = file + ":" + std::to_string(spots.size() + 2);
      spots.push_back(spot);
    }
  }
  return spots;
}

}  // namespace testing_support
}  // namespace opl
