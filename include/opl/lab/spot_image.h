// Rendering laser spots into a synthetic camera image with known truth
// (docs/spot_detection.md, "The rendering model").
//
// The model. A spot is a 2D Gaussian of light on the sensor, given in IMAGE
// coordinates (OpenCV's pixel convention, as vision/camera_model.h: (0, 0) is
// the CENTRE of the top-left pixel, u to the right, v down; pixel (row i,
// column j) covers u in [j - 0.5, j + 0.5), v in [i - 0.5, i + 0.5)):
//
//   g(u, v) = A exp(-1/2 d^T C^-1 d),   d = (u - u0, v - v0),
//
// A the peak amplitude [DN per px^2 of sensor area, i.e. the value a pixel
// would read if g were constant over it], C the 2x2 shape covariance [px^2].
// The total flux is 2 pi sqrt(det C) A [DN] (2 pi sigma^2 A for a round spot).
// Diameter: this module uses the 1/e^2 intensity diameter, D = 4 sigma
// (RoundSpotShape); an elliptical spot has 1/e^2 diameters 4 sigma_major and
// 4 sigma_minor (EllipticalSpotShape).
//
// Each pixel's clean value is the integral of g over the pixel's area, so the
// centroid of the rendered light is (u0, v0) and the sum of the pixels is the
// flux (up to the light outside the rendered window, below 2e-6 of the flux
// at 5 sigma). Axis-aligned spots (C diagonal) integrate exactly as a product
// of erf differences. Rotated ones factor as N(v) N(u | v): the u integral
// over a pixel is an erf difference, the v integral an m-point Gauss-Legendre
// rule over each pixel row (m = 8..48 nodes, more for narrower integrands;
// tests/lab/spot_image_test.cc checks pixels against brute-force integration).
// Only a window of +-window_sigmas standard deviations (per axis) around each
// spot is rendered.
//
// Speckle (optional). The laser light of a spot is multiplied by a lumpy field
//   I = g (1 - c + c S),   S = |h * w|^2 / E|h * w|^2,
// w complex white Gaussian noise on the pixel grid (real and imaginary parts
// independent, unit variance), h a Gaussian low-pass kernel of standard
// deviation `speckle_grain_px` (sampled, cv::getGaussianKernel): the field's
// autocorrelation is then exp(-r^2 / (4 grain^2)) and the intensity
// autocorrelation coefficient |mu|^2 = exp(-r^2 / (2 grain^2)), so
// `speckle_grain_px` is the correlation length of the speckle intensity. S is
// fully developed speckle (exponential statistics, mean 1, contrast
// std/mean = 1), so I / g has mean 1 and contrast c. S is sampled per pixel
// (it multiplies the pixel-integrated light). Each spot draws its own field
// (seeded from `seed` and the spot's index).
//
// Background and noise. The image is
//   DN = clip(round(B(u, v) + sum of spots + noise), 0, full scale)
// with B = background_dn + gradient_u (u - (W-1)/2) + gradient_v (v - (H-1)/2)
// (or a given background image, SpotImageOptions::background_image_dn),
// noise = Poisson shot noise of the signal in electrons (signal DN * gain,
// back to DN / gain) plus Gaussian read noise (read_noise_dn). So a flat field
// of level L has variance L / gain + read^2 [DN^2] (plus 1/12 of quantisation).
// Shot noise off: gain_e_per_dn = 0. Pixels whose noisy value exceeds full
// scale (2^bit_depth - 1) are clipped and reported (saturation).
//
// Determinism: std::mt19937_64 seeded through SplitMix64, our own normal and
// Poisson generators (no std::*_distribution), so a seed gives the same image
// with any standard library up to the last bits of the C library's maths.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"

