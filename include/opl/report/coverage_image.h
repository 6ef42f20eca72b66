// Where on the sensor the board's corners fell in a camera calibration: a
// count per cell of a grid over the image, and a picture of it (PNG) for
// `opl_camera calibrate --report` (docs/images.md, "Calibrating a camera").
//
// A calibration constrains the distortion only where corners were seen: a
// lens calibrated from views that all sit in the middle of the image
// extrapolates its distortion into the corners. The coverage says how much
// of the sensor the views reached.
//
// The picture: the sensor outline (scaled to fit max_side_px), the grid of
// coverage cells with the empty ones tinted red, every detected corner as a
// dot in its view's colour, each view's outline (the convex hull of its
// corners) in the same colour, a legend naming the views and a caption with
// the counts and the covered fraction. Colours are spaced by the golden
// angle in hue, so neighbouring views differ.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "opl/core/status.h"
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
  int max_side_px = 1000;  // the sensor is drawn at most this large, in [200, 4000]
  std::string title;       // first line of the caption (e.g. the camera name)
  Status Validate() const;
};

// The picture described above: an 8-bit BGR image. InvalidArgument for bad
// options or coverage that does not match the size.
Result<cv::Mat> DrawCoverageImage(int width_px, int height_px, const std::vector<BoardView>& views,
                                  const SensorCoverage& coverage,
                                  const CoverageImageOptions& options = {});

}  // namespace opl
