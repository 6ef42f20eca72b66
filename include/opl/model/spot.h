// Spots: measured 3D points of laser spots in the (unscaled) scene frame.
// File format: docs/formats.md, "Spots CSV".
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace opl {

// One spot of one beam.
struct SpotObservation {
  int beam_id = 0;  // 1..n^2; 0 while the spot is not assigned to a beam
  Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();  // scene units
  // Covariance of point_in_scene (scene units^2), when known (e.g. from the
  // sx, sy, sz columns of a spots CSV: diag(sx^2, sy^2, sz^2)).
  std::optional<Eigen::Matrix3d> cov_in_scene;
};

// A spot as read from a file: which source it belongs to, and where it came
// from (for messages).
//
// A spot may be unassigned: source "" (source not known) and/or
// observation.beam_id 0 (beam not known), e.g. a point read from a spots CSV
// with empty source/beam fields or from another package's point table. Such a
// spot must be identified (given both) before it can be used to locate or
// calibrate a source. A spot with only one of the two keeps it as a hint.
struct Spot {
  std::string source;  // "" = unassigned
  SpotObservation observation;  // observation.beam_id 0 = unassigned
  std::string where;  // e.g. "spots.csv:14"
  // The module placement it was shot at (Scene::module_placements; issue
  // 20): spots of different placements are different grids of the same
  // source. Empty when the module stood at one place.
  std::string placement{};

  // True when the spot names its source and its beam (source not empty and
  // beam_id >= 1). Says nothing about whether they exist in a calibration.
  bool assigned() const { return !source.empty() && observation.beam_id >= 1; }
};

// Groups the assigned spots by source name (order of first appearance is not
// kept: the map is sorted by name); unassigned spots (!assigned()) are left
// out.
std::map<std::string, std::vector<SpotObservation>> GroupSpotsBySource(
    const std::vector<Spot>& spots);

}  // namespace opl
