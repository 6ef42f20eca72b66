// Camera calibration from several images of a known planar board
// (docs/targets_and_calibration.md).
//
// The model is the camera of vision/camera_model.h (pinhole + Brown-Conrady,
// OpenCV's order and pixel convention). Each view v sees the board at an
// unknown pose cam_from_board_v; the intrinsics and the poses minimise the
// sum of squared reprojection errors of the board's corners (Zhang's planar
// initialisation, then Levenberg-Marquardt: cv::calibrateCamera, extended
// form). The result reports what a user needs to trust a calibration: the
// overall and per-view RMS reprojection error, and the standard deviation of
// every intrinsic parameter, to first order. Two ways:
//  - views with pixel covariance blocks (BoardView; tag boards: each tag's
//    4 corners from the edge fit, whose neighbouring corners share an edge
//    and so have correlated errors): the sandwich
//      Cov = lambda (J^T J)^-1 J^T Sigma J (J^T J)^-1
//    of the least-squares estimate under the corners' block covariance
//    Sigma, with lambda = r^T Sigma^-1 r / (2N - P) (1 when the detector's
//    covariances are the size of the residuals; it follows them otherwise);
//  - otherwise (chessboards) the inverse of the Gauss-Newton normal matrix
//    scaled by the residual variance: sum of squared residuals / (2N - P)
//    for N corners, P free parameters, which assumes independent, equal
//    corner noise. OpenCV before 4.8 (and 3.4.20) divides by N - P instead
//    (opencv/opencv#19803, fixed by #22992), which overstates every standard
//    deviation by about sqrt(2); this is corrected here, and checked against
//    a Monte Carlo in the tests.
// Both assume a correct model (no board or lens model error).
//
// Boards:
//  - TagBoard: a grid of tag36h11 tags (vision/tag_detection.h), numbered
//    row-major from first_id. Board frame: origin at the top-left corner of
//    the black square of the top-left tag, x to the right along a row of
//    tags, y down along a column, z = x cross y (into the board, away from a
//    camera that sees it unmirrored). Every detected tag gives 4 corners, so
//    a partly visible or partly occluded board still contributes.
//  - Chessboard: inner corners found by cv::findChessboardCorners and refined
//    by cv::cornerSubPix; corner (i, j) (row i, column j, in the detector's
//    order) is at (j * square, i * square, 0). The whole board must be seen.
//
// Errors (Status, never an abort): bad options or board; fewer views than
// CameraCalibrationOptions::min_views (at least 3: a plane gives two
// constraints on the intrinsics per view); "image N: no board found" (or
// fewer than min_corners_per_view corners); an empty or wrongly typed image;
// images of different sizes; a solve that does not give finite parameters.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/vision/camera_model.h"
#include "opl/vision/tag_detection.h"

namespace opl {

// A grid of tag36h11 tags (frame: see above).
struct TagBoard {
  int columns = 0;        // tags per row, >= 1
  int rows = 0;           // tags per column, >= 1
  double tag_size = 0.0;  // side of a tag's black square [board units, e.g. mm], > 0
  double tag_gap = 0.0;   // gap between neighbouring black squares [board units], >= 0
  int first_id = 0;       // id of the top-left tag; ids run row-major; all ids < 587

  Status Validate() const;
  int NumTags() const { return columns * rows; }
  bool HasTag(int id) const { return id >= first_id && id < first_id + NumTags(); }
  // The corners of tag `id`'s black square in the board frame, in the corner
  // order of TagDetection (top-left, top-right, bottom-right, bottom-left as
  // printed). InvalidArgument for an id not on the board.
  Result<std::array<Eigen::Vector3d, 4>> TagCorners(int id) const;
};

// A chessboard given by its inner corners (OpenCV's sample: 9 x 6).
struct Chessboard {
  int inner_columns = 9;     // inner corners per row, >= 2
  int inner_rows = 6;        // inner corners per column, >= 2
  double square_size = 1.0;  // side of a square [board units], > 0

