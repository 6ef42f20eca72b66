#include "opl/vision/camera_calibration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <sstream>
#include <string>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/version.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"

namespace opl {
namespace {

constexpr int kTag36h11Count = 587;

std::string ViewName(const std::vector<std::string>& names, size_t index) {
  if (index < names.size() && !names[index].empty()) return names[index];
  return "image " + std::to_string(index);
}

Status CheckGrayImage(const cv::Mat& image, const std::string& name) {
  if (image.empty()) return Status::InvalidArgument(name + ": image is empty");
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3 && image.type() != CV_16UC1) {
    return Status::InvalidArgument(name + ": image type " + std::to_string(image.type()) +
                                   ": expected CV_8UC1, CV_8UC3 or CV_16UC1");
  }
  return Status::Ok();
}


// The sandwich standard deviations of the intrinsics (see the header) when
// every view has pixel covariance blocks covering its corners, each positive
// definite; false otherwise (the caller keeps the residual-based figures).
bool SandwichIntrinsicsStd(const std::vector<BoardView>& views, const cv::Mat& camera_matrix,
                           const cv::Mat& dist_coeffs, const std::vector<cv::Mat>& rvecs,
                           const std::vector<cv::Mat>& tvecs, const CameraCalibrationOptions& options,
                           std::array<double, kNumCameraParameters>* std_out) {
  for (const BoardView& view : views) {
    size_t rows = 0;
    for (const Eigen::MatrixXd& block : view.pixel_covariance_blocks_px2) {
      if (block.rows() < 2 || block.rows() % 2 != 0 || block.cols() != block.rows()) return false;
      rows += static_cast<size_t>(block.rows());
    }
    if (rows != 2 * view.pixels.size()) return false;
  }
  // Free intrinsics as columns of the Jacobian: each a combination of
  // projectPoints' columns fx, fy, cx, cy, k1, k2, p1, p2, k3 (6 .. 14).
  const double aspect = camera_matrix.at<double>(0, 0) / camera_matrix.at<double>(1, 1);
  std::vector<std::array<double, kNumCameraParameters>> free;  // weights on the 9 columns
  std::vector<int> free_index;                                   // its parameter (kNumCameraParameters order)
  auto add = [&](int k, int other = -1, double other_weight = 0.0) {
    std::array<double, kNumCameraParameters> w{};
    w[static_cast<size_t>(k)] = 1.0;
    if (other >= 0) w[static_cast<size_t>(other)] = other_weight;
    free.push_back(w);
    free_index.push_back(k);
  };
  if (options.fix_aspect_ratio) {
    add(1, 0, aspect);  // fy, and fx = aspect fy with it
  } else {
    add(0);
    add(1);
  }
  add(2);
  add(3);
  add(4);
  add(5);
  if (!options.fix_tangential) {
    add(6);
    add(7);
  }
  if (!options.fix_k3) add(8);
  const int ni = static_cast<int>(free.size());
  const int num_params = ni + 6 * static_cast<int>(views.size());
  Eigen::MatrixXd JtJ = Eigen::MatrixXd::Zero(num_params, num_params);
  Eigen::MatrixXd JtSJ = Eigen::MatrixXd::Zero(num_params, num_params);
  double chi2 = 0.0;
  int num_residuals = 0;
  for (size_t v = 0; v < views.size(); ++v) {
    const BoardView& view = views[v];
    std::vector<cv::Point3d> obj;
    for (const Eigen::Vector3d& P : view.points_in_board) obj.emplace_back(P.x(), P.y(), P.z());
    std::vector<cv::Point2d> projected;
    cv::Mat jacobian;
    cv::projectPoints(obj, rvecs[v], tvecs[v], camera_matrix, dist_coeffs, projected, jacobian);
    const int n = static_cast<int>(obj.size());
    // The view's Jacobian over (free intrinsics, its 6 pose parameters).
    Eigen::MatrixXd J(2 * n, ni + 6);
    Eigen::VectorXd r(2 * n);
    for (int i = 0; i < 2 * n; ++i) {
      const double* row = jacobian.ptr<double>(i);
      for (int f = 0; f < ni; ++f) {
        double sum = 0.0;
        const std::array<double, kNumCameraParameters>& weights = free[static_cast<size_t>(f)];
        for (int k = 0; k < kNumCameraParameters; ++k) sum += weights[static_cast<size_t>(k)] * row[6 + k];
        J(i, f) = sum;
      }
      for (int k = 0; k < 6; ++k) J(i, ni + k) = row[k];  // rvec, tvec
      const size_t corner = static_cast<size_t>(i / 2);
      const Eigen::Vector2d& p = view.pixels[corner];
      r(i) = i % 2 == 0 ? projected[corner].x - p.x() : projected[corner].y - p.y();
    }
    const Eigen::MatrixXd JtJv = J.transpose() * J;
    Eigen::MatrixXd JtSJv = Eigen::MatrixXd::Zero(ni + 6, ni + 6);
    int at = 0;
    for (const Eigen::MatrixXd& block : view.pixel_covariance_blocks_px2) {
      const int m = static_cast<int>(block.rows());
      const Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (block + block.transpose()));
      if (llt.info() != Eigen::Success || !block.allFinite()) return false;
      const Eigen::MatrixXd Jb = J.middleRows(at, m);
      JtSJv += Jb.transpose() * block * Jb;
      chi2 += r.segment(at, m).dot(llt.solve(r.segment(at, m)));
      at += m;
    }
    num_residuals += 2 * n;
    // Scatter into the whole problem: intrinsics first, then 6 per view.
    const int pose = ni + 6 * static_cast<int>(v);
    auto scatter = [&](const Eigen::MatrixXd& from, Eigen::MatrixXd* to) {
      to->topLeftCorner(ni, ni) += from.topLeftCorner(ni, ni);
      to->block(0, pose, ni, 6) += from.topRightCorner(ni, 6);
      to->block(pose, 0, 6, ni) += from.bottomLeftCorner(6, ni);
      to->block(pose, pose, 6, 6) += from.bottomRightCorner(6, 6);
    };
    scatter(JtJv, &JtJ);
    scatter(JtSJv, &JtSJ);
  }
  if (num_residuals <= num_params) return false;
  // (J^T J)^-1 through its equilibrated form (the columns differ in scale
  // by orders of magnitude: fx against k2).
  const Eigen::VectorXd diagonal = JtJ.diagonal();
  if (!((diagonal.array() > 0.0).all() && diagonal.allFinite())) return false;
  const Eigen::VectorXd d = diagonal.cwiseSqrt().cwiseInverse();
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(d.asDiagonal() * JtJ * d.asDiagonal());
  if (!lu.isInvertible()) return false;
  const Eigen::MatrixXd inverse = d.asDiagonal() * lu.inverse() * d.asDiagonal();
  const double lambda = chi2 / (num_residuals - num_params);
  const Eigen::MatrixXd cov = lambda * inverse * JtSJ * inverse;
  std_out->fill(0.0);
  for (int f = 0; f < ni; ++f) {
    const double var = cov(f, f);
    if (!(var > 0.0 && std::isfinite(var))) return false;
    (*std_out)[static_cast<size_t>(free_index[static_cast<size_t>(f)])] = std::sqrt(var);
  }
  if (options.fix_aspect_ratio) (*std_out)[0] = aspect * (*std_out)[1];
  return true;
}
}  // namespace

