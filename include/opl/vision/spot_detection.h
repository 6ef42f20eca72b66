// Detecting laser spots in an image and measuring their centres to a fraction
// of a pixel (docs/spot_detection.md).
//
// Input: one single-channel image, CV_8U or CV_16U (a camera's raw or
// monochrome output; convert colour images first). Coordinates are OpenCV's
// pixel convention (vision/camera_model.h): (0, 0) is the CENTRE of the
// top-left pixel, u to the right, v down.
//
// The algorithm:
//  1. Background and noise, local and robust. The image is cut into blocks of
//     background_block_px; in each block the median of a sample of pixels is
//     the background and 1.4826 MAD(a - b) / sqrt(2) of horizontally adjacent
//     pixel pairs (a, b) the noise sigma (differences cancel smooth
//     background and gradients); about 16 x 16 pixels are sampled per block.
//     Both block grids are median-filtered (3 x 3; the noise 5 x 5: a spot
//     filling a block does not lift its background) and interpolated
//     bilinearly between block centres.
//  2. Threshold. The background-subtracted image is smoothed by a Gaussian of
//     smoothing_sigma_px (a matched filter for spots of a few px); a pixel is
//     "on" when the smoothed value exceeds threshold_sigma times the noise of
//     the smoothed image: the block noise times the filter's white-noise gain
//     sqrt(sum k^2), or, where larger, the smoothed image's noise measured
//     per block (1.4826 MAD / sqrt(2) of differences 8 px apart, at least 6
//     smoothing sigmas), which JPEG's correlated noise needs. The pixels are
//     compared coarse to fine (SpotDetectionOptions::coarse_to_fine): only
//     in the 8 x 8 cells whose smoothed maximum exceeds a lower bound of the
//     threshold over the cell; the same mask as comparing every pixel.
//  3. Components (cv::connectedComponentsWithStats, 8-connected, run only
//     inside groups of background blocks holding "on" pixels). Rejected:
//     area outside [min_area_px, max_area_px]; touching the image border
//     (its centre would be biased); second-moment elongation (major / minor
//     sigma) above max_elongation; several peaks (merged spots: two local
//     maxima, each above half the component's maximum, at least
//     min_peak_separation_px apart, with a dip between them below
//     merged_dip_fraction of the lower one, on the component smoothed by a
//     Gaussian of half its minor second-moment sigma, at least
//     smoothing_sigma_px, so that the speckle lumps of one spot do not count
//     as peaks).
//  4. Centre. First the intensity-weighted centroid of the
//     background-subtracted pixels in a square window around the component
//     (half-size from its bounding box), iterated twice with the window
//     re-centred. Then (refine_with_fit) a 2D elliptical Gaussian
//       m(u, v) = b + A exp(-1/2 d^T P d),  d = (u - u0, v - v0),
//     7 parameters (u0, v0, A, b, P11, P12, P22), fitted by
//     Levenberg-Marquardt to the pixels of that window, saturated pixels
//     (>= saturation_dn) EXCLUDED: the unsaturated wings still determine the
//     centre of a clipped spot, which a centroid cannot. Pixels are weighted
//     by 1 / (noise^2 + signal / gain) when gain_e_per_dn > 0, equally
//     otherwise. When the residuals show multiplicative noise (speckle:
//     variance gamma^2 s_i^2, s_i the fitted signal, gamma^2 by moments, or
//     the speckle_contrast option) that matters at the peak, the fit is
//     repeated with weights 1 / (sigma_i^2 + gamma^2 s_i^2), so that the lumpy
//     core no longer dominates the centre. The Gaussian is point-sampled:
//     a pixel-integrated Gaussian is close to a Gaussian of sigma^2 + 1/12,
//     and the centre is unbiased by symmetry (measured: 0.011-0.013 px RMS
//     at SNR 100).
//     Why a fit: at SNR 100 the fit's centre scatters ~0.012 px; the centroid
//     of the same window 4-13 times more (it weights the noise of the wings
//     by their distance), is biased by saturation, and is worse under speckle
//     too (docs/spot_detection.md has the measured figures).
//  6. Duplicates: of two detections whose centres are closer than
//     min_spot_separation_px, the one of lower peak is dropped (a lumpy spot
//     is one spot).
//  5. Uncertainty. The centre's 2x2 covariance is s^2 (J^T W J)^-1 restricted
//     to (u0, v0), s^2 = chi^2 / (n - 7) the reduced chi-square. After the
//     speckle reweighting it is the sandwich H^-1 M H^-1 with the speckle
//     correlated between pixels, covariance gamma^2 s_i s_j
//     exp(-d^2 / (2 g^2)), g the grain (speckle_grain_px, or estimated from
//     the residuals' lag-1 correlation: then an underestimate, see
//     SpotDetectionOptions::speckle_contrast). For the centroid fallback it
//     is the propagated pixel noise. Every covariance is symmetric to the
//     bit; a fit whose covariance is not positive definite is not used (the
//     centroid is reported, flagged kSpotFitFailed).
//
// Errors (Status): InvalidArgument for an empty image, a wrong type or
// channel count (the message names the type, e.g. "CV_32FC1"), or bad
// options. An image without spots is a valid result with no spots.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"

