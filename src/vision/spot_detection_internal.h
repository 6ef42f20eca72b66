// Private to src/vision: the pieces of DetectSpots shared by its files
// (opl/vision/spot_detection.h has the contract).
//
//   spot_background.cc     the background and noise model: a grid of block
//                          values and its local plane at a spot; Median
//   spot_centroid.cc       a spot's window and its intensity-weighted centroid
//   spot_gaussian_fit.cc   the elliptical Gaussian fit of a spot and the
//                          covariance of its centre under correlated speckle
//   spot_detection.cc      DetectSpots: background, threshold, components,
//                          windows, fits; the options and the result text
//
// Pixel convention: pixel (x, y) = (column, row) has its centre at (u, v) =
// (x, y); positions and sizes in px, values in DN (the image's units).
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace opl {
namespace spot_internal {

// A coarse grid of per-block values, interpolated bilinearly between block
// centres (clamped beyond the outer centres).
class BlockGrid {
 public:
  BlockGrid(cv::Mat values, int block_px, int width, int height)
      : values_(std::move(values)), block_(block_px), width_(width), height_(height) {}

  // The value at (u, v) [px].
  double At(double u, double v) const;

  // Values of row v at every column, into `out` (size width). The column
  // interpolation table is built on the first call.
  void Row(int v, std::vector<float>* out);

  // Values of row v at columns [u0, u1) into out[0 .. u1 - u0), the very
  // arithmetic of Row (the same floats, to the bit).
  void RowSpan(int v, int u0, int u1, float* out);

 private:
  // The column table (first call) and row_ for row v (kept while v repeats).
  void PrepareRow(int v);
  float ValueInRow(int u) const {
    const size_t k = static_cast<size_t>(u);
    return static_cast<float>((1 - col_t_[k]) * row_[static_cast<size_t>(col_i0_[k])] +
                              col_t_[k] * row_[static_cast<size_t>(col_i1_[k])]);
  }

  // Block b covers [b B, min((b+1) B, size)); its centre is the midpoint.
  double Centre(int b, int size) const;
  void Coordinate(double p, int size, int n, int* i0, int* i1, double* t) const;

  cv::Mat values_;  // CV_32F
  int block_;
  int width_, height_;
  std::vector<int> col_i0_, col_i1_;
  std::vector<double> col_t_, row_;
  int row_v_ = -1;  // the row row_ holds
};

// One row of a CV_8U or CV_16U image, read as float.
class PixRow {
 public:
  PixRow(const cv::Mat& m, int y)
      : u8_(m.depth() == CV_8U ? m.ptr<uint8_t>(y) : nullptr),
        u16_(m.depth() == CV_8U ? nullptr : m.ptr<uint16_t>(y)) {}
  float operator[](int x) const { return u8_ != nullptr ? u8_[x] : u16_[x]; }

 private:
  const uint8_t* u8_;
  const uint16_t* u16_;
};

// The median of *v (reordered); 0 when empty.
double Median(std::vector<float>* v);

// The background near one spot as a plane through the block grid's value at
// a centre and its slopes over +-16 px: evaluating the grid per pixel costs
// more than the rest of the spot's work, and over a window the grid is
// (piecewise) linear anyway.
class LocalBackground {
 public:
  LocalBackground(const BlockGrid& grid, double u, double v) : u_(u), v_(v) {
    b0_ = grid.At(u, v);
    gu_ = (grid.At(u + 16, v) - grid.At(u - 16, v)) / 32.0;
    gv_ = (grid.At(u, v + 16) - grid.At(u, v - 16)) / 32.0;
  }
  double At(double u, double v) const { return b0_ + gu_ * (u - u_) + gv_ * (v - v_); }

 private:
  double u_, v_, b0_, gu_, gv_;
};

struct Window {
  int x0, y0, x1, y1;  // inclusive
  bool clipped;
};

// The window of half-size `half` around (u, v), clipped to the image.
Window MakeWindow(double u, double v, int half, int width, int height);

struct CentroidResult {
  double u = 0, v = 0, flux = 0, peak = 0;
  Eigen::Matrix2d shape = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  bool ok = false;
};

// Intensity-weighted centroid of (image - background) over window w.
CentroidResult Centroid(const cv::Mat& img, const LocalBackground& bg, const Window& w, double noise,
                        double gain);

struct FitResult {
  double u = 0, v = 0, amplitude = 0, background = 0, reduced_chi2 = 0;
  double speckle_gamma = 0;  // multiplicative noise fraction used in the weights (0: none)
  double speckle_grain = 0;  // its correlation length estimated from the residuals [px]
  Eigen::Matrix<double, 7, 1> theta = Eigen::Matrix<double, 7, 1>::Zero();
  Eigen::Matrix2d shape = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  bool ok = false;
};

struct Pixel {
  double x, y, value, weight;
};

// Model b + A exp(-q/2), q = d^T P d; theta = (u0, v0, A, b, P11, P12, P22).
using Vec7 = Eigen::Matrix<double, 7, 1>;
using Mat7 = Eigen::Matrix<double, 7, 7>;

// Levenberg-Marquardt fit of the model to the pixels from `start`; not ok when
// it leaves the window, is wider than it or has no positive-definite covariance.
FitResult FitGaussian(const std::vector<Pixel>& px, const Vec7& start, const Window& w,
                      int max_iterations);

// Covariance of the centre of a fit weighted for speckle (weights w_i =
// 1 / (base_i + gamma^2 s_i^2)) when the speckle is correlated between
// pixels: the sandwich H^-1 M H^-1 with
//   M = sum_ij w_i w_j J_i J_j^T (delta_ij base_i + gamma^2 s_i s_j rho(d_ij)),
//   rho(d) = exp(-d^2 / (2 g^2)),
// g estimated from the lag-1 autocorrelation of the normalised residuals of
// the speckle-dominated pixels. Sets fit->covariance and fit->speckle_grain.
void SpeckleCovariance(const std::vector<Pixel>& px, const std::vector<double>& base_var,
                       double gamma2, double known_grain, const Window& w, FitResult* fit);

}  // namespace spot_internal
}  // namespace opl
