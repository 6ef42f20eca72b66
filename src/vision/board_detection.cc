#include "opl/vision/board_detection.h"

#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"

namespace opl {

CalibrationBoard CalibrationBoard::TagGrid(const TagBoard& board) {
  CalibrationBoard b;
  b.kind = Kind::kTagGrid;
  b.tag_grid = board;
  return b;
}

CalibrationBoard CalibrationBoard::ChessboardOf(const Chessboard& board) {
  CalibrationBoard b;
  b.kind = Kind::kChessboard;
  b.chessboard = board;
  return b;
}

Status CalibrationBoard::Validate() const {
  return kind == Kind::kTagGrid ? tag_grid.Validate() : chessboard.Validate();
}

int CalibrationBoard::NumCorners() const {
  return kind == Kind::kTagGrid ? 4 * tag_grid.NumTags() : chessboard.inner_columns * chessboard.inner_rows;
}

std::string CalibrationBoard::Describe() const {
  if (kind == Kind::kChessboard) {
    return "chessboard " + std::to_string(chessboard.inner_columns) + " x " +
           std::to_string(chessboard.inner_rows) + " inner corners, square " +
           FormatNumber(chessboard.square_size) + " mm";
  }
  const TagBoard& t = tag_grid;
  return "tag36h11 grid " + std::to_string(t.columns) + " x " + std::to_string(t.rows) + " tags (ids " +
         std::to_string(t.first_id) + ".." + std::to_string(t.first_id + t.NumTags() - 1) + "), tag " +
         FormatNumber(t.tag_size) + " mm, gap " + FormatNumber(t.tag_gap) + " mm";
}

namespace {

Result<BoardView> DetectChessboard(const cv::Mat& image, const Chessboard& board,
                                   const CameraCalibrationOptions& options) {
  if (image.empty()) return Status::InvalidArgument("image is empty");
  cv::Mat gray;
  if (image.type() == CV_16UC1) {
    image.convertTo(gray, CV_8U, 1.0 / 257.0);
  } else if (image.type() == CV_8UC1 || image.type() == CV_8UC3) {
    gray = image;
  } else {
    return Status::InvalidArgument("image type " + std::to_string(image.type()) +
                                   ": expected 8- or 16-bit grey or 8-bit BGR");
  }
  Result<BoardView> classic = DetectChessboardView(gray, board, options);
  if (classic.ok() || classic.status().code() != StatusCode::kNoSolution) return classic;
  // The sector-based detector: more robust, already sub-pixel.
  cv::Mat gray8 = gray;
  if (gray.type() == CV_8UC3) cv::cvtColor(gray, gray8, cv::COLOR_BGR2GRAY);
  std::vector<cv::Point2f> corners;
  const cv::Size pattern(board.inner_columns, board.inner_rows);
  bool found = false;
  try {
    found = cv::findChessboardCornersSB(gray8, pattern, corners, cv::CALIB_CB_NORMALIZE_IMAGE);
  } catch (const cv::Exception&) {
    found = false;
  }
  if (!found || static_cast<int>(corners.size()) != board.inner_columns * board.inner_rows) {
    return classic.status();
  }
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

}  // namespace

Result<BoardView> DetectCalibrationBoard(const cv::Mat& image, const CalibrationBoard& board,
                                         const CameraCalibrationOptions& options) {
  OPL_RETURN_IF_ERROR(board.Validate());
  if (board.kind == CalibrationBoard::Kind::kChessboard) {
    return DetectChessboard(image, board.chessboard, options);
  }
  return DetectTagBoardView(image, board.tag_grid, options);
}

}  // namespace opl
