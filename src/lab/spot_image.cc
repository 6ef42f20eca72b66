#include "opl/lab/spot_image.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

// Poisson draw of mean mu >= 0: Knuth's multiplication for mu < 10, else
// Hormann's transformed rejection with squeeze (PTRS, 1993), as numpy does.
double PoissonDraw(double mu, std::mt19937_64& rng) {
  if (mu <= 0.0) return 0.0;
  if (mu < 10.0) {
    const double limit = std::exp(-mu);
    double product = Uniform01(rng);
    double k = 0.0;
    while (product > limit) {
      product *= Uniform01(rng);
      k += 1.0;
    }
    return k;
  }
  const double slam = std::sqrt(mu);
  const double loglam = std::log(mu);
  const double b = 0.931 + 2.53 * slam;
  const double a = -0.059 + 0.02483 * b;
  const double invalpha = 1.1239 + 1.1328 / (b - 3.4);
  const double vr = 0.9277 - 3.6224 / (b - 2.0);
  for (;;) {
    const double U = Uniform01(rng) - 0.5;
    const double V = Uniform01(rng);
    const double us = 0.5 - std::fabs(U);
    const double k = std::floor((2.0 * a / us + b) * U + mu + 0.43);
    if (us >= 0.07 && V <= vr) return k;
    if (k < 0.0 || (us < 0.013 && V > us)) continue;
    if (std::log(V) + std::log(invalpha) - std::log(a / (us * us) + b) <=
        -mu + k * loglam - std::lgamma(k + 1.0)) {
      return k;
    }
  }
}

bool Finite(double x) { return std::isfinite(x); }

// Speckle field with a margin so that the blur sees no border; returns the
// normalised intensity (expected mean 1) of size rows x cols.
cv::Mat SpeckleField(int cols, int rows, double grain_px, uint64_t seed) {
  const int radius = std::max(1, static_cast<int>(std::ceil(4.0 * grain_px)));
  const cv::Mat kernel = cv::getGaussianKernel(2 * radius + 1, grain_px, CV_64F);
  double k2 = 0.0;
  for (int i = 0; i < kernel.rows; ++i) k2 += kernel.at<double>(i) * kernel.at<double>(i);
  const double expected_intensity = 2.0 * k2 * k2;  // E|h*w|^2, separable kernel
  const int big_rows = rows + 2 * radius;
  const int big_cols = cols + 2 * radius;
  cv::Mat re(big_rows, big_cols, CV_64F), im(big_rows, big_cols, CV_64F);
  std::mt19937_64 rng(SplitMix64(seed).Next());
  NormalGenerator normal;
  for (int r = 0; r < big_rows; ++r) {
    double* pr = re.ptr<double>(r);
    double* pi = im.ptr<double>(r);
    for (int c = 0; c < big_cols; ++c) {
      pr[c] = normal(rng);
      pi[c] = normal(rng);
    }
  }
  cv::Mat fre, fim;
  cv::sepFilter2D(re, fre, CV_64F, kernel, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_CONSTANT);
  cv::sepFilter2D(im, fim, CV_64F, kernel, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_CONSTANT);
  cv::Mat out(rows, cols, CV_64F);
  for (int r = 0; r < rows; ++r) {
    const double* a = fre.ptr<double>(r + radius) + radius;
    const double* b = fim.ptr<double>(r + radius) + radius;
    double* o = out.ptr<double>(r);
    for (int c = 0; c < cols; ++c) o[c] = (a[c] * a[c] + b[c] * b[c]) / expected_intensity;
  }
  return out;
}

// Integral of exp(-x^2 / (2 s^2)) over [lo, hi].
double GaussIntegral1d(double lo, double hi, double s) {
  const double k = 1.0 / (std::sqrt(2.0) * s);
  return 0.5 * std::sqrt(2.0 * kPi) * s * (std::erf(hi * k) - std::erf(lo * k));
}

