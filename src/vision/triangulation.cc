#include "opl/vision/triangulation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <ceres/jet.h>
#include <Eigen/Dense>

#include "opl/core/format.h"

namespace opl {
namespace {

using Jet3 = ceres::Jet<double, 3>;

// Pixel of `point_in_scene` in `camera` and its 2x3 Jacobian; false behind.
bool ProjectWithJacobian(const Camera& camera, const Eigen::Vector3d& point_in_scene,
                         Eigen::Vector2d* pixel, Eigen::Matrix<double, 2, 3>* J) {
  const auto packed_d = camera.intrinsics.Packed();
  Jet3 packed[kNumCameraParameters];
  for (int i = 0; i < kNumCameraParameters; ++i) packed[i] = Jet3(packed_d[static_cast<size_t>(i)]);
  Jet3 X[3];
  for (int i = 0; i < 3; ++i) X[i] = Jet3(point_in_scene(i), i);
  const Eigen::Matrix3d R = camera.cam_from_scene.RotationMatrix();
  const Eigen::Vector3d& t = camera.cam_from_scene.translation;
  Jet3 Xc[3];
  for (int r = 0; r < 3; ++r) {
    Xc[r] = Jet3(t(r));
    for (int c = 0; c < 3; ++c) Xc[r] += R(r, c) * X[c];
  }
  Jet3 px[2];
  if (!ProjectPointInCamera(packed, Xc, px)) return false;
  for (int r = 0; r < 2; ++r) {
    (*pixel)(r) = px[r].a;
    J->row(r) = px[r].v.transpose();
  }
  return true;
}

double DistanceToNearestCamera(const std::vector<Eigen::Vector3d>& centers,
                               const Eigen::Vector3d& X) {
  double d = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& c : centers) d = std::min(d, (X - c).norm());
  return d;
}

double LargestRayAngleDeg(const std::vector<Eigen::Vector3d>& centers, const Eigen::Vector3d& X) {
  double best = 0.0;
  for (size_t i = 0; i < centers.size(); ++i) {
    const Eigen::Vector3d di = (X - centers[i]).normalized();
    for (size_t j = i + 1; j < centers.size(); ++j) {
      const Eigen::Vector3d dj = (X - centers[j]).normalized();
      best = std::max(best, std::atan2(di.cross(dj).norm(), di.dot(dj)));
    }
  }
  return best * 180.0 / kPi;
}

}  // namespace

Status TriangulationOptions::Validate() const {
  if (!(min_triangulation_angle_deg >= 0.0 && min_triangulation_angle_deg < 90.0)) {
    return Status::InvalidArgument("TriangulationOptions.min_triangulation_angle_deg = " +
                                   FormatNumber(min_triangulation_angle_deg) +
                                   ": must be in [0, 90)");
  }
  if (max_iterations < 1) {
    return Status::InvalidArgument("TriangulationOptions.max_iterations = " +
                                   std::to_string(max_iterations) + ": must be >= 1");
  }
  if (!(step_tolerance > 0.0 && step_tolerance < 1.0)) {
    return Status::InvalidArgument("TriangulationOptions.step_tolerance = " +
                                   FormatNumber(step_tolerance) + ": must be in (0, 1)");
  }
  return Status::Ok();
}

std::string TriangulatedPoint::ToText() const {
  const Eigen::Vector3d sigma = covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  return "point " + FormatTriple("%.6f", point_in_scene) + " sigma " +
         FormatTriple("%.3g", sigma) + ", " + std::to_string(residuals_px.size()) +
         " views, rms residual " + FormatPrintf("%.4f", rms_residual_px) + " px, angle " +
         FormatPrintf("%.2f", triangulation_angle_deg) + " deg";
}