namespace opl {

struct SpotDetectionOptions {
  // Block size of the background and noise estimate [px], >= 8. Larger than
  // a spot (a few spot diameters), smaller than background variations.
  int background_block_px = 64;
  // Sigma of the Gaussian smoothing before thresholding [px], in [0, 10]
  // (0: no smoothing). About the spot's sigma is optimal for detection.
  double smoothing_sigma_px = 1.0;
  // Detection threshold, in noise standard deviations of the smoothed
  // image, > 0. At 5, white noise smoothed at 1 px crosses it in ~20 small
  // patches per MP (most rejected by min_area_px, not all); at 6, none was
  // seen in the tests' 1.6 MP of noise. A spot of SNR 20 (peak / noise) and
  // sigma 1 px reaches ~35 sigma of the smoothed image.
  double threshold_sigma = 6.0;
  // Noise floor [DN] (an 8-bit image with almost no noise has MAD 0), > 0.
  double min_noise_dn = 0.5;
  // Accepted component area, pixels above threshold.
  int min_area_px = 4;
  int max_area_px = 20000;
  // Maximum ratio of major to minor sigma of a component's second moments.
  double max_elongation = 4.0;
  // Merged-spot test (step 3 of the header): peaks at least this far apart
  // [px] with a dip between them below this fraction of the lower peak.
  double min_peak_separation_px = 3.0;
  double merged_dip_fraction = 0.7;
  // Duplicates (step 6): two detections whose centres end closer than this
  // [px] are one spot seen twice (a spot broken into two components, e.g.
  // by JPEG's chroma blocks, whose two fits converge on it): the one of
  // lower peak is dropped. >= 0 (0: keep both).
  double min_spot_separation_px = 2.0;
  // Reject components that touch the image border.
  bool reject_border = true;
  // Pixels at or above this value are saturated [DN]; 0: the type's maximum
  // (255 or 65535). Set it for a 10/12-bit sensor in a 16-bit container.
  double saturation_dn = 0.0;
  // Refine the centroid with the elliptical Gaussian fit (step 4). false:
  // report the centroid.
  bool refine_with_fit = true;
  // Conversion gain [electrons/DN] for the fit's weights; 0: unknown, equal
  // weights. >= 0.
  double gain_e_per_dn = 0.0;
  // Fit window half-size bounds [px].
  int min_window_half_px = 4;
  int max_window_half_px = 40;
  // Levenberg-Marquardt iterations, >= 1.
  int max_iterations = 50;
  // Speckle of the spots' light, when known (from the optics, or measured
  // once from repeated images): contrast c in [0, 1] (std / mean of the
  // light's multiplicative noise) and intensity correlation length [px]
  // (lab/spot_image.h defines both). 0: estimated per spot from the fit's
  // residuals, which UNDERESTIMATES both (the fit absorbs the speckle's
  // coarse part): the reported covariance is then too small by a factor
  // 2-6 in sigma under strong speckle (docs/spot_detection.md). Used for the
  // weights and the covariance (step 5), not for detection.
  double speckle_contrast = 0.0;
  double speckle_grain_px = 0.0;
  // Step 2's mask coarse to fine: per 8 x 8 cell the smoothed image's
  // maximum against a lower bound of the threshold, and the pixels compared
  // only in the cells that exceed it. The same mask, hence the same spots,
  // to the bit (src/vision/spot_threshold_mask.h argues why no "on" pixel is
  // missed); false: every pixel compared (the reference the tests compare
  // with).
  bool coarse_to_fine{true};

