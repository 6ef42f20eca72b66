// Scene: a photogrammetry set-up as a value: the cameras, the coded targets on
// the walls, the three targets of the scene frame, a scale artifact, the laser
// module and the surface its grids land on, how spots and images look, and the
// shots (which camera took which image, with which lasers on). Read from the
// scene JSON (io/scene_json.h; docs/formats.md, "Scene JSON").
//
// One description serves two uses:
//  - the virtual lab renders it (lab/render_scene.h; `opl_simulate images`):
//    it needs everything, including the true camera poses and the module;
//  - the image front end measures it (pipeline/measure_images.h;
//    `opl_measure --images`): it needs the cameras' intrinsics, the tag size
//    and the frame tags, the artifact (for calibration) and the shots; the
//    true poses and the module, when present, are ignored (the front end
//    finds the poses from the images and the module from the spots; read
//    with SceneUse::kMeasure, io/scene_json.h, the module is not even opened
//    and the tag placements are optional).
//
// Frames and units: the scene frame is the simulation's world, millimetres,
// Z up. Tags are posed by their TAG frame (as lab/planar_target_image.h,
// MakeTagTarget): origin at the centre of the black square, x to the right
// and y down as printed, z into the wall (away from a viewer who reads the
// tag). A camera's pose is cam_from_scene (camera_model.h: x right, y down,
// z along the optical axis).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/sim/module_design.h"
#include "opl/vision/camera_model.h"

namespace opl {

// How a camera's intrinsics were calibrated: the optional "calibration" record
// of a scene camera, written by `opl_camera calibrate` (docs/formats.md,
// "Cameras JSON"). Informative: the front end uses the intrinsics only.
struct SceneCameraCalibration {
  // 1-sigma standard deviation of fx, fy, cx, cy [px], k1, k2, p1, p2, k3
  // (kNumCameraParameters order); 0 for a parameter held fixed; >= 0, finite.
  std::array<double, kNumCameraParameters> intrinsics_std{};
  double rms_px = 0.0;   // RMS reprojection error of the calibration [px], >= 0
  int num_views = 0;     // images used, >= 0
  int num_corners = 0;   // board corners used, >= 0
  std::string board;     // the board, as described by CalibrationBoard::Describe (may be empty)
};

struct SceneCamera {
  std::string name;               // unique, non-empty
  CameraIntrinsics intrinsics;    // calibrated (Validate()d), with the image size
  // True pose (the virtual lab renders with it). Absent in a measured scene.
  std::optional<Rigid3d> cam_from_scene;
  // How the intrinsics were calibrated, when the file says so.
  std::optional<SceneCameraCalibration> calibration;
};

struct SceneTag {
  int id = 0;             // tag36h11 id, 0..586, unique in the scene
  Rigid3d scene_from_tag; // true pose of the tag frame (header comment); may be
                          // absent in a measured scene (identity then)
};

struct SceneTags {
  std::string family = "tag36h11";  // the only family supported
  // Edge of the black square, mm, > 0. The front end uses it only to start
  // the solve at roughly the right scale (the result's scale is the laser
  // module's or the artifact's); an approximate printed size is enough.
  double size_mm = 100.0;
  std::vector<SceneTag> tags;
};

// The scene frame of the measurement (vision/scene_frame.h): origin at the
// centre of tag `origin_tag`, X towards the centre of `axis_tag`, XY plane
// through the centre of `plane_tag`. Three distinct tag ids of the scene.
struct SceneFrameTags {
  int origin_tag = 0;
  int axis_tag = 1;
  int plane_tag = 2;
};

// A scale artifact (a bar) carrying two tags whose centres are a calibrated
// distance apart.
struct SceneArtifact {
  int tag_1 = 0;
  int tag_2 = 1;
  double length_mm = 1000.0;      // calibrated distance between the centres, > 0
  double length_sigma_mm = 0.0;   // its standard uncertainty, >= 0
};

// How laser spots look in the images.
struct SpotLook {
  // 1/e^2 diameter of the spot on the surface, mm, > 0. Each spot is drawn as
  // the projection of that disc: elliptical where the surface is oblique.
  double diameter_mm = 3.0;
  // Peak of a spot as a fraction of full scale (> 1 saturates the centre).
  double peak_fraction = 0.6;
  // Speckle: contrast in [0, 1] (0 = clean spots) and grain, px (> 0).
  double speckle_contrast = 0.0;
  double speckle_grain_px = 1.5;
};

// How images are exposed and written.
struct ImageLook {
  int bit_depth = 8;               // 8 or 16 (PNG)
  double background_level = 0.25;  // wall, fraction of full scale
  double black_level = 0.05;       // tag black, fraction of full scale
  double white_level = 0.6;        // tag white, fraction of full scale
  double blur_sigma_px = 0.0;      // Gaussian PSF of the tags, px
  double read_noise = 0.0;         // Gaussian read noise, fraction of full scale
  double gain_e_per_dn = 0.0;      // shot noise (0: off), electrons per DN
  int subpixels_per_axis = 2;      // tag rendering supersampling, 1..8

