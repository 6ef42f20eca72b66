// Test support: a simulated calibration session (opl/sim/simulate_slices.h)
// turned into CalibrateSource input, and a random module pose.
#pragma once

#include <random>
#include <string>
#include <vector>

#include "opl/calibrate/calibrate_source.h"
#include "opl/sim/simulate_slices.h"
#include "support/synthetic_source.h"

namespace opl::test {

// The samples of one source among simulated slices.
inline std::vector<CalibrationSample> SamplesOf(const std::vector<SimulatedSpot>& spots,
                                                const std::string& source) {
  std::vector<CalibrationSample> out;
  for (const SimulatedSpot& s : spots) {
    if (s.spot.source != source) continue;
    CalibrationSample c;
    c.beam_id = s.spot.observation.beam_id;
    c.slice = s.slice;
    c.point_mm = s.spot.observation.point_in_scene;
    c.cov_mm2 = s.spot.observation.cov_in_scene;
    out.push_back(c);
  }
  return out;
}

// Slices renumbered so that each holds one source's grid (source index *
// 1000 + screen), as a session that photographs one grid at a time gives them.
inline std::vector<int> OneGridPerSlice(const std::vector<SimulatedSpot>& spots,
                                        const ModuleDesign& design) {
  std::vector<int> out;
  for (const SimulatedSpot& s : spots) {
    int index = 0;
    while (design.sources[index].name != s.spot.source) ++index;
    out.push_back(1000 * index + s.slice);
  }
  return out;
}

// A random rigid motion: any rotation, a translation within +-range_mm.
inline Rigid3d RandomMotion(std::mt19937_64& rng, double range_mm) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Rigid3d(RandomRotation(rng), range_mm * Eigen::Vector3d(u(rng), u(rng), u(rng)));
}

}  // namespace opl::test