  // Checks every field; the message names the field, its value and the rule.
  Status Validate() const;
};

// Flags of a detected spot (bit mask).
enum SpotFlag : uint32_t {
  kSpotSaturated = 1u << 0,   // at least one saturated pixel (excluded from the fit)
  kSpotFitFailed = 1u << 1,   // the fit did not converge, left the window or gave no positive
                              // definite covariance: centroid reported
  kSpotPoorFit = 1u << 2,     // reduced chi^2 above 4 (speckle, blemish, wrong model)
  kSpotNearBorder = 1u << 3,  // fit window clipped by the image border
};

struct DetectedSpot {
  double u_px = 0.0;  // centre, OpenCV pixel convention [px]
  double v_px = 0.0;
  // Covariance of (u, v) [px^2] (header, step 5).
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Zero();
  double centroid_u_px = 0.0;  // intensity-weighted centroid (step 4) [px]
  double centroid_v_px = 0.0;
  double peak_dn = 0.0;        // fitted amplitude A (centroid: brightest background-subtracted pixel) [DN]
  double background_dn = 0.0;  // local background (fitted b, or the block estimate) [DN]
  double flux_dn = 0.0;        // sum of background-subtracted pixels in the window [DN]
  // Shape: second moments of the light [px^2]. From the fit: P^-1 (the
  // point-sampled Gaussian: a pixel-integrated spot of covariance C fits
  // C + I/12). From the centroid: window second moments.
  Eigen::Matrix2d shape_px2 = Eigen::Matrix2d::Zero();
  int area_px = 0;               // pixels above threshold
  int saturated_px = 0;          // saturated pixels in the window
  double reduced_chi2 = 0.0;     // of the fit (1 for pure noise when gain is given or noise uniform)
  double snr = 0.0;              // peak / background noise sigma
  // Multiplicative noise of the spot's light (speckle contrast), estimated
  // from the fit's residuals when it is significant (step 4), else 0.
  double speckle_contrast = 0.0;
  uint32_t flags = 0;            // SpotFlag bits

  bool has(SpotFlag f) const { return (flags & f) != 0; }
};

struct SpotDetectionResult {
  std::vector<DetectedSpot> spots;  // accepted spots, ordered by v then u
  double background_dn = 0.0;       // median block background [DN]
  double noise_dn = 0.0;            // median block noise sigma [DN]
  double threshold_dn = 0.0;        // median threshold on the smoothed image above background [DN]
  int components = 0;               // connected components found
  int rejected_small = 0;           // area < min_area_px
  int rejected_large = 0;           // area > max_area_px
  int rejected_border = 0;          // touching the border
  int rejected_elongated = 0;       // elongation > max_elongation
  int rejected_merged = 0;          // several peaks
  int rejected_duplicate = 0;       // centre within min_spot_separation_px of a brighter one (step 6)
  // Fraction of the image's 8 x 8 cells thresholded pixel by pixel (1 when
  // SpotDetectionOptions::coarse_to_fine is off).
  double fine_fraction{};

  // Short readable summary: counts, background, noise, threshold.
  std::string ToText() const;
};

// See the header comment. `image`: CV_8UC1 or CV_16UC1.
Result<SpotDetectionResult> DetectSpots(const cv::Mat& image,
                                        const SpotDetectionOptions& options = SpotDetectionOptions());

// "CV_16UC1" etc. for messages.
std::string OpenCvTypeName(int type);

}  // namespace opl
