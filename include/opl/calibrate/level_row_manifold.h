// LevelRowManifold: the (az, el) of the m non-central beams of a source's
// central row, constrained to be "level": sum_j az_j el_j = 0. With the
// central beam at az = el = 0 this fixes the roll of a calibration exactly
// (the gauge of method.md; see docs/calibrate.md, "Gauge").
//
// Why not the plain mean elevation: a roll phi about the central beam changes
// each row elevation by about -phi az_j; for a row symmetric about the central
// beam those changes cancel in the mean, so "mean elevation 0" leaves the roll
// free. The level condition is the least-squares reading of the same idea:
// the row's elevations have zero regression slope against azimuth through the
// central beam, i.e. the roll minimising sum_j el_j^2.
//
// Ambient x = (az_1..az_m, el_1..el_m) with az . el = 0 and az != 0; tangent
// size 2m - 1:
//   Plus(x, (da, de)) : a' = az + da,  e' = el + B(az) de,
//                       el' = e' - (a' . e' / |a'|^2) a'      (projection)
// where the columns of B(az) (m x (m-1)) are an orthonormal basis of the
// vectors orthogonal to az (a Householder reflection), so at delta = 0 the
// tangent metric is the ambient one restricted to the constraint.
#pragma once

#include <ceres/manifold.h>
#include <Eigen/Core>

namespace opl {

class LevelRowManifold final : public ceres::Manifold {
 public:
  explicit LevelRowManifold(int m) : m_(m) {}

  int AmbientSize() const override { return 2 * m_; }
  int TangentSize() const override { return 2 * m_ - 1; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;

  // B(az): m x (m-1), orthonormal columns orthogonal to az (az != 0).
  static Eigen::MatrixXd OrthogonalBasis(const Eigen::VectorXd& az);
  // d Plus / d delta at delta = 0, 2m x (2m-1) (column-major Eigen matrix).
  Eigen::MatrixXd PlusJacobianAt(const double* x) const;
  // Projects el onto the constraint: el - (az . el / |az|^2) az.
  static void Project(const double* az, double* el, int m);

 private:
  int m_;
};

}  // namespace opl
