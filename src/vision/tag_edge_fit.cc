// Private to src/vision: the edge model of a tag (tag_edge_fit.h).
#include "vision/tag_edge_fit.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace opl {
namespace tag_internal {

// The standard normal cdf Phi(z) and pdf phi(z) from one exponential: erfc
// by Abramowitz & Stegun 7.1.26 (absolute error < 1.5e-7, i.e. 1.5e-7 of the
// edge contrast: far below any grey level).
void NormalCdfPdf(double z, double* cdf, double* pdf) {
  const double e = std::exp(-0.5 * z * z);
  *pdf = e * 0.3989422804014327;  // 1 / sqrt(2 pi)
  const double x = std::abs(z) * 0.7071067811865476;
  const double t = 1.0 / (1.0 + 0.3275911 * x);
  const double erfc_x =
      t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429)))) * e;
  *cdf = z >= 0.0 ? 1.0 - 0.5 * erfc_x : 0.5 * erfc_x;
}

double Bilinear(const cv::Mat& image, double x, double y) {
  const int j = static_cast<int>(std::floor(x));
  const int i = static_cast<int>(std::floor(y));
  const int j0 = std::clamp(j, 0, image.cols - 1), j1 = std::clamp(j + 1, 0, image.cols - 1);
  const int i0 = std::clamp(i, 0, image.rows - 1), i1 = std::clamp(i + 1, 0, image.rows - 1);
  const double fx = x - j, fy = y - i;
  const double top = (1.0 - fx) * image.at<double>(i0, j0) + fx * image.at<double>(i0, j1);
  const double bot = (1.0 - fx) * image.at<double>(i1, j0) + fx * image.at<double>(i1, j1);
  return (1.0 - fy) * top + fy * bot;
}

double EdgeCurve::D(const Eigen::Vector2d& p) const {
  const double s = S(p);
  const Eigen::Vector2d q = p - mid;
  return std::cos(theta) * q.x() + std::sin(theta) * q.y() - c + kappa * s * s;
}

Eigen::Vector2d EdgeCurve::Gradient(const Eigen::Vector2d& p) const {
  return Eigen::Vector2d(std::cos(theta), std::sin(theta)) + 2.0 * kappa * S(p) * u;
}

Eigen::RowVector3d EdgeCurve::ParamJacobian(const Eigen::Vector2d& p) const {
  const double s = S(p);
  const Eigen::Vector2d q = p - mid;
  return Eigen::RowVector3d(-std::sin(theta) * q.x() + std::cos(theta) * q.y(), -1.0, s * s);
}

