#include "opl/locate/p3p.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>

namespace opl {
namespace {

// Real roots of c3 g^3 + c2 g^2 + c1 g + c0; returns their count.
int RealCubicRoots(double c3, double c2, double c1, double c0, double roots[3]) {
  const double scale = std::max({std::abs(c3), std::abs(c2), std::abs(c1), std::abs(c0)});
  if (scale == 0.0) return 0;
  if (std::abs(c3) < 1e-14 * scale) {
    // Quadratic (or linear).
    if (std::abs(c2) < 1e-14 * scale) {
      if (c1 == 0.0) return 0;
      roots[0] = -c0 / c1;
      return 1;
    }
    const double disc = c1 * c1 - 4.0 * c2 * c0;
    if (disc < 0.0) return 0;
    const double q = -0.5 * (c1 + std::copysign(std::sqrt(disc), c1));
    roots[0] = q / c2;
    roots[1] = q != 0.0 ? c0 / q : roots[0];
    return 2;
  }
  const double a = c2 / c3, b = c1 / c3, c = c0 / c3;
  // Depressed cubic x^3 + p x + q with g = x - a/3.
  const double p = b - a * a / 3.0;
  const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
  const double disc = q * q / 4.0 + p * p * p / 27.0;
  int n = 0;
  if (disc > 0.0) {
    const double s = std::sqrt(disc);
    roots[n++] = std::cbrt(-q / 2.0 + s) + std::cbrt(-q / 2.0 - s) - a / 3.0;
  } else {
    const double r = std::sqrt(std::max(0.0, -p / 3.0));
    const double arg = (r > 0.0) ? std::clamp(-q / (2.0 * r * r * r), -1.0, 1.0) : 0.0;
    const double phi = std::acos(arg);
    for (int k = 0; k < 3; ++k) {
      roots[n++] = 2.0 * r * std::cos((phi - 2.0 * M_PI * k) / 3.0) - a / 3.0;
    }
  }
  // One Newton step each on the original polynomial.
  for (int i = 0; i < n; ++i) {
    const double g = roots[i];
    const double f = ((c3 * g + c2) * g + c1) * g + c0;
    const double df = (3.0 * c3 * g + 2.0 * c2) * g + c1;
    if (df != 0.0) roots[i] = g - f / df;
  }
  return n;
}

// Newton steps on F_ij = l_i^2 + l_j^2 - 2 b_ij l_i l_j - a_ij.
void PolishDistances(const double a[3], const double b[3], Eigen::Vector3d* lambda) {
  // Pair order: (0,1) -> a[0], b[0]; (0,2) -> a[1], b[1]; (1,2) -> a[2], b[2].
  Eigen::Vector3d& l = *lambda;
  for (int it = 0; it < 3; ++it) {
    Eigen::Vector3d F;
    F(0) = l(0) * l(0) + l(1) * l(1) - 2.0 * b[0] * l(0) * l(1) - a[0];
    F(1) = l(0) * l(0) + l(2) * l(2) - 2.0 * b[1] * l(0) * l(2) - a[1];
    F(2) = l(1) * l(1) + l(2) * l(2) - 2.0 * b[2] * l(1) * l(2) - a[2];
    Eigen::Matrix3d J;
    J << 2.0 * (l(0) - b[0] * l(1)), 2.0 * (l(1) - b[0] * l(0)), 0.0,
        2.0 * (l(0) - b[1] * l(2)), 0.0, 2.0 * (l(2) - b[1] * l(0)),
        0.0, 2.0 * (l(1) - b[2] * l(2)), 2.0 * (l(2) - b[2] * l(1));
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-300)) return;
    const Eigen::Vector3d step = J.inverse() * F;
    l -= step;
    if (step.norm() <= 1e-15 * l.norm()) return;
  }
}

}  // namespace

