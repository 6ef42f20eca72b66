#include "opl/uncertainty/cramer_rao.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"

namespace opl {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;

Status CheckGeometry(const SourceSpotGeometry& g) {
  if (g.points_in_scene.size() != g.covariances.size()) {
    return Status::InvalidArgument(std::to_string(g.points_in_scene.size()) + " points but " +
                                   std::to_string(g.covariances.size()) + " covariances");
  }
  const Eigen::Vector3d& o = g.scene_from_source.translation;
  for (size_t k = 0; k < g.points_in_scene.size(); ++k) {
    const Eigen::Vector3d d = g.points_in_scene[k] - o;
    if (!d.allFinite() || d.norm() == 0.0) {
      return Status::InvalidArgument("spot " + std::to_string(k) +
                                     ": not finite or at the projection origin");
    }
    const Eigen::Matrix3d& s = g.covariances[k];
    if (!s.allFinite() || (s - s.transpose()).cwiseAbs().maxCoeff() > 1e-12 * s.cwiseAbs().maxCoeff() ||
        s.llt().info() != Eigen::Success) {
      return Status::InvalidArgument("spot " + std::to_string(k) +
                                     ": covariance not symmetric positive definite");
    }
  }
  return Status::Ok();
}

// A_k = dp_k / d(dtheta, do).
Matrix36d PointJacobian(const Eigen::Vector3d& point, const Eigen::Vector3d& origin) {
  Matrix36d a;
  a.leftCols<3>() = -Skew(point - origin);
  a.rightCols<3>() = Eigen::Matrix3d::Identity();
  return a;
}

// The inverse of a symmetric positive definite 6 x 6 matrix, Jacobi-scaled
// first (rotation and origin blocks differ by the squared scene size);
// NoSolution when it is singular to double precision.
Result<Matrix6d> InverseOf(const Matrix6d& information) {
  const Eigen::Matrix<double, 6, 1> d = information.diagonal();
  if (!(d.minCoeff() > 0.0) || !information.allFinite()) {
    return Status::NoSolution("the spots do not determine the pose (singular information)");
  }
  const Eigen::Matrix<double, 6, 1> s = d.cwiseSqrt().cwiseInverse();
  const Matrix6d scaled = s.asDiagonal() * information * s.asDiagonal();
  Eigen::LDLT<Matrix6d> ldlt(scaled);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 1e-14) {
    return Status::NoSolution("the spots do not determine the pose (singular information)");
  }
  const Matrix6d inverse = s.asDiagonal() * ldlt.solve(Matrix6d::Identity()) * s.asDiagonal();
  return Matrix6d(0.5 * (inverse + inverse.transpose()));
}

}  // namespace

const char* SpotWeightingName(SpotWeighting weighting) {
  return weighting == SpotWeighting::kEfficient ? "efficient" : "unweighted";
}

Result<SpotWeighting> ParseSpotWeighting(const std::string& text) {
  if (text == "efficient") return SpotWeighting::kEfficient;
  if (text == "unweighted") return SpotWeighting::kUnweighted;
  return Status::InvalidArgument("unknown weighting '" + text + "' (known: efficient, unweighted)");
}

Result<Matrix6d> PoseCramerRaoBound(const SourceSpotGeometry& geometry) {
  OPL_RETURN_IF_ERROR(CheckGeometry(geometry));
  const Eigen::Vector3d& o = geometry.scene_from_source.translation;
  Matrix6d information = Matrix6d::Zero();
  for (size_t k = 0; k < geometry.points_in_scene.size(); ++k) {
    const Eigen::Vector3d& p = geometry.points_in_scene[k];
    const Eigen::Matrix3d sigma_inv = geometry.covariances[k].inverse();
    const Eigen::Vector3d u = (p - o).normalized();  // dp/dt_k up to its length
    const Eigen::Vector3d w = sigma_inv * u;
    const Eigen::Matrix3d projected = sigma_inv - w * w.transpose() / u.dot(w);
    const Matrix36d a = PointJacobian(p, o);
    information.noalias() += a.transpose() * projected * a;
  }
  return InverseOf(information);
}

Result<Matrix6d> PoseFirstOrderCovariance(const SourceSpotGeometry& geometry,
                                           SpotWeighting weighting) {
  OPL_RETURN_IF_ERROR(CheckGeometry(geometry));
  const Eigen::Vector3d& o = geometry.scene_from_source.translation;
  const Eigen::Matrix3d r_t = geometry.scene_from_source.RotationMatrix().transpose();
  Matrix6d h = Matrix6d::Zero();
  Matrix6d meat = Matrix6d::Zero();
  for (size_t k = 0; k < geometry.points_in_scene.size(); ++k) {
    const Eigen::Vector3d& p = geometry.points_in_scene[k];
    const Eigen::Matrix<double, 2, 3> f = AzElJacobian(r_t * (p - o)) * r_t;
    const Eigen::Matrix2d angular_cov = f * geometry.covariances[k] * f.transpose();
    const Eigen::Matrix2d w = weighting == SpotWeighting::kEfficient
                                  ? Eigen::Matrix2d(angular_cov.inverse())
                                  : Eigen::Matrix2d::Identity();
    const Eigen::Matrix<double, 2, 6> g = f * PointJacobian(p, o);
    h.noalias() += g.transpose() * w * g;
    meat.noalias() += g.transpose() * w * angular_cov * w * g;
  }
  Result<Matrix6d> h_inv = InverseOf(h);
  if (!h_inv.ok()) return h_inv.status();
  const Matrix6d c = *h_inv * meat * *h_inv;
  return Matrix6d(0.5 * (c + c.transpose()));
}

double LengthStd(const Eigen::Vector3d& origin_i, const Eigen::Matrix3d& cov_i,
                 const Eigen::Vector3d& origin_j, const Eigen::Matrix3d& cov_j) {
  const Eigen::Vector3d d = origin_i - origin_j;
  const double length = d.norm();
  if (!(length > 0.0)) return 0.0;
  const Eigen::Vector3d g = d / length;
  return std::sqrt(std::max(0.0, g.dot((cov_i + cov_j) * g)));
}

}  // namespace opl
