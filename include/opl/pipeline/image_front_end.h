// The image front end: from the photographs of a scene to 3D laser spots and
// tag positions in the scene frame, with no manual step (docs/images.md).
//
//   Result<Scene> scene = ReadSceneJson("scene.json");
//   Result<FrontEndResult> fe = RunImageFrontEnd(*scene, "images/", FrontEndOptions());
//   // fe->spots: 3D points (unscaled scene units) with covariances, to be
//   // identified and located (pipeline/measure_images.h)
//
// The chain, per scene (lab/scene.h describes the cameras, the tags and the
// shots; the images are the shots' files in `images_dir`):
//  1. Every image is read (8/16-bit grey or colour PNG/TIFF/JPEG; sensor
//     pixels, an EXIF orientation is not applied; colour: tags in luma,
//     spots in spot_channel, vision/shot_image.h) and checked against its
//     camera's calibrated size.
//  2. Detection, per image, in parallel: coded targets (DetectTags,
//     vision/tag_detection.h) and laser spots (DetectSpots, vision/
//     spot_detection.h). Spots inside a detected tag's quad are dropped (its
//     white cells are not lasers). Laser-off shots ("lasers": []) are read
//     first: their tags are used, and their images are the dark frames
//     subtracted from the lit shots of the same camera, slice and place before
//     their spots are detected (use_dark_frames, vision/dark_frame.h).
//  3. Start poses of every image and tag from the tags (PosesFromTags,
//     vision/tag_poses.h; the scale is that of the nominal tag size).
//  4. Bundle adjustment of the tag corners (cameras' intrinsics held, one
//     pose per image), Huber loss: tag observations that stay beyond
//     `max_tag_residual_px` are dropped; those beyond `tag_outlier_factor`
//     x the median corner residual (at least `min_tag_outlier_residual_px`:
//     a corner a highlight pulled off its edge) are kept with their
//     residual as their standard error (a note on the image either way).
//  5. Spots matched across the images of each exposure group (the shots with
//     the same lasers on and the same slice: taken at the same time, or at
//     least of the same spots), by epipolar geometry and a third view
//     (MatchSpots, vision/spot_matching.h).
//  6. One bundle adjustment of tags and spots together, in the datum of the
//     scene frame (the first corners of the frame's three tags), with
//     first-order covariances of every point (Schur complement). When the
//     spots' residuals are larger than their covariances say (speckle: the
//     detector's covariance is too small), a variance component is
//     estimated: the isotropic pixel variance that, added to every spot's
//     covariance, brings their chi^2 to their redundancy (the same for the
//     tag corners when theirs are too small); steps 5-6 then run once more.
//     The spots' variance factor that remains (above 1) scales their 3D
//     covariances a posteriori.
//  7. The scene frame of the tag centres (scene.frame: origin, axis, plane
//     tag; when absent, the three placed tags spanning the largest triangle)
//     (SceneFromThreePoints, vision/scene_frame.h); every point, covariance
//     and camera moved into it. The unit is still that of the nominal tag
//     size: the scale comes from the laser module or the artifact.
//
// Errors (Status, never an abort): InvalidArgument for an invalid scene or
// options, an image whose size is not its camera's ("cam1_A.png: image is
// 1280 x 720 but camera 'cam1' is calibrated for 1024 x 768"); IoError for a
// missing or unreadable image (names the file); NoSolution when no tag is
// found in any image, fewer than two images can be placed, a frame tag is not
// found, or the bundle adjustment fails. What could not be used (an image
// that could not be placed, a tag seen once) is reported per image, not an
// error.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/vision/bundle_adjustment.h"
#include "opl/vision/camera_model.h"
#include "opl/vision/shot_image.h"
#include "opl/vision/spot_detection.h"
#include "opl/vision/spot_matching.h"
#include "opl/vision/tag_detection.h"