int SolveP3P(const std::array<Eigen::Vector3d, 3>& f, const std::array<Eigen::Vector3d, 3>& X,
             std::array<PoseRt, 4>* solutions) {
  // Squared scene distances and bearing cosines of the pairs (0,1), (0,2), (1,2).
  const Eigen::Vector3d d01 = X[0] - X[1], d02 = X[0] - X[2];
  const double a[3] = {d01.squaredNorm(), d02.squaredNorm(), (X[1] - X[2]).squaredNorm()};
  const double b[3] = {f[0].dot(f[1]), f[0].dot(f[2]), f[1].dot(f[2])};
  if (!(a[0] > 0.0 && a[1] > 0.0 && a[2] > 0.0)) return 0;

  // Quadratic forms of the three equations: Lambda^T M_ij Lambda = a_ij.
  Eigen::Matrix3d M01 = Eigen::Matrix3d::Zero(), M02 = Eigen::Matrix3d::Zero(),
                  M12 = Eigen::Matrix3d::Zero();
  M01(0, 0) = M01(1, 1) = 1.0;
  M01(0, 1) = M01(1, 0) = -b[0];
  M02(0, 0) = M02(2, 2) = 1.0;
  M02(0, 2) = M02(2, 0) = -b[1];
  M12(1, 1) = M12(2, 2) = 1.0;
  M12(1, 2) = M12(2, 1) = -b[2];
  // Homogeneous combinations: Lambda^T D Lambda = 0.
  const Eigen::Matrix3d D1 = a[2] * M01 - a[0] * M12;
  const Eigen::Matrix3d D2 = a[2] * M02 - a[1] * M12;

  // det(D1 + g D2) = c3 g^3 + c2 g^2 + c1 g + c0, from its values at 0, +-1, inf.
  const double c0 = D1.determinant();
  const double c3 = D2.determinant();
  const double p_plus = (D1 + D2).determinant();
  const double p_minus = (D1 - D2).determinant();
  const double c2 = 0.5 * (p_plus + p_minus) - c0;
  const double c1 = 0.5 * (p_plus - p_minus) - c3;
  double gammas[3];
  const int num_gammas = RealCubicRoots(c3, c2, c1, c0, gammas);

  // Scene-side basis for the rotation.
  Eigen::Matrix3d XX;
  XX << d01, d02, d01.cross(d02);
  const double det_xx = XX.determinant();
  if (!(std::abs(det_xx) > 1e-12 * a[0] * std::sqrt(a[0] * a[1]))) return 0;
  const Eigen::Matrix3d XX_inv = XX.inverse();

  int count = 0;
  for (int gi = 0; gi < num_gammas && count == 0; ++gi) {
    const Eigen::Matrix3d D0 = D1 + gammas[gi] * D2;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(D0);
    const Eigen::Vector3d& ev = eig.eigenvalues();  // ascending
    // A degenerate conic that is a real line pair has eigenvalues of opposite
    // sign around the zero one: ev(0) < 0 < ev(2).
    if (!(ev(0) < 0.0 && ev(2) > 0.0)) continue;
    const Eigen::Vector3d v_neg = eig.eigenvectors().col(0);
    const Eigen::Vector3d v_pos = eig.eigenvectors().col(2);
    const double k = std::sqrt(-ev(0) / ev(2));
    for (int sign = -1; sign <= 1; sign += 2) {
      // Lambda^T D0 Lambda = ev2 (v_pos.L)^2 + ev0 (v_neg.L)^2 = 0
      //   =>  (v_pos + sign k v_neg) . Lambda = 0.
      const Eigen::Vector3d u = v_pos + sign * k * v_neg;
      int i = 0;
      u.cwiseAbs().maxCoeff(&i);
      const int j = (i + 1) % 3, kk = (i + 2) % 3;
      // lambda_i = alpha lambda_j + beta lambda_k; tau = lambda_k / lambda_j.
      const double alpha = -u(j) / u(i), beta = -u(kk) / u(i);
      auto pair_index = [](int p, int q) { return (p + q) - 1; };  // (0,1)->0 (0,2)->1 (1,2)->2
      const double a_ij = a[pair_index(i, j)], b_ij = b[pair_index(i, j)];
      const double a_jk = a[pair_index(j, kk)], b_jk = b[pair_index(j, kk)];
      // a_ij (1 + tau^2 - 2 b_jk tau) = a_jk (w^2 + 1 - 2 b_ij w), w = alpha + beta tau.
      const double qa = a_ij - a_jk * beta * beta;
      const double qb = -2.0 * a_ij * b_jk - a_jk * (2.0 * alpha * beta - 2.0 * b_ij * beta);
      const double qc = a_ij - a_jk * (alpha * alpha + 1.0 - 2.0 * b_ij * alpha);
      double taus[2];
      int num_taus = 0;
      if (std::abs(qa) < 1e-14 * (std::abs(qb) + std::abs(qc))) {
        if (qb != 0.0) taus[num_taus++] = -qc / qb;
      } else {
        const double disc = qb * qb - 4.0 * qa * qc;
        if (disc >= -1e-12 * qb * qb) {
          const double sq = std::sqrt(std::max(0.0, disc));
          const double qq = -0.5 * (qb + std::copysign(sq, qb));
          taus[num_taus++] = qq / qa;
          if (qq != 0.0) taus[num_taus++] = qc / qq;
        }
      }
      for (int ti = 0; ti < num_taus && count < 4; ++ti) {
        const double tau = taus[ti];
        if (!(tau > 0.0)) continue;
        const double den = 1.0 + tau * tau - 2.0 * b_jk * tau;
        if (!(den > 0.0)) continue;
        Eigen::Vector3d lambda;
        lambda(j) = std::sqrt(a_jk / den);
        lambda(kk) = tau * lambda(j);
        lambda(i) = (alpha + beta * tau) * lambda(j);
        if (!(lambda(i) > 0.0)) continue;
        PolishDistances(a, b, &lambda);
        if (!(lambda.minCoeff() > 0.0)) continue;
        const Eigen::Vector3d y01 = lambda(0) * f[0] - lambda(1) * f[1];
        const Eigen::Vector3d y02 = lambda(0) * f[0] - lambda(2) * f[2];
        Eigen::Matrix3d YY;
        YY << y01, y02, y01.cross(y02);
        Eigen::Matrix3d R = YY * XX_inv;
        if (!(R.determinant() > 0.0) || !R.allFinite()) continue;
        // Project onto SO(3) (exact input gives an exact rotation already).
        R = Eigen::Quaterniond(R).normalized().toRotationMatrix();
        PoseRt& pose = (*solutions)[count++];
        pose.R = R;
        pose.t = lambda(0) * f[0] - R * X[0];
      }
    }
  }
  return count;
}

}  // namespace opl
