// The elliptical Gaussian fit of a spot (FitGaussian: Levenberg-Marquardt on
// b + A exp(-q/2) over the window's pixels) and the covariance of its centre
// when the speckle noise is correlated between pixels (SpeckleCovariance).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <Eigen/Dense>

#include "vision/spot_detection_internal.h"

namespace opl {
namespace spot_internal {
namespace {

// The symmetric part of a 2x2 block of an inverse: a solve against the
// identity is symmetric only to rounding, and a covariance handed on must be
// symmetric to the bit (MatchSpots and the bundle adjustment check it).
Eigen::Matrix2d SymmetricPart(const Eigen::Matrix2d& m) { return 0.5 * (m + m.transpose()); }

// A symmetric 2x2 matrix that is finite and positive definite.
bool IsPositiveDefinite(const Eigen::Matrix2d& c) {
  return c.allFinite() && c(0, 0) > 0 && c(1, 1) > 0 && c(0, 0) * c(1, 1) - c(0, 1) * c(1, 0) > 0;
}

// The weighted sum of squared residuals at t, keeping each pixel's
// exp(-q/2) in *e for Normal at the same t (the exponentials are most of a
// fit's work; Normal would compute the same values again).
double Cost(const std::vector<Pixel>& px, const Vec7& t, std::vector<double>* e) {
  e->resize(px.size());
  double c = 0;
  for (size_t i = 0; i < px.size(); ++i) {
    const Pixel& p = px[i];
    const double du = p.x - t(0), dv = p.y - t(1);
    const double q = t(4) * du * du + 2 * t(5) * du * dv + t(6) * dv * dv;
    (*e)[i] = std::exp(-0.5 * q);
    const double r = p.value - (t(3) + t(2) * (*e)[i]);
    c += p.weight * r * r;
  }
  return c;
}

// Normal equations at t; `exps` from Cost at the same t.
void Normal(const std::vector<Pixel>& px, const Vec7& t, const std::vector<double>& exps, Mat7* H,
            Vec7* g) {
  H->setZero();
  g->setZero();
  Vec7 j;
  for (size_t i = 0; i < px.size(); ++i) {
    const Pixel& p = px[i];
    const double du = p.x - t(0), dv = p.y - t(1);
    const double e = exps[i];
    const double Ae = t(2) * e;
    const double r = p.value - (t(3) + Ae);
    j(0) = Ae * (t(4) * du + t(5) * dv);
    j(1) = Ae * (t(5) * du + t(6) * dv);
    j(2) = e;
    j(3) = 1.0;
    j(4) = -0.5 * Ae * du * du;
    j(5) = -Ae * du * dv;
    j(6) = -0.5 * Ae * dv * dv;
    // The lower triangle of H += w j j^T, with the very operations of
    // Eigen's selfadjointView<Lower>().rankUpdate(j, w) (column c gets
    // (w j_c) j_r), so the fit is the same to the bit; written out because
    // Eigen's rank update of a fixed 7 x 7 is an out-of-line generic loop,
    // the largest single cost of DetectSpots on 18 MP images.
    for (int c = 0; c < 7; ++c) {
      const double wj = p.weight * j(c);
      for (int row = c; row < 7; ++row) (*H)(row, c) += wj * j(row);
    }
    g->noalias() += p.weight * r * j;
  }
  *H = H->selfadjointView<Eigen::Lower>();
}

bool Admissible(const Vec7& t) {
  return t.allFinite() && t(2) > 0 && t(4) > 0 && t(6) > 0 && t(4) * t(6) - t(5) * t(5) > 0;
}

// Jacobian row of the model at pixel p (see Normal) and the signal A e.
void ModelRow(const Pixel& p, const Vec7& t, Vec7* j, double* signal, double* residual) {
  const double du = p.x - t(0), dv = p.y - t(1);
  const double q = t(4) * du * du + 2 * t(5) * du * dv + t(6) * dv * dv;
  const double e = std::exp(-0.5 * q);
  const double Ae = t(2) * e;
  (*j)(0) = Ae * (t(4) * du + t(5) * dv);
  (*j)(1) = Ae * (t(5) * du + t(6) * dv);
  (*j)(2) = e;
  (*j)(3) = 1.0;
  (*j)(4) = -0.5 * Ae * du * du;
  (*j)(5) = -Ae * du * dv;
  (*j)(6) = -0.5 * Ae * dv * dv;
  *signal = Ae;
  *residual = p.value - (t(3) + Ae);
}

}  // namespace

FitResult FitGaussian(const std::vector<Pixel>& px, const Vec7& start, const Window& w,
                      int max_iterations) {
  FitResult out;
  if (px.size() < 12 || !Admissible(start)) return out;
  Vec7 t = start;
  std::vector<double> exps, trial_exps;  // of Cost at t, at the trial
  double cost = Cost(px, t, &exps);
  double lambda = 1e-3;
  Mat7 H;
  Vec7 g;
  bool converged = false;
  for (int it = 0; it < max_iterations && !converged; ++it) {
    Normal(px, t, exps, &H, &g);
    bool improved = false;
    for (int tries = 0; tries < 12 && !improved; ++tries) {
      Mat7 A = H;
      for (int i = 0; i < 7; ++i) A(i, i) += lambda * std::max(H(i, i), 1e-12);
      const Vec7 step = A.ldlt().solve(g);
      const Vec7 trial = t + step;
      if (!step.allFinite() || !Admissible(trial)) {
        lambda *= 10;
        continue;
      }
      const double trial_cost = Cost(px, trial, &trial_exps);
      if (trial_cost <= cost) {
        const double decrease = cost - trial_cost;
        t = trial;
        exps.swap(trial_exps);
        improved = true;
        lambda = std::max(lambda / 10, 1e-9);
        // Converged: the centre moves by less than 1e-5 px (far below its
        // noise) or the cost no longer decreases.
        if (decrease <= 1e-10 * cost || (std::fabs(step(0)) < 1e-5 && std::fabs(step(1)) < 1e-5)) {
          converged = true;
        }
        cost = trial_cost;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) converged = true;  // no descent direction left: at the minimum (or stuck)
  }
  // The fitted centre must stay inside the window, the spot not wider than it.
  if (!Admissible(t) || t(0) < w.x0 - 0.5 || t(0) > w.x1 + 0.5 || t(1) < w.y0 - 0.5 ||
      t(1) > w.y1 + 0.5) {
    return out;
  }
  Eigen::Matrix2d P;
  P << t(4), t(5), t(5), t(6);
  const Eigen::Matrix2d shape = P.inverse();
  const double half = 0.5 * std::max(w.x1 - w.x0 + 1, w.y1 - w.y0 + 1);
  if (!(shape(0, 0) < half * half && shape(1, 1) < half * half)) return out;
  Normal(px, t, exps, &H, &g);
  const Eigen::LDLT<Mat7> ldlt(H);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return out;
  const Mat7 inv = ldlt.solve(Mat7::Identity());
  const double dof = static_cast<double>(px.size()) - 7.0;
  out.reduced_chi2 = cost / dof;
  out.theta = t;
  out.u = t(0);
  out.v = t(1);
  out.amplitude = t(2);
  out.background = t(3);
  out.shape = shape;
  out.covariance = out.reduced_chi2 * SymmetricPart(inv.topLeftCorner<2, 2>());
  out.ok = IsPositiveDefinite(out.covariance);
  return out;
}

// Covariance of the centre of a fit weighted for speckle (weights w_i =
// 1 / (base_i + gamma^2 s_i^2)) when the speckle is correlated between
// pixels: the sandwich H^-1 M H^-1 with
//   M = sum_ij w_i w_j J_i J_j^T (delta_ij base_i + gamma^2 s_i s_j rho(d_ij)),
//   rho(d) = exp(-d^2 / (2 g^2)),
// g estimated from the lag-1 autocorrelation of the normalised residuals of
// the speckle-dominated pixels. Sets fit->covariance and fit->speckle_grain.
void SpeckleCovariance(const std::vector<Pixel>& px, const std::vector<double>& base_var,
                       double gamma2, double known_grain, const Window& w, FitResult* fit) {
  const Vec7& t = fit->theta;
  const int ww = w.x1 - w.x0 + 1, wh = w.y1 - w.y0 + 1;
  std::vector<int> index(static_cast<size_t>(ww * wh), -1);
  std::vector<Vec7> J(px.size());
  std::vector<double> sig(px.size()), z(px.size()), frac(px.size());
  Mat7 H = Mat7::Zero();
  for (size_t i = 0; i < px.size(); ++i) {
    double r = 0;
    ModelRow(px[i], t, &J[i], &sig[i], &r);
    z[i] = r * std::sqrt(px[i].weight);
    frac[i] = gamma2 * sig[i] * sig[i] * px[i].weight;  // speckle share of the variance
    H.noalias() += px[i].weight * J[i] * J[i].transpose();
    const int xi = static_cast<int>(px[i].x) - w.x0, yi = static_cast<int>(px[i].y) - w.y0;
    index[static_cast<size_t>(yi * ww + xi)] = static_cast<int>(i);
  }
  double num = 0, den = 0, fsum = 0;
  int pairs = 0;
  for (size_t i = 0; i < px.size(); ++i) {
    if (frac[i] < 0.8) continue;
    const int xi = static_cast<int>(px[i].x) - w.x0, yi = static_cast<int>(px[i].y) - w.y0;
    const int neighbours[2][2] = {{xi + 1, yi}, {xi, yi + 1}};
    for (const auto& n : neighbours) {
      if (n[0] >= ww || n[1] >= wh) continue;
      const int j = index[static_cast<size_t>(n[1] * ww + n[0])];
      if (j < 0 || frac[static_cast<size_t>(j)] < 0.8) continue;
      num += z[i] * z[static_cast<size_t>(j)];
      den += 0.5 * (z[i] * z[i] + z[static_cast<size_t>(j)] * z[static_cast<size_t>(j)]);
      fsum += 0.5 * (frac[i] + frac[static_cast<size_t>(j)]);
      ++pairs;
    }
  }
  double g2 = known_grain * known_grain;
  if (known_grain <= 0) {
    if (pairs < 8 || !(den > 0)) return;
    const double rho1 = std::clamp(num / den / (fsum / pairs), 0.0, 0.95);
    if (rho1 < 0.05) return;  // uncorrelated: the weighted fit's covariance holds
    g2 = -1.0 / (2.0 * std::log(rho1));
  }
  const int reach = static_cast<int>(std::ceil(3.0 * std::sqrt(g2)));
  const int side = 2 * reach + 1;
  std::vector<double> rho_table(static_cast<size_t>(side * side));
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      rho_table[static_cast<size_t>((dy + reach) * side + dx + reach)] =
          std::exp(-0.5 * (dx * dx + dy * dy) / g2);
    }
  }
  Mat7 M = Mat7::Zero();
  for (size_t i = 0; i < px.size(); ++i) {
    const int xi = static_cast<int>(px[i].x) - w.x0, yi = static_cast<int>(px[i].y) - w.y0;
    Vec7 acc = px[i].weight * base_var[i] * J[i];  // the uncorrelated part (j = i)
    for (int dy = -reach; dy <= reach; ++dy) {
      for (int dx = -reach; dx <= reach; ++dx) {
        const int xj = xi + dx, yj = yi + dy;
        if (xj < 0 || yj < 0 || xj >= ww || yj >= wh) continue;
        const int j = index[static_cast<size_t>(yj * ww + xj)];
        if (j < 0) continue;
        const double rho = rho_table[static_cast<size_t>((dy + reach) * side + dx + reach)];
        acc += px[static_cast<size_t>(j)].weight * gamma2 * sig[i] * sig[static_cast<size_t>(j)] *
               rho * J[static_cast<size_t>(j)];
      }
    }
    M.noalias() += px[i].weight * J[i] * acc.transpose();
  }
  const Eigen::LDLT<Mat7> ldlt(H);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return;
  const Mat7 Hinv = ldlt.solve(Mat7::Identity());
  const Mat7 C = Hinv * (0.5 * (M + M.transpose())) * Hinv;
  const Eigen::Matrix2d cov = SymmetricPart(C.topLeftCorner<2, 2>());
  if (IsPositiveDefinite(cov)) {
    fit->covariance = cov;
    fit->speckle_grain = std::sqrt(g2);
  }
}

}  // namespace spot_internal
}  // namespace opl
