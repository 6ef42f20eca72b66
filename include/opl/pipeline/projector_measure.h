// The scale inside the adjustment, from a two-step measurement: the image
// front end's final adjustment (FrontEndResult::adjustment) and the
// identified, located spots of MeasureScaleFromFrontEnd become a projector
// adjustment (vision/projector_adjustment.h) started from the two-step
// solution scaled by its s. FrontEndOptions::scale_in_adjustment makes
// MeasureScaleFromImages / MeasureScaleFromFrontEnd call it
// (ImageMeasureReport::projector).
//
// The start: cameras and tag corners of the front end's adjustment times s;
// the module pose from the first located source (scene_from_source times s,
// composed with the calibration's source_from_module); each identified
// spot's depth the projection of its scaled 3D point on its beam. One
// placement per module placement of the scene (SceneShot::placement; one,
// "all shots", when the scene lists none), each started from its first
// located source. The datum: the frame tags' four corners each (the
// front end's scene frame, now metric), so that s = |B - A| / |B - A|_unscaled
// with A, B the centres of the origin and axis tags.
//
// Errors: InvalidArgument when the front end kept no adjustment (the COLMAP
// path) or no spot is identified; NoSolution when no source was located;
// those of ProjectorAdjust.
#pragma once

#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/model/module_calibration.h"
#include "opl/vision/projector_adjustment.h"

namespace opl {

struct ImageMeasureReport;

// The projector adjustment's input built from a two-step report (header
// comment); options.datum_point_sets and unscaled_datum_length are set, and
// options.length_point_sets to the centres (four corners) of each pair of
// `tag_lengths` (tag ids; InvalidArgument naming a tag the adjustment does
// not hold).
Result<ProjectorAdjustmentData> ProjectorDataFromTwoStep(
    const ImageMeasureReport& two_step, const ModuleCalibration& calibration,
    ProjectorAdjustmentOptions* options, const std::vector<std::pair<int, int>>& tag_lengths = {});

// ProjectorDataFromTwoStep then ProjectorAdjust.
Result<ProjectorAdjustmentResult> AdjustScaleWithProjector(
    const ImageMeasureReport& two_step, const ModuleCalibration& calibration,
    ProjectorAdjustmentOptions options = ProjectorAdjustmentOptions(),
    const std::vector<std::pair<int, int>>& tag_lengths = {});

}  // namespace opl
