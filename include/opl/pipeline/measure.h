// The measurement pipeline: from a module calibration and the measured spots of
// one scene to the scene's scale factor. This is the runnable part of the
// opl_measure tool as a library function (apps/opl_measure.cc only parses
// options, reads files and prints).
//
//   Result<ModuleCalibration> cal = ReadModuleCalibrationJson("cal.json");
//   Result<SpotsCsvData> spots = ReadSpotsCsv("spots.csv");
//   Result<MeasureReport> report = MeasureScale(*cal, spots->spots, MeasureOptions());
//   std::cout << report->ToText();      // or ToJson()
//   // every scene coordinate times report->scale.scale_factor is in mm
//
// Steps: when any spot is unassigned (empty source or beam: a point set as
// photogrammetry exports it), the spots are first identified against the
// calibrated patterns (IdentifySpots, identify_spots.h): found sources get
// their points, an ambiguous or unfound source is not located (and says
// why), points left unassigned are not used. Then every spot is checked against the calibration (its source must exist,
// its beam must be in that source's pattern, no (source, beam) pair twice);
// every source with spots is located (LocateSource); the scale factor is
// computed from the calibrated separations between located sources
// (ComputeScaleFactor). A calibrated source with no spots at all is not
// located and is listed in MeasureReport::sources_without_spots; the scale
// then uses the separations between the other sources.
//
// Units: spot coordinates are in "scene units" (whatever the photogrammetry
// used); calibrated lengths are mm; the scale factor is mm per scene unit.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/identify/identify_spots.h"
#include "opl/locate/locate_source.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"
#include "opl/scale/scale_factor.h"

namespace opl {

struct MeasureOptions {
  // Options of every source's locate (LocateSource); defaults as documented
  // there.
  LocateOptions locate;
  // Options of the identification of unassigned spots (IdentifySpots).
  IdentifyOptions identify;

  // Checks every field (delegates to LocateOptions::Validate and
  // IdentifyOptions::Validate); the message names the field.
  Status Validate() const;
};

struct MeasureReport {
  // The located sources, in the order of the calibration, each with its name.
  std::vector<std::pair<std::string, LocateResult>> sources;
  // The module placement of each of `sources` (Spot::placement; empty when
  // the spots name none). With several placements a source is located once
  // per placement: placements in order of first appearance in the spots,
  // then sources in calibration order.
  std::vector<std::string> source_placements;
  // Calibrated sources that had no spot (not located).
  std::vector<std::string> sources_without_spots;
  // When spots had to be identified: what IdentifySpots found (per source
  // outcome, per point assignment). Sources it did not find or found
  // ambiguous are in sources_without_spots too.
  std::optional<IdentifyResult> identification;
  ScaleResult scale;

  // A readable summary: per source the origin (scene units), rotation angles
  // (deg), origin standard deviations, RMS residual (microradians), spots used
  // and outlier beam ids; per length L_photo +- u, L_cal, s_ij; then s +- u(s)
  // and, with two or more lengths, the consistency chi2/dof.
  std::string ToText() const;
  // One JSON object (format "opl.measure_report", version 1): sources[],
  // lengths[], scale_factor, u_scale_factor, chi2, dof, ... (docs/formats.md,
  // "Measure report JSON"). Doubles written to round-trip exactly.
  std::string ToJson() const;
};

// Errors:
//  - InvalidArgument: invalid options or calibration; from IdentifySpots; a spot naming a source
//    not in the calibration ("spots.csv:14: unknown source 'C' (calibration
//    has A, B)"); the same (source, beam) twice (names both lines); a beam id
//    the source's pattern lacks; a non-finite spot;
//  - NoSolution: a source whose spots do not determine its pose (too few,
//    degenerate; "source 'A': " + LocateSource's message), or no calibrated
//    separation joins two located sources (after an identification, the
//    message ends with what it found: "identification: A found (118 points);
//    B ambiguous: ...").
Result<MeasureReport> MeasureScale(const ModuleCalibration& calibration,
                                   const std::vector<Spot>& spots,
                                   const MeasureOptions& options = MeasureOptions());

}  // namespace opl
