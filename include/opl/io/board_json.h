// Board JSON: the description of a calibration board (vision/board_detection.h)
// as a file (docs/formats.md, "Board JSON"). `opl_camera board --board-json`
// writes it beside the printable board; `opl_camera calibrate --board` reads
// it.
//
//   {"format": "opl.board", "version": 1, "type": "tag_grid",
//    "family": "tag36h11", "cols": 6, "rows": 4, "first_id": 0,
//    "tag_size_mm": 30, "gap_mm": 7.5}
//   {"format": "opl.board", "version": 1, "type": "chessboard",
//    "inner_cols": 9, "inner_rows": 6, "square_mm": 25}
//
// A tag grid gives either "gap_mm" (between neighbouring black squares) or
// "pitch_mm" (centre to centre, = tag_size_mm + gap_mm), not both; the board
// frame is TagBoard's (vision/camera_calibration.h: origin at the outer
// top-left corner of the top-left tag's black square, x right, y down).
//
// Errors are one line, "<file>: <field>: <what is wrong>" (ParseError; IoError
// when the file cannot be read); unknown fields are errors.
#pragma once

#include <string>

#include "opl/core/status.h"
#include "opl/vision/board_detection.h"

namespace opl {

Result<CalibrationBoard> ReadBoardJson(const std::string& path);
Result<CalibrationBoard> ParseBoardJson(const std::string& text, const std::string& name_for_messages);
// The board as a board JSON document (a tag grid with "gap_mm").
std::string FormatBoardJson(const CalibrationBoard& board);

}  // namespace opl
