// A calibration board of either kind, and finding it in one image
// (docs/images.md, "Calibrating a camera"; the board JSON: docs/formats.md,
// "Board JSON").
//
// Two kinds of planar board, both in vision/camera_calibration.h:
//  - a grid of tag36h11 tags (TagBoard), as `opl_camera board` prints it and
//    the virtual lab renders it (lab/planar_target_image.h,
//    MakeTagBoardTarget). Every tag found gives its 4 corners, so a board
//    seen in part, cut by the image border or partly covered still counts;
//  - a chessboard (Chessboard) given by its inner corners, which must all be
//    seen.
//
// Detection. Tags: DetectTags (vision/tag_detection.h) with the options'
// `detection`; tags of ids not on the board are ignored, an id seen twice
// (a reflection, a second board) is dropped. Chessboard:
// cv::findChessboardCorners (adaptive threshold, normalised image) refined
// by cv::cornerSubPix (OpenCV's calibration sample), and when that finds
// nothing cv::findChessboardCornersSB (more robust to blur and uneven light;
// its corners are already sub-pixel). A 16-bit image is reduced to 8 bits for
// the chessboard detectors.
//
// Errors: InvalidArgument for a bad board or options, or an image that is
// empty or not 8/16-bit grey or 8-bit BGR; NoSolution "no board found: ..."
// (with what was seen) when the board is not in the image.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/vision/camera_calibration.h"

namespace opl {

struct CalibrationBoard {
  enum class Kind { kTagGrid, kChessboard };
  Kind kind = Kind::kTagGrid;
  TagBoard tag_grid;      // when kind == kTagGrid (units: mm)
  Chessboard chessboard;  // when kind == kChessboard (units: mm)

  static CalibrationBoard TagGrid(const TagBoard& board);
  static CalibrationBoard ChessboardOf(const Chessboard& board);

  // OK, or the field of the board in use that is out of its domain.
  Status Validate() const;
  // Corners of a fully seen board: 4 per tag, or inner columns x inner rows.
  int NumCorners() const;
  // One line for reports, e.g. "tag36h11 grid 6 x 4 tags (ids 0..23), tag
  // 30 mm, gap 7.5 mm" or "chessboard 9 x 6 inner corners, square 25 mm".
  std::string Describe() const;
};

// The board's corners in `image` with their board coordinates [mm] (see
// above). The view's name is left empty.
Result<BoardView> DetectCalibrationBoard(const cv::Mat& image, const CalibrationBoard& board,
                                         const CameraCalibrationOptions& options);

}  // namespace opl