namespace opl {

struct FrontEndOptions {
  // Colour photographs: the channel in which laser spots are detected (tags
  // always in luma); vision/shot_image.h. Grey images are used as they are.
  SpotChannel spot_channel = SpotChannel::kRed;
  TagDetectionOptions tags;
  SpotDetectionOptions spots;
  SpotMatchOptions matching;
  // A tag corner observation whose residual after the first bundle
  // adjustment exceeds this is dropped [px], > 0.
  double max_tag_residual_px = 2.0;
  // One whose residual exceeds tag_outlier_factor x the median corner
  // residual of that adjustment, when that is above
  // min_tag_outlier_residual_px [px] (a corner pulled off its edge by a
  // highlight or a lamp over the tag), is down-weighted: its covariance
  // becomes at least (residual^2 / 2) I. Dropping it instead could leave a
  // frame tag seen from one position. Both > 0.
  double tag_outlier_factor = 4.0;
  double min_tag_outlier_residual_px = 0.25;
  // A tag is adjusted only when each of its corners is seen from two
  // camera positions whose rays meet there at this angle or more [deg], in
  // (0, 90). Two images from one position (one pose per image, a camera
  // that shot each grid from where it stood) do not fix a corner's depth;
  // such a tag is reported in the warnings and not used.
  double min_tag_triangulation_angle_deg = 1.0;
  // Detections that are not laser spots, dropped before matching: a blob
  // whose peak is below min_spot_snr times the background noise (noise
  // patches, fragments along wall edges and shadows, whose fit fails and
  // whose centroid is then spuriously precise), or whose centre's standard
  // deviation (the larger of the covariance's two) exceeds
  // max_spot_center_sigma_px (a hot pixel or a spike: its Gaussian fit
  // leaves the centre undetermined, 1e1-1e7 px, and such a detection would
  // fit any epipolar gate). Laser spots measured on renders by OPL's lab and
  // by an independent renderer have SNR 40-250 and centre sigmas of
  // 0.01-0.3 px. min_spot_snr >= 0, max_spot_center_sigma_px > 0.
  double min_spot_snr = 10.0;
  double max_spot_center_sigma_px = 1.0;
  // Warnings (FrontEndResult::warnings), each naming the image: its spot or
  // tag RMS above warn_rms_ratio times its model's; more than
  // warn_unmatched_fraction of its spots unmatched (when it has 10 or more);
  // more than warn_saturated_fraction of its spots saturated; more blobs
  // rejected by the spot gates than warn_blob_ratio times its spots (and at
  // least 50). Lossy JPEG images are named in one warning. All > 0.
  double warn_rms_ratio = 3.0;
  double warn_unmatched_fraction = 0.5;
  double warn_saturated_fraction = 0.5;
  double warn_blob_ratio = 2.0;
  // Refusal: when the tag corners scatter more than max_tag_rms_ratio times
  // what their covariances say (the square root of their variance factor
  // after the first adjustment), the geometry is wrong (intrinsics, a
  // camera that moved between shots sharing a pose, tags not flat) and the
  // front end returns NoSolution naming the images with the largest tag
  // RMS, unless `force` (then it is a warning). Tag corners are not
  // speckled: on sound scenes their factor is 1-2 (RMS ratio 1-1.4); a 1%
  // focal length error in one of five cameras gives 12. > 1.
  double max_tag_rms_ratio = 3.0;
  bool force = false;
  // Floor of a spot's pixel standard deviation [px], >= 0: the detector's
  // covariance is enlarged to at least this (it underestimates speckle).
  double min_spot_sigma_px = 0.02;
  // The detector underestimates the spread of speckled spots
  // (docs/spot_detection.md). When the spots' variance factor after the
  // adjustment (chi^2 of their residuals over their redundancy) exceeds
  // max_spot_variance_factor, the variance e [px^2] that makes it 1 when
  // added to every spot covariance (C + e I) is estimated and the matching
  // and the adjustment are run again with C + e I (step 6 of the header),
  // so that the matching gates and the 3D covariances (hence u(s)) follow
  // the observed scatter. Speckle of a fixed grain size moves a centroid
  // by about the same amount whatever the spot's brightness, so an added
  // term fits it better than a factor on the detector's (noise-driven)
  // covariance: the factor kept the bright spots' covariances too small
  // and u(s) 22% low (docs/images.md). Tag corners get the same treatment
  // when their own variance factor exceeds the limit. > 1.
  bool rescale_spot_covariances = true;
  double max_spot_variance_factor = 1.5;
  // One pose per camera instead of one per image: the shots of a camera
  // (SceneShot::camera) share its pose in the adjustment. For cameras that
  // stay put the whole session (tripods, nothing touched between shots):
  // every shot's tags then place the camera, and the pose error no longer
  // differs from shot to shot, so it largely cancels between two grids
  // photographed in different shots (a calibration's separations:
  // docs/images.md, "Calibration sessions"). The start poses of a camera's
  // shots (from their tags) must agree within max_camera_move_mm (centre)
  // and max_camera_turn_mrad, else the front end refuses (InvalidArgument
  // naming the camera and the two shots). Both > 0.
  bool one_pose_per_camera = false;
  double max_camera_move_mm = 5.0;
  double max_camera_turn_mrad = 2.0;
  // Laser-off (dark) frames (vision/dark_frame.h; docs/images.md,
  // "Laser-off frames"). A shot with "lasers": [] shows no laser: its tags
  // are used, its spots are not looked for, and it is in no exposure group.
  // With use_dark_frames, each lit shot's spots are detected in its image
  // minus the laser-off shot of the same camera and the same slice whose
  // tags moved least, when their common tags' corners moved at most
  // max_dark_frame_shift_px (median; else the camera moved between the
  // shots and the lit image is used alone, with a note). The same slice:
  // in a calibration session the screen moves between slices and the
  // cameras do not, so the tags cannot tell one slice's laser-off shot from
  // another's (a lit shot with laser-off shots of its camera on other
  // slices only is used alone, with a note). > 0.
  bool use_dark_frames = true;
  double max_dark_frame_shift_px = 1.0;
  // With match_dark_frame_exposure, the laser-off frame's exposure is
  // measured against the lit shot's (vision/dark_frame.h,
  // EstimateDarkFrameGain: automatic exposure, flickering lights) and,
  // where the mismatch matters (DarkFrameGainMatters), the frame is scaled
  // by it before the subtraction (ImageFindings::dark_frame_gain, and a
  // note). A gain outside [min, max]_dark_frame_gain is a different scene
  // light, not an exposure: the frame is not subtracted (a note). Frames of
  // one exposure are subtracted as they are.
  bool match_dark_frame_exposure = true;
  double min_dark_frame_gain = 0.5;
  double max_dark_frame_gain = 2.0;
  // The scale inside the adjustment (vision/projector_adjustment.h; docs/
  // multiview.md, "The projector model"): after the two-step measurement
  // (MeasureScaleFromImages / MeasureScaleFromFrontEnd), the laser module
  // enters the bundle adjustment as a calibrated projector, started from
  // the two-step solution, and the adjusted scene comes out in mm with s and
  // u(s) (ImageMeasureReport::projector), and its s is the report's s
  // (ImageMeasureReport::scale_factor). On by default: over 200 seeded
  // scenes its u(s) is 29 times smaller than the two-step's, both honest
  // (docs/multiview.md, "Several placements"). Where it cannot run (the
  // COLMAP path keeps no adjustment) or fails, the report falls back to
  // the two-step s and says why. RunImageFrontEnd itself ignores it.
  bool scale_in_adjustment = true;
  // Worker threads for the detection (and for CalibrateFromImages' re-solves
  // of the shared errors), >= 0; 0 = every core.
  int num_threads = 0;
  // Called after each image is detected and at each later stage:
  // (stage, done, total); may be empty.
  std::function<void(const std::string& stage, int done, int total)> progress;
  // Per-camera spot warning: a camera whose spot RMS (over every spot
  // observation of its placed images) exceeds warn_camera_spot_rms_ratio
  // times the median of the other cameras' AND warn_camera_spot_rms_min_px.
  // The per-image test above compares an image with its model, and the
  // spots' variance component (step 6), common to every image, grows with
  // one bad camera until that camera no longer stands out from its model;
  // the matching gates, which follow that variance, also cut the bad
  // camera's worst spots (they stay unmatched), so its RMS stays within
  // 2-3 times the others' (spots jittered by 0.35 px per axis in one of
  // four cameras: 0.16 px against 0.08 px, model 0.13 px;
  // tests/integration/camera_spot_rms_warning_test.cc). The floor keeps
  // sharp scenes quiet. Needs three or more cameras with 10 or more spot
  // observations each. Both > 0.
  double warn_camera_spot_rms_ratio{2.0};
  double warn_camera_spot_rms_min_px{0.1};