Status TagBoard::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("TagBoard." + field + " = " + FormatNumber(value) + ": " + rule);
  };
  if (columns < 1 || columns > 100) return bad("columns", columns, "must be in [1, 100]");
  if (rows < 1 || rows > 100) return bad("rows", rows, "must be in [1, 100]");
  if (!(tag_size > 0.0 && std::isfinite(tag_size))) return bad("tag_size", tag_size, "must be finite and > 0");
  if (!(tag_gap >= 0.0 && std::isfinite(tag_gap))) return bad("tag_gap", tag_gap, "must be finite and >= 0");
  if (first_id < 0 || first_id + columns * rows > kTag36h11Count) {
    return bad("first_id", first_id,
               "ids first_id .. first_id + columns * rows - 1 must lie in [0, 586] (tag36h11)");
  }
  return Status::Ok();
}

Result<std::array<Eigen::Vector3d, 4>> TagBoard::TagCorners(int id) const {
  if (!HasTag(id)) {
    return Status::InvalidArgument("TagBoard: tag id " + std::to_string(id) + " is not on the board (ids " +
                                   std::to_string(first_id) + " .. " +
                                   std::to_string(first_id + NumTags() - 1) + ")");
  }
  const int k = id - first_id;
  const int r = k / columns, c = k % columns;
  const double pitch = tag_size + tag_gap;
  const double x = c * pitch, y = r * pitch;
  return std::array<Eigen::Vector3d, 4>{Eigen::Vector3d(x, y, 0.0), Eigen::Vector3d(x + tag_size, y, 0.0),
                                        Eigen::Vector3d(x + tag_size, y + tag_size, 0.0),
                                        Eigen::Vector3d(x, y + tag_size, 0.0)};
}