// Nodes and weights of m-point Gauss-Legendre quadrature on [-1, 1]
// (Newton iteration on the Legendre polynomial, Numerical Recipes' gauleg).
void GaussLegendre(int m, std::vector<double>* nodes, std::vector<double>* weights) {
  nodes->assign(static_cast<size_t>(m), 0.0);
  weights->assign(static_cast<size_t>(m), 0.0);
  for (int i = 0; i < (m + 1) / 2; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (m + 0.5));
    double dp = 1.0;
    for (int it = 0; it < 100; ++it) {
      double p1 = 1.0, p2 = 0.0;
      for (int j = 1; j <= m; ++j) {
        const double p3 = p2;
        p2 = p1;
        p1 = ((2.0 * j - 1.0) * z * p2 - (j - 1.0) * p3) / j;
      }
      dp = m * (z * p1 - p2) / (z * z - 1.0);
      const double z1 = z;
      z = z1 - p1 / dp;
      if (std::fabs(z - z1) < 1e-15) break;
    }
    (*nodes)[static_cast<size_t>(i)] = -z;
    (*nodes)[static_cast<size_t>(m - 1 - i)] = z;
    const double w = 2.0 / ((1.0 - z * z) * dp * dp);
    (*weights)[static_cast<size_t>(i)] = w;
    (*weights)[static_cast<size_t>(m - 1 - i)] = w;
  }
}

// Renders one spot's clean light into `window_out` (CV_64F, window size).
void RenderSpotWindow(const SpotToRender& spot, const cv::Rect& window, cv::Mat* window_out) {
  *window_out = cv::Mat::zeros(window.height, window.width, CV_64F);
  const Eigen::Matrix2d C =
      0.5 * (spot.shape_covariance_px2 + spot.shape_covariance_px2.transpose());
  const double A = spot.peak_dn;
  if (C(0, 1) == 0.0) {
    const double su = std::sqrt(C(0, 0));
    const double sv = std::sqrt(C(1, 1));
    std::vector<double> gu(static_cast<size_t>(window.width)), gv(static_cast<size_t>(window.height));
    for (int j = 0; j < window.width; ++j) {
      const double u = window.x + j - spot.u_px;
      gu[static_cast<size_t>(j)] = GaussIntegral1d(u - 0.5, u + 0.5, su);
    }
    for (int i = 0; i < window.height; ++i) {
      const double v = window.y + i - spot.v_px;
      gv[static_cast<size_t>(i)] = GaussIntegral1d(v - 0.5, v + 0.5, sv);
    }
    for (int i = 0; i < window.height; ++i) {
      double* row = window_out->ptr<double>(i);
      for (int j = 0; j < window.width; ++j) {
        row[j] = A * gu[static_cast<size_t>(j)] * gv[static_cast<size_t>(i)];
      }
    }
    return;
  }
  // Rotated: g = A 2 pi sqrt(det C) N(dv; C_vv) N(du; k dv, s^2), k = C_uv / C_vv,
  // s^2 = C_uu - C_uv^2 / C_vv. The u integral over a pixel is an erf
  // difference; the v integral uses Gauss-Legendre on each pixel row.
  const double svv = std::sqrt(C(1, 1));
  const double k = C(0, 1) / C(1, 1);
  const double s = std::sqrt(C(0, 0) - C(0, 1) * k);
  const double scale = std::min(svv, s / std::max(std::fabs(k), 1e-12));
  const int m = std::clamp(static_cast<int>(std::ceil(4.0 / scale)) + 6, 8, 48);
  std::vector<double> nodes, weights;
  GaussLegendre(m, &nodes, &weights);
  const double norm = A * 2.0 * kPi * std::sqrt(C.determinant()) / (std::sqrt(2.0 * kPi) * svv);
  const double inv_s = 1.0 / (std::sqrt(2.0) * s);
  std::vector<double> edge(static_cast<size_t>(window.width + 1));
  for (int i = 0; i < window.height; ++i) {
    double* row = window_out->ptr<double>(i);
    const double mid = window.y + i - spot.v_px;
    for (int q = 0; q < m; ++q) {
      const double dv = mid + 0.5 * nodes[static_cast<size_t>(q)];
      const double wv = 0.5 * weights[static_cast<size_t>(q)] * norm *
                        std::exp(-0.5 * dv * dv / (svv * svv));
      const double mu = spot.u_px + k * dv;
      for (int j = 0; j <= window.width; ++j) {
        edge[static_cast<size_t>(j)] = std::erf((window.x + j - 0.5 - mu) * inv_s);
      }
      for (int j = 0; j < window.width; ++j) {
        row[j] += wv * 0.5 * (edge[static_cast<size_t>(j + 1)] - edge[static_cast<size_t>(j)]);
      }
    }
  }
}

}  // namespace