  Status Validate() const;
};

// What was found in one image.
struct ImageFindings {
  std::string file;    // as in the scene's shot
  std::string camera;  // its camera's name
  std::vector<int> tag_ids;       // tags detected (increasing id)
  int spots_detected = 0;         // laser spots detected (outside tags, past the gates)
  int blobs_rejected = 0;         // detections outside tags that failed the spot gates
  int spots_matched = 0;          // of those, in a 3D spot
  int spots_saturated = 0;        // of the spots, those with a saturated pixel
  bool lossy_jpeg = false;        // the file is a JPEG
  bool laser_off = false;         // "lasers": [] (a dark frame)
  std::string dark_frame;         // the laser-off shot subtracted before detecting spots, or empty
  bool placed = false;            // its pose was found
  double tag_rms_px = 0.0;        // RMS tag corner residual after the adjustment
  double spot_rms_px = 0.0;       // RMS spot residual after the adjustment
  // What the covariances predict for those RMS (sqrt of the mean of
  // trace / 2 over the image's observations, variance components included).
  double tag_model_rms_px = 0.0;
  double spot_model_rms_px = 0.0;
  std::vector<std::string> notes; // why something was not used
  // The laser spots kept (spots_detected of them; FrontEndSpot::views
  // index them) and the centres of the blobs the spot gates rejected, for
  // overlays and checks.
  std::vector<DetectedSpot> spots;
  std::vector<Eigen::Vector2d> rejected_blobs_px;
  std::vector<TagDetection> tags;  // the tags detected (tag_ids' corners)
  // The image decoder's warnings: the file is damaged but decoded (a JPEG
  // cut short, corrupt JPEG data, a bad CRC in a PNG text chunk; one safe
  // line each, vision/image_decode.h). Each such image also gets a warning
  // in FrontEndResult::warnings.
  std::vector<std::string> decode_warnings{};
  // The factor the laser-off frame (dark_frame) was scaled by before it was
  // subtracted: its exposure against this image's
  // (FrontEndOptions::match_dark_frame_exposure); 1 when they match or no
  // frame was subtracted.
  double dark_frame_gain{1.0};
};

// A laser spot in 3D.
struct FrontEndSpot {
  Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();  // scene frame, unscaled
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();      // first order
  // Its split (BundleResult::point_shared_factors): covariance =
  // own_covariance + shared_factor shared_factor^T, and two spots' errors
  // are correlated through shared_factor (the cameras' and the datum tags'
  // errors, which every spot shares): Cov(spot i, spot j) = K_i K_j^T.
  Eigen::Matrix3d own_covariance = Eigen::Matrix3d::Zero();
  Eigen::MatrixXd shared_factor;  // 3 x m, the same m for every spot; empty when not computed
  int group = 0;  // exposure group index (FrontEndResult::groups)
  // The detections it was made of: (image index, index in that image's spots).
  std::vector<std::pair<int, int>> views;
};

// Shots with the same lasers on, the same slice and the same module
// placement.
struct ExposureGroup {
  std::vector<std::string> lasers;  // sorted
  int slice = 0;
  std::vector<int> images;          // indices into the shots
  std::string placement{};          // SceneShot::placement (empty: none)
};

struct FrontEndResult {
  std::vector<ImageFindings> images;   // one per shot, scene order
  std::vector<Camera> cameras;         // one per shot, scene frame (placed ones valid)
  std::vector<ExposureGroup> groups;
  std::vector<FrontEndSpot> spots;
  // Tag centres in the scene frame and their covariances, by id.
  std::map<int, Eigen::Vector3d> tag_centers;
  std::map<int, Eigen::Matrix3d> tag_center_covariances;
  // The same split as FrontEndSpot's, by id: a tag centre's error is
  // own + K z with own independent between tags and spots (its corners' own
  // covariances / 16) and K (3 x m, the mean of its corners' shared
  // factors) shared with every point: Cov(tag a, tag b) = K_a K_b^T,
  // Cov(tag a, spot j) = K_a K_j^T. Empty when the adjustment gave no split.
  // (tag_center_covariances above leaves out the corners' cross terms;
  // own + K K^T is the full first-order covariance.)
  std::map<int, Eigen::Matrix3d> tag_center_own_covariances;
  std::map<int, Eigen::MatrixXd> tag_center_shared_factors;
  std::array<int, 3> frame_tags = {-1, -1, -1};  // origin, axis, plane
  // When not empty, what the frame is instead of the frame tags' (the COLMAP
  // path: "the COLMAP model's frame ...").
  std::string frame_description;
  double rms_reprojection_px = 0.0;  // final adjustment, every observation
  double variance_factor = 0.0;      // final adjustment
  // The spots' and the tag corners' variance factors after the first
  // adjustment, and the standard deviations added to their pixel
  // covariances in quadrature (0: not enlarged; FrontEndOptions::
  // rescale_spot_covariances).
  double spot_variance_factor = 0.0;
  double spot_extra_sigma_px = 0.0;
  double tag_variance_factor = 0.0;
  double tag_extra_sigma_px = 0.0;
  // The spots' variance factor of the final adjustment when above 1 (else
  // 1): the 3D spot covariances are multiplied by it (a posteriori), so
  // that they, and u(s), follow the observed scatter.
  double spot_point_covariance_scale = 1.0;
  std::string bundle_report;         // BundleResult::Report() of the final adjustment
  // The final adjustment's data moved to the scene frame (unscaled): its
  // cameras (BundleData::cameras, one per placed camera pose), its points
  // (tag corners first, then spot k at first_spot_point + k) and
  // observations (tag corners, then spots), and each tag's corner 0 (by
  // id). For the projector adjustment (scale_in_adjustment); empty on the
  // COLMAP path.
  BundleData adjustment;
  int first_spot_point = 0;
  std::map<int, int> tag_first_point;
  std::vector<std::string> warnings;

  // Per image one line (file, camera, tags, spots detected/matched, RMS),
  // then the groups, the adjustment and the warnings.
  std::string ToText() const;
};

// OK when at least one shot of the scene has a laser on; else
// InvalidArgument "shots: no shot has a laser on (every shot's 'lasers' is
// empty or absent): there are no spots to measure". RunImageFrontEnd, MeasureScaleFromImages
// and CalibrateFromImages refuse such a scene ("scene: shots: ...") before reading
// any image; the tools name the scene file.
Status CheckSceneHasLasers(const Scene& scene);

Result<FrontEndResult> RunImageFrontEnd(const Scene& scene, const std::string& images_dir,
                                        const FrontEndOptions& options = FrontEndOptions());

}  // namespace opl