Status Chessboard::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("Chessboard." + field + " = " + FormatNumber(value) + ": " + rule);
  };
  if (inner_columns < 2 || inner_columns > 200) return bad("inner_columns", inner_columns, "must be in [2, 200]");
  if (inner_rows < 2 || inner_rows > 200) return bad("inner_rows", inner_rows, "must be in [2, 200]");
  if (!(square_size > 0.0 && std::isfinite(square_size))) {
    return bad("square_size", square_size, "must be finite and > 0");
  }
  return Status::Ok();
}

Status CameraCalibrationOptions::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("CameraCalibrationOptions." + field + " = " + FormatNumber(value) +
                                   ": " + rule);
  };
  if (min_views < 3) return bad("min_views", min_views, "must be >= 3 (a planar board needs 3 views)");
  if (min_corners_per_view < 6) return bad("min_corners_per_view", min_corners_per_view, "must be >= 6");
  if (max_iterations < 1) return bad("max_iterations", max_iterations, "must be >= 1");
  if (!(parameter_tolerance > 0.0 && parameter_tolerance < 1.0)) {
    return bad("parameter_tolerance", parameter_tolerance, "must be in (0, 1)");
  }
  if (chessboard_subpix_half_window_px < 2 || chessboard_subpix_half_window_px > 50) {
    return bad("chessboard_subpix_half_window_px", chessboard_subpix_half_window_px, "must be in [2, 50]");
  }
  {
    Status s = detection.Validate();
    if (!s.ok()) return Status::InvalidArgument("CameraCalibrationOptions.detection: " + s.message());
  }
  return Status::Ok();
}

std::string CameraCalibration::Report() const {
  std::ostringstream out;
  const char* names[kNumCameraParameters] = {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"};
  const auto packed = intrinsics.Packed();
  out << "Camera calibration: " << num_views << " views, " << num_corners << " corners, image "
      << intrinsics.width_px << " x " << intrinsics.height_px << "\n";
  out << "  RMS reprojection error " << FormatPrintf("%.4f", rms_px) << " px\n";
  for (int k = 0; k < kNumCameraParameters; ++k) {
    out << "  " << names[k] << " = " << FormatNumber(packed[k], 8);
    if (intrinsics_std[k] > 0.0) {
      out << " +- " << FormatNumber(intrinsics_std[k], 3) << (k < 4 ? " px" : "") << " (1 sigma)";
    } else {
      out << (k < 4 ? " px" : "") << " (fixed)";
    }
    out << "\n";
  }
  std::vector<size_t> order(view_rms_px.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return view_rms_px[a] > view_rms_px[b]; });
  out << "  worst views:";
  for (size_t k = 0; k < std::min<size_t>(3, order.size()); ++k) {
    const size_t v = order[k];
    out << " " << (v < view_names.size() ? view_names[v] : std::to_string(v)) << " "
        << FormatPrintf("%.4f", view_rms_px[v]) << " px";
    if (k + 1 < std::min<size_t>(3, order.size())) out << ",";
  }
  out << "\n";
  return out.str();
}

