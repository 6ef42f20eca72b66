// The calibration from photographs: the images of a calibration session ->
// 3D spots per slice -> the module calibration. The runnable part of
// `opl_calibrate --images` as a library function (docs/images.md,
// "Calibration sessions").
//
//   Result<Scene> scene = ReadSceneJson("session.json");      // shots with slices
//   Result<ModuleCalibration> nominal = ExactCalibration(*design);
//   Result<ImageCalibrationReport> r = CalibrateFromImages(*scene, "images/", *nominal);
//   FormatModuleCalibrationJson(r->calibration.calibration) ...
//
// A session: the module is fixed, a flat screen is placed at several depths
// (slices); at each depth each grid is photographed by the cameras, one laser
// on at a time (the shots' `lasers` and `slice`). The walls carry the coded
// targets and a scale artifact (scene.artifact: two tags whose centres are a
// calibrated distance apart).
//
// Steps: the image front end (pipeline/image_front_end.h) places every image
// from the tags on the walls (one bundle adjustment over the whole session,
// so every slice is in one frame) and gives the 3D spots of every exposure
// group (one laser, one slice); the artifact's two tag centres scale the
// frame to mm (ComputeArtifactScaling, with their covariances); each group's
// spots are identified against the nominal patterns (IdentifySessionSlices:
// a group is a slice of one grid) and every source is calibrated
// (CalibrateModule).
//
// The spots' errors are not independent: every spot of an image shares its
// camera's pose error, and every spot the datum tags' (FrontEndSpot::
// shared_factor). With propagate_shared_errors (the default) each spot is
// weighted by its own covariance and the shared part is added to the
// calibration's covariances by AddSharedErrors (calibrate/shared_errors.h):
// two re-solves per component, m = 9 + 6 per camera pose (one per image, or
// one per camera with FrontEndOptions::one_pose_per_camera). Without it, the spots
// are weighted by their whole covariance as if independent, and on noisy
// images u(separation) comes out far too small: 36 um where seeds 1-10 of
// the example session made noisy scatter by 63 um (docs/images.md,
// "Calibration sessions").
//
// Errors: those of RunImageFrontEnd, IdentifySessionSlices, CalibrateModule
// and AddSharedErrors; InvalidArgument when the scene has no artifact;
// NoSolution when an artifact tag was not placed or no spot is identified.
#pragma once

#include <string>
#include <vector>

#include "opl/calibrate/calibrate_module.h"
#include "opl/calibrate/shared_errors.h"
#include "opl/core/status.h"
#include "opl/identify/identify_slices.h"
#include "opl/lab/scene.h"
#include "opl/model/module_calibration.h"
#include "opl/pipeline/image_front_end.h"

namespace opl {

struct ImageCalibrationOptions {
  FrontEndOptions front_end;
  CalibrateModuleOptions calibrate;
  IdentifyOptions identify;
  bool propagate_shared_errors = true;

  Status Validate() const;
};

struct ImageCalibrationReport {
  FrontEndResult front_end;
  CalibrationScaling scaling;            // from the artifact's tags
  SessionIdentification identification;  // slice = exposure group index
  ModuleCalibrationResult calibration;
  // The separations' u split into the spots' own errors and the shared ones
  // (components 0 when not propagated).
  SharedErrorSummary shared;
  // For each of identification.spots, the index of its 3D spot in
  // front_end.spots (the overlays' labels: pipeline/calibrate_overlays.h).
  std::vector<int> identified_front_end_spots{};

  // The front end's report, the identification's, the scaling, then the
  // separations' own / shared split.
  std::string ToText() const;
};

Result<ImageCalibrationReport> CalibrateFromImages(
    const Scene& scene, const std::string& images_dir, const ModuleCalibration& nominal,
    const ImageCalibrationOptions& options = ImageCalibrationOptions());

}  // namespace opl
