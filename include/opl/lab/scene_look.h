// The harder virtual lab: the room and the camera beyond tags and spots.
// A shot of a plain scene is a grey wall, tags and spots with sensor noise
// (lab/render_scene.h). Real photographs also show a textured wall, light
// that varies across the image, lamps, highlights and reflective dots that
// are not laser spots, a lens that darkens the corners and may be out of
// focus, a colour sensor behind a Bayer mosaic, and JPEG files. Each is an
// optional field of ImageLook (lab/scene.h); this header composes them.
//
// The model of one image (every level a fraction of full scale before the
// last step):
//  1. Wall: background_level, or the wall texture (a photograph scaled to
//     cover the image, centred, its mean at background_level and its
//     variation scaled by wall_texture_contrast). The tags (their black
//     square, white quiet zone and the blur around them) are drawn over it:
//     the wall shows wherever the tag image is at background_level.
//  2. Ambient light: a linear ramp from -a/2 to +a/2 across the image at
//     ambient_angle_deg.
//  3. Distractors (MakeDistractors): Gaussian blobs of their colour.
//  4. Defocus: a Gaussian PSF over 1-3 (the caller widens the spots' own
//     shape by the same sigma, so their light stays an exact Gaussian).
//  5. Spots: the laser light times the camera's response in each channel.
//  6. Vignetting and exposure: everything times (1 - v (r / r_corner)^2) x
//     the shot's exposure (SceneShot::exposure; 1 unless given).
//  7. Sensor: to DN, (Bayer: sampled on an RGGB mosaic), shot and read
//     noise, rounding and clipping, (Bayer: demosaiced by OpenCV).
// Truth stays exact: tags and spots are where the plain lab puts them; none
// of the steps moves a tag edge or a spot centre (the ramp and vignetting
// shift a spot's light-weighted centre by less than 1e-3 px at the
// documented ranges for spots of a few px).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/vision/camera_model.h"

namespace opl {

// A bright thing in the room that is not a laser spot.
struct Distractor {
  enum class Kind { kSpecularHighlight, kLamp, kRetroreflector };
  Kind kind = Kind::kRetroreflector;
  Eigen::Vector2d center_px = Eigen::Vector2d::Zero();  // OpenCV pixel convention
  Eigen::Matrix2d shape_covariance_px2 = Eigen::Matrix2d::Identity();
  double peak_fraction = 1.0;                 // of full scale (> 1 saturates)
  std::array<double, 3> rgb = {1.0, 1.0, 1.0};  // colour, red green blue, max 1
};

// "specular_highlight", "lamp", "retroreflector".
const char* DistractorKindName(Distractor::Kind kind);

// `count` distractors in a width x height image, seeded: about 40%
// specular highlights (white streaks, 3-12 px by 0.8-2 px sigma, saturating),
// 30% lamps (warm white discs, 1.5-5 px sigma, saturating), 30%
// retro-reflective dots (white, 1-2.5 px sigma, like a laser spot).
std::vector<Distractor> MakeDistractors(int count, int width_px, int height_px, uint64_t seed);

// A wall texture read once: the photograph as CV_32FC3 BGR in [0, 1]
// (grey made BGR; 8 and 16-bit files), decoded as the shots are
// (vision/image_decode.h: sensor pixels, an EXIF orientation not applied).
// IoError naming the file when it cannot be read as an image, is damaged
// (its decoder warned: a JPEG cut short, ...) or is not 8 or 16 bit.
Result<cv::Mat> ReadWallTexture(const std::string& path);

// What ComposeSceneImage needs of a shot.
struct SceneImageLayers {
  // The tags over a wall at look.background_level (lab/planar_target_image.h,
  // keep_levels): CV_32FC1, fractions of full scale, the image's size.
  cv::Mat tag_levels;
  // The laser light alone (spots with speckle, no background, no noise):
  // CV_32FC1, fractions of full scale, the image's size; may be empty (no
  // lit source).
  cv::Mat spot_light;
  cv::Mat wall_texture;  // ReadWallTexture, or empty
  std::vector<Distractor> distractors;
  // The shot's exposure (SceneShot::exposure): every layer's light is
  // scaled by it before the sensor (step 6), > 0.
  double exposure = 1.0;
};

struct SceneImage {
  cv::Mat image;           // CV_8U/CV_16U, 1 channel, or 3 (BGR) with look.color
  cv::Mat saturated_mask;  // CV_8U, 255 where the spot channel (red, or grey) reads full scale
};

// Steps 1-7 of the header for one image of `camera`'s size; noise seeded by
// `noise_seed`. InvalidArgument when a layer's size or type is off.
Result<SceneImage> ComposeSceneImage(const SceneImageLayers& layers, const ImageLook& look,
                                     const CameraIntrinsics& camera, uint64_t noise_seed);

}  // namespace opl