namespace opl {

// One spot to render, in image coordinates.
struct SpotToRender {
  double u_px = 0.0;  // centre, OpenCV pixel convention [px]
  double v_px = 0.0;
  // Shape covariance [px^2], symmetric positive definite.
  Eigen::Matrix2d shape_covariance_px2 = Eigen::Matrix2d::Identity();
  // Peak amplitude A of the continuous Gaussian [DN]; for a fraction f of
  // full scale use f * SpotImageFullScale(options). Values above full scale
  // saturate.
  double peak_dn = 1000.0;
};

// Round spot of 1/e^2 diameter `diameter_px`: sigma = diameter / 4.
Eigen::Matrix2d RoundSpotShape(double diameter_px);
// Elliptical spot: 1/e^2 diameters along its major and minor axes [px], the
// major axis at `angle_rad` from +u towards +v (i.e. clockwise on screen).
Eigen::Matrix2d EllipticalSpotShape(double major_diameter_px, double minor_diameter_px,
                                    double angle_rad);

struct SpotImageOptions {
  int width_px = 640;   // image size [px], >= 1
  int height_px = 480;
  int bit_depth = 16;   // 8 (CV_8U) or 16 (CV_16U); full scale 2^bit_depth - 1 DN
  // Background level at the image centre [DN], >= 0, and its gradient
  // [DN/px] along u and v (the level is clipped at 0 where it goes negative).
  double background_dn = 100.0;
  double background_gradient_u_dn_per_px = 0.0;
  double background_gradient_v_dn_per_px = 0.0;
  // Optional background image [DN]: CV_32FC1, height_px x width_px, finite.
  // When non-empty it replaces background_dn and the gradients (B(u, v) in
  // the header is then this image, clipped at 0), e.g. a noise-free
  // rendering of targets (lab/planar_target_image.h, keep_levels) times full
  // scale, so that spots are added to it and noise is applied once.
  cv::Mat background_image_dn;
  // Speckle contrast c in [0, 1] (0: no speckle) and intensity correlation
  // length [px] (> 0; 1-2 px is typical of a laser spot seen by a camera).
  double speckle_contrast = 0.0;
  double speckle_grain_px = 1.5;
  // Conversion gain [electrons/DN]: shot noise variance signal/gain [DN^2].
  // 0 turns shot noise off. >= 0.
  double gain_e_per_dn = 0.0;
  // Gaussian read noise standard deviation [DN], >= 0.
  double read_noise_dn = 0.0;
  // Half-size of the window rendered around each spot, in standard
  // deviations of the spot along u and v; in [3, 10].
  double window_sigmas = 5.0;
  // Also return the clean image (expected value before noise, quantisation
  // and clipping; speckle included), CV_32F. Costs 4 bytes per pixel.
  bool keep_clean = false;
  // Seed of the speckle and the noise.
  uint64_t seed = 1;

  // Checks every field; the message names the field, its value and the rule.
  Status Validate() const;
};

// 2^bit_depth - 1: 255 or 65535.
double SpotImageFullScale(const SpotImageOptions& options);

// Truth of one rendered spot.
struct RenderedSpotTruth {
  double u_px = 0.0;  // the centre given
  double v_px = 0.0;
  double flux_dn = 0.0;         // clean light rendered in the image (sum of its pixels) [DN]
  int saturated_pixels = 0;     // pixels of its window at full scale
  cv::Rect window;              // pixels rendered (clipped to the image)
};

struct SpotImage {
  cv::Mat image;           // CV_16U or CV_8U, height x width
  cv::Mat saturated_mask;  // CV_8U, 255 where the pixel reads full scale (clipped)
  cv::Mat clean_dn;        // CV_32F expected value (options.keep_clean), else empty
  std::vector<RenderedSpotTruth> spots;  // input order
  int saturated_pixels = 0;              // in the whole image
};

// Renders `spots` over the background with speckle and noise as set by
// `options` (header comment). InvalidArgument for bad options or a spot with
// a non-finite centre, a non-positive or non-finite peak, or a shape
// covariance that is not symmetric positive definite or has a sigma along u
// or v outside [0.05, 1000] px (the message names the spot's index). Spots
// may lie partly or wholly outside the image. Memory: a CV_32F accumulator
// of the image size besides the output.
Result<SpotImage> RenderSpotImage(const std::vector<SpotToRender>& spots,
                                  const SpotImageOptions& options);

// A fully developed speckle intensity field (header comment), height x width,
// CV_64F, expected mean 1, intensity correlation length grain_px [px];
// seeded. InvalidArgument for a non-positive size or grain.
Result<cv::Mat> RenderSpeckleField(int width_px, int height_px, double grain_px,
                                   uint64_t seed);

}  // namespace opl
