// Points CSV: any table of 3D points with `x`, `y`, `z` columns, e.g. the
// target coordinates a photogrammetry package exports. opl_measure --apply
// multiplies every point of such a file by the scale factor.
// Full description: docs/formats.md, "Points CSV".
//
//   name,x,y,z,flags
//   T1,102.5,33.0,-4.25,ok
//
// The x, y, z columns are found by header name (case-insensitive), in any
// order; every other column, and the header, is kept verbatim (the exact text
// of each field, quotes included). Same CSV rules and messages as the spots
// CSV (src/io/csv.h): RFC 4180 quoting, blank lines skipped (and dropped on
// output), field counts checked, non-finite coordinates rejected:
//   "scene.csv:7: field 'z': not finite: 'inf'"
// This class holds the whole table; opl_measure --apply streams instead
// (ScalePointFile, opl/io/scale_point_file.h: the same output and messages, a
// record at a time, any size).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"

namespace opl {

class PointsCsv {
 public:
  // Parses CSV text; `name` prefixes messages.
  static Result<PointsCsv> Parse(const std::string& text, const std::string& name);
  // Reads a file: IoError when it cannot be read, else as Parse.
  static Result<PointsCsv> Read(const std::string& path);

  int num_points() const { return static_cast<int>(points_.size()); }
  const std::vector<Eigen::Vector3d>& points() const { return points_; }  // file order
  const std::vector<int>& lines() const { return lines_; }  // 1-based line of each point
  // The point names of an `id` column (or, without one, a `name` column),
  // unquoted, in file order; empty when the file has neither column.
  const std::vector<std::string>& ids() const { return ids_; }

  // Multiplies every point by `s` (x' = s * x, per coordinate, in double).
  // InvalidArgument when s is not finite and > 0; the points are unchanged then.
  Status Scale(double s);

  // The table as CSV: the header and the other columns as read, x, y, z written
  // with the shortest text that reads back exactly; "\n" line ends.
  std::string Format() const;

 private:
  std::string header_line_;                      // raw header fields joined by ','
  std::vector<std::vector<std::string>> raw_;    // raw fields of each row
  std::vector<Eigen::Vector3d> points_;
  std::vector<int> lines_;
  std::vector<std::string> ids_;
  int column_[3] = {-1, -1, -1};                 // x, y, z column indices
};

}  // namespace opl
