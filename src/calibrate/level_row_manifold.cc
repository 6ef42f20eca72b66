#include "opl/calibrate/level_row_manifold.h"

#include <cmath>

#include <Eigen/LU>

namespace opl {

Eigen::MatrixXd LevelRowManifold::OrthogonalBasis(const Eigen::VectorXd& az) {
  const int m = static_cast<int>(az.size());
  // Householder H = I - 2 v v^T / (v^T v) maps az to -+|az| e_1; its columns
  // 2..m are orthonormal and orthogonal to az.
  Eigen::VectorXd v = az;
  const double norm = az.norm();
  v(0) += az(0) >= 0.0 ? norm : -norm;
  const double vv = v.squaredNorm();
  Eigen::MatrixXd H = Eigen::MatrixXd::Identity(m, m);
  if (vv > 0.0) H -= (2.0 / vv) * v * v.transpose();
  return H.rightCols(m - 1);
}

void LevelRowManifold::Project(const double* az, double* el, int m) {
  Eigen::Map<const Eigen::VectorXd> a(az, m);
  Eigen::Map<Eigen::VectorXd> e(el, m);
  const double aa = a.squaredNorm();
  if (aa > 0.0) e -= (a.dot(e) / aa) * a;
}

bool LevelRowManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  Eigen::Map<const Eigen::VectorXd> az(x, m_), el(x + m_, m_);
  Eigen::Map<const Eigen::VectorXd> da(delta, m_), de(delta + m_, m_ - 1);
  Eigen::Map<Eigen::VectorXd> a_new(x_plus_delta, m_), e_new(x_plus_delta + m_, m_);
  const Eigen::VectorXd a = az + da;
  if (!(a.squaredNorm() > 0.0)) return false;
  e_new = el + OrthogonalBasis(az) * de;
  a_new = a;
  Project(x_plus_delta, x_plus_delta + m_, m_);
  return true;
}

Eigen::MatrixXd LevelRowManifold::PlusJacobianAt(const double* x) const {
  Eigen::Map<const Eigen::VectorXd> az(x, m_), el(x + m_, m_);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(2 * m_, 2 * m_ - 1);
  J.topLeftCorner(m_, m_).setIdentity();
  // el' = e' - (a'.e'/|a'|^2) a'; at delta = 0 (a'.e' = 0):
  //   d el' / d da = -(1/|a|^2) a el^T,   d el' / d de = B(az).
  const double aa = az.squaredNorm();
  J.bottomLeftCorner(m_, m_) = -(1.0 / aa) * az * el.transpose();
  J.bottomRightCorner(m_, m_ - 1) = OrthogonalBasis(az);
  return J;
}

bool LevelRowManifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      jacobian, 2 * m_, 2 * m_ - 1) = PlusJacobianAt(x);
  return true;
}

bool LevelRowManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  Eigen::Map<const Eigen::VectorXd> ya(y, m_), ye(y + m_, m_), xa(x, m_), xe(x + m_, m_);
  // The inverse of Plus: da = ya - xa, and de with xe + B de = ye + c ya for
  // some c (ye is the projection of xe + B de along ya).
  Eigen::Map<Eigen::VectorXd>(y_minus_x, m_) = ya - xa;
  Eigen::MatrixXd A(m_, m_);
  A.leftCols(m_ - 1) = OrthogonalBasis(xa);
  A.col(m_ - 1) = -ya;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(A);
  const Eigen::VectorXd sol = lu.solve(Eigen::VectorXd(ye - xe));
  if (!sol.allFinite()) return false;
  Eigen::Map<Eigen::VectorXd>(y_minus_x + m_, m_ - 1) = sol.head(m_ - 1);
  return true;
}

bool LevelRowManifold::MinusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<const Eigen::VectorXd> xa(x, m_);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(2 * m_ - 1, 2 * m_);
  J.topLeftCorner(m_, m_).setIdentity();
  J.bottomRightCorner(m_ - 1, m_) = OrthogonalBasis(xa).transpose();
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      jacobian, 2 * m_ - 1, 2 * m_) = J;
  return true;
}

}  // namespace opl
