// The measurement with a COLMAP model as the cameras and poses: images ->
// 3D spots in the model's frame -> scale factor s of the model
// (docs/colmap.md, "Measuring a COLMAP model").
//
//   Result<Scene> scene = ReadSceneJson("scene.json");        // shots: lasers, slices
//   Result<ColmapModel> model = ReadColmapModel("sparse/0");   // cameras, poses, points
//   Result<ModuleCalibration> cal = ReadModuleCalibrationJson("cal.json");
//   Result<ImageMeasureReport> r = MeasureScaleFromColmap(*scene, "images/", *model, *cal);
//   ColmapModel scaled = ScaledColmapModel(*model, r->measure.scale_factor);
//
// What the scene JSON still says: which images there are (its shots), which
// lasers each lit and which slice (the exposure groups), and the cameras'
// names (a shot's camera is only a label here). What the model says instead:
// every shot's intrinsics and pose. A shot's image is the model's image of
// the same NAME (the shot's `file`, exactly); a shot the model does not
// have (COLMAP did not register it) is reported "not placed".
//
// The chain: the front end's detection (RunImageFrontEnd, steps 1-2: spots,
// dark frames); the intrinsics of the model's cameras (IntrinsicsFromColmap:
// exact mapping or a refusal, held constant), the poses of its images (start
// values, adjusted); the model's 3D points seen from two or more of the
// scene's cameras (positions: two shots of one scene camera are one
// position), their rays meeting there at min_tag_triangulation_angle_deg or
// more, as tie points, with their 2D observations (COLMAP pixels ->
// OPL pixels, io/colmap_model.h), isotropic standard deviation
// tie_point_sigma_px; then the front end's steps 5-6 (exposure groups,
// matching, one adjustment of poses, tie points and spots with the variance
// components, in the three-point datum of three tie points spanning a large
// triangle). The spots are then moved into the model's frame by the
// similarity that maps the adjusted camera centres onto the model's
// (Umeyama), so that s applies to the model as it is: every coordinate of
// the model multiplied by s is in millimetres. Then MeasureScaleFromFrontEnd
// (pipeline/measure_images.h): identification, location, s and u(s).
//
// Errors: those of ReadColmapModel's consumers (a camera model OPL refuses,
// naming the COLMAP camera and the shot), of the front end and of the
// measurement; NoSolution when fewer than two shots with lasers are in the
// model, fewer than three cameras are placed or no tie point is seen twice.
#pragma once

#include <string>

#include "opl/core/status.h"
#include "opl/io/colmap_model.h"
#include "opl/lab/scene.h"
#include "opl/model/module_calibration.h"
#include "opl/pipeline/image_front_end.h"
#include "opl/pipeline/measure_images.h"

namespace opl {

struct ColmapMeasureOptions {
  // Detection, matching, adjustment and measurement, as for the tag path.
  // front_end.one_pose_per_camera is not used (one pose per model image).
  ImageMeasureOptions image;
  // Standard deviation of a tie point's 2D observation, per coordinate [px].
  // 0: from the model, the mean of the used points' ERROR (COLMAP's mean
  // reprojection error |r|) divided by sqrt(pi / 2) (|r| of an isotropic 2D
  // Gaussian), at least 0.05 px. >= 0. The variance component of the front
  // end enlarges it when the residuals say it is too small.
  double tie_point_sigma_px = 0.0;
  // At most this many tie points, those with the longest tracks first
  // (bounds the adjustment's time on large models), >= 3.
  int max_tie_points = 4000;

  Status Validate() const;
};

// The front end with the model's cameras and poses (header comment); the
// spots in the model's frame and unit.
Result<FrontEndResult> RunImageFrontEndFromColmap(
    const Scene& scene, const std::string& images_dir, const ColmapModel& model,
    const ColmapMeasureOptions& options = ColmapMeasureOptions());

// The measurement: RunImageFrontEndFromColmap then MeasureScaleFromFrontEnd.
// measure.scale_factor converts the model's unit to millimetres.
Result<ImageMeasureReport> MeasureScaleFromColmap(
    const Scene& scene, const std::string& images_dir, const ColmapModel& model,
    const ModuleCalibration& calibration,
    const ColmapMeasureOptions& options = ColmapMeasureOptions());

}  // namespace opl
