// The measurement from photographs: images -> 3D spots -> scale factor.
// The runnable part of `opl_measure --images` as a library function.
//
//   Result<Scene> scene = ReadSceneJson("scene.json");
//   Result<ModuleCalibration> cal = ReadModuleCalibrationJson("cal.json");
//   Result<ImageMeasureReport> r = MeasureScaleFromImages(*scene, "images/", *cal);
//   std::cout << r->ToText();   // per image, the adjustment, then s +- u(s)
//
// Steps: the image front end (pipeline/image_front_end.h) gives the 3D spots
// of every exposure group with their covariances, in the scene frame of the
// frame tags, unscaled. Each exposure group is identified on its own
// (IdentifySpots, identify/identify_spots.h): two grids shot separately are
// separate point sets, even where they interleave in space. The shots'
// laser metadata says which grid a spot can belong to: with one laser on,
// its spots carry that source (identified against its pattern only, so
// sources with the same nominal pattern cannot be confused); with several
// lasers on, any source. A spot identified as a source that was off in its
// exposure group, or a (source, beam) already given by another group, is
// reported and not used. In a group's identification, a source whose laser
// was off is reported "not found" with the detail "laser off in these
// shots" (": not searched" when one laser was on). The assigned spots then
// go to MeasureScale
// (pipeline/measure.h): every source located, the scale factor computed
// from the calibrated separations.
//
// Units: the scene's unscaled unit is that of the nominal tag size (about
// mm); s converts it to mm exactly.
//
// Errors: those of RunImageFrontEnd, IdentifySpots (prefixed by the group)
// and MeasureScale; NoSolution when no spot of any group is identified.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"
#include "opl/pipeline/image_front_end.h"
#include "opl/pipeline/measure.h"
#include "opl/vision/projector_adjustment.h"

namespace opl {

struct ImageMeasureOptions {
  FrontEndOptions front_end;
  MeasureOptions measure;
  // The 3D spots' errors are not independent: every spot of an image shares
  // its camera's pose error (and the datum tags' errors), which MeasureScale,
  // treating the spots as independent, cannot see, while u(s) of a small
  // module is set by a near-degenerate direction in which such a common
  // error does not average down. When true (and the front end gave the split,
  // FrontEndSpot::shared_factor), MeasureScale weights each spot by its own
  // covariance only, and the shared part is propagated to s separately, by
  // central differences: s re-solved with every spot moved by +- one
  // standard deviation of each shared component (2 m re-solves, m = 9 + 6
  // per camera): u(s)^2 = u_own^2 + sum_k g_k^2.
  bool propagate_shared_errors = true;
  // With FrontEndOptions::scale_in_adjustment: tag-to-tag lengths (pairs of
  // tag ids, centre to centre) the projector adjustment reports in mm with
  // their uncertainty (ProjectorAdjustmentResult::lengths_mm, in this
  // order), e.g. opl_verify's check lengths.
  std::vector<std::pair<int, int>> projector_tag_lengths;

  Status Validate() const;
};

// Where an image measurement's s comes from (ImageMeasureReport::scale_method).
enum class ScaleMethod {
  kAdjustment,  // the module as a calibrated projector inside the adjustment
  kTwoStep,     // the unscaled adjustment, then the located sources
};
// "adjustment", "two-step".
const char* ScaleMethodName(ScaleMethod method);

struct ImageMeasureReport {
  FrontEndResult front_end;
  // The 3D spots, front-end order, with the source and beam they were
  // identified as (empty / 0 when not); `where` says "spot K (group G, N
  // views)". The assigned ones were given to MeasureScale.
  std::vector<Spot> spots;
  // Per exposure group, its identification (empty for a group without spots).
  std::vector<IdentifyResult> identification;
  MeasureReport measure;
  // Spots not used: identified as a source that was off in their exposure
  // group, or a (source, beam) another group already gave.
  std::vector<std::string> metadata_conflicts;
  // u(s) in its two parts (ImageMeasureOptions::propagate_shared_errors):
  // the spots' own errors (MeasureScale's) and the shared ones; u(s) in
  // `measure` is their root sum of squares. 0 / 0 when not propagated.
  double u_scale_factor_own = 0.0;
  double u_scale_factor_shared = 0.0;
  int shared_components = 0;  // m
  // g_k = ds / dz_k, k = 1..m: how s moves with each shared component z_k
  // of the front end's errors (FrontEndSpot::shared_factor,
  // FrontEndResult::tag_center_shared_factors); empty when not propagated.
  // With the tags' shared factors it gives the covariance of s with any
  // tag-to-tag length (pipeline/verify_lengths.h).
  Eigen::VectorXd scale_shared_gradient;
  // With FrontEndOptions::scale_in_adjustment: the projector adjustment
  // started from this two-step solution (pipeline/projector_measure.h):
  // cameras and tags in mm, s and u(s) of the scale inside the adjustment.
  std::optional<ProjectorAdjustmentResult> projector;
  // The scale factor this report gives: opl_measure's headline s, the one
  // --apply and Python's report.s use. The projector adjustment's s and
  // u(s) when it ran; else the two-step s and u(s) of `measure`, with
  // scale_method_note saying why (the option off; the COLMAP path, which
  // keeps no adjustment of its own; or the adjustment's error).
  double scale_factor = 0.0;
  double u_scale_factor = 0.0;
  ScaleMethod scale_method = ScaleMethod::kTwoStep;
  std::string scale_method_note;
  // The projector adjustment's error when it was asked for and failed (the
  // report then gives the two-step s, with a warning); OK otherwise.
  Status projector_status;

  // The front end's report, each group's identification, the two-step
  // measurement, the conflicts, the projector adjustment, then the
  // reported s and where it comes from.
  std::string ToText() const;
  // {"format": "opl.image_measure_report", "version": 1, "scale_factor",
  //  "u_scale_factor", "scale_method", "scale_method_note", "images": [...],
  //  "exposure_groups": [...], "frame_tags": [...], "rms_reprojection_px",
  //  "variance_factor", "spot_variance_factor", "spot_extra_sigma_px",
  //  "tag_variance_factor", "tag_extra_sigma_px", "u_scale_factor_own",
  //  "u_scale_factor_shared", "warnings",
  //  "measure": <the measure report JSON>, "metadata_conflicts": [...],
//  and with the projector adjustment "projector": {"scale_factor",
//  "u_scale_factor", "datum_length_mm", "u_datum_length_mm",
//  "variance_factor", "rms_tag_px", "rms_spot_px"}}.
  std::string ToJson() const;
};


Result<ImageMeasureReport> MeasureScaleFromImages(
    const Scene& scene, const std::string& images_dir, const ModuleCalibration& calibration,
    const ImageMeasureOptions& options = ImageMeasureOptions());

// The steps after the front end (identification, location, s), on a front
// end's result however it was made (RunImageFrontEnd, or the COLMAP path of
// pipeline/colmap_measure.h). Of options.front_end only scale_in_adjustment
// is used.
Result<ImageMeasureReport> MeasureScaleFromFrontEnd(
    FrontEndResult front_end, const ModuleCalibration& calibration,
    const ImageMeasureOptions& options = ImageMeasureOptions());

}  // namespace opl