Eigen::Matrix2d RoundSpotShape(double diameter_px) {
  const double s = diameter_px / 4.0;
  return Eigen::Matrix2d::Identity() * s * s;
}

Eigen::Matrix2d EllipticalSpotShape(double major_diameter_px, double minor_diameter_px,
                                    double angle_rad) {
  const double s1 = major_diameter_px / 4.0;
  const double s2 = minor_diameter_px / 4.0;
  Eigen::Matrix2d R;
  R << std::cos(angle_rad), -std::sin(angle_rad), std::sin(angle_rad), std::cos(angle_rad);
  const Eigen::Matrix2d C = R * Eigen::Vector2d(s1 * s1, s2 * s2).asDiagonal() * R.transpose();
  Eigen::Matrix2d out = 0.5 * (C + C.transpose());  // exactly symmetric
  if (std::fabs(out(0, 1)) <= 1e-14 * std::sqrt(out(0, 0) * out(1, 1))) out(0, 1) = out(1, 0) = 0;
  return out;
}

double SpotImageFullScale(const SpotImageOptions& options) {
  return options.bit_depth == 8 ? 255.0 : 65535.0;
}

Status SpotImageOptions::Validate() const {
  auto bad = [](const char* field, double value, const char* rule) {
    return Status::InvalidArgument(std::string("SpotImageOptions.") + field + " = " +
                                   FormatNumber(value) + ": " + rule);
  };
  if (width_px < 1) return bad("width_px", width_px, "must be >= 1");
  if (height_px < 1) return bad("height_px", height_px, "must be >= 1");
  if (static_cast<double>(width_px) * height_px > 4.0e8) {
    return bad("width_px", width_px, "width_px * height_px must be <= 4e8");
  }
  if (bit_depth != 8 && bit_depth != 16) return bad("bit_depth", bit_depth, "must be 8 or 16");
  if (!Finite(background_dn) || background_dn < 0) {
    return bad("background_dn", background_dn, "must be finite and >= 0");
  }
  if (!Finite(background_gradient_u_dn_per_px)) {
    return bad("background_gradient_u_dn_per_px", background_gradient_u_dn_per_px,
               "must be finite");
  }
  if (!Finite(background_gradient_v_dn_per_px)) {
    return bad("background_gradient_v_dn_per_px", background_gradient_v_dn_per_px,
               "must be finite");
  }
  if (!background_image_dn.empty()) {
    if (background_image_dn.type() != CV_32FC1 || background_image_dn.cols != width_px ||
        background_image_dn.rows != height_px) {
      return Status::InvalidArgument(
          "SpotImageOptions.background_image_dn: " + std::to_string(background_image_dn.cols) +
          " x " + std::to_string(background_image_dn.rows) + " " +
          (background_image_dn.type() == CV_32FC1 ? "CV_32FC1" : "not CV_32FC1") +
          ": must be CV_32FC1 of width_px x height_px (" + std::to_string(width_px) + " x " +
          std::to_string(height_px) + ")");
    }
    if (!cv::checkRange(background_image_dn)) {
      return Status::InvalidArgument("SpotImageOptions.background_image_dn: not finite");
    }
  }
  if (!(speckle_contrast >= 0.0 && speckle_contrast <= 1.0)) {
    return bad("speckle_contrast", speckle_contrast, "must be in [0, 1]");
  }
  if (!(speckle_grain_px > 0.0 && speckle_grain_px <= 100.0)) {
    return bad("speckle_grain_px", speckle_grain_px, "must be in (0, 100]");
  }
  if (!(gain_e_per_dn >= 0.0) || !Finite(gain_e_per_dn)) {
    return bad("gain_e_per_dn", gain_e_per_dn, "must be finite and >= 0 (0: no shot noise)");
  }
  if (!(read_noise_dn >= 0.0) || !Finite(read_noise_dn)) {
    return bad("read_noise_dn", read_noise_dn, "must be finite and >= 0");
  }
  if (!(window_sigmas >= 3.0 && window_sigmas <= 10.0)) {
    return bad("window_sigmas", window_sigmas, "must be in [3, 10]");
  }
  return Status::Ok();
}

