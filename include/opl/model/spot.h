// Spots: measured 3D points of laser spots in the (unscaled) scene frame.
// File format: docs/formats.md, "Spots CSV".
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace opl {

// One spot of one known beam.
struct SpotObservation {
  int beam_id = 0;
  Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();  // scene units
  // Covariance of point_in_scene (scene units^2), when known (e.g. from the
  // sx, sy, sz columns of a spots CSV: diag(sx^2, sy^2, sz^2)).
  std::optional<Eigen::Matrix3d> cov_in_scene;
};

// A spot as read from a file: which source it belongs to, and where it came
// from (for messages).
struct Spot {
  std::string source;
  SpotObservation observation;
  std::string where;  // e.g. "spots.csv:14"
};

// Groups spots by source name (order of first appearance is not kept: the map
// is sorted by name).
std::map<std::string, std::vector<SpotObservation>> GroupSpotsBySource(
    const std::vector<Spot>& spots);

}  // namespace opl
