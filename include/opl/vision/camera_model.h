// Camera model: pinhole with Brown-Conrady distortion (k1, k2, k3 radial;
// p1, p2 tangential), the model and parameter order of OpenCV's calib3d.
//
// A point X_cam = (X, Y, Z) in the camera frame (X right, Y down, Z forward
// along the optical axis, Z > 0 in front) projects to the pixel (u, v) as
//   x = X / Z,  y = Y / Z,  r2 = x^2 + y^2,
//   radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3,
//   xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2),
//   yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y,
//   u = fx xd + cx,  v = fy yd + cy.
// Pixel convention (OpenCV's): (0, 0) is the CENTRE of the top-left pixel,
// u grows to the right, v downwards; pixel (i, j) covers u in [j-0.5, j+0.5),
// v in [i-0.5, i+0.5).
//
// A camera's pose is cam_from_scene: X_cam = R X_scene + t (geometry/rigid3.h).
//
// The templated functions compile for double and ceres::Jet, so that cost
// functions can use them under automatic differentiation.
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"

namespace opl {

// Order of the packed intrinsic parameter vector, as used by the bundle
// adjustment and camera calibration: fx, fy, cx, cy, k1, k2, p1, p2, k3.
inline constexpr int kNumCameraParameters = 9;

struct CameraIntrinsics {
  int width_px = 0;   // image size; pixels outside it are not observed
  int height_px = 0;
  double fx_px = 0.0;  // focal lengths [px]
  double fy_px = 0.0;
  double cx_px = 0.0;  // principal point [px], OpenCV pixel convention
  double cy_px = 0.0;
  double k1 = 0.0, k2 = 0.0, k3 = 0.0;  // radial distortion
  double p1 = 0.0, p2 = 0.0;            // tangential (decentring) distortion

  // fx, fy, cx, cy, k1, k2, p1, p2, k3.
  std::array<double, kNumCameraParameters> Packed() const;
  static CameraIntrinsics FromPacked(const double* packed, int width_px, int height_px);

  // OK, or names the first field that is out of its domain (non-positive size
  // or focal length, non-finite value).
  Status Validate() const;
};

// Distorts normalized image coordinates (x, y) -> (xd, yd). `packed` is the
// intrinsic vector in kNumCameraParameters order (only entries 4..8 are read).
template <typename T>
void DistortNormalized(const T* packed, const T& x, const T& y, T* xd, T* yd) {
  const T& k1 = packed[4];
  const T& k2 = packed[5];
  const T& p1 = packed[6];
  const T& p2 = packed[7];
  const T& k3 = packed[8];
  const T x2 = x * x;
  const T y2 = y * y;
  const T xy = x * y;
  const T r2 = x2 + y2;
  const T radial = T(1.0) + r2 * (k1 + r2 * (k2 + r2 * k3));
  *xd = x * radial + T(2.0) * p1 * xy + p2 * (r2 + T(2.0) * x2);
  *yd = y * radial + p1 * (r2 + T(2.0) * y2) + T(2.0) * p2 * xy;
}

// Projects a point in the camera frame to a pixel. Returns false (and leaves
// `pixel` unset) for a point at or behind the camera (Z <= 0).
template <typename T>
bool ProjectPointInCamera(const T* packed, const T* point_in_cam, T* pixel) {
  if (!(point_in_cam[2] > T(0.0))) return false;
  const T x = point_in_cam[0] / point_in_cam[2];
  const T y = point_in_cam[1] / point_in_cam[2];
  T xd, yd;
  DistortNormalized(packed, x, y, &xd, &yd);
  pixel[0] = packed[0] * xd + packed[2];
  pixel[1] = packed[1] * yd + packed[3];
  return true;
}

// A calibrated camera placed in the scene.
struct Camera {
  std::string name;
  CameraIntrinsics intrinsics;
  Rigid3d cam_from_scene;

  // Pixel of a scene point; false for a point behind the camera. Does not
  // check the image bounds (see InImage).
  bool Project(const Eigen::Vector3d& point_in_scene, Eigen::Vector2d* pixel) const;
  // True when the pixel lies inside the image, `margin_px` from its border.
  bool InImage(const Eigen::Vector2d& pixel, double margin_px = 0.0) const;
  // Camera centre in the scene frame.
  Eigen::Vector3d CenterInScene() const;
};

// The pose of a camera at `center_in_scene` whose optical axis (+Z) points
// at `target_in_scene`, with the scene's Z axis up: the camera's X axis is
// horizontal (Z_cam x Z_scene) and its Y axis points down in the image;
// when the optical axis is within 8 deg of vertical, the scene's Y axis
// serves as "up" instead. Then rolled by `roll_rad` about the optical axis
// (positive: the picture turns clockwise, scene-up moving towards +u).
// InvalidArgument when the centre and the target coincide or are not finite.
Result<Rigid3d> CamFromSceneLookingAt(const Eigen::Vector3d& center_in_scene,
                                      const Eigen::Vector3d& target_in_scene, double roll_rad = 0.0);

// Pixel of a point in the camera frame (double version); false behind.
bool ProjectToPixel(const CameraIntrinsics& intrinsics, const Eigen::Vector3d& point_in_cam,
                    Eigen::Vector2d* pixel);

// Inverts the distortion: the normalized undistorted coordinates (x, y) of a
// pixel, so that the ray (x, y, 1) in the camera frame projects to it.
// Gauss-Newton on the distortion model, to 1e-12 in normalized units; fails
// (kNoSolution) where the model is not invertible near the pixel (a strongly
// distorted image corner beyond the model's fold).
Result<Eigen::Vector2d> UndistortPixel(const CameraIntrinsics& intrinsics,
                                       const Eigen::Vector2d& pixel);

}  // namespace opl