Result<cv::Mat> RenderSpeckleField(int width_px, int height_px, double grain_px, uint64_t seed) {
  if (width_px < 1 || height_px < 1) {
    return Status::InvalidArgument("RenderSpeckleField: size " + FormatNumber(width_px) + " x " +
                                   FormatNumber(height_px) + " px: must be >= 1 x 1");
  }
  if (!(grain_px > 0.0 && grain_px <= 100.0)) {
    return Status::InvalidArgument("RenderSpeckleField: grain_px = " + FormatNumber(grain_px) +
                                   ": must be in (0, 100]");
  }
  return SpeckleField(width_px, height_px, grain_px, seed);
}

Result<SpotImage> RenderSpotImage(const std::vector<SpotToRender>& spots,
                                  const SpotImageOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  for (size_t k = 0; k < spots.size(); ++k) {
    const SpotToRender& s = spots[k];
    const std::string where = "spot " + std::to_string(k) + ": ";
    if (!Finite(s.u_px) || !Finite(s.v_px) || std::fabs(s.u_px) > 1e7 || std::fabs(s.v_px) > 1e7) {
      return Status::InvalidArgument(where + "centre (" + FormatNumber(s.u_px) + ", " +
                                     FormatNumber(s.v_px) + ") px must be finite and within 1e7");
    }
    if (!Finite(s.peak_dn) || s.peak_dn <= 0.0) {
      return Status::InvalidArgument(where + "peak_dn = " + FormatNumber(s.peak_dn) +
                                     ": must be finite and > 0");
    }
    const Eigen::Matrix2d& C = s.shape_covariance_px2;
    if (!C.allFinite() || C(0, 0) <= 0.0 || C(1, 1) <= 0.0 ||
        std::fabs(C(0, 1) - C(1, 0)) > 1e-12 * std::sqrt(C(0, 0) * C(1, 1)) ||
        C.determinant() <= 0.0) {
      return Status::InvalidArgument(where + "shape_covariance_px2 [" + FormatNumber(C(0, 0)) +
                                     ", " + FormatNumber(C(0, 1)) + "; " + FormatNumber(C(1, 0)) +
                                     ", " + FormatNumber(C(1, 1)) +
                                     "] must be symmetric positive definite");
    }
    const double smin = std::sqrt(std::min(C(0, 0), C(1, 1)));
    const double smax = std::sqrt(std::max(C(0, 0), C(1, 1)));
    if (smax > 1000.0 || std::sqrt(C.determinant()) / (smax * smax) < 1e-6 || smin < 0.05) {
      return Status::InvalidArgument(where + "shape_covariance_px2: sigma along u, v = " +
                                     FormatNumber(std::sqrt(C(0, 0))) + ", " +
                                     FormatNumber(std::sqrt(C(1, 1))) +
                                     " px: must be in [0.05, 1000] and not degenerate");
    }
  }

  const int W = options.width_px;
  const int H = options.height_px;
  const cv::Rect image_rect(0, 0, W, H);
  cv::Mat light = cv::Mat::zeros(H, W, CV_32F);
  SpotImage out;
  out.spots.resize(spots.size());
  SplitMix64 seeds(options.seed);
  const uint64_t noise_seed = seeds.Next();
  for (size_t k = 0; k < spots.size(); ++k) {
    const SpotToRender& s = spots[k];
    const uint64_t speckle_seed = seeds.Next();
    RenderedSpotTruth& truth = out.spots[k];
    truth.u_px = s.u_px;
    truth.v_px = s.v_px;
    const double hu = options.window_sigmas * std::sqrt(s.shape_covariance_px2(0, 0));
    const double hv = options.window_sigmas * std::sqrt(s.shape_covariance_px2(1, 1));
    const int x0 = static_cast<int>(std::floor(s.u_px - hu + 0.5));
    const int x1 = static_cast<int>(std::floor(s.u_px + hu + 0.5));
    const int y0 = static_cast<int>(std::floor(s.v_px - hv + 0.5));
    const int y1 = static_cast<int>(std::floor(s.v_px + hv + 0.5));
    const cv::Rect window = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1) & image_rect;
    truth.window = window;
    if (window.area() == 0) continue;
    cv::Mat w;
    RenderSpotWindow(s, window, &w);
    if (options.speckle_contrast > 0.0) {
      const cv::Mat S = SpeckleField(window.width, window.height, options.speckle_grain_px,
                                     speckle_seed);
      const double c = options.speckle_contrast;
      w = w.mul((1.0 - c) + c * S);
    }
    truth.flux_dn = cv::sum(w)[0];
    cv::Mat roi = light(window);
    for (int i = 0; i < window.height; ++i) {
      float* dst = roi.ptr<float>(i);
      const double* src = w.ptr<double>(i);
      for (int j = 0; j < window.width; ++j) dst[j] = static_cast<float>(dst[j] + src[j]);
    }
  }

  const double full_scale = SpotImageFullScale(options);
  const bool shot = options.gain_e_per_dn > 0.0;
  const bool read = options.read_noise_dn > 0.0;
  std::mt19937_64 rng(noise_seed);
  NormalGenerator normal;
  out.image = cv::Mat(H, W, options.bit_depth == 8 ? CV_8U : CV_16U);
  out.saturated_mask = cv::Mat::zeros(H, W, CV_8U);
  if (options.keep_clean) out.clean_dn = cv::Mat(H, W, CV_32F);
  const double cu = 0.5 * (W - 1);
  const double cv_ = 0.5 * (H - 1);
  for (int i = 0; i < H; ++i) {
    const float* l = light.ptr<float>(i);
    uint8_t* sat = out.saturated_mask.ptr<uint8_t>(i);
    float* clean = options.keep_clean ? out.clean_dn.ptr<float>(i) : nullptr;
    const double bg_row = options.background_dn + options.background_gradient_v_dn_per_px * (i - cv_);
    const float* bg_image =
        options.background_image_dn.empty() ? nullptr : options.background_image_dn.ptr<float>(i);
    for (int j = 0; j < W; ++j) {
      const double bg = std::max(
          0.0, bg_image != nullptr ? static_cast<double>(bg_image[j])
                                   : bg_row + options.background_gradient_u_dn_per_px * (j - cu));
      const double expected = bg + l[j];
      if (clean != nullptr) clean[j] = static_cast<float>(expected);
      double value = expected;
      if (shot) value = PoissonDraw(expected * options.gain_e_per_dn, rng) / options.gain_e_per_dn;
      if (read) value += options.read_noise_dn * normal(rng);
      value = std::round(value);
      if (value >= full_scale) {  // clipped (or exactly at full scale: the same reading)
        sat[j] = 255;
        value = full_scale;
      }
      if (value < 0.0) value = 0.0;
      if (options.bit_depth == 8) {
        out.image.ptr<uint8_t>(i)[j] = static_cast<uint8_t>(value);
      } else {
        out.image.ptr<uint16_t>(i)[j] = static_cast<uint16_t>(value);
      }
    }
  }
  out.saturated_pixels = cv::countNonZero(out.saturated_mask);
  for (RenderedSpotTruth& t : out.spots) {
    if (t.window.area() > 0) t.saturated_pixels = cv::countNonZero(out.saturated_mask(t.window));
  }
  return out;
}

}  // namespace opl
