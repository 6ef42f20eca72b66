// DetectSpots (opl/vision/spot_detection.h): background and noise per block,
// the smoothed image's threshold, connected components and their gates, then
// per spot its window, centroid, Gaussian fit and covariance; also
// SpotDetectionOptions::Validate, SpotDetectionResult::ToText and
// OpenCvTypeName.
#include "opl/vision/spot_detection.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "vision/spot_detection_internal.h"
#include "vision/spot_threshold_mask.h"

namespace opl {
namespace {

// Lag of the pixel differences that measure the smoothed image's noise [px]
// (at least): past the 8 x 8 blocks of JPEG, a Bayer pattern's
// interpolation and the smoothing kernel itself.
constexpr int kMinNoiseLagPx = 8;

using spot_internal::BlockGrid;
using spot_internal::Centroid;
using spot_internal::CentroidResult;
using spot_internal::FitGaussian;
using spot_internal::FitResult;
using spot_internal::LocalBackground;
using spot_internal::MakeWindow;
using spot_internal::Median;
using spot_internal::Pixel;
using spot_internal::PixRow;
using spot_internal::SpeckleCovariance;
using spot_internal::Vec7;
using spot_internal::Window;

// The median as Median gives it (the element at index n / 2 of the sorted
// values; 0 when n is 0) of n values in 0..255, from their counts.
double MedianOfCounts(const std::array<int, 256>& count, int n) {
  if (n == 0) return 0.0;
  const int mid = n / 2;
  int below = 0;
  for (int k = 0; k < 256; ++k) {
    below += count[static_cast<size_t>(k)];
    if (below > mid) return k;
  }
  return 255.0;
}

}  // namespace

std::string OpenCvTypeName(int type) {
  static const char* const depths[] = {"CV_8U", "CV_8S", "CV_16U", "CV_16S",
                                       "CV_32S", "CV_32F", "CV_64F", "CV_16F"};
  const int depth = CV_MAT_DEPTH(type);
  const int channels = CV_MAT_CN(type);
  return std::string(depths[depth]) + "C" + std::to_string(channels);
}

Status SpotDetectionOptions::Validate() const {
  auto bad = [](const char* field, double value, const char* rule) {
    return Status::InvalidArgument(std::string("SpotDetectionOptions.") + field + " = " +
                                   FormatNumber(value) + ": " + rule);
  };
  if (background_block_px < 8) return bad("background_block_px", background_block_px, "must be >= 8");
  if (!(smoothing_sigma_px >= 0 && smoothing_sigma_px <= 10)) {
    return bad("smoothing_sigma_px", smoothing_sigma_px, "must be in [0, 10]");
  }
  if (!(threshold_sigma > 0) || !std::isfinite(threshold_sigma)) {
    return bad("threshold_sigma", threshold_sigma, "must be finite and > 0");
  }
  if (!(min_noise_dn > 0) || !std::isfinite(min_noise_dn)) {
    return bad("min_noise_dn", min_noise_dn, "must be finite and > 0");
  }
  if (min_area_px < 1) return bad("min_area_px", min_area_px, "must be >= 1");
  if (max_area_px < min_area_px) return bad("max_area_px", max_area_px, "must be >= min_area_px");
  if (!(max_elongation >= 1) || !std::isfinite(max_elongation)) {
    return bad("max_elongation", max_elongation, "must be finite and >= 1");
  }
  if (!(min_peak_separation_px >= 1) || !std::isfinite(min_peak_separation_px)) {
    return bad("min_peak_separation_px", min_peak_separation_px, "must be finite and >= 1");
  }
  if (!(merged_dip_fraction > 0 && merged_dip_fraction <= 1)) {
    return bad("merged_dip_fraction", merged_dip_fraction, "must be in (0, 1]");
  }
  if (!(min_spot_separation_px >= 0) || !std::isfinite(min_spot_separation_px)) {
    return bad("min_spot_separation_px", min_spot_separation_px, "must be finite and >= 0");
  }
  if (!(saturation_dn >= 0) || !std::isfinite(saturation_dn)) {
    return bad("saturation_dn", saturation_dn, "must be finite and >= 0 (0: the type's maximum)");
  }
  if (!(gain_e_per_dn >= 0) || !std::isfinite(gain_e_per_dn)) {
    return bad("gain_e_per_dn", gain_e_per_dn, "must be finite and >= 0 (0: unknown)");
  }
  if (min_window_half_px < 2) return bad("min_window_half_px", min_window_half_px, "must be >= 2");
  if (max_window_half_px < min_window_half_px) {
    return bad("max_window_half_px", max_window_half_px, "must be >= min_window_half_px");
  }
  if (max_iterations < 1) return bad("max_iterations", max_iterations, "must be >= 1");
  if (!(speckle_contrast >= 0 && speckle_contrast <= 1)) {
    return bad("speckle_contrast", speckle_contrast, "must be in [0, 1] (0: estimate)");
  }
  if (!(speckle_grain_px >= 0 && speckle_grain_px <= 20)) {
    return bad("speckle_grain_px", speckle_grain_px, "must be in [0, 20] (0: estimate)");
  }
  return Status::Ok();
}

std::string SpotDetectionResult::ToText() const {
  std::ostringstream s;
  s << spots.size() << " spots from " << components << " components (rejected: " << rejected_small
    << " small, " << rejected_large << " large, " << rejected_border << " at the border, "
    << rejected_elongated << " elongated, " << rejected_merged << " merged, " << rejected_duplicate
    << " duplicate); background "
    << FormatNumber(background_dn, 6) << " DN, noise " << FormatNumber(noise_dn, 4)
    << " DN, threshold " << FormatNumber(threshold_dn, 4) << " DN above background";
  return s.str();
}

Result<SpotDetectionResult> DetectSpots(const cv::Mat& image, const SpotDetectionOptions& options) {
  if (image.empty()) return Status::InvalidArgument("DetectSpots: image is empty");
  if (image.type() != CV_8UC1 && image.type() != CV_16UC1) {
    return Status::InvalidArgument("DetectSpots: image type " + OpenCvTypeName(image.type()) +
                                   " (" + FormatNumber(image.cols) + " x " +
                                   FormatNumber(image.rows) +
                                   "): must be single-channel CV_8UC1 or CV_16UC1");
  }
  OPL_RETURN_IF_ERROR(options.Validate());
  const int W = image.cols, H = image.rows;
  const double saturation = options.saturation_dn > 0
                                ? options.saturation_dn
                                : (image.depth() == CV_8U ? 255.0 : 65535.0);
  const cv::Mat& img = image;  // read in its own type (PixRow): no full-size copy

  // 1. Background and noise per block.
  const int B = options.background_block_px;
  const int nbx = (W + B - 1) / B, nby = (H + B - 1) / B;
  cv::Mat bg_blocks(nby, nbx, CV_32F), noise_blocks(nby, nbx, CV_32F);
  // Sample about 16 x 16 pixels (and pairs) per block: enough for a robust
  // median and MAD, and 1/16 of the work of all pixels at 64 px blocks.
  const int stride = std::max(1, B / 16);
  std::vector<float> sample, diffs;
  std::array<int, 256> sample_count{}, diff_count{};
  for (int by = 0; by < nby; ++by) {
    for (int bx = 0; bx < nbx; ++bx) {
      const int x0 = bx * B, x1 = std::min(W, x0 + B);
      const int y0 = by * B, y1 = std::min(H, y0 + B);
      double median_sample = 0.0, median_diff = 0.0;
      if (img.depth() == CV_8U) {
        // 8 bit: the same medians by counting (the values are 0..255).
        sample_count.fill(0);
        diff_count.fill(0);
        int num_samples = 0, num_diffs = 0;
        for (int y = y0; y < y1; y += stride) {
          const uint8_t* row = img.ptr<uint8_t>(y);
          for (int x = x0; x < x1; x += stride) {
            ++sample_count[row[x]];
            ++num_samples;
            if (x + 1 < W) {
              ++diff_count[static_cast<size_t>(std::abs(row[x + 1] - row[x]))];
              ++num_diffs;
            }
          }
        }
        median_sample = MedianOfCounts(sample_count, num_samples);
        median_diff = MedianOfCounts(diff_count, num_diffs);
      } else {
        sample.clear();
        diffs.clear();
        for (int y = y0; y < y1; y += stride) {
          const PixRow row(img, y);
          for (int x = x0; x < x1; x += stride) {
            sample.push_back(row[x]);
            if (x + 1 < W) diffs.push_back(std::fabs(row[x + 1] - row[x]));
          }
        }
        median_sample = Median(&sample);
        median_diff = Median(&diffs);
      }
      bg_blocks.at<float>(by, bx) = static_cast<float>(median_sample);
      const double sigma = 1.4826 * median_diff / std::sqrt(2.0);
      noise_blocks.at<float>(by, bx) = static_cast<float>(std::max(sigma, options.min_noise_dn));
    }
  }
  if (nbx >= 3 && nby >= 3) {
    cv::Mat bg_filtered, noise_filtered;  // distinct buffers: the inputs stay intact
    cv::medianBlur(bg_blocks, bg_filtered, 3);
    // The noise varies slowly (with the background level): a wider median.
    cv::medianBlur(noise_blocks, noise_filtered, nbx >= 5 && nby >= 5 ? 5 : 3);
    bg_blocks = bg_filtered;
    noise_blocks = noise_filtered;
  }
  SpotDetectionResult result;
  {
    std::vector<float> v(bg_blocks.begin<float>(), bg_blocks.end<float>());
    result.background_dn = Median(&v);
    std::vector<float> n(noise_blocks.begin<float>(), noise_blocks.end<float>());
    result.noise_dn = Median(&n);
  }

  // 2. Smoothing and threshold.
  cv::Mat smooth;
  double noise_gain = 1.0;
  if (options.smoothing_sigma_px > 0) {
    const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * options.smoothing_sigma_px)));
    const cv::Mat k = cv::getGaussianKernel(2 * radius + 1, options.smoothing_sigma_px, CV_32F);
    cv::sepFilter2D(img, smooth, CV_32F, k, k, cv::Point(-1, -1), 0.0, cv::BORDER_REFLECT);
    double k2 = 0;
    for (int i = 0; i < k.rows; ++i) k2 += static_cast<double>(k.at<float>(i)) * k.at<float>(i);
    noise_gain = k2;  // sqrt(sum of the 2D kernel's squares) = sum of the 1D kernel's squares
  } else {
    img.convertTo(smooth, CV_32F);
  }
  // The smoothed image's own noise per block, measured rather than
  // predicted: 1.4826 MAD of differences at a lag beyond the noise's
  // correlation length. For white noise it equals noise_gain times the
  // pixel noise; for correlated noise (JPEG's 8 x 8 blocks, demosaicing,
  // denoising) the white-noise prediction from adjacent pixels is several
  // times too small and the threshold would cut through the noise. The
  // threshold uses the larger of the two.
  cv::Mat smooth_noise_blocks(nby, nbx, CV_32F);
  {
    const int lag = std::max(
        kMinNoiseLagPx, 2 * static_cast<int>(std::ceil(3.0 * options.smoothing_sigma_px)));
    for (int by = 0; by < nby; ++by) {
      for (int bx = 0; bx < nbx; ++bx) {
        const int x0 = bx * B, x1 = std::min(W, x0 + B);
        const int y0 = by * B, y1 = std::min(H, y0 + B);
        diffs.clear();
        for (int y = y0; y < y1; y += stride) {
          const float* row = smooth.ptr<float>(y);
          for (int x = x0; x < x1 && x + lag < W; x += stride) {
            diffs.push_back(std::fabs(row[x + lag] - row[x]));
          }
        }
        const double sigma = diffs.empty() ? 0.0 : 1.4826 * Median(&diffs) / std::sqrt(2.0);
        smooth_noise_blocks.at<float>(by, bx) = static_cast<float>(
            std::max(sigma, noise_gain * noise_blocks.at<float>(by, bx)));
      }
    }
    if (nbx >= 5 && nby >= 5) {
      cv::Mat filtered;
      cv::medianBlur(smooth_noise_blocks, filtered, 5);
      smooth_noise_blocks = filtered;
    } else if (nbx >= 3 && nby >= 3) {
      cv::Mat filtered;
      cv::medianBlur(smooth_noise_blocks, filtered, 3);
      smooth_noise_blocks = filtered;
    }
  }
  cv::Mat thr_blocks = bg_blocks + smooth_noise_blocks * options.threshold_sigma;
  {
    std::vector<float> n(smooth_noise_blocks.begin<float>(), smooth_noise_blocks.end<float>());
    result.threshold_dn = options.threshold_sigma * Median(&n);
  }
  const BlockGrid bg(bg_blocks, B, W, H);
  const BlockGrid noise(noise_blocks, B, W, H);
  BlockGrid thr(thr_blocks, B, W, H);
  // The "on" pixels, and the blocks holding one: the components are
  // labelled only inside groups of such blocks (a sparse mask of 18 MP costs
  // a full-image cv::connectedComponentsWithStats 100-200 ms; its active
  // blocks, little). Coarse to fine or at every pixel: the same mask
  // (vision/spot_threshold_mask.h).
  cv::Mat mask, active;
  int cells_tested = 0;
  spot_internal::ThresholdMask(smooth, thr_blocks, &thr, B, options.coarse_to_fine, &mask, &active,
                               &cells_tested);
  {
    const int C = spot_internal::kThresholdCellPx;
    const double cells = static_cast<double>((W + C - 1) / C) * ((H + C - 1) / C);
    result.fine_fraction = cells_tested / cells;
  }

  // 3. Components, per group of 8-connected active blocks (a component's
  // blocks are all active and connected, so it lies in one group's bounding
  // box; a box may overlap another group's, so a component is taken only by
  // the group of the block of its first pixel).
  cv::Mat groups, group_stats, group_centroids;
  const int num_groups =
      cv::connectedComponentsWithStats(active, groups, group_stats, group_centroids, 8, CV_32S);
  for (int group = 1; group < num_groups; ++group) {
    const cv::Rect rect =
        cv::Rect(group_stats.at<int>(group, cv::CC_STAT_LEFT) * B,
                 group_stats.at<int>(group, cv::CC_STAT_TOP) * B,
                 group_stats.at<int>(group, cv::CC_STAT_WIDTH) * B,
                 group_stats.at<int>(group, cv::CC_STAT_HEIGHT) * B) &
        cv::Rect(0, 0, W, H);
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(mask(rect), labels, stats, centroids, 8, CV_32S);
    auto label_at = [&](int x, int y) { return labels.at<int>(y - rect.y, x - rect.x); };
    for (int label = 1; label < n; ++label) {
      const int left = stats.at<int>(label, cv::CC_STAT_LEFT) + rect.x;
      const int top = stats.at<int>(label, cv::CC_STAT_TOP) + rect.y;
      const int bw = stats.at<int>(label, cv::CC_STAT_WIDTH);
      const int bh = stats.at<int>(label, cv::CC_STAT_HEIGHT);
      const int area = stats.at<int>(label, cv::CC_STAT_AREA);
      {
        int first_x = left;
        while (label_at(first_x, top) != label) ++first_x;
        if (groups.at<int>(top / B, first_x / B) != group) continue;
      }
      ++result.components;
      if (area < options.min_area_px) {
        ++result.rejected_small;
        continue;
      }
      if (area > options.max_area_px) {
        ++result.rejected_large;
        continue;
      }
      if (options.reject_border && (left == 0 || top == 0 || left + bw == W || top + bh == H)) {
        ++result.rejected_border;
        continue;
      }
      // Weighted moments of the component's pixels.
      const LocalBackground lbg(bg, left + 0.5 * (bw - 1), top + 0.5 * (bh - 1));
      double s = 0, su = 0, sv = 0, suu = 0, suv = 0, svv = 0;
      for (int y = top; y < top + bh; ++y) {
        const PixRow row(img, y);
        for (int x = left; x < left + bw; ++x) {
          if (label_at(x, y) != label) continue;
          const double val = std::max(0.0, row[x] - lbg.At(x, y));
          s += val;
          su += val * x;
          sv += val * y;
          suu += val * x * x;
          suv += val * x * y;
          svv += val * y * y;
        }
      }
      if (!(s > 0)) {
        ++result.rejected_small;
        continue;
      }
      const double mu = su / s, mv = sv / s;
      Eigen::Matrix2d m2;
      m2 << suu / s - mu * mu, suv / s - mu * mv, suv / s - mu * mv, svv / s - mv * mv;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(m2);
      const double lmin = std::max(eig.eigenvalues()(0), 1.0 / 12.0);
      const double lmax = std::max(eig.eigenvalues()(1), 1.0 / 12.0);
      if (std::sqrt(lmax / lmin) > options.max_elongation) {
        ++result.rejected_elongated;
        continue;
      }
      // Merged: distinct strong peaks with a dip between them, on the
      // component smoothed at half its own minor sigma (at least
      // smoothing_sigma_px), so that speckle lumps of a large spot merge
      // while two spots keep their dip.
      const double sm = std::max(options.smoothing_sigma_px, 0.5 * std::sqrt(lmin));
      const int margin = static_cast<int>(std::ceil(3.0 * sm)) + 1;
      const cv::Rect roi = cv::Rect(left - margin, top - margin, bw + 2 * margin, bh + 2 * margin) &
                           cv::Rect(0, 0, W, H);
      cv::Mat local;
      cv::Mat roi_f;
      img(roi).convertTo(roi_f, CV_32F);
      cv::GaussianBlur(roi_f, local, cv::Size(0, 0), sm, sm, cv::BORDER_REFLECT);
      auto local_at = [&](int x, int y) {
        return static_cast<double>(local.at<float>(y - roi.y, x - roi.x)) - lbg.At(x, y);
      };
      struct Peak {
        int x, y;
        double value;
      };
      std::vector<Peak> peaks;
      double max_val = -1e300;
      for (int y = top; y < top + bh; ++y) {
        for (int x = left; x < left + bw; ++x) {
          if (label_at(x, y) != label) continue;
          const float centre = local.at<float>(y - roi.y, x - roi.x);
          bool is_max = true;
          for (int dy = -1; dy <= 1 && is_max; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              const int xx = x + dx - roi.x, yy = y + dy - roi.y;
              if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= roi.width || yy >= roi.height) {
                continue;
              }
              if (local.at<float>(yy, xx) > centre) {
                is_max = false;
                break;
              }
            }
          }
          const double value = local_at(x, y);
          max_val = std::max(max_val, value);
          if (is_max) peaks.push_back({x, y, value});
        }
      }
      std::sort(peaks.begin(), peaks.end(), [](const Peak& p, const Peak& q) { return p.value > q.value; });
      std::vector<Peak> kept;
      const double sep2 = options.min_peak_separation_px * options.min_peak_separation_px;
      for (const Peak& p : peaks) {
        if (p.value < 0.5 * max_val) break;
        bool far = true;
        for (const Peak& k : kept) {
          const double dx = p.x - k.x, dy = p.y - k.y;
          if (dx * dx + dy * dy < sep2) far = false;
        }
        if (far) kept.push_back(p);
        if (kept.size() >= 6) break;
      }
      bool merged = false;
      for (size_t i = 0; i < kept.size() && !merged; ++i) {
        for (size_t j = i + 1; j < kept.size() && !merged; ++j) {
          const double dx = kept[j].x - kept[i].x, dy = kept[j].y - kept[i].y;
          const int steps = static_cast<int>(std::ceil(std::hypot(dx, dy)));
          double dip = 1e300;
          for (int k = 1; k < steps; ++k) {
            const double t = static_cast<double>(k) / steps;
            const int x = static_cast<int>(std::lround(kept[i].x + t * dx));
            const int y = static_cast<int>(std::lround(kept[i].y + t * dy));
            dip = std::min(dip, local_at(x, y));
          }
          if (dip < options.merged_dip_fraction * std::min(kept[i].value, kept[j].value)) merged = true;
        }
      }
      if (merged) {
        ++result.rejected_merged;
        continue;
      }

      // 4. Centroid in a window, re-centred twice.
      const int half = std::clamp(static_cast<int>(std::ceil(0.625 * std::max(bw, bh) + 2.0)),
                                  options.min_window_half_px, options.max_window_half_px);
      const double sigma_bg = noise.At(mu, mv);
      CentroidResult c;
      double cu = mu, cv_ = mv;
      Window w{};
      for (int pass = 0; pass < 3; ++pass) {
        w = MakeWindow(cu, cv_, half, W, H);
        if (w.x0 > w.x1 || w.y0 > w.y1) {  // the centroid wandered off the image
          c.ok = false;
          break;
        }
        const CentroidResult next = Centroid(img, lbg, w, sigma_bg, options.gain_e_per_dn);
        if (!next.ok) break;
        c = next;
        cu = c.u;
        cv_ = c.v;
      }
      if (!c.ok) {
        ++result.rejected_small;
        continue;
      }
      DetectedSpot spot;
      spot.area_px = area;
      spot.centroid_u_px = c.u;
      spot.centroid_v_px = c.v;
      spot.flux_dn = c.flux;
      spot.background_dn = lbg.At(c.u, c.v);
      if (w.clipped) spot.flags |= kSpotNearBorder;
      int saturated = 0;
      std::vector<Pixel> pixels;
      pixels.reserve(static_cast<size_t>((w.x1 - w.x0 + 1) * (w.y1 - w.y0 + 1)));
      for (int y = w.y0; y <= w.y1; ++y) {
        const PixRow row(img, y);
        for (int x = w.x0; x <= w.x1; ++x) {
          if (row[x] >= saturation) {
            ++saturated;
            continue;
          }
          double var = sigma_bg * sigma_bg;
          if (options.gain_e_per_dn > 0) {
            var += std::max(0.0, row[x] - spot.background_dn) / options.gain_e_per_dn;
          }
          pixels.push_back({static_cast<double>(x), static_cast<double>(y), row[x], 1.0 / var});
        }
      }
      spot.saturated_px = saturated;
      if (saturated > 0) spot.flags |= kSpotSaturated;

      FitResult fit;
      if (options.refine_with_fit) {
        // Start: centroid, window moments (less the pixel box), amplitude from
        // the flux (robust to clipping).
        Eigen::Matrix2d shape = c.shape - Eigen::Matrix2d::Identity() / 12.0;
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> se(shape);
        Eigen::Vector2d ev = se.eigenvalues().cwiseMax(0.25);
        shape = se.eigenvectors() * ev.asDiagonal() * se.eigenvectors().transpose();
        const Eigen::Matrix2d P = shape.inverse();
        const double amp = std::max(c.peak, c.flux / (2 * kPi * std::sqrt(shape.determinant())));
        Vec7 start;
        start << c.u, c.v, amp, spot.background_dn, P(0, 0), P(0, 1), P(1, 1);
        fit = FitGaussian(pixels, start, w, options.max_iterations);
        // Multiplicative (speckle) noise: residual variance sigma_i^2 + gamma^2 s_i^2,
        // s_i the fitted signal; gamma^2 by moments. When it matters at the
        // peak, refit with those weights (they flatten the core's weight, so
        // the lumpy core no longer dominates the centre).
        if (fit.ok) {
          double num = 0, den = 0;
          std::vector<double> signal2(pixels.size());
          for (size_t i = 0; i < pixels.size(); ++i) {
            const Pixel& p = pixels[i];
            const double du = p.x - fit.u, dv = p.y - fit.v;
            const Eigen::Vector2d d(du, dv);
            const double sig = fit.amplitude * std::exp(-0.5 * d.dot(fit.shape.ldlt().solve(d)));
            const double r = p.value - fit.background - sig;
            signal2[i] = sig * sig;
            num += signal2[i] * (r * r - 1.0 / p.weight);
            den += signal2[i] * signal2[i];
          }
          const double gamma2 = options.speckle_contrast > 0
                                    ? options.speckle_contrast * options.speckle_contrast
                                    : (den > 0 ? std::max(0.0, num / den) : 0.0);
          if (gamma2 * fit.amplitude * fit.amplitude > 0.25 * sigma_bg * sigma_bg) {
            std::vector<Pixel> reweighted = pixels;
            for (size_t i = 0; i < pixels.size(); ++i) {
              reweighted[i].weight = 1.0 / (1.0 / pixels[i].weight + gamma2 * signal2[i]);
            }
            const Eigen::Matrix2d P2 = fit.shape.inverse();
            Vec7 start2;
            start2 << fit.u, fit.v, fit.amplitude, fit.background, P2(0, 0), P2(0, 1), P2(1, 1);
            const FitResult refit = FitGaussian(reweighted, start2, w, options.max_iterations);
            if (refit.ok) {
              fit = refit;
              fit.speckle_gamma = std::sqrt(gamma2);
              std::vector<double> base_var(pixels.size());
              for (size_t i = 0; i < pixels.size(); ++i) base_var[i] = 1.0 / pixels[i].weight;
              SpeckleCovariance(reweighted, base_var, gamma2, options.speckle_grain_px, w, &fit);
            }
          }
        }
      }
      if (fit.ok) {
        spot.u_px = fit.u;
        spot.v_px = fit.v;
        spot.covariance_px2 = fit.covariance;
        spot.peak_dn = fit.amplitude;
        spot.background_dn = fit.background;
        spot.shape_px2 = fit.shape;
        spot.reduced_chi2 = fit.reduced_chi2;
        spot.speckle_contrast = fit.speckle_gamma;
        if (fit.reduced_chi2 > 4.0) spot.flags |= kSpotPoorFit;
      } else {
        if (options.refine_with_fit) spot.flags |= kSpotFitFailed;
        spot.u_px = c.u;
        spot.v_px = c.v;
        spot.covariance_px2 = c.covariance;
        spot.peak_dn = c.peak;
        spot.shape_px2 = c.shape;
      }
      spot.snr = spot.peak_dn / sigma_bg;
      result.spots.push_back(spot);
    }
  }
  std::sort(result.spots.begin(), result.spots.end(), [](const DetectedSpot& a, const DetectedSpot& b) {
    return a.v_px != b.v_px ? a.v_px < b.v_px : a.u_px < b.u_px;
  });
  // 6. Duplicates: a sweep along v (sorted) over the pairs closer than the
  // separation; the lower peak of each such pair is dropped.
  const double separation = options.min_spot_separation_px;
  if (separation > 0.0 && result.spots.size() > 1) {
    std::vector<bool> dropped(result.spots.size(), false);
    for (size_t i = 0; i < result.spots.size(); ++i) {
      const DetectedSpot& a = result.spots[i];
      for (size_t j = i + 1; j < result.spots.size(); ++j) {
        const DetectedSpot& b = result.spots[j];
        if (b.v_px - a.v_px >= separation) break;
        if (std::hypot(b.u_px - a.u_px, b.v_px - a.v_px) >= separation) continue;
        dropped[b.peak_dn > a.peak_dn ? i : j] = true;
      }
    }
    std::vector<DetectedSpot> kept;
    kept.reserve(result.spots.size());
    for (size_t i = 0; i < result.spots.size(); ++i) {
      if (dropped[i]) {
        ++result.rejected_duplicate;
      } else {
        kept.push_back(result.spots[i]);
      }
    }
    result.spots = std::move(kept);
  }
  return result;
}

}  // namespace opl
