#include "opl/vision/camera_model.h"

#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "opl/core/format.h"

namespace opl {

std::array<double, kNumCameraParameters> CameraIntrinsics::Packed() const {
  return {fx_px, fy_px, cx_px, cy_px, k1, k2, p1, p2, k3};
}

CameraIntrinsics CameraIntrinsics::FromPacked(const double* packed, int width_px,
                                              int height_px) {
  CameraIntrinsics c;
  c.width_px = width_px;
  c.height_px = height_px;
  c.fx_px = packed[0];
  c.fy_px = packed[1];
  c.cx_px = packed[2];
  c.cy_px = packed[3];
  c.k1 = packed[4];
  c.k2 = packed[5];
  c.p1 = packed[6];
  c.p2 = packed[7];
  c.k3 = packed[8];
  return c;
}

Status CameraIntrinsics::Validate() const {
  if (width_px <= 0 || height_px <= 0) {
    return Status::InvalidArgument("camera: image size must be positive, got " +
                                   std::to_string(width_px) + " x " +
                                   std::to_string(height_px) + " px");
  }
  const char* names[kNumCameraParameters] = {"fx", "fy", "cx", "cy", "k1",
                                             "k2", "p1", "p2", "k3"};
  const auto packed = Packed();
  for (int i = 0; i < kNumCameraParameters; ++i) {
    if (!std::isfinite(packed[i])) {
      return Status::InvalidArgument(std::string("camera: field '") + names[i] +
                                     "' is not finite");
    }
  }
  if (!(fx_px > 0.0) || !(fy_px > 0.0)) {
    return Status::InvalidArgument("camera: focal lengths must be positive, got fx = " +
                                   FormatNumber(fx_px) + ", fy = " + FormatNumber(fy_px));
  }
  return Status::Ok();
}

bool ProjectToPixel(const CameraIntrinsics& intrinsics, const Eigen::Vector3d& point_in_cam,
                    Eigen::Vector2d* pixel) {
  const auto packed = intrinsics.Packed();
  return ProjectPointInCamera(packed.data(), point_in_cam.data(), pixel->data());
}

bool Camera::Project(const Eigen::Vector3d& point_in_scene, Eigen::Vector2d* pixel) const {
  return ProjectToPixel(intrinsics, cam_from_scene * point_in_scene, pixel);
}

bool Camera::InImage(const Eigen::Vector2d& pixel, double margin_px) const {
  return pixel.x() >= -0.5 + margin_px && pixel.y() >= -0.5 + margin_px &&
         pixel.x() <= intrinsics.width_px - 0.5 - margin_px &&
         pixel.y() <= intrinsics.height_px - 0.5 - margin_px;
}

Eigen::Vector3d Camera::CenterInScene() const { return cam_from_scene.Inverse().translation; }

Result<Rigid3d> CamFromSceneLookingAt(const Eigen::Vector3d& center_in_scene,
                                      const Eigen::Vector3d& target_in_scene, double roll_rad) {
  const Eigen::Vector3d axis = target_in_scene - center_in_scene;
  if (!axis.allFinite() || !std::isfinite(roll_rad) || !(axis.norm() > 0.0)) {
    return Status::InvalidArgument("camera placement: the centre and the target must be finite and distinct");
  }
  const Eigen::Vector3d z = axis.normalized();
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::abs(z.dot(up)) > 0.99) up = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;  // rows: the camera axes in the scene frame
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = z;
  R = Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R;
  return Rigid3d(R, -(R * center_in_scene));
}

Result<Eigen::Vector2d> UndistortPixel(const CameraIntrinsics& intrinsics,
                                       const Eigen::Vector2d& pixel) {
  const auto packed = intrinsics.Packed();
  const Eigen::Vector2d target((pixel.x() - intrinsics.cx_px) / intrinsics.fx_px,
                               (pixel.y() - intrinsics.cy_px) / intrinsics.fy_px);
  Eigen::Vector2d xy = target;  // start from the distorted coordinates
  for (int iter = 0; iter < 50; ++iter) {
    // Distortion and its 2x2 Jacobian by central formulas (closed form).
    const double x = xy.x(), y = xy.y();
    const double k1 = packed[4], k2 = packed[5], p1 = packed[6], p2 = packed[7],
                 k3 = packed[8];
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dradial_dr2 = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
    double xd, yd;
    DistortNormalized(packed.data(), x, y, &xd, &yd);
    const Eigen::Vector2d residual(xd - target.x(), yd - target.y());
    if (residual.norm() < 1e-12) return xy;
    Eigen::Matrix2d J;
    J(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * p1 * y + 6.0 * p2 * x;
    J(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
    J(1, 0) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
    J(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * p1 * y + 2.0 * p2 * x;
    if (std::abs(J.determinant()) < 1e-9) break;
    xy -= J.inverse() * residual;
    if (!xy.allFinite()) break;
  }
  return Status::NoSolution("camera: the distortion model cannot be inverted at pixel (" +
                            FormatNumber(pixel.x()) + ", " + FormatNumber(pixel.y()) + ")");
}

}  // namespace opl