bool FitEdge(const cv::Mat& image, const Eigen::Vector2d& p, const Eigen::Vector2d& q,
             const Eigen::Vector2d& centre, const EdgeFitSettings& settings, EdgeCurve* edge) {
  const double band_px = settings.band_px;
  const double length = (q - p).norm();
  if (!(length > 2.0 * settings.corner_exclusion_px + 2.0)) return false;
  edge->u = (q - p) / length;
  edge->mid = 0.5 * (p + q);
  Eigen::Vector2d n(-edge->u.y(), edge->u.x());
  if (n.dot(edge->mid - centre) < 0.0) n = -n;  // outward
  edge->theta = std::atan2(n.y(), n.x());
  const double theta0 = edge->theta;
  edge->c = 0.0;
  edge->kappa = 0.0;
  const double half_run = 0.5 * length - settings.corner_exclusion_px;

  std::vector<Eigen::Vector2d> pts;
  std::vector<double> values;
  for (int pass = 0; pass < 2; ++pass) {
    // Pixels in the band around the current curve.
    pts.clear();
    values.clear();
    const Eigen::Vector2d ends[2] = {edge->mid - 0.5 * length * edge->u, edge->mid + 0.5 * length * edge->u};
    const double pad = band_px + 2.0;
    const int j0 = std::max(0, static_cast<int>(std::floor(std::min(ends[0].x(), ends[1].x()) - pad)));
    const int j1 = std::min(image.cols - 1, static_cast<int>(std::ceil(std::max(ends[0].x(), ends[1].x()) + pad)));
    const int i0 = std::max(0, static_cast<int>(std::floor(std::min(ends[0].y(), ends[1].y()) - pad)));
    const int i1 = std::min(image.rows - 1, static_cast<int>(std::ceil(std::max(ends[0].y(), ends[1].y()) + pad)));
    for (int i = i0; i <= i1; ++i) {
      for (int j = j0; j <= j1; ++j) {
        const Eigen::Vector2d px(j, i);
        if (std::abs(edge->S(px)) > half_run) continue;
        if (std::abs(edge->D(px)) > band_px) continue;
        pts.push_back(px);
        values.push_back(image.at<double>(i, j));
      }
    }
    int m = static_cast<int>(pts.size());
    if (m < settings.min_pixels) return false;
    const int m_band = m;
    if (pass == 0) {
      // Initial levels: means of the inner and outer halves of the band.
      double in_sum = 0.0, out_sum = 0.0;
      int in_n = 0, out_n = 0;
      for (int k = 0; k < m; ++k) {
        if (edge->D(pts[k]) < -0.5) { in_sum += values[k]; ++in_n; }
        if (edge->D(pts[k]) > 0.5) { out_sum += values[k]; ++out_n; }
      }
      if (in_n == 0 || out_n == 0) return false;
      edge->a = in_sum / in_n;
      edge->b = out_sum / out_n - edge->a;
      edge->sigma = 1.0;
      if (!(edge->b > 0.0)) return false;
    }
    // Levenberg-Marquardt, parameters (theta, c, kappa, a, b, log sigma).
    // Pixel positions relative to the midpoint, and s^2, once per pass.
    std::vector<double> qx(static_cast<size_t>(m)), qy(qx.size()), s2(qx.size());
    for (int k = 0; k < m; ++k) {
      const Eigen::Vector2d rel = pts[k] - edge->mid;
      qx[k] = rel.x();
      qy[k] = rel.y();
      const double sk = edge->u.dot(rel);
      s2[k] = sk * sk;
    }
    auto cost_and_jacobian = [&](const Eigen::Matrix<double, 6, 1>& params,
                                 Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr) {
      const double ct = std::cos(params[0]), st = std::sin(params[0]);
      const double c = params[1], kappa = params[2];
      const double a = params[3], b = params[4], sigma = std::exp(params[5]);
      double cost = 0.0;
      if (jtj) jtj->setZero();
      if (jtr) jtr->setZero();
      for (int k = 0; k < m; ++k) {
        const double d = ct * qx[k] + st * qy[k] - c + kappa * s2[k];
        const double z = d / sigma;
        double cdf, pdf;
        NormalCdfPdf(z, &cdf, &pdf);
        const double r = a + b * cdf - values[k];
        cost += r * r;
        if (jtj) {
          const double dr_dd = b * pdf / sigma;
          Eigen::Matrix<double, 6, 1> g;
          g[0] = dr_dd * (-st * qx[k] + ct * qy[k]);
          g[1] = -dr_dd;
          g[2] = dr_dd * s2[k];
          g[3] = 1.0;
          g[4] = cdf;
          g[5] = -dr_dd * d;  // d r / d log(sigma)
          *jtj += g * g.transpose();
          *jtr += g * r;
        }
      }
      return cost;
    };
    Eigen::Matrix<double, 6, 1> x;
    x << edge->theta, edge->c, edge->kappa, edge->a, edge->b, std::log(edge->sigma);
    if (pass == 0) {
      // The initial quad can be a pixel or two off: search the offset first.
      double best = cost_and_jacobian(x, nullptr, nullptr);
      const double c0 = x[1];
      const double range = std::min(band_px, 2.0);
      for (double dc = -range; dc <= range; dc += 0.5) {
        Eigen::Matrix<double, 6, 1> trial = x;
        trial[1] = c0 + dc;
        const double cost = cost_and_jacobian(trial, nullptr, nullptr);
        if (cost < best) {
          best = cost;
          x[1] = trial[1];
        }
      }
    }
    double cost = 0.0;
    Eigen::Matrix<double, 6, 6> jtj;
    Eigen::Matrix<double, 6, 1> jtr;
    // Outliers: pixels that do not belong to the step (a highlight, a lamp or
    // a retro-reflective dot over the edge) would pull the fitted edge by up
    // to a pixel while the corner's covariance stays small. After each
    // convergence, pixels whose residual exceeds
    // max(outlier_mad_factor x 1.4826 MAD, outlier_contrast_fraction x b) are
    // dropped and the fit is run again (at most max_outlier_rounds times); an
    // edge that loses more than max_outlier_fraction of its band fails.
    for (int round = 0;; ++round) {
    double lambda = 1e-3;
    cost = cost_and_jacobian(x, &jtj, &jtr);
    for (int iter = 0; iter < 30; ++iter) {
      Eigen::Matrix<double, 6, 6> damped = jtj;
      for (int k = 0; k < 6; ++k) damped(k, k) += lambda * std::max(jtj(k, k), 1e-12);
      Eigen::Matrix<double, 6, 1> step = -damped.ldlt().solve(jtr);
      if (!step.allFinite()) return false;
      // A trust region in the natural units: the edge moves by at most
      // 0.5 px, sigma changes by at most 30% per step.
      const double move = std::abs(step[1]) + std::abs(step[0]) * 0.5 * length +
                          std::abs(step[2]) * 0.25 * length * length;
      if (move > 0.5) step.head<3>() *= 0.5 / move;
      step[5] = std::clamp(step[5], -0.3, 0.3);
      const Eigen::Matrix<double, 6, 1> trial = x + step;
      Eigen::Matrix<double, 6, 6> trial_jtj;
      Eigen::Matrix<double, 6, 1> trial_jtr;
      const double trial_cost = cost_and_jacobian(trial, &trial_jtj, &trial_jtr);
      if (trial_cost < cost) {
        x = trial;
        // Converged when the edge moves by less than 1e-5 px anywhere on it.
        const bool small = std::abs(step[1]) < 1e-5 && std::abs(step[0]) * length < 1e-5 &&
                           std::abs(step[2]) * 0.25 * length * length < 1e-5;
        cost = trial_cost;
        jtj = trial_jtj;
        jtr = trial_jtr;
        lambda = std::max(lambda * 0.3, 1e-9);
        if (small) break;
      } else {
        lambda *= 10.0;
        if (lambda > 1e8) break;
      }
    }
    if (round >= settings.max_outlier_rounds) break;
    std::vector<double> residuals(static_cast<size_t>(m)), abs_residuals(residuals.size());
    {
      const double ct = std::cos(x[0]), st = std::sin(x[0]), sig = std::exp(x[5]);
      for (int k = 0; k < m; ++k) {
        double cdf, pdf;
        NormalCdfPdf((ct * qx[k] + st * qy[k] - x[1] + x[2] * s2[k]) / sig, &cdf, &pdf);
        residuals[k] = x[3] + x[4] * cdf - values[k];
        abs_residuals[k] = std::abs(residuals[k]);
      }
    }
    std::nth_element(abs_residuals.begin(), abs_residuals.begin() + m / 2, abs_residuals.end());
    const double robust_sigma = 1.4826 * abs_residuals[static_cast<size_t>(m / 2)];
    const double limit = std::max(settings.outlier_mad_factor * robust_sigma,
                                  settings.outlier_contrast_fraction * std::abs(x[4]));
    int kept = 0;
    for (int k = 0; k < m; ++k) {
      if (std::abs(residuals[k]) > limit) continue;
      pts[kept] = pts[k];
      values[kept] = values[k];
      qx[kept] = qx[k];
      qy[kept] = qy[k];
      s2[kept] = s2[k];
      ++kept;
    }
    if (kept == m) break;
    if (kept < settings.min_pixels || m_band - kept > settings.max_outlier_fraction * m_band) return false;
    m = kept;
    pts.resize(static_cast<size_t>(m));
    values.resize(static_cast<size_t>(m));
    }
    edge->theta = x[0];
    edge->c = x[1];
    edge->kappa = x[2];
    edge->a = x[3];
    edge->b = x[4];
    edge->sigma = std::exp(x[5]);
    const double variance = cost / std::max(1, m - 6);
    edge->rms = std::sqrt(cost / m);
    Eigen::Matrix<double, 6, 6> cov = jtj.inverse() * variance;
    if (!cov.allFinite()) return false;
    edge->cov = cov.topLeftCorner<3, 3>();
    // The band of pass 0 was centred on the initial quad's edge: refit on a
    // re-centred band only when the fitted edge moved away from it.
    const double moved = std::abs(edge->c) + std::abs(edge->theta - theta0) * 0.5 * length +
                         std::abs(edge->kappa) * 0.25 * length * length;
    if (pass == 0 && moved < 0.02) break;
  }
  return edge->b > 0.0 && edge->sigma < settings.max_sigma_px && edge->sigma > 0.05;
}

