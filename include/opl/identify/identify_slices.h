// Identifying the spots of a calibration session (method.md, "Calibrating a
// source"; docs/identify.md, "Calibration sessions").
//
// In a calibration session the module is fixed and each slice (one
// photograph) holds one grid on a screen. Before a calibration exists, its
// spots can only be identified against nominal patterns: the design's
// (ExactCalibration of a ModuleDesign) or an earlier calibration of the
// module. Two things differ from a measurement (IdentifySpots):
//  - the directions are nominal, so the gate widens by
//    IdentifyOptions::nominal_tolerance_rad (directions_nominal = true);
//  - an ideal pattern is symmetric under a 90 deg roll, so the grid alone
//    cannot say which way up the source is. The set-up can: the module is
//    mounted as designed. Every source's nominal orientation in the
//    calibration frame (the nominal calibration's calibration_from_source)
//    is the prior of IdentifyOptions::expected_rotation; hypotheses farther
//    from it than expected_rotation_tolerance_deg are not considered. The
//    numbering of a calibrated pattern is defined by this orientation.
//  - the sources may have the same pattern: which source threw a grid is told
//    by where it comes from. Each source's nominal origin is the prior of
//    IdentifyOptions::expected_origin, with a tolerance of 0.4 times the
//    distance between the two closest nominal origins (unless the caller gave
//    expected_origin).
//
// Every slice is identified on its own (IdentifySpots on its spots); spots
// that already have source and beam pass through. A slice whose grid is not
// identified for sure is left out and reported; the calibration decides
// whether what remains is enough.
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/identify/identify_spots.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"

namespace opl {

struct SliceIdentification {
  int slice = 0;
  int points = 0;        // spots of the slice
  int assigned = 0;      // of them assigned (passed through included)
  std::string source;    // the source found, empty when none
  std::string detail;    // why nothing (or more than one source) was found
};

struct SessionIdentification {
  std::vector<Spot> spots;  // the assigned spots, input order
  std::vector<int> slices;  // their slices
  std::vector<SliceIdentification> per_slice;  // in slice order
  int unassigned = 0;       // spots left out

  // One line per slice with a problem and a total line, e.g.
  //   "Identification: 2180 of 2420 spots assigned in 20 slices; slice 7: no
  //    source identified (A ambiguous: ...)".
  std::string ToText() const;
};

// `slices` has one entry per spot. `options.directions_nominal` is set and
// `options.expected_rotation` and `expected_origin` filled from `nominal` (a
// source already there keeps the caller's). Errors: InvalidArgument when the sizes differ, from
// IdentifySpots (bad options, unknown source names, non-finite points).
Result<SessionIdentification> IdentifySessionSlices(const ModuleCalibration& nominal,
                                                    const std::vector<Spot>& spots,
                                                    const std::vector<int>& slices,
                                                    IdentifyOptions options = IdentifyOptions());

}  // namespace opl
