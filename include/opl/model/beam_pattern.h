// BeamPattern: the calibrated (or designed) pointing directions of the beams of
// one source's n x n grid, in that source's frame.
//
// Beam numbering (method.md), n odd: id = row * n + col + 1, row 0 is the top
// row (largest Z), col 0 the rightmost column seen from behind the source
// looking out (smallest Y). For n = 11: beam 1 top right, 61 central, 121 bottom
// left. A pattern may lack some beams (a calibration that could not fit them).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"

namespace opl {

// The largest grid a pattern may have: n <= 201, i.e. at most 40401 beams. Real
// DOEs fan a beam into grids of up to about 100 x 100 (the prototype: 11 x 11);
// twice that leaves room while keeping every n x n array small (a few MB) and
// every beam id, n^2 and products of ids far from int overflow. Every reader
// (design and calibration JSON, pattern CSV) and every tool option enforces it
// (docs/formats.md).
constexpr int kMaxBeamsPerSide = 201;

// OK when n is odd and in [3, kMaxBeamsPerSide]; else InvalidArgument
// "beams_per_side must be odd and in [3, 201], got <n>".
Status CheckBeamsPerSide(int beams_per_side);
// "must be odd and in [3, 201], got <n>" (the tail of CheckBeamsPerSide's
// message, for readers that name the field themselves); empty when valid.
std::string BeamsPerSideProblem(long long beams_per_side);

struct Beam {
  int id = 0;           // 1 .. n*n
  double az_rad = 0.0;  // azimuth of the beam in the source frame
  double el_rad = 0.0;  // elevation of the beam in the source frame
  // Covariance of (az, el), rad^2, when the calibration provides it.
  std::optional<Eigen::Matrix2d> cov_azel_rad2;

  // Unit direction of the beam in the source frame.
  Eigen::Vector3d DirectionInSource() const;
};

// Beam id from (row, col); both 0-based.
inline int BeamId(int row, int col, int beams_per_side) { return row * beams_per_side + col + 1; }
inline int BeamRow(int id, int beams_per_side) { return (id - 1) / beams_per_side; }
inline int BeamCol(int id, int beams_per_side) { return (id - 1) % beams_per_side; }

class BeamPattern {
 public:
  BeamPattern() = default;
  // Builds a pattern; call Validate() (or use Create) before relying on it.
  BeamPattern(int beams_per_side, std::vector<Beam> beams);
  // Validated construction: n odd in [3, kMaxBeamsPerSide], ids in 1..n^2 and unique, finite angles,
  // |el| < pi/2, covariances symmetric positive semi-definite.
  static Result<BeamPattern> Create(int beams_per_side, std::vector<Beam> beams);

  Status Validate() const;

  int beams_per_side() const { return beams_per_side_; }
  // 0 when n is outside [1, kMaxBeamsPerSide] (an invalid pattern): n^2 never
  // overflows.
  int central_beam_id() const {
    return beams_per_side_ >= 1 && beams_per_side_ <= kMaxBeamsPerSide
               ? (beams_per_side_ * beams_per_side_ + 1) / 2
               : 0;
  }
  const std::vector<Beam>& beams() const { return beams_; }
  // The beam with this id, or nullptr when the pattern lacks it or the id is out
  // of range.
  const Beam* Find(int id) const;
  // Unit direction of a beam of this pattern (precomputed from az/el).
  // Precondition: Find(id) != nullptr.
  const Eigen::Vector3d& DirectionInSource(int id) const {
    return directions_[index_by_id_[id]];
  }

 private:
  int beams_per_side_ = 0;
  std::vector<Beam> beams_;       // sorted by id
  std::vector<Eigen::Vector3d> directions_;  // parallel to beams_
  std::vector<int> index_by_id_;  // id -> index into beams_, or -1
};

}  // namespace opl