bool IntersectEdges(const EdgeCurve& e1, const EdgeCurve& e2, const Eigen::Vector2d& start,
                    double max_move_px, Eigen::Vector2d* corner, Eigen::Matrix2d* cov,
                    Eigen::Matrix<double, 2, 3>* d_corner_d_e1, Eigen::Matrix<double, 2, 3>* d_corner_d_e2) {
  Eigen::Vector2d p = start;
  Eigen::Matrix2d J;
  for (int iter = 0; iter < 20; ++iter) {
    const Eigen::Vector2d F(e1.D(p), e2.D(p));
    J.row(0) = e1.Gradient(p).transpose();
    J.row(1) = e2.Gradient(p).transpose();
    if (std::abs(J.determinant()) < 1e-6) return false;
    const Eigen::Vector2d step = -J.inverse() * F;
    p += step;
    if (step.norm() < 1e-12) break;
  }
  if (!p.allFinite() || (p - start).norm() > max_move_px) return false;
  J.row(0) = e1.Gradient(p).transpose();
  J.row(1) = e2.Gradient(p).transpose();
  const Eigen::Matrix2d Jinv = J.inverse();
  const Eigen::Matrix<double, 2, 3> A1 = -Jinv.col(0) * e1.ParamJacobian(p);
  const Eigen::Matrix<double, 2, 3> A2 = -Jinv.col(1) * e2.ParamJacobian(p);
  *corner = p;
  *cov = A1 * e1.cov * A1.transpose() + A2 * e2.cov * A2.transpose();
  if (d_corner_d_e1 != nullptr) *d_corner_d_e1 = A1;
  if (d_corner_d_e2 != nullptr) *d_corner_d_e2 = A2;
  return true;
}