  // The harder lab (lab/scene_look.h; docs/formats.md, "Scene JSON"): every
  // field optional; the defaults render the plain grey lab above exactly.
  //
  // Colour sensor: images are RGB (written BGR, as OpenCV does). Tags and an
  // untextured wall are grey; the laser is seen through the camera's
  // response to its wavelength, relative per channel (red, green, blue),
  // each in [0, 1]; the default is a 658 nm diode seen by a typical RGB
  // sensor: mostly red.
  bool color = false;
  std::array<double, 3> laser_response_rgb = {1.0, 0.10, 0.03};
  // Bayer: the colour image is sampled on an RGGB mosaic, the noise applied
  // to the mosaic, and the image demosaiced again (OpenCV's bilinear), as a
  // camera's JPEG is made. Needs `color`.
  bool bayer = false;
  // Wall texture: a photograph (path; relative to the scene JSON's folder)
  // scaled to cover each image, as the wall behind and between the tags.
  // Its mean level is background_level; `wall_texture_contrast` in [0, 1]
  // scales its variation (1: the photograph's own contrast).
  std::string wall_texture;
  double wall_texture_contrast = 1.0;
  // Ambient light: a linear ramp of this amplitude (fraction of full scale,
  // from -a/2 to +a/2 across the image) at `ambient_angle_deg` from +u
  // towards +v, on everything but the spots.
  double ambient_gradient = 0.0;
  double ambient_angle_deg = 0.0;
  // Vignetting: the light falls to 1 - vignetting at the image corners
  // (1 - v (r / r_corner)^2, r from the principal point), in [0, 0.9].
  double vignetting = 0.0;
  // Defocus of the whole image: a Gaussian PSF of this sigma, px, in
  // [0, 10] (the spots' shape covariance grows by sigma^2 I; the tags' PSF
  // combines with blur_sigma_px).
  double defocus_sigma_px = 0.0;
  // Bright distractors per camera, in [0, 1000]: specular highlights,
  // small lamps and retro-reflective dots at seeded places of the image.
  // They belong to the room: every shot of a camera shows the same ones,
  // lasers on or off. Their places are in the truth JSON.
  int distractors = 0;
  // File format: "png" (lossless, 8 or 16 bit) or "jpeg" (8 bit) at
  // `jpeg_quality` in [1, 100], optionally carrying an EXIF Orientation
  // tag (0: none, else 1..8) that OPL ignores (vision/shot_image.h) and most
  // viewers apply.
  std::string format = "png";
  int jpeg_quality = 95;
  int exif_orientation = 0;

