// Planar targets seen by a distorted camera: synthetic grayscale images with
// known truth, for testing tag detection and camera calibration
// (docs/targets_and_calibration.md).
//
// The model. A PlanarTarget is a flat rectangle in the scene carrying a
// piecewise-constant texture: texel (r, c) of `texture` is a square cell of
// side `texel_size` (scene units) with a constant reflectance in [0, 1]
// (0 = black, 1 = white). The target frame has its origin at the OUTER
// top-left corner of texel (0, 0), x along the texture's columns, y along its
// rows, z = x cross y (pointing away from a viewer who sees the texture
// unmirrored); the target covers x in [0, cols * texel_size],
// y in [0, rows * texel_size], z = 0. It sits in the scene at
// scene_from_target.
//
// Rendering is exact inverse mapping. Each pixel is split into n x n
// sub-pixels (n = subpixels_per_axis); the corners of every sub-pixel are
// undistorted once per camera (UndistortPixel, the map is kept by the
// renderer), their rays intersected with the target plane, and the resulting
// quadrilateral in the texture is clipped against every texel it overlaps:
// the sub-pixel's value is the area-weighted mean of the texels' reflectances
// (the background level where it leaves the target). Edges are thus
// integrated analytically, not point sampled; the only approximation is that
// a sub-pixel's image on the plane is taken as the straight-sided quad through
// its four corners (exact for a pinhole, a curvature error of order
// (distortion gradient x sub-pixel size)^2 otherwise), which is why
// supersampling still converges (tests/lab/planar_target_image_test.cc). Then
// an optional Gaussian PSF (blur_sigma_px, applied to the pixel-integrated
// image, which equals integrating the blurred optical image), additive
// Gaussian noise, and quantisation to 8 or 16 bits. Levels are fractions of
// full scale (1.0 = 255 or 65535).
//
// Truth. Every tag printed on a target (TargetTag: id and the 4 corners of its
// black square in the target frame) is projected with the camera model.
// Corner order, shared with DetectTags (vision/tag_detection.h): as the tag is
// printed (drawMarker's image, looking at the printed face), 0 = top-left,
// 1 = top-right, 2 = bottom-right, 3 = bottom-left; in the image of a camera
// facing the tag upright this is clockwise (v points down).
//
// Errors (Status, never an abort): bad options, a camera whose intrinsics do
// not validate, an empty or non-single-channel texture, a non-positive texel
// size, an unknown tag id.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/vision/camera_calibration.h"
#include "opl/vision/camera_model.h"

namespace opl {

// A tag printed on a target: its id (tag36h11) and the corners of its black
// square in the target frame (z = 0), in the order top-left, top-right,
// bottom-right, bottom-left as printed.
struct TargetTag {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_in_target;
};

struct PlanarTarget {
  // Reflectance per texel: CV_8UC1 (0..255 -> 0..1) or CV_32FC1 / CV_64FC1
  // (0..1). Each texel is a square of side texel_size in the target frame.
  cv::Mat texture;
  double texel_size = 0.0;     // side of one texel [scene units], > 0
  Rigid3d scene_from_target;   // pose of the target frame (see above)
  std::vector<TargetTag> tags; // tags printed on it, for the truth