cv::Mat ReadTagBits(const cv::Mat& image, const std::array<Eigen::Vector2d, 4>& corners, double sharpening,
                    double* contrast) {
  // Homography from tag cell coordinates (0..8) to the image.
  std::vector<cv::Point2f> src = {{0.f, 0.f}, {8.f, 0.f}, {8.f, 8.f}, {0.f, 8.f}};
  std::vector<cv::Point2f> dst;
  for (const auto& c : corners) dst.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()));
  const cv::Mat Hcv = cv::getPerspectiveTransform(src, dst);
  const double* H = Hcv.ptr<double>(0);
  auto sample = [&](double cx, double cy) {
    double sum = 0.0;
    for (int a = -1; a <= 1; ++a) {
      for (int b = -1; b <= 1; ++b) {
        const double x = cx + 0.2 * a, y = cy + 0.2 * b;
        const double w = H[6] * x + H[7] * y + H[8];
        sum += Bilinear(image, (H[0] * x + H[1] * y + H[2]) / w, (H[3] * x + H[4] * y + H[5]) / w);
      }
    }
    return sum / 9.0;
  };
  // The 10 x 10 cells of the tag and the ring around it (quiet zone): row
  // r, column c of `grid` is the cell whose centre is (c - 0.5, r - 0.5).
  double grid[10][10];
  for (int r = 0; r < 10; ++r) {
    for (int c = 0; c < 10; ++c) {
      const bool ring = r == 0 || r == 9 || c == 0 || c == 9;
      const bool corner = (r == 0 || r == 9) && (c == 0 || c == 9);
      grid[r][c] = ring && corner ? 0.0 : sample(c - 0.5, r - 0.5);
    }
  }
  // Black (border) and white (quiet zone) levels, each a plane
  // level(x, y) = l0 + l1 x + l2 y over the tag (light falls off across an
  // oblique tag), least squares over their cells.
  auto fit_plane = [&](bool white) {
    Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Atb = Eigen::Vector3d::Zero();
    for (int r = 0; r < 10; ++r) {
      for (int c = 0; c < 10; ++c) {
        const bool ring = r == 0 || r == 9 || c == 0 || c == 9;
        const bool corner = (r == 0 || r == 9) && (c == 0 || c == 9);
        const bool border = !ring && (r == 1 || r == 8 || c == 1 || c == 8);
        if (white ? (!ring || corner) : !border) continue;
        const Eigen::Vector3d a(1.0, c - 4.5, r - 4.5);
        AtA += a * a.transpose();
        Atb += a * grid[r][c];
      }
    }
    return Eigen::Vector3d(AtA.ldlt().solve(Atb));
  };
  const Eigen::Vector3d black = fit_plane(false), white = fit_plane(true);
  if (contrast != nullptr) *contrast = white[0] - black[0];
  const Eigen::Vector3d threshold = 0.5 * (black + white);
  cv::Mat bits(6, 6, CV_8UC1);
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      const int gr = r + 2, gc = c + 2;
      // Sharpened as libapriltag's decoder does: v + s (4 v - 4 neighbours).
      const double v = grid[gr][gc];
      const double lap = 4.0 * v - grid[gr - 1][gc] - grid[gr + 1][gc] - grid[gr][gc - 1] - grid[gr][gc + 1];
      const double t = threshold[0] + threshold[1] * (gc - 4.5) + threshold[2] * (gr - 4.5);
      bits.at<uchar>(r, c) = v + sharpening * lap > t ? 1 : 0;
    }
  }
  return bits;
}

}  // namespace tag_internal
}  // namespace opl
