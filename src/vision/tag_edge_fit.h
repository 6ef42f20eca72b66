// Private to src/vision: the edge model that refines a tag's corners
// (vision/tag_detection.h has the contract, docs/targets_and_calibration.md
// the figures).
//
// Each of the four edges of a tag's black square is the curve
//   d(p) = cos(theta) x + sin(theta) y - c + kappa s^2 = 0,
// with (x, y) = p - mid (mid: the initial midpoint of the edge, so that theta
// and c are nearly uncorrelated), s = u . (p - mid) along the fixed initial
// direction u, d > 0 on the outer (white) side. The image across it is a
// blurred step I(p) = a + b Phi(d(p) / sigma), fitted by Levenberg-Marquardt
// over the pixels of a band around the edge (away from the corners). A
// corner is the intersection of its two edge curves; its covariance is
// propagated from the fits' covariances (residual variance x (J^T J)^-1).
//
// Pixel convention: pixel (i, j) has its centre at (x, y) = (j, i).
#pragma once

#include <array>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace opl {
namespace tag_internal {

constexpr int kTagCells = 8;  // tag36h11: 6 x 6 data cells and a 1-cell black border

// The standard normal cdf Phi(z) and pdf phi(z).
void NormalCdfPdf(double z, double* cdf, double* pdf);

// Bilinear sample of a CV_64FC1 image at (x, y), pixel centres at integers,
// clamped to the image.
double Bilinear(const cv::Mat& image, double x, double y);

struct EdgeCurve {
  double theta = 0.0, c = 0.0, kappa = 0.0;
  Eigen::Vector2d u = Eigen::Vector2d::UnitX(), mid = Eigen::Vector2d::Zero();  // fixed parametrisation
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // of (theta, c, kappa)
  double a = 0.0, b = 0.0, sigma = 1.0;           // levels and edge spread [px]
  double rms = 0.0;                               // RMS residual [grey levels]

  double S(const Eigen::Vector2d& p) const { return u.dot(p - mid); }
  double D(const Eigen::Vector2d& p) const;
  Eigen::Vector2d Gradient(const Eigen::Vector2d& p) const;
  // d D / d (theta, c, kappa)
  Eigen::RowVector3d ParamJacobian(const Eigen::Vector2d& p) const;
};

struct EdgeFitSettings {
  double band_px = 2.0;              // half-width of the band fitted [px]
  double corner_exclusion_px = 2.5;  // pixels this close to a corner (along the edge) are not used [px]
  double max_sigma_px = 4.0;         // a fitted edge spread above this fails the fit [px]
  int min_pixels = 12;               // fewer pixels in the band fail the fit
  // Outlier pixels (FitEdge): residual above max(outlier_mad_factor x robust
  // sigma, outlier_contrast_fraction x step height) after a convergence.
  double outlier_mad_factor = 4.0;
  double outlier_contrast_fraction = 0.05;
  int max_outlier_rounds = 2;
  double max_outlier_fraction = 0.25;  // more outliers in the band fail the fit
};

// Fits the edge from corner p to corner q of a quad whose centre is `centre`
// (image: CV_64FC1). False when the band is too small, the fit does not
// converge to a dark-inside step, or its spread is out of (0.05, max_sigma_px).
bool FitEdge(const cv::Mat& image, const Eigen::Vector2d& p, const Eigen::Vector2d& q,
             const Eigen::Vector2d& centre, const EdgeFitSettings& settings, EdgeCurve* edge);

// Intersection of two edge curves near `start` (within max_move_px), and its
// covariance [px^2]. Optionally the derivatives of the corner with respect
// to each edge's (theta, c, kappa) (for the covariance of two corners that
// share an edge).
bool IntersectEdges(const EdgeCurve& e1, const EdgeCurve& e2, const Eigen::Vector2d& start,
                    double max_move_px, Eigen::Vector2d* corner, Eigen::Matrix2d* cov,
                    Eigen::Matrix<double, 2, 3>* d_corner_d_e1 = nullptr,
                    Eigen::Matrix<double, 2, 3>* d_corner_d_e2 = nullptr);

// The 6 x 6 data cells of a tag read through its corners (order of
// vision/tag_detection.h) in a CV_64FC1 image: 1 = white. Each cell's value
// is the mean of 3 x 3 bilinear samples 0.2 cell apart around its centre,
// sharpened as libapriltag's decoder does (v + sharpening (4 v - the 4
// neighbours)); the threshold is midway between two planes fitted over the
// tag, the black border's and the quiet zone's (the ring of cells around the
// tag), so that light falling off across an oblique tag is followed.
// `contrast` (optional): quiet zone - border at the tag's centre [grey levels].
cv::Mat ReadTagBits(const cv::Mat& image, const std::array<Eigen::Vector2d, 4>& corners, double sharpening,
                    double* contrast = nullptr);

}  // namespace tag_internal
}  // namespace opl