Result<CameraCalibration> CalibrateCamera(const std::vector<BoardView>& views, int width_px, int height_px,
                                          const CameraCalibrationOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (width_px < 1 || height_px < 1) {
    return Status::InvalidArgument("CalibrateCamera: image size " + std::to_string(width_px) + " x " +
                                   std::to_string(height_px) + ": must be positive");
  }
  if (static_cast<int>(views.size()) < options.min_views) {
    return Status::InvalidArgument("CalibrateCamera: " + std::to_string(views.size()) +
                                   " views, at least min_views = " + std::to_string(options.min_views) +
                                   " are needed");
  }
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  int num_corners = 0;
  for (size_t v = 0; v < views.size(); ++v) {
    const BoardView& view = views[v];
    const std::string name = view.name.empty() ? "view " + std::to_string(v) : view.name;
    if (view.points_in_board.size() != view.pixels.size()) {
      return Status::InvalidArgument(name + ": " + std::to_string(view.points_in_board.size()) +
                                     " board points but " + std::to_string(view.pixels.size()) + " pixels");
    }
    if (static_cast<int>(view.pixels.size()) < options.min_corners_per_view) {
      return Status::InvalidArgument(name + ": " + std::to_string(view.pixels.size()) +
                                     " corners, fewer than min_corners_per_view = " +
                                     std::to_string(options.min_corners_per_view));
    }
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    for (size_t k = 0; k < view.pixels.size(); ++k) {
      const Eigen::Vector3d& P = view.points_in_board[k];
      const Eigen::Vector2d& p = view.pixels[k];
      if (!P.allFinite() || !p.allFinite() || P.z() != 0.0) {
        return Status::InvalidArgument(name + ": corner " + std::to_string(k) +
                                       ": not finite, or board point not on z = 0");
      }
      if (p.x() < -0.5 || p.y() < -0.5 || p.x() > width_px - 0.5 || p.y() > height_px - 0.5) {
        return Status::InvalidArgument(name + ": corner " + std::to_string(k) + " at (" + FormatNumber(p.x()) +
                                       ", " + FormatNumber(p.y()) + ") is outside the " +
                                       std::to_string(width_px) + " x " + std::to_string(height_px) + " image");
      }
      obj.emplace_back(static_cast<float>(P.x()), static_cast<float>(P.y()), 0.f);
      img.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    num_corners += static_cast<int>(img.size());
    object_points.push_back(std::move(obj));
    image_points.push_back(std::move(img));
  }

  int flags = 0;
  if (options.fix_k3) flags |= cv::CALIB_FIX_K3;
  if (options.fix_tangential) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  if (options.fix_aspect_ratio) flags |= cv::CALIB_FIX_ASPECT_RATIO;
  cv::Mat camera_matrix = cv::Mat::eye(3, 3, CV_64F);  // aspect ratio 1 when fixed
  cv::Mat dist_coeffs = cv::Mat::zeros(5, 1, CV_64F);
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_intrinsics, std_extrinsics, per_view_errors;
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, options.max_iterations,
                                  options.parameter_tolerance);
  double rms = 0.0;
  try {
    rms = cv::calibrateCamera(object_points, image_points, cv::Size(width_px, height_px), camera_matrix,
                              dist_coeffs, rvecs, tvecs, std_intrinsics, std_extrinsics, per_view_errors,
                              flags, criteria);
  } catch (const cv::Exception& e) {
    return Status::NoSolution("CalibrateCamera: OpenCV failed: " + std::string(e.what()));
  }
  CameraCalibration result;
  CameraIntrinsics& K = result.intrinsics;
  K.width_px = width_px;
  K.height_px = height_px;
  K.fx_px = camera_matrix.at<double>(0, 0);
  K.fy_px = camera_matrix.at<double>(1, 1);
  K.cx_px = camera_matrix.at<double>(0, 2);
  K.cy_px = camera_matrix.at<double>(1, 2);
  K.k1 = dist_coeffs.at<double>(0);
  K.k2 = dist_coeffs.at<double>(1);
  K.p1 = dist_coeffs.at<double>(2);
  K.p2 = dist_coeffs.at<double>(3);
  K.k3 = dist_coeffs.at<double>(4);
  {
    Status s = K.Validate();
    if (!(std::isfinite(rms)) || !s.ok()) {
      return Status::NoSolution("CalibrateCamera: the solve gave no valid camera (" + s.message() + ")");
    }
  }
  // OpenCV's order: fx, fy, cx, cy, k1, k2, p1, p2, k3, ... = ours.
  // Residual variance: OpenCV < 4.8 uses SSR / (N - P) with N the number of
  // corners; the unbiased estimate is SSR / (2N - P) (2 residuals per corner).
  double std_scale = 1.0;
// Fixed by opencv/opencv#22992 (3.4: #23025), merged January 2023: in 4.8.0
// and 3.4.20 (the MC test in camera_calibration_test.cc checks the result).
#if CV_VERSION_MAJOR < 3 || (CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR < 8) || \
    (CV_VERSION_MAJOR == 3 && (CV_VERSION_MINOR < 4 || CV_VERSION_REVISION < 20))
  {
    int free_intrinsics = 8;  // fx, fy, cx, cy, k1, k2, p1, p2
    if (options.fix_aspect_ratio) free_intrinsics -= 1;
    if (options.fix_tangential) free_intrinsics -= 2;
    if (!options.fix_k3) free_intrinsics += 1;
    const double n = num_corners;
    const double p = free_intrinsics + 6.0 * static_cast<double>(views.size());
    if (n - p > 0.0) std_scale = std::sqrt((n - p) / (2.0 * n - p));
  }
#endif
  for (int k = 0; k < kNumCameraParameters; ++k) {
    result.intrinsics_std[k] = k < std_intrinsics.rows ? std_scale * std_intrinsics.at<double>(k) : 0.0;
    if (!std::isfinite(result.intrinsics_std[k])) result.intrinsics_std[k] = 0.0;
  }
  // With CALIB_FIX_ASPECT_RATIO OpenCV holds fx (fx = fy * aspect, updated
  // from fy) and reports its std dev as 0: fx's follows from fy's.
  if (options.fix_aspect_ratio) result.intrinsics_std[0] = result.intrinsics_std[1] * K.fx_px / K.fy_px;
  // Views with pixel covariances (tag boards): the sandwich instead.
  {
    std::array<double, kNumCameraParameters> sandwich{};
    if (SandwichIntrinsicsStd(views, camera_matrix, dist_coeffs, rvecs, tvecs, options, &sandwich)) {
      result.intrinsics_std = sandwich;
      result.std_from_pixel_covariances = true;
    }
  }
  result.rms_px = rms;
  result.num_views = static_cast<int>(views.size());
  result.num_corners = num_corners;
  for (size_t v = 0; v < views.size(); ++v) {
    result.view_rms_px.push_back(per_view_errors.at<double>(static_cast<int>(v)));
    cv::Mat R;
    cv::Rodrigues(rvecs[v], R);
    Eigen::Matrix3d Re;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) Re(i, j) = R.at<double>(i, j);
    }
    result.cam_from_board.emplace_back(
        Re, Eigen::Vector3d(tvecs[v].at<double>(0), tvecs[v].at<double>(1), tvecs[v].at<double>(2)));
    result.view_names.push_back(views[v].name.empty() ? "view " + std::to_string(v) : views[v].name);
    result.view_num_corners.push_back(static_cast<int>(views[v].pixels.size()));
  }
  return result;
}

