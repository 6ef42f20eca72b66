#include "opl/vision/scene_frame.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "opl/core/format.h"

namespace opl {
namespace {

bool AllFinite(const Eigen::Vector3d& v) { return v.allFinite(); }

Status CheckCovariance(const Eigen::Matrix3d& cov, const char* name) {
  if (!cov.allFinite()) {
    return Status::InvalidArgument(std::string("ScaleFromArtifact: ") + name +
                                   " is not finite");
  }
  const double asym = (cov - cov.transpose()).cwiseAbs().maxCoeff();
  const double mag = std::max(cov.cwiseAbs().maxCoeff(), 1e-300);
  if (asym > 1e-9 * mag) {
    return Status::InvalidArgument(std::string("ScaleFromArtifact: ") + name +
                                   " is not symmetric (asymmetry " + FormatNumber(asym) + ")");
  }
  const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvalues()(0);
  if (min_eig < -1e-9 * mag) {
    return Status::InvalidArgument(std::string("ScaleFromArtifact: ") + name +
                                   " is not positive semi-definite (eigenvalue " +
                                   FormatNumber(min_eig) + ")");
  }
  return Status::Ok();
}

}  // namespace

Status SceneFrameOptions::Validate() const {
  if (!(min_relative_distance > 0.0 && min_relative_distance < 1.0)) {
    return Status::InvalidArgument("SceneFrameOptions.min_relative_distance = " +
                                   FormatNumber(min_relative_distance) +
                                   ": must be in (0, 1)");
  }
  if (!(min_angle_deg > 0.0 && min_angle_deg < 90.0)) {
    return Status::InvalidArgument("SceneFrameOptions.min_angle_deg = " +
                                   FormatNumber(min_angle_deg) + ": must be in (0, 90)");
  }
  return Status::Ok();
}

Result<Rigid3d> SceneFromThreePoints(const Eigen::Vector3d& a_in_old,
                                     const Eigen::Vector3d& b_in_old,
                                     const Eigen::Vector3d& c_in_old,
                                     const SceneFrameOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (!AllFinite(a_in_old) || !AllFinite(b_in_old) || !AllFinite(c_in_old)) {
    return Status::InvalidArgument("scene frame: a target (A, B or C) is not finite");
  }
  const double ab = (b_in_old - a_in_old).norm();
  const double ac = (c_in_old - a_in_old).norm();
  const double bc = (c_in_old - b_in_old).norm();
  const double size = std::max({ab, ac, bc});
  if (!(size > 0.0)) {
    return Status::InvalidArgument("scene frame: targets A, B and C coincide");
  }
  const double min_distance = options.min_relative_distance * size;
  if (ab <= min_distance) {
    return Status::InvalidArgument("scene frame: targets A and B coincide (|AB| = " +
                                   FormatNumber(ab) + ")");
  }
  if (ac <= min_distance || bc <= min_distance) {
    return Status::InvalidArgument("scene frame: target C coincides with " +
                                   std::string(ac <= min_distance ? "A" : "B") +
                                   " (distance " + FormatNumber(std::min(ac, bc)) + ")");
  }
  const Eigen::Vector3d x = (b_in_old - a_in_old) / ab;
  // Angle of C from the line AB seen from A and from B; the smaller one.
  const double sin_a = x.cross(c_in_old - a_in_old).norm() / ac;
  const double sin_b = x.cross(c_in_old - b_in_old).norm() / bc;
  const double angle_deg = std::asin(std::min(1.0, std::min(sin_a, sin_b))) * 180.0 / kPi;
  if (angle_deg < options.min_angle_deg) {
    return Status::InvalidArgument("scene frame: targets A, B, C are collinear (C is " +
                                   FormatNumber(angle_deg, 4) + " deg from line AB, below " +
                                   FormatNumber(options.min_angle_deg) + " deg)");
  }
  double rows[9];
  ThreePointFrame(a_in_old.data(), b_in_old.data(), c_in_old.data(), rows);
  Eigen::Matrix3d R;
  R << rows[0], rows[1], rows[2], rows[3], rows[4], rows[5], rows[6], rows[7], rows[8];
  return Rigid3d(R, -(R * a_in_old));
}

Rigid3d CamFromNewScene(const Rigid3d& cam_from_old_scene, const Rigid3d& new_scene_from_old,
                        double scale) {
  const Eigen::Quaterniond q = cam_from_old_scene.rotation * new_scene_from_old.rotation.conjugate();
  const Eigen::Vector3d t =
      scale * (cam_from_old_scene.translation - (q * new_scene_from_old.translation));
  return Rigid3d(q, t);
}

Status TransformScene(const Rigid3d& new_scene_from_old, double scale,
                      std::vector<Camera>* cameras,
                      std::vector<Eigen::Vector3d>* points_in_scene) {
  if (!(std::isfinite(scale) && scale > 0.0)) {
    return Status::InvalidArgument("TransformScene: scale = " + FormatNumber(scale) +
                                   ": must be positive and finite");
  }
  if (!new_scene_from_old.rotation.coeffs().allFinite() ||
      !new_scene_from_old.translation.allFinite()) {
    return Status::InvalidArgument("TransformScene: new_scene_from_old is not finite");
  }
  if (cameras != nullptr) {
    for (Camera& c : *cameras) {
      c.cam_from_scene = CamFromNewScene(c.cam_from_scene, new_scene_from_old, scale);
    }
  }
  if (points_in_scene != nullptr) {
    for (Eigen::Vector3d& p : *points_in_scene) p = scale * (new_scene_from_old * p);
  }
  return Status::Ok();
}

Result<ArtifactScale> ScaleFromArtifact(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                                        double calibrated_length, const Eigen::Matrix3d& cov1,
                                        const Eigen::Matrix3d& cov2,
                                        double calibrated_length_sigma) {
  if (!AllFinite(p1) || !AllFinite(p2)) {
    return Status::InvalidArgument("ScaleFromArtifact: an artifact target is not finite");
  }
  if (!(std::isfinite(calibrated_length) && calibrated_length > 0.0)) {
    return Status::InvalidArgument("ScaleFromArtifact: calibrated_length = " +
                                   FormatNumber(calibrated_length) +
                                   ": must be positive and finite");
  }
  if (!(std::isfinite(calibrated_length_sigma) && calibrated_length_sigma >= 0.0)) {
    return Status::InvalidArgument("ScaleFromArtifact: calibrated_length_sigma = " +
                                   FormatNumber(calibrated_length_sigma) +
                                   ": must be non-negative and finite");
  }
  OPL_RETURN_IF_ERROR(CheckCovariance(cov1, "cov1"));
  OPL_RETURN_IF_ERROR(CheckCovariance(cov2, "cov2"));
  const double length = (p2 - p1).norm();
  if (!(length > 0.0)) {
    return Status::InvalidArgument("ScaleFromArtifact: the two targets coincide");
  }
  const Eigen::Vector3d u = (p2 - p1) / length;
  ArtifactScale out;
  out.measured_length = length;
  out.measured_length_sigma = std::sqrt(std::max(0.0, u.dot((cov1 + cov2) * u)));
  out.scale = calibrated_length / length;
  const double rel_measured = out.measured_length_sigma / length;
  const double rel_cal = calibrated_length_sigma / calibrated_length;
  out.scale_sigma = out.scale * std::sqrt(rel_measured * rel_measured + rel_cal * rel_cal);
  return out;
}

}  // namespace opl
