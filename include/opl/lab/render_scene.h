// Rendering a scene (lab/scene.h): the image every shot's camera takes of the
// tags on the walls and the laser spots of the lit sources, with the exact
// truth of what it shows (`opl_simulate images`; docs/formats.md, "Scene
// truth JSON").
//
// Pixel convention: OpenCV's, as vision/camera_model.h: (0, 0) is the CENTRE
// of the top-left pixel, u to the right, v down. Every truth position is the
// exact MODEL position (the camera model applied to the true 3D point): a
// perfect detector finds it, up to the rendering's own approximations (tag
// edges integrated per sub-pixel; spot light integrated per pixel).
//
// The model of one shot:
//  1. Tags. Each tag is a tag36h11 target (MakeTagTarget) of black square
//     scene.tags.size_mm with a white quiet zone of kSceneTagQuietZoneCells
//     cells, posed at its scene_from_tag, drawn (PlanarTargetRenderer,
//     created on demand: memory follows the tags' area in the image) over
//     the wall at image.background_level, tag black and white at
//     image.black_level and image.white_level, then the Gaussian PSF
//     image.blur_sigma_px; noise-free, kept at float precision. A tag is drawn
//     only when its printed face looks towards the camera (a wall hides its
//     back) and it is not wholly behind the camera.
//  2. Spots. For every lit source (shot.lasers) and every beam of its pattern
//     (MakePattern, with its fabrication error), the beam's ray from the
//     projection origin is intersected with slice shot.slice of the module's
//     surface (Surface::IntersectRaySlice). The spot is drawn when the point
//     is in front of the camera, projects inside the image, and the surface
//     there faces the camera (the camera and the source on the same side of
//     the tangent plane); there is no other occlusion. (A spot whose centre
//     is outside the image but within 5 sigma of it is drawn too, its light
//     reaching the border, and reported not visible.) Its image is the
//     projection of a disc of 1/e^2 diameter spots.diameter_mm lying in the
//     tangent plane: a Gaussian of covariance J S J^T (S = (D/4)^2 (I - n n^T),
//     J = d pixel / d point at the spot, by central differences), so oblique
//     spots are elliptical, centred on the projected point, peak
//     spots.peak_fraction of full scale, with speckle as RenderSpotImage.
//  3. Sensor (a scene with any field of the harder lab set, ImageLook::
//     HasSceneLook, composes the tags, the spots' light and the room as
//     lab/scene_look.h says instead). The spots are added to the tag image (RenderSpotImage with the
//     tag image as background) and noise applied once: shot noise
//     (image.gain_e_per_dn) and read noise (image.read_noise of full scale),
//     rounding and clipping to image.bit_depth. Seeds derive from scene.seed
//     and the shot index: a shot renders the same whatever else is rendered.
//
// Memory: about 18 bytes per pixel at the peak (4912 x 3684: 332 MB, 5 s on
// one core). A tag that straddles the camera's plane (partly behind it) makes
// the target renderer undistort the whole image's sub-pixel grid: slow on
// large images (tens of seconds at 18 MP) though memory stays bounded.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/lab/scene_look.h"

namespace opl {

// White quiet zone around each rendered tag, in tag cells (size_mm / 8).
inline constexpr int kSceneTagQuietZoneCells = 2;

// A tag of the scene in 3D.
struct SceneTagTruth {
  int id = 0;
  Eigen::Vector3d center_in_scene = Eigen::Vector3d::Zero();  // centre of the black square, mm
  // Corners of the black square, mm, in DetectTags' order: top-left,
  // top-right, bottom-right, bottom-left as printed.
  std::array<Eigen::Vector3d, 4> corners_in_scene;
};

// A laser spot on the surface in 3D (one per placement, source, beam and
// slice).
struct SceneSpotTruth {
  std::string source;
  std::string placement;  // Scene::module_placements name; empty when the scene has none
  int beam = 0;   // beam id (method.md numbering)
  int slice = 0;  // slice of the surface
  Eigen::Vector3d point_in_scene = Eigen::Vector3d::Zero();  // beam ray hit, mm
  Eigen::Vector3d normal_in_scene = Eigen::Vector3d::UnitX(); // unit surface normal, towards the source
};

// A tag in one image.
struct TagView {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px;  // projected corners (NaN behind the camera)
  bool facing = false;    // the printed face looks towards the camera (drawn)
  bool in_image = false;  // facing, every corner in front and inside the image
};

// A spot in one image.
struct SpotView {
  int spot_index = 0;  // into SceneRenderer::spots()
  Eigen::Vector2d center_px = Eigen::Vector2d::Zero();  // projected point (NaN behind the camera)
  Eigen::Matrix2d shape_covariance_px2 = Eigen::Matrix2d::Zero();  // drawn Gaussian (drawn only)
  // Drawn and its centre inside the image: in front of the camera, surface
  // facing it (header, step 2).
  bool visible = false;
  int saturated_pixels = 0;
};

struct RenderedShot {
  int shot_index = 0;
  cv::Mat image;                // CV_8UC1 or CV_16UC1 (image.bit_depth), the camera's size
  std::vector<TagView> tags;    // every tag of the scene, scene order
  std::vector<SpotView> spots;  // every hit of the lit sources on the shot's slice
  // The camera's distractors (image.distractors; lab/scene_look.h), drawn.
  std::vector<Distractor> distractors;
};

// Renders the shots of a scene. Create() validates the scene for rendering,
// makes the patterns and the 3D truth; RenderShot() is then independent per
// shot and may be called from several threads at once.
class SceneRenderer {
 public:
  // Errors: Scene::ValidateForRendering(), a pattern file that cannot be read.
  static Result<SceneRenderer> Create(const Scene& scene);

  // The image and truth of scene.shots[shot_index]. InvalidArgument for an
  // index out of range.
  Result<RenderedShot> RenderShot(int shot_index) const;

  const Scene& scene() const { return scene_; }
  const std::vector<SceneTagTruth>& tags() const { return tags_; }  // scene order
  // Every hit of every source on every slice some shot shows (placements in
  // scene order, then sources in module order, then slice, then beam id).
  // At a placement the module is moved by SceneModulePlacement::
  // SceneFromDesign; the surface stays.
  const std::vector<SceneSpotTruth>& spots() const { return spots_; }

 private:
  SceneRenderer() = default;
  Scene scene_;
  std::vector<SceneTagTruth> tags_;
  std::vector<SceneSpotTruth> spots_;
  cv::Mat wall_texture_;  // image.wall_texture, read once (shared, read-only)
  std::vector<std::vector<Distractor>> distractors_;  // per camera, scene order
};

// Convenience: SceneRenderer::Create(scene) then RenderShot(shot_index).
Result<RenderedShot> RenderShot(const Scene& scene, int shot_index);

}  // namespace opl