  // Size of the target [scene units].
  double Width() const { return texture.cols * texel_size; }
  double Height() const { return texture.rows * texel_size; }
};

// The tag36h11 texture of `id`: the 8 x 8 cells of the marker (6 x 6 data
// bits inside a 1-cell black border, as cv::aruco::drawMarker with
// DICT_APRILTAG_36h11 draws it) surrounded by `quiet_zone_cells` white cells:
// a CV_8UC1 image of (8 + 2 q) x (8 + 2 q) texels, 0 or 255. InvalidArgument
// for an id outside [0, 586] or a negative quiet zone.
Result<cv::Mat> MakeTag36h11Texture(int id, int quiet_zone_cells = 1);

// A single-tag target: the tag `id` with a black square of side `tag_size`
// (scene units) and a white quiet zone of `quiet_zone_cells` cells, posed by
// its TAG frame: scene_from_tag, whose origin is the centre of the black
// square, x to the right and y down as printed (so its corners are at
// (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2), z = 0). The target frame
// is the tag frame shifted to the texture's top-left corner.
Result<PlanarTarget> MakeTagTarget(int id, double tag_size, const Rigid3d& scene_from_tag,
                                   int quiet_zone_cells = 1);

// A tag board (vision/camera_calibration.h: TagBoard) as a target posed by its
// BOARD frame (scene_from_board; board frame as in TagBoard). The texel is a
// tag cell (tag_size / 8); the gap between tags must be a whole number of
// cells (InvalidArgument otherwise); `margin_cells` white cells surround the
// outer tags.
Result<PlanarTarget> MakeTagBoardTarget(const TagBoard& board, const Rigid3d& scene_from_board,
                                        int margin_cells = 2);

struct TargetRenderOptions {
  double background_level = 0.35;  // level where no target is seen [fraction of full scale]
  double black_level = 0.08;       // level of reflectance 0 [fraction of full scale]
  double white_level = 0.85;       // level of reflectance 1 [fraction of full scale]
  double blur_sigma_px = 0.0;      // Gaussian PSF sigma [px]; 0 = none; <= 10
  double noise_sigma = 0.0;        // additive Gaussian noise [fraction of full scale], >= 0
  int bit_depth = 8;               // 8 (CV_8UC1) or 16 (CV_16UC1)
  uint64_t seed = 1;               // noise seed (the same seed gives the same image)
  // Also return `levels`: the image after the PSF, before noise and
  // quantisation, CV_32F fractions of full scale (4 bytes per pixel).
  bool keep_levels = false;

  // OK, or names the field, its value and the broken constraint.
  Status Validate() const;
};

// The truth of one tag in a rendered image.
struct RenderedTag {
  int id = 0;
  int target_index = 0;                     // index into the targets rendered
  std::array<Eigen::Vector2d, 4> corners_px; // projected corners, order above
  bool in_image = false;  // every corner in front of the camera and inside the image
};

struct RenderedTargetImage {
  cv::Mat image;                 // CV_8UC1 or CV_16UC1, the camera's size
  cv::Mat levels;                // CV_32FC1 before noise and quantisation (keep_levels), else empty
  std::vector<RenderedTag> tags; // every tag of every target, in target order
};

// Renders targets seen by one camera. Create() precomputes the undistorted
// rays of every sub-pixel corner (it depends on the camera only); Render()
// can then be called for any targets and options. The map holds
// (n W + 1)(n H + 1) rays of 16 bytes (50 MB for 1024 x 768 at n = 2; 1.2 GB
// for 18 MP): for large images use CreateOnDemand(), which keeps no map and
// undistorts, at every Render(), only the sub-pixel corners inside each
// target's bounding box in the image (the same rays, so the same image).
// Either way Render() keeps sub-pixel values only in tiles of 64 x 64 pixels
// that a target's bounding box touches, and works through each box in bands
// of 64 pixel rows, besides one CV_64F image of the camera's size: memory
// follows the targets' area in the image, not n^2 W H (18 MP, n = 2, ten
// tags: ~150 MB for the image and its levels).
class PlanarTargetRenderer {
 public:
  // InvalidArgument for intrinsics that do not validate or
  // subpixels_per_axis outside [1, 8].
  static Result<PlanarTargetRenderer> Create(const Camera& camera, int subpixels_per_axis = 2);
  // The same without the precomputed map (see above): slower per Render()
  // when targets cover much of the image, memory independent of n^2 W H.
  static Result<PlanarTargetRenderer> CreateOnDemand(const Camera& camera,
                                                     int subpixels_per_axis = 2);

  // The image of `targets` and the truth of their tags. Targets are painted
  // in order over the background (a later one covers an earlier one where
  // they overlap in the image, whatever their depths).
  Result<RenderedTargetImage> Render(const std::vector<PlanarTarget>& targets,
                                     const TargetRenderOptions& options) const;

  const Camera& camera() const { return camera_; }
  int subpixels_per_axis() const { return subpixels_; }

 private:
  PlanarTargetRenderer() = default;
  Camera camera_;
  int subpixels_ = 2;
  int grid_cols_ = 0, grid_rows_ = 0;   // n W + 1, n H + 1
  // Normalized (x, y) per grid corner, NaN where undefined; empty when
  // created on demand (RayAt computes them then).
  std::vector<Eigen::Vector2d> rays_;
  Eigen::Vector2d RayAt(int grid_row, int grid_col) const;
};

}  // namespace opl