Result<BoardView> DetectTagBoardView(const cv::Mat& image, const TagBoard& board,
                                     const CameraCalibrationOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(board.Validate());
  Result<std::vector<TagDetection>> detections = DetectTags(image, options.detection);
  if (!detections.ok()) return detections.status();
  BoardView view;
  std::vector<int> seen;
  for (const TagDetection& det : *detections) {
    if (!board.HasTag(det.id)) continue;
    // An id seen twice (a reflection, a second board) is ambiguous: skip both.
    const int count = static_cast<int>(std::count_if(detections->begin(), detections->end(),
                                                     [&](const TagDetection& d) { return d.id == det.id; }));
    if (count > 1) continue;
    Result<std::array<Eigen::Vector3d, 4>> corners = board.TagCorners(det.id);
    if (!corners.ok()) return corners.status();
    for (int c = 0; c < 4; ++c) {
      view.points_in_board.push_back((*corners)[c]);
      view.pixels.push_back(det.corners_px[c]);
    }
    // The tag's corners' covariance: each corner's, and the shared edges'
    // cross terms (an unrefined corner's: fallback_corner_sigma_px, no cross
    // terms). The OpenCV refinements give none: no blocks for the view.
    if (options.detection.refinement == TagCornerRefinement::kEdgeFit) {
      Eigen::MatrixXd block = Eigen::MatrixXd::Zero(8, 8);
      for (int c = 0; c < 4; ++c) {
        const int d = (c + 1) % 4;
        block.block<2, 2>(2 * c, 2 * c) = det.corner_covariance_px2[c];
        block.block<2, 2>(2 * c, 2 * d) = det.corner_cross_covariance_px2[c];
        block.block<2, 2>(2 * d, 2 * c) = det.corner_cross_covariance_px2[c].transpose();
      }
      view.pixel_covariance_blocks_px2.push_back(block);
    }
  }
  if (view.pixel_covariance_blocks_px2.size() * 4 != view.pixels.size()) view.pixel_covariance_blocks_px2.clear();
  if (static_cast<int>(view.pixels.size()) < options.min_corners_per_view) {
    return Status::NoSolution("no board found: " + std::to_string(view.pixels.size() / 4) +
                              " tags of the board detected (" + std::to_string(view.pixels.size()) +
                              " corners, fewer than min_corners_per_view = " +
                              std::to_string(options.min_corners_per_view) + ")");
  }
  return view;
}

