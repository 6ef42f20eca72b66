// Private to src/io: turns the fields of one record into a Spot, shared by the
// spots CSV reader and the point-table reader so that both apply the same
// rules with the same messages ("<file>:<line>: field '<column>': <what>").
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/io/spots_csv.h"

namespace opl {
namespace csv_internal {

// Index of each known column in a record's fields, -1 when absent. x, y, z
// must be set; the sigmas all three or none.
struct SpotFieldColumns {
  int source = -1;
  int beam = -1;
  int xyz[3] = {-1, -1, -1};
  int sigma[3] = {-1, -1, -1};
  int slice = -1;
  int id = -1;
  int placement = -1;

  bool has_sigmas() const { return sigma[0] >= 0; }
};

// Parses the spot of `fields` (the record at `line` of `name`) and appends it
// to data->spots, its slice to data->slices (when columns.slice is set) and
// its id to data->point_ids (when columns.id is set). Rules:
//   source: any text; empty (or no column) = unassigned, Spot::source "".
//   beam: empty (or no column) = unassigned, beam_id 0; else an integer >= 1.
//   x, y, z: finite numbers. sx, sy, sz: finite and > 0, giving
//   cov_in_scene = diag(sx^2, sy^2, sz^2). slice: an integer >= 0. id: any text.
//   placement: any text (Spot::placement; empty = none).
// data is unchanged on error.
Status AppendSpot(const std::vector<std::string>& fields, int line, const std::string& name,
                  const SpotFieldColumns& columns, SpotsCsvData* data);

}  // namespace csv_internal
}  // namespace opl
