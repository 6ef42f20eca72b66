// Internal to the image front end (src/pipeline/front_end_*.cc and
// image_front_end.cc): the state of one run between its stages, which
// RunImageFrontEnd (pipeline/image_front_end.h) calls in order; the numbers
// are the header's steps. The stages live by concept:
//   front_end_detect.cc  1-2  read, detect tags and spots, laser-off frames
//   front_end_tags.cc    3-4  start poses, the tags' adjustment, the frame
//                             tags, the refusal of a broken geometry
//   front_end_spots.cc   5-6  exposure groups, matching, the joint
//                             adjustment, the variance components
//   front_end_report.cc  7    per-image RMS, warnings, the scene frame
//   front_end_colmap.cc       the COLMAP path (pipeline/colmap_measure.h):
//                             cameras and poses from a COLMAP model instead
//                             of 3-4, its points as tie points, and the
//                             model's frame instead of 7
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "opl/io/colmap_model.h"
#include "opl/pipeline/image_front_end.h"
#include "opl/vision/tag_poses.h"

namespace opl {
namespace front_end_internal {

struct ImageData {
  std::vector<TagDetection> tags;
  std::vector<DetectedSpot> spots;
  int blobs_rejected = 0;  // FrontEndOptions' spot gates
  int spots_saturated = 0;
  bool lossy_jpeg = false;
  std::vector<Eigen::Vector2d> rejected_blobs_px;
  int dark_frame = -1;  // laser-off shot subtracted, or -1
  double dark_frame_gain = 1.0;  // its scale (FrontEndOptions::match_dark_frame_exposure)
  std::string dark_frame_note;   // why its exposure was matched, or why it was not subtracted
  std::vector<std::pair<int, double>> dark_candidates;  // (laser-off shot, tag shift px)
  std::vector<std::string> decode_warnings;  // ShotImage::decode_warnings
};

// One run of the front end: its state between the stages, which
// RunImageFrontEnd calls in order (the numbers of the header's steps).
struct FrontEndRun {
  struct TagObservationRef {
    int image;
    int tag;
    int corner;
  };
  struct SpotObservationRef {
    int image;
    int spot;
  };

  FrontEndRun(const Scene& scene_in, const std::string& images_dir_in,
              const FrontEndOptions& options_in)
      : scene(scene_in), images_dir(images_dir_in), options(options_in),
        num_images(static_cast<int>(scene_in.shots.size())) {}

  void Progress(const std::string& stage, int done, int total) const {
    if (options.progress) options.progress(stage, done, total);
  }
  void Init();
  Status Detect();            // 1-2
  Status PlaceCameras();      // 3, and the tags' bundle data
  // A tag whose corners are not seen from two camera positions at least
  // min_tag_triangulation_angle_deg apart (two images of one camera
  // position, or a corner dropped as an outlier) leaves its corners' depth
  // undetermined: its observations are removed and its points made
  // constant (AdjustTags removes them), with a warning.
  void DropTagsSeenFromOnePosition();
  // An image left without a tag observation is not held by the tags: it is
  // reported not placed (camera_of_image -1), with a note saying why.
  void UnplaceImagesWithoutTags();
  Status ChooseFrameTags();
  // NoSolution naming a frame tag that is not (or no longer) adjusted.
  Status CheckFrameTagsUsable(const std::string& when) const;
  Status AdjustTags();        // 4
  void GroupShots();          // 5: the exposure groups
  Status MatchGroups();       // 5: matching, into the bundle
  Status AdjustAll();         // 6
  // The variance components after pass `pass`; true: run 5-6 again.
  bool EstimateVarianceComponents(int pass);
  Status MatchAndAdjust();    // 5-6 with the variance components
  void PerImageRms();
  // The warnings of FrontEndOptions::warn_* (after PerImageRms).
  void WarnOutOfRange();
  // The camera warning of FrontEndOptions::warn_camera_spot_rms_min_px.
  void WarnCameraSpotRms();
  // FrontEndOptions::max_tag_rms_ratio, unless force.
  Status RefuseBrokenGeometry() const;
  Status MoveToSceneFrame();  // 7

  // The COLMAP path, in this order around Detect / GroupShots / MatchAndAdjust:
  // the shots' images found in the model and their intrinsics taken from it
  // (before Detect); the bundle of the model's poses and tie points, and
  // the datum (instead of 3-4); the spots moved into the model's frame
  // (instead of 7).
  Status UseColmapCameras(const ColmapModel& model);
  Status PlaceCamerasFromColmap(const ColmapModel& model, double tie_sigma_px,
                                int max_tie_points);
  Status MoveToColmapFrame();

  const Scene& scene;
  const std::string& images_dir;
  const FrontEndOptions& options;
  const int num_images;
  int threads = 1;
  FrontEndResult result;
  std::vector<CameraIntrinsics> intrinsics;
  std::vector<ImageData> data;
  std::optional<TagPoses> poses;
  BundleData bundle;
  std::vector<int> camera_of_image;
  std::map<int, int> first_corner_point;  // tag id -> index of its corner 0
  std::vector<TagObservationRef> tag_refs;
  std::array<int, 3> frame_tags = {-1, -1, -1};
  BundleOptions bundle_options;
  int num_tag_observations = 0;
  BundleData tag_bundle;  // after step 4
  std::vector<SpotObservationRef> spot_refs;
  std::vector<int> spot_group;
  int first_spot_point = 0;
  Result<BundleResult> adjusted = Status::NoSolution("not run");
  // Variance components added to the spots' and the tag corners' pixel
  // covariances [px^2], and the spots' variance factor of the last pass.
  double spot_extra_var_px2 = 0.0;
  double tag_extra_var_px2 = 0.0;
  double last_spot_variance_factor = 1.0;
  double spot_point_scale = 1.0;  // a posteriori, on the 3D spot covariances
  // Per image (PerImageRms): sum of squared spot residuals [px^2] and their
  // number, for the per-camera RMS of WarnOutOfRange.
  std::vector<double> spot_residual_sum_px2;
  std::vector<int> spot_residual_count;
  // The points of the final adjustment's three-point datum; -1: the frame
  // tags' first corners (the tag path).
  std::array<int, 3> datum_points = {-1, -1, -1};
  // COLMAP path: the model's image of each shot (nullptr: not in the model).
  std::vector<const ColmapImage*> colmap_image_of_shot;
};

}  // namespace front_end_internal
}  // namespace opl
