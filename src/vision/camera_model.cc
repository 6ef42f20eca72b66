#include "opl/vision/camera_model.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "opl/core/format.h"
#include "opl/vision/intrinsics_limits.h"

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

IntrinsicsFault FindImplausibleIntrinsics(const CameraIntrinsics& in) {
  const double side = std::max(in.width_px, in.height_px);
  const double f_lo = kMinFocalPerImageSide * side, f_hi = kMaxFocalPerImageSide * side;
  const std::string f_range = "must be in [" + FormatNumber(f_lo, 6) + ", " +
                              FormatNumber(f_hi, 6) + "] px (0.05 to 100 times the image's " +
                              "larger side, " + FormatNumber(side, 6) + " px), got ";
  if (!(in.fx_px >= f_lo && in.fx_px <= f_hi)) return {"fx", f_range + FormatNumber(in.fx_px)};
  if (!(in.fy_px >= f_lo && in.fy_px <= f_hi)) return {"fy", f_range + FormatNumber(in.fy_px)};
  const double m = kPrincipalPointMargin;
  if (!(in.cx_px >= -m * in.width_px && in.cx_px <= (1.0 + m) * in.width_px)) {
    return {"cx", "the principal point must lie within the image widened by half its width on "
                  "each side, [" + FormatNumber(-m * in.width_px, 6) + ", " +
                  FormatNumber((1.0 + m) * in.width_px, 6) + "] px, got " +
                  FormatNumber(in.cx_px)};
  }
  if (!(in.cy_px >= -m * in.height_px && in.cy_px <= (1.0 + m) * in.height_px)) {
    return {"cy", "the principal point must lie within the image widened by half its height on "
                  "each side, [" + FormatNumber(-m * in.height_px, 6) + ", " +
                  FormatNumber((1.0 + m) * in.height_px, 6) + "] px, got " +
                  FormatNumber(in.cy_px)};
  }
  if (!(std::abs(in.p1) <= kMaxTangential)) {
    return {"p1", "tangential distortion must be within +-0.5, got " + FormatNumber(in.p1)};
  }
  if (!(std::abs(in.p2) <= kMaxTangential)) {
    return {"p2", "tangential distortion must be within +-0.5, got " + FormatNumber(in.p2)};
  }
  // The farthest image corner, in normalized (distorted) coordinates.
  double corner = 0.0;
  for (const double u : {-0.5, in.width_px - 0.5}) {
    for (const double v : {-0.5, in.height_px - 0.5}) {
      corner = std::max(corner, std::hypot((u - in.cx_px) / in.fx_px, (v - in.cy_px) / in.fy_px));
    }
  }
  const auto rd = [&](double r) {
    const double r2 = r * r;
    return r * (1.0 + r2 * (in.k1 + r2 * (in.k2 + r2 * in.k3)));
  };
  const auto blamed = [&](double r) {
    const double r2 = r * r;
    const double t1 = std::abs(in.k1 * r2), t2 = std::abs(in.k2 * r2 * r2),
                 t3 = std::abs(in.k3 * r2 * r2 * r2);
    return t1 >= t2 && t1 >= t3 ? "k1" : t2 >= t3 ? "k2" : "k3";
  };
  // Walk out from the centre until r_d reaches the corner (barrel distortion
  // needs r beyond it): r_d must rise at every step.
  const int kSteps = 20000;
  const double h = corner / 2000.0;
  double previous = 0.0;
  for (int i = 1; i <= kSteps; ++i) {
    const double r = i * h;
    const double now = rd(r);
    if (!(now > previous)) {
      return {blamed(r), "the distortion folds back inside the image (r_d stops increasing at "
                         "r = " + FormatNumber(r, 3) + ", r_d = " + FormatNumber(previous, 3) +
                         "; the image corner is at r_d = " + FormatNumber(corner, 3) +
                         ", normalized)"};
    }
    if (now >= corner) {
      const double scale = now / r;
      if (!(scale >= 1.0 / kMaxRadialScale && scale <= kMaxRadialScale)) {
        return {blamed(r), "the radial distortion scales the image corner by " +
                               FormatNumber(scale, 3) + " (r = " + FormatNumber(r, 3) +
                               " -> r_d = " + FormatNumber(corner, 3) +
                               ", normalized); at most a factor 3 either way"};
      }
      return {};
    }
    previous = now;
  }
  // r_d stays below the corner out to 10 corner radii: it compresses too much.
  return {blamed(kSteps * h), "the radial distortion squeezes the image corner by more than a "
                              "factor 3 (r_d(" + FormatNumber(kSteps * h, 3) + ") = " +
                              FormatNumber(previous, 3) + " < " + FormatNumber(corner, 3) + ")"};
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
