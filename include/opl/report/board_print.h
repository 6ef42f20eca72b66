// A printable tag-grid calibration board (vision/camera_calibration.h,
// TagBoard) at its exact physical size: PDF (vector, through cairo) or PNG
// (at a given dpi, with the dpi in its pHYs chunk). `opl_camera board`
// writes it (docs/images.md, "Calibrating a camera").
//
// The page. The tags sit `margin_mm` from the page's left and top edges
// (white: it is part of the tags' quiet zone), the grid as TagBoard
// describes it: tag i (row-major from first_id) has its black square at
// x = margin + c * pitch, y = margin + r * pitch [mm from the page's top-left
// corner], pitch = tag_size + tag_gap. Below the grid, in the margin strip:
// a scale check mark (a 100 mm line with end ticks and 10 mm ticks: measure
// it on the print; a printer that "fits to page" shrinks it) and the board's
// parameters (family, rows x cols, ids, tag size, gap, pitch), so that a
// print says what it is. Tags are drawn as one filled path per page
// (no hairline seams between cells); each cell is the tag36h11 code of
// lab/planar_target_image.h (MakeTag36h11Texture), the same bits that
// cv::aruco draws.
//
// Page size: "fit" (the board, its margins and the strip) or a paper size
// ("a4", "a3", "letter"), portrait or landscape, whichever holds it; the
// board then stays at the top-left margin (so the layout above holds).
//
// PNG: width_px = round(page_width_mm * dpi / 25.4) (likewise the height),
// the page drawn at exactly dpi / 25.4 px per mm (anti-aliased: an edge
// between pixels is the area-weighted grey), grey 8-bit.
//
// Errors (InvalidArgument): a board that does not validate, a gap narrower
// than one tag cell (tag_size / 8: neighbouring tags need a white quiet zone
// of a cell), a margin narrower than 2 cells or 5 mm, a dpi outside
// [50, 2400], a page that cannot hold the board, a PNG above 30000 px a side.
#pragma once

#include <string>

#include "opl/core/status.h"
#include "opl/vision/camera_calibration.h"

namespace opl {

struct BoardPrintOptions {
  double margin_mm = 15.0;   // white space left, top and right of the tags [mm]
  std::string page = "fit";  // "fit", "a4", "a3" or "letter"
  double dpi = 300.0;        // PNG only: pixels per inch, in [50, 2400]
  // PDF only: the document's Creator and Subject metadata (the tool's
  // provenance, io/provenance.h: "OPL opl_camera 0.1.0 ..." and its JSON);
  // empty: "opl_camera board" and none.
  std::string pdf_creator;
  std::string pdf_subject;
  Status Validate() const;
};

struct BoardPrintLayout {
  double page_width_mm = 0.0;
  double page_height_mm = 0.0;
  double board_x_mm = 0.0;  // page position of the board frame's origin (top-left of
  double board_y_mm = 0.0;  // the top-left tag's black square), from the page's top-left
  double scale_line_y_mm = 0.0;  // the 100 mm line, from x = board_x_mm
  int png_width_px = 0;     // at options.dpi
  int png_height_px = 0;
};

Result<BoardPrintLayout> LayOutBoardPrint(const TagBoard& board, const BoardPrintOptions& options);

// The PDF document (one page), as bytes.
Result<std::string> RenderBoardPdf(const TagBoard& board, const BoardPrintOptions& options);
// The PNG file, as bytes.
Result<std::string> RenderBoardPng(const TagBoard& board, const BoardPrintOptions& options);

}  // namespace opl
