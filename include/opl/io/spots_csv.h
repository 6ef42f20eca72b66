// Spots CSV: measured 3D points of laser spots, one spot a row.
// Full description: docs/formats.md, "Spots CSV".
//
//   source,beam,x,y,z,sx,sy,sz
//   A,61,1012.5,3.25,-0.5,0.1,0.1,0.1
//   ,,1013.25,2.5,-0.75,0.1,0.1,0.1
//
// Columns are found by their header names (case-insensitive), in any order;
// unknown columns are ignored. Required: `x`, `y`, `z` (scene units).
// Optional: `source` (a source name of the module calibration) and `beam` (the
// beam id, an integer >= 1); `sx`, `sy`, `sz` (standard deviations, scene
// units; all three or none; > 0 and finite), giving
// SpotObservation::cov_in_scene = diag(sx^2, sy^2, sz^2); and `slice` (an
// integer >= 0, the calibration slice a spot was measured in), returned
// alongside the spots; `placement` (the module placement the spot was shot
// at, Spot::placement: spots of different placements are different grids;
// empty = none). Fields follow RFC 4180 (quotes for names holding commas
// or quotes); blank lines are skipped. Each Spot's `where` is "<file>:<line>".
//
// Unassigned spots: an empty `source` field (or no `source` column) gives
// Spot::source == "", an empty `beam` field (or no `beam` column) gives
// observation.beam_id == 0. A spot is assigned (Spot::assigned()) only when it
// has both; a spot with just one of them keeps it as a hint but counts as
// unassigned. A later step (identification) assigns them; the measure and
// calibrate steps need assigned spots.
//
// Errors are ParseErrors naming the file and line (and the field), e.g.
//   "spots.csv:14: field 'x': not a number: 'abc'"
//   "spots.csv:9: field 'y': not finite: 'nan'"
//   "spots.csv:3: expected 5 fields (as the header), found 4"
//   "spots.csv:1: missing column 'x' (a spots CSV needs x,y,z; source,beam are optional)"
//   "spots.csv:4: field 'beam': beam id must be >= 1, got 0"
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/model/spot.h"

namespace opl {

struct SpotsCsvData {
  std::vector<Spot> spots;  // in file order
  // The `slice` column, one entry per spot, when the file has that column;
  // empty otherwise.
  std::vector<int> slices;
  bool has_sigmas = false;  // the file has sx, sy, sz columns
  // Header names of the columns this reader does not use, in file order (a
  // tool may refuse them: opl_calibrate does, to catch misnamed columns).
  // Always empty from a point table (opl/io/point_table.h: no header names).
  std::vector<std::string> other_columns;
  // Point names, one entry per spot, from the `id` column of a point table
  // (opl/io/point_table.h); empty otherwise. ParseSpotsCsv does not fill it (an
  // `id` column of a spots CSV is one of other_columns).
  std::vector<std::string> point_ids;

  // Spots that are not assigned to a source and beam (!Spot::assigned()).
  int num_unassigned() const;
};

// Parses CSV text; `name` (the file path) is used in `where` and in messages.
Result<SpotsCsvData> ParseSpotsCsv(const std::string& text, const std::string& name);

// Reads a file: IoError when it cannot be read, else as ParseSpotsCsv.
Result<SpotsCsvData> ReadSpotsCsv(const std::string& path);

// An extra column written after the standard ones (one value per spot).
struct SpotsCsvExtraColumn {
  std::string name;
  std::vector<std::string> values;
};

// Formats spots as a Spots CSV: `source,beam,x,y,z`, then `sx,sy,sz` when
// every spot has a covariance (the square roots of its diagonal: off-diagonal
// terms are not representable and are dropped), then `placement` when a spot
// has one, then `extra` columns. Numbers
// are written with the shortest text that reads back exactly; an unassigned
// beam (id 0) is an empty field, an empty source `""`, so unassigned spots read
// back unassigned. InvalidArgument when an extra column's size differs from the
// number of spots, a beam id is negative, or a value is not finite.
Result<std::string> FormatSpotsCsv(const std::vector<Spot>& spots,
                                   const std::vector<SpotsCsvExtraColumn>& extra = {});

}  // namespace opl