  Status Validate() const;
};

// Corresponding board points and image pixels of one view.
struct BoardView {
  std::string name;                           // for messages, e.g. "left01.jpg"
  std::vector<Eigen::Vector3d> points_in_board;  // z = 0
  std::vector<Eigen::Vector2d> pixels;           // same order
  // Optional: the covariance of the pixels [px^2] as blocks along `pixels`:
  // each block is the full covariance of the next rows() / 2 corners
  // (x and y of each corner in turn), e.g. 8 x 8 for a tag's 4 corners,
  // whose edge fits share edges. Empty: unknown (the corners are then taken
  // as independent, of one common variance; see CalibrateCamera).
  std::vector<Eigen::MatrixXd> pixel_covariance_blocks_px2{};
};

struct CameraCalibrationOptions {
  int min_views = 3;             // fewer usable views is an error; >= 3
  int min_corners_per_view = 8;  // a view with fewer corners is "no board found"; >= 6
  bool fix_k3 = true;            // k3 held at 0 (recommended unless the lens is very wide)
  bool fix_tangential = false;   // p1 = p2 = 0 held
  bool fix_aspect_ratio = false; // fx / fy held at 1 (then fy's std dev is fx's)
  // Termination of the Levenberg-Marquardt solve (OpenCV's defaults).
  int max_iterations = 30;                 // >= 1
  double parameter_tolerance = 2.220446049250313e-16;  // relative change that stops it, in (0, 1)
  // Tag detection on TagBoard images.
  TagDetectionOptions detection;
  // Chessboard corner refinement: cornerSubPix half window [px], >= 2.
  int chessboard_subpix_half_window_px = 11;

  Status Validate() const;
};

struct CameraCalibration {
  CameraIntrinsics intrinsics;
  // Standard deviation of fx, fy, cx, cy, k1, k2, p1, p2, k3 (kNumCameraParameters
  // order; 0 for a parameter held fixed) [px for fx..cy, unitless for the rest].
  std::array<double, kNumCameraParameters> intrinsics_std{};
  double rms_px = 0.0;                 // RMS reprojection error over all corners
  std::vector<double> view_rms_px;     // per view (RMS of its corners)
  std::vector<Rigid3d> cam_from_board; // per view
  std::vector<std::string> view_names; // per view
  std::vector<int> view_num_corners;   // per view
  int num_views = 0;
  int num_corners = 0;
  // How intrinsics_std was found (CalibrateCamera): true from the views'
  // pixel covariance blocks, false from the residuals alone.
  bool std_from_pixel_covariances = false;

  // A few lines: the intrinsics with their std devs, the RMS, the worst views.
  std::string Report() const;
};

// Calibrates from corresponding points (the boards already detected). All
// pixels must lie in a width_px x height_px image.
Result<CameraCalibration> CalibrateCamera(const std::vector<BoardView>& views, int width_px,
                                          int height_px, const CameraCalibrationOptions& options);

// The corners of the tags of `board` detected in `image` (DetectTags with
// options.detection; tags of other ids ignored). NoSolution when fewer than
// min_corners_per_view corners are found.
Result<BoardView> DetectTagBoardView(const cv::Mat& image, const TagBoard& board,
                                     const CameraCalibrationOptions& options);

// The inner corners of `board` in `image` (8-bit gray or BGR). NoSolution when
// the chessboard is not found.
Result<BoardView> DetectChessboardView(const cv::Mat& image, const Chessboard& board,
                                       const CameraCalibrationOptions& options);

// Detects the board in every image and calibrates. `image_names` (optional,
// same size as images) name the views in messages; "image N" otherwise.
Result<CameraCalibration> CalibrateCameraFromTagBoard(const std::vector<cv::Mat>& images,
                                                      const TagBoard& board,
                                                      const CameraCalibrationOptions& options,
                                                      const std::vector<std::string>& image_names = {});
Result<CameraCalibration> CalibrateCameraFromChessboard(const std::vector<cv::Mat>& images,
                                                        const Chessboard& board,
                                                        const CameraCalibrationOptions& options,
                                                        const std::vector<std::string>& image_names = {});

}  // namespace opl
