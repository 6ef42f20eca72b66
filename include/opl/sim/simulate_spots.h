// SimulateSpots: the spots a module design throws on its surface, with seeded
// missing spots, noise and outliers (docs/simulation.md, "Simulating spots").
//
// For every source (design order), every slice of the surface (a list of
// planes has one slice per plane, other surfaces one) and every beam of the
// source's pattern (by id), the beam's ray
//     origin t, direction R * DirectionFromAzEl(az_b, el_b)    (scene frame)
// is intersected with the slice (Surface::IntersectRaySlice). Beams whose ray
// misses are skipped. The N hits, in that order, are the candidates:
//
//  1. Missing: exactly round(missing_fraction * N) candidates, chosen uniformly
//     at random without replacement, are dropped. K = N - missing remain.
//  2. Noise: every candidate gets a draw e ~ N(0, Sigma),
//     Sigma = R_n diag(spot_noise_mm^2) R_n^T (ModuleDesign::SpotCovarianceMm2);
//     the draw of a candidate does not depend on which others are dropped.
//  3. Outliers: exactly round(outlier_fraction * K) of the kept spots, chosen
//     uniformly at random, are moved by a vector of length exactly
//     outlier_distance_mm perpendicular to their beam's ray, at a uniformly
//     random angle around it (measured from a reference direction fixed in
//     the source frame, so that ModuleDesign::Transformed moves outliers
//     too): an angular error of about outlier_distance_mm / range for the
//     locate solve.
//  The spot's point is true + e (+ the outlier offset).
//
// Determinism: the same design and options give bit-identical output on one
// platform. Random numbers come from std::mt19937_64 (fully specified by the
// standard), seeded through SplitMix64 (three independent streams: missing,
// outliers, noise), with our own uniform-integer (rejection) and Box-Muller
// normal generators, so no implementation-defined std::*_distribution is used;
// only the last bits of std::log/std::cos/std::sin may differ between C
// libraries.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/model/spot.h"
#include "opl/sim/module_design.h"

namespace opl {

struct SpotSimulationOptions {
  // Seed of every random choice; same seed => identical spots.
  uint64_t seed = 1;
  // Fraction of the hits dropped, in [0, 1]; exactly round(fraction * N).
  double missing_fraction = 0.0;
  // Fraction of the kept spots made outliers, in [0, 1]; exactly
  // round(fraction * K).
  double outlier_fraction = 0.0;
  // Displacement of an outlier perpendicular to its beam's ray, mm, finite > 0.
  double outlier_distance_mm = 5.0;
  // When true, each spot carries cov_in_scene = the design's noise covariance
  // (mm^2; singular if a standard deviation is 0), whether or not it is an
  // outlier (downstream code is not told which spots are outliers).
  bool attach_covariance = true;

  // OK, or a message naming the field, its value and the broken constraint.
  Status Validate() const;
};

struct SimulatedSpot {
  // source = the source's name; observation = (beam id, noisy point in the
  // scene, mm, covariance when attached); where = "simulated".
  Spot spot;
  Eigen::Vector3d true_point_in_scene = Eigen::Vector3d::Zero();  // noise-free hit, mm
  int slice = 0;         // index of the plane of a PlaneListSurface, else 0
  bool outlier = false;  // moved by outlier_distance_mm (step 3 above)
};

// Errors: InvalidArgument from design.Validate() or options.Validate();
// IoError/ParseError from a pattern file; NoSolution when no beam of any
// source hits the surface.
Result<std::vector<SimulatedSpot>> SimulateSpots(const ModuleDesign& design,
                                                 const SpotSimulationOptions& options);

// The spots alone (what a Spots CSV would hold), in the same order.
std::vector<Spot> SpotsOf(const std::vector<SimulatedSpot>& simulated);

}  // namespace opl
