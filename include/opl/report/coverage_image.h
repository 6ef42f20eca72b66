// Where on the sensor the board's corners fell in a camera calibration: a
// count per cell of a grid over the image, and a picture of it for
// `opl_camera calibrate --report` (docs/images.md, "Calibrating a camera"),
// as PNG, SVG or PDF (report/plot_format.h), drawn with cairo like the other
// report figures.
//
// A calibration constrains the distortion only where corners were seen: a
// lens calibrated from views that all sit in the middle of the image
// extrapolates its distortion into the corners. The coverage says how much
// of the sensor the views reached.
//
// The picture: a two-line caption (the title with the counts and the image
// size; the covered fraction and a key), the sensor (scaled so that its
// longer side is max_side_px) with the grid of coverage cells, the covered
// ones light grey (RGB 240,240,240) and the empty ones tinted red (RGB
// 255,205,205), 1 px grid lines (RGB 200,200,200) and a 2 px dark outline
// (RGB 40,40,40) just outside it; every detected corner as a dot (radius
// 2.5 px) in its view's colour and each view's outline (the convex hull of
// its corners, 1 px) in the same colour; at the right a legend naming the
// views (file name without folder, and its number of corners; as many as
// fit, then "... and N more"). Colours: hue stepped by the golden angle
// (137.5 degrees), so neighbouring views differ.
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/report/grid_heatmap.h"  // PixelRect
#include "opl/report/plot_format.h"
#include "opl/vision/camera_calibration.h"

namespace opl {

struct SensorCoverage {
  int cells_across = 0;  // columns of the grid over the image
  int cells_down = 0;    // rows (cells about square)
  std::vector<int> corners_per_cell;  // row-major, cells_across * cells_down
  int num_corners = 0;
  double fraction_covered = 0.0;  // cells holding at least one corner / all cells

  // e.g. "corners in 62 of 80 cells (78%) of a 10 x 8 grid over the image;
  // empty: top-left, bottom-right".
  std::string Summary() const;
};

// Counts the corners of `views` per cell of a grid `cells_across` wide (and as
// many rows as keep the cells about square, at least 1) over a
// width_px x height_px image. Corners outside the image are not counted.
// InvalidArgument for a non-positive size or cells_across outside [1, 100].
Result<SensorCoverage> ComputeSensorCoverage(int width_px, int height_px,
                                             const std::vector<BoardView>& views,
                                             int cells_across = 10);

struct CoverageImageOptions {
  int max_side_px = 1000;  // the sensor's longer side is drawn this large, in [200, 4000]
  std::string title;       // starts the caption (e.g. "Camera 'cam0'"); default "Sensor coverage"
  Status Validate() const;
};

// Where things are in the picture, in pixels (x right, y down, integer pixel
// centres as the other report figures; PNG: one pixel per layout pixel).
struct CoverageImageLayout {
  int image_width = 0;
  int image_height = 0;
  // The whole image, scaled: image pixel (u, v) is drawn centred at
  // x = sensor.x - 0.5 + (u + 0.5) * sensor.width / width_px, likewise y.
  PixelRect sensor;
  PixelRect legend;  // the legend's column at the right
  int cells_across = 0, cells_down = 0;

  // The pixels of coverage cell (row, col), row 0 at the top: columns
  // sensor.x + sensor.width * col / cells_across up to the next cell's first
  // column, likewise rows. Its first column and first row carry the grid
  // line (except at the sensor's left and top edges). Empty for a cell
  // outside the grid.
  PixelRect Cell(int row, int col) const;
};

// Checks the arguments and computes the layout. InvalidArgument with one line
// naming the problem: bad options, a non-positive image size, or a coverage
// that is not a grid of cells_across x cells_down counts, e.g.
//   "CoverageImageOptions.max_side_px = 100: must be in [200, 4000]"
//   "coverage picture: SensorCoverage.corners_per_cell has 7 entries, expected 4 x 2 = 8"
Result<CoverageImageLayout> LayoutCoverageImage(int width_px, int height_px,
                                                const std::vector<BoardView>& views,
                                                const SensorCoverage& coverage,
                                                const CoverageImageOptions& options = {});

// The picture described above in `format` (the file's bytes; `metadata` goes
// into a PDF's information dictionary, PNG and SVG are stamped when staged,
// io/output_set.h). Errors as LayoutCoverageImage; IoError "coverage picture:
// cannot render the png: ..." if cairo fails. Never throws.
Result<std::vector<unsigned char>> RenderCoverageImage(int width_px, int height_px,
                                                       const std::vector<BoardView>& views,
                                                       const SensorCoverage& coverage,
                                                       PlotFormat format,
                                                       const CoverageImageOptions& options = {},
                                                       const PlotMetadata& metadata = {});

}  // namespace opl
