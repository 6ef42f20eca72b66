// Test support: a small, independent generator of one source's spots, written
// from first principles (not through opl/sim), so that the solvers are checked
// against data the library under test did not make.
#pragma once

#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "opl/geometry/rigid3.h"
#include "opl/geometry/spherical.h"
#include "opl/model/beam_pattern.h"
#include "opl/model/spot.h"

namespace opl::test {

// n x n beams on a tangent-plane lattice, theta0 apart along the central row
// and column; ids per method.md (row 0 top, col 0 smallest Y).
inline BeamPattern TangentLatticePattern(int n, double full_angle_rad) {
  const double theta0 = full_angle_rad / (n - 1);
  const int m = (n - 1) / 2;
  std::vector<Beam> beams;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const Eigen::Vector3d d(1.0, std::tan((c - m) * theta0), std::tan((m - r) * theta0));
      Beam b;
      b.id = r * n + c + 1;
      b.az_rad = AzimuthRad(d);
      b.el_rad = ElevationRad(d);
      beams.push_back(b);
    }
  }
  return BeamPattern(n, beams);
}

inline Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Quaterniond q(g(rng), g(rng), g(rng), g(rng));
  return q.normalized();
}

// Spots of every beam on the plane {x : n . (x - c) = 0} given in the source
// frame (normal along +X at distance `distance`, tilted by `tilt_rad` about Z),
// mapped to the scene by scene_from_source. Noise: isotropic sigma (scene
// units) per coordinate, covariance attached when sigma > 0.
inline std::vector<SpotObservation> SpotsOnPlane(const BeamPattern& pattern,
                                                 const Rigid3d& scene_from_source,
                                                 double distance, double tilt_rad,
                                                 double sigma, std::mt19937_64& rng,
                                                 std::vector<Eigen::Vector3d>* truth = nullptr) {
  const Eigen::Vector3d normal(std::cos(tilt_rad), std::sin(tilt_rad), 0.0);
  const Eigen::Vector3d center(distance, 0.0, 0.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<SpotObservation> spots;
  for (const Beam& b : pattern.beams()) {
    const Eigen::Vector3d d = b.DirectionInSource();
    const double s = normal.dot(center) / normal.dot(d);
    const Eigen::Vector3d p = scene_from_source * (s * d);
    SpotObservation o;
    o.beam_id = b.id;
    o.point_in_scene = p;
    if (truth) truth->push_back(p);
    if (sigma > 0.0) {
      o.point_in_scene += sigma * Eigen::Vector3d(g(rng), g(rng), g(rng));
      o.cov_in_scene = sigma * sigma * Eigen::Matrix3d::Identity();
    }
    spots.push_back(o);
  }
  return spots;
}

}  // namespace opl::test