  // True when a field of the harder lab departs from the plain grey lab
  // (file format aside).
  bool HasSceneLook() const {
    return color || bayer || !wall_texture.empty() || ambient_gradient != 0.0 ||
           vignetting != 0.0 || defocus_sigma_px != 0.0 || distractors != 0;
  }
};

// One placement of the laser module (issue 20): a set of shots in which the
// module stood still at one place of the volume. The module as designed
// (Scene::module) is moved rigidly: rotated by rotation_deg (R = Rx Ry Rz,
// degrees, the angle convention of method.md) about the centroid of its
// sources' designed origins, then translated by translation_mm. The surface
// its grids land on (the walls) does not move. The identity placement is the
// module as designed.
struct SceneModulePlacement {
  std::string name;  // unique, non-empty; shots name it
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();

  // The rigid motion above for `design`: scene_from_source of every source
  // becomes SceneFromDesign(design) * scene_from_source.
  Rigid3d SceneFromDesign(const ModuleDesign& design) const;
};

// A calibrated test length (VDI/VDE 2634-1, ISO 10360-13; opl_verify): the
// distance between the centres of two tags, as a calibration certificate
// gives it.
struct SceneCheckLength {
  std::string name;  // unique, non-empty
  int tag_1 = 0;
  int tag_2 = 1;
  double length_mm = 0.0;        // calibrated distance between the centres, > 0
  double length_sigma_mm = 0.0;  // its standard uncertainty, >= 0
};

struct SceneShot {
  std::string camera;               // a SceneCamera name
  std::string file;                 // image file, relative to the images folder
  std::vector<std::string> lasers;  // names of the module's sources that are on
  int slice = 0;                    // calibration slice index (0 for a measurement)
  // The module placement of this shot (Scene::module_placements), empty when
  // the scene lists none. With placements, every lit shot names one.
  std::string placement{};
  // The shot's exposure relative to the scene's, in (0, 10]: the renderer
  // scales all the light of the image by it (a camera on automatic
  // exposure, flickering lights), before the sensor's noise and clipping.
  // The harder lab only (ImageLook::HasSceneLook). The front end ignores
  // it: it measures a laser-off shot's exposure against each lit shot from
  // the images (vision/dark_frame.h, EstimateDarkFrameGain).
  double exposure{1.0};
};

struct Scene {
  std::vector<SceneCamera> cameras;
  SceneTags tags;
  std::optional<SceneFrameTags> frame;
  std::optional<SceneArtifact> artifact;
  // The true module and the surface its spots land on (sim/module_design.h).
  // For a calibration scene the design's surface is a list of planes (the
  // screen at each depth, PlaneListSurface) and shot.slice selects the plane
  // a shot shows; any other surface has the one slice 0.
  std::optional<ModuleDesign> module;
  SpotLook spots;
  ImageLook image;
  uint64_t seed = 1;  // of every random draw of the rendering
  std::vector<SceneShot> shots;
  // Where the module stood (empty: one place, the module as designed).
  std::vector<SceneModulePlacement> module_placements;
  // Calibrated test lengths between tags (opl_verify; may be empty).
  std::vector<SceneCheckLength> check_lengths;

  // Checks the description as a measurement input: at least one camera,
  // unique names, valid intrinsics, unique tag ids within 0..586, frame and
  // artifact tags within 0..586 and, when the scene lists its tags (a scene
  // for measuring may not: the front end finds them), among them, looks in
  // range, every shot naming
  // a camera (and lasers of the module when a module is given), unique
  // files, module placements with unique names and finite motions (every
  // lit shot naming one when any is listed), check lengths with unique
  // names, two distinct tags (among the scene's when listed) and a positive
  // length. The message names the field, e.g. "shots[3].camera: no camera
  // named 'cam9'".
  Status Validate() const;
  // Validate() plus what rendering needs: every camera posed, a module.
  Status ValidateForRendering() const;

  const SceneCamera* FindCamera(const std::string& name) const;  // nullptr if none
  const SceneTag* FindTag(int id) const;                          // nullptr if none
  // Index into module_placements; -1 if none of that name.
  int FindModulePlacement(const std::string& name) const;
};

}  // namespace opl