Result<TriangulatedPoint> TriangulatePoint(const std::vector<PointObservation>& observations,
                                           const TriangulationOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  const size_t n = observations.size();
  if (n < 2) {
    return Status::InvalidArgument("triangulation: " + std::to_string(n) +
                                   " view(s) given, at least 2 are needed");
  }
  std::vector<Eigen::Matrix2d> weights(n);
  std::vector<Eigen::Vector3d> centers(n);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const PointObservation& o = observations[i];
    const std::string view = "triangulation: view " + std::to_string(i);
    if (o.camera == nullptr) return Status::InvalidArgument(view + ": camera is null");
    const Status camera_ok = o.camera->intrinsics.Validate();
    if (!camera_ok.ok()) return Status::InvalidArgument(view + ": " + camera_ok.message());
    if (!o.camera->cam_from_scene.rotation.coeffs().allFinite() ||
        !o.camera->cam_from_scene.translation.allFinite()) {
      return Status::InvalidArgument(view + ": camera pose is not finite");
    }
    if (!o.pixel_px.allFinite()) {
      return Status::InvalidArgument(view + ": pixel is not finite");
    }
    const Eigen::Matrix2d& S = o.covariance_px2;
    if (!S.allFinite() || std::abs(S(0, 1) - S(1, 0)) > 1e-12 * S.cwiseAbs().maxCoeff()) {
      return Status::InvalidArgument(view + ": pixel covariance is not finite and symmetric");
    }
    Eigen::LLT<Eigen::Matrix2d> llt(S);
    if (llt.info() != Eigen::Success || !(S.determinant() > 0.0)) {
      return Status::InvalidArgument(view + ": pixel covariance is not positive definite");
    }
    weights[i] = llt.solve(Eigen::Matrix2d::Identity());
    const Result<Eigen::Vector2d> xy = UndistortPixel(o.camera->intrinsics, o.pixel_px);
    if (!xy.ok()) {
      return Status::NoSolution(view + ": pixel " + FormatNumber(o.pixel_px.x()) + ", " +
                                FormatNumber(o.pixel_px.y()) +
                                " cannot be undistorted: " + xy.status().message());
    }
    const Eigen::Matrix3d R = o.camera->cam_from_scene.RotationMatrix();
    const Eigen::Vector3d d = (R.transpose() * Eigen::Vector3d(xy->x(), xy->y(), 1.0)).normalized();
    centers[i] = o.camera->CenterInScene();
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - d * d.transpose();
    A += P;
    b += P * centers[i];
  }
  // Linear start: the midpoint of all rays.
  Eigen::Vector3d X = A.ldlt().solve(b);
  const double angle0 = LargestRayAngleDeg(centers, X);
  if (!X.allFinite() || angle0 < options.min_triangulation_angle_deg) {
    return Status::NoSolution("triangulation: rays nearly parallel: triangulation angle " +
                              FormatNumber(std::isfinite(angle0) ? angle0 : 0.0, 4) +
                              " deg, below min_triangulation_angle_deg = " +
                              FormatNumber(options.min_triangulation_angle_deg));
  }

  TriangulatedPoint out;
  out.residuals_px.resize(n);
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  auto linearize = [&](const Eigen::Vector3d& at, Eigen::Vector3d* g, double* chi2) -> Status {
    H.setZero();
    g->setZero();
    *chi2 = 0.0;
    for (size_t i = 0; i < n; ++i) {
      Eigen::Vector2d px;
      Eigen::Matrix<double, 2, 3> J;
      if (!ProjectWithJacobian(*observations[i].camera, at, &px, &J)) {
        return Status::NoSolution("triangulation: point behind camera of view " +
                                  std::to_string(i) +
                                  (observations[i].camera->name.empty()
                                       ? std::string()
                                       : " ('" + observations[i].camera->name + "')"));
      }
      const Eigen::Vector2d r = px - observations[i].pixel_px;
      out.residuals_px[i] = r;
      H += J.transpose() * weights[i] * J;
      *g += J.transpose() * weights[i] * r;
      *chi2 += r.dot(weights[i] * r);
    }
    return Status::Ok();
  };
  Eigen::Vector3d g;
  double chi2 = 0.0;
  OPL_RETURN_IF_ERROR(linearize(X, &g, &chi2));
  bool converged = false;
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    const Eigen::Vector3d step = -H.ldlt().solve(g);
    if (!step.allFinite()) break;
    X += step;
    out.iterations = iter + 1;
    OPL_RETURN_IF_ERROR(linearize(X, &g, &chi2));
    if (step.norm() <= options.step_tolerance * DistanceToNearestCamera(centers, X)) {
      converged = true;
      break;
    }
  }
  if (!converged) {
    // Noisy data converge in a few iterations; a step that keeps moving at
    // 1e-12 relative after max_iterations is round-off: accept it when the
    // gradient is negligible, else fail.
    const Eigen::Vector3d step = -H.ldlt().solve(g);
    if (!step.allFinite() || step.norm() > 1e-9 * DistanceToNearestCamera(centers, X)) {
      return Status::NoSolution("triangulation: Gauss-Newton did not converge in " +
                                std::to_string(options.max_iterations) + " iterations");
    }
  }
  out.point_in_scene = X;
  Eigen::LDLT<Eigen::Matrix3d> ldlt(H);
  out.covariance = ldlt.solve(Eigen::Matrix3d::Identity());
  out.chi2 = chi2;
  out.variance_factor = n > 2 ? chi2 / static_cast<double>(2 * n - 3) : 0.0;
  double sum_sq = 0.0;
  for (const Eigen::Vector2d& r : out.residuals_px) sum_sq += r.squaredNorm();
  out.rms_residual_px = std::sqrt(sum_sq / static_cast<double>(2 * n));
  out.triangulation_angle_deg = LargestRayAngleDeg(centers, X);
  if (out.triangulation_angle_deg < options.min_triangulation_angle_deg) {
    return Status::NoSolution("triangulation: rays nearly parallel: triangulation angle " +
                              FormatNumber(out.triangulation_angle_deg, 4) +
                              " deg, below min_triangulation_angle_deg = " +
                              FormatNumber(options.min_triangulation_angle_deg));
  }
  return out;
}

}  // namespace opl