Result<BoardView> DetectChessboardView(const cv::Mat& image, const Chessboard& board,
                                       const CameraCalibrationOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(board.Validate());
  if (image.empty()) return Status::InvalidArgument("image is empty");
  cv::Mat gray;
  if (image.type() == CV_8UC1) {
    gray = image;
  } else if (image.type() == CV_8UC3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    return Status::InvalidArgument("image type " + std::to_string(image.type()) +
                                   ": expected CV_8UC1 or CV_8UC3 for chessboard detection");
  }
  const cv::Size pattern(board.inner_columns, board.inner_rows);
  std::vector<cv::Point2f> corners;
  const bool found = cv::findChessboardCorners(
      gray, pattern, corners,
      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK);
  if (!found || static_cast<int>(corners.size()) != board.inner_columns * board.inner_rows) {
    return Status::NoSolution("no board found: the " + std::to_string(board.inner_columns) + " x " +
                              std::to_string(board.inner_rows) + " chessboard was not detected");
  }
  const int w = options.chessboard_subpix_half_window_px;
  cv::cornerSubPix(gray, corners, cv::Size(w, w), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.001));
  BoardView view;
  for (int i = 0; i < board.inner_rows; ++i) {
    for (int j = 0; j < board.inner_columns; ++j) {
      const cv::Point2f& p = corners[static_cast<size_t>(i * board.inner_columns + j)];
      view.points_in_board.emplace_back(j * board.square_size, i * board.square_size, 0.0);
      view.pixels.emplace_back(p.x, p.y);
    }
  }
  return view;
}

namespace {

template <typename Detect>
Result<CameraCalibration> CalibrateFromImages(const std::vector<cv::Mat>& images,
                                              const CameraCalibrationOptions& options,
                                              const std::vector<std::string>& image_names, Detect detect) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (!image_names.empty() && image_names.size() != images.size()) {
    return Status::InvalidArgument("image_names: " + std::to_string(image_names.size()) + " names for " +
                                   std::to_string(images.size()) + " images");
  }
  if (static_cast<int>(images.size()) < options.min_views) {
    return Status::InvalidArgument("CalibrateCamera: " + std::to_string(images.size()) +
                                   " images, at least min_views = " + std::to_string(options.min_views) +
                                   " are needed");
  }
  std::vector<BoardView> views;
  for (size_t v = 0; v < images.size(); ++v) {
    const std::string name = ViewName(image_names, v);
    OPL_RETURN_IF_ERROR(CheckGrayImage(images[v], name));
    if (images[v].size() != images[0].size()) {
      return Status::InvalidArgument(name + ": size " + std::to_string(images[v].cols) + " x " +
                                     std::to_string(images[v].rows) + " differs from the first image's " +
                                     std::to_string(images[0].cols) + " x " + std::to_string(images[0].rows));
    }
    Result<BoardView> view = detect(images[v]);
    if (!view.ok()) return Status(view.status().code(), name + ": " + view.status().message());
    view->name = name;
    views.push_back(std::move(*view));
  }
  return CalibrateCamera(views, images[0].cols, images[0].rows, options);
}

}  // namespace

Result<CameraCalibration> CalibrateCameraFromTagBoard(const std::vector<cv::Mat>& images, const TagBoard& board,
                                                      const CameraCalibrationOptions& options,
                                                      const std::vector<std::string>& image_names) {
  OPL_RETURN_IF_ERROR(board.Validate());
  return CalibrateFromImages(images, options, image_names,
                             [&](const cv::Mat& image) { return DetectTagBoardView(image, board, options); });
}

Result<CameraCalibration> CalibrateCameraFromChessboard(const std::vector<cv::Mat>& images,
                                                        const Chessboard& board,
                                                        const CameraCalibrationOptions& options,
                                                        const std::vector<std::string>& image_names) {
  OPL_RETURN_IF_ERROR(board.Validate());
  return CalibrateFromImages(images, options, image_names,
                             [&](const cv::Mat& image) { return DetectChessboardView(image, board, options); });
}

}  // namespace opl
