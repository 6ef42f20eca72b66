// Camera and tag poses from coded targets: the starting point of the bundle
// adjustment when nothing but calibrated intrinsics is known
// (docs/multiview.md, "Poses from tags").
//
// The model. Every image i was taken by a camera with known intrinsics K_i
// and unknown pose cam_from_scene_i; every tag t (tag36h11, vision/
// tag_detection.h) is a square of nominal side s at an unknown pose
// scene_from_tag_t (tag frame: origin at the centre of the black square, x to
// the right and y down as printed, corners TL, TR, BR, BL at (-+s/2, -+s/2, 0)
// as lab/planar_target_image.h). A detected tag gives its four corner pixels.
//
// The algorithm (incremental, like a structure-from-motion initialisation):
//  1. Per detection, the two planar pose solutions of the tag in the camera
//     (OpenCV's IPPE, with the camera's distortion) and their reprojection
//     errors. A small or far tag is often ambiguous (its two solutions
//     reproject almost equally well); both are kept as candidates.
//  2. The scene frame starts as the frame of the tag seen in the most images
//     (its better solution in the image where it is seen largest).
//  3. Repeat until nothing changes:
//     - an image seeing placed tags is placed: each candidate pose (from each
//       placed tag it sees, both solutions) is scored by the median
//       reprojection error of ALL placed tags' corners in that image; the
//       best is refined by Levenberg-Marquardt on those corners
//       (cv::solvePnP, extrinsic guess);
//     - a tag seen by placed images is placed: each candidate (from each
//       placed image, both solutions, and the nominal square fitted to its
//       corners triangulated from two or more placed images) is scored by
//       its corners' RMS reprojection error over all placed images that see
//       it; the best is kept.
//     Images are placed in the order of how many placed tags they see, tags
//     in the order of how many placed images see them, so that the best
//     constrained go first.
//  4. `refinement_rounds` rounds of alternating refinement: every image by
//     Levenberg-Marquardt on all its tags' corners, then every tag but the
//     reference from its corners triangulated in all placed images (the
//     nominal square fitted to them, Umeyama), when that lowers its error.
//  5. Images or tags never connected to the first tag are reported unplaced.
//
// The scale of the result is that of the nominal tag side: if the tags are
// printed 1% larger than `tag_size`, every distance is 1% short. The bundle
// adjustment that follows keeps that scale; the laser module or an artifact
// fixes it (method.md). Accuracy: a start for the bundle adjustment (typically
// within a fraction of a percent of the scene size), not a measurement.
//
// Errors (Status, never an abort): InvalidArgument for a non-positive tag
// size, intrinsics that do not validate (names the image), sizes that
// disagree; NoSolution when no tag is seen twice or no image can be placed.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/vision/camera_model.h"
#include "opl/vision/tag_detection.h"

namespace opl {

struct TagPoseOptions {
  // Nominal side of the black square of every tag [scene units], > 0.
  double tag_size = 100.0;
  // A placed image or tag whose RMS corner reprojection error exceeds this is
  // reported in TagPoses::warnings [px], > 0 (it is still placed: the bundle
  // adjustment may fix it or reject it).
  double warn_rms_px = 2.0;
  // Rounds of alternating refinement after every image and tag is placed
  // (step 4 of the header), >= 0.
  int refinement_rounds = 3;

  Status Validate() const;
};

struct TagPoses {
  // Per image, its pose; nullopt when it could not be placed.
  std::vector<std::optional<Rigid3d>> cam_from_scene;
  // Per placed tag id, its pose.
  std::map<int, Rigid3d> scene_from_tag;
  int reference_tag = -1;  // the tag whose frame is the scene frame
  // Per image, RMS corner reprojection error of its placed tags [px]
  // (0 for an unplaced image).
  std::vector<double> image_rms_px;
  std::vector<std::string> warnings;  // images/tags unplaced or poorly fitted
};

// The corners of a tag of side `tag_size` in its tag frame, order TL, TR,
// BR, BL (z = 0).
std::array<Eigen::Vector3d, 4> TagCornersInTag(double tag_size);

// Poses of the images (intrinsics per image) and of the tags they see
// (detections per image), header comment.
Result<TagPoses> PosesFromTags(const std::vector<CameraIntrinsics>& intrinsics_per_image,
                               const std::vector<std::vector<TagDetection>>& tags_per_image,
                               const TagPoseOptions& options = TagPoseOptions());

}  // namespace opl
