// A camera calibrated from a set of image files of a board: what
// `opl_camera calibrate` runs (docs/images.md, "Calibrating a camera").
//
//   Result<std::vector<std::string>> files = ListImageFiles("shots/");
//   Result<CameraImagesCalibration> cal =
//       CalibrateCameraFromImageFiles(*files, board, CameraImagesOptions{});
//   std::cout << cal->ToText();                       // intrinsics +- sigma, per view
//   SceneCamera camera = cal->ToSceneCamera("cam0");  // io/cameras_json.h writes it
//
// Every image is read (ReadShotImage: sensor pixels, EXIF orientation
// ignored, grey) and the board looked for in it (vision/board_detection.h),
// one image at a time (only the corners are kept, so a hundred 24 MP images
// need no more memory than one). An image without the board is REJECTED with
// the reason and the others go on; then the camera is calibrated over the
// views kept (vision/camera_calibration.h: intrinsics, their standard
// deviations, per-view RMS). With max_view_rms_px set, views whose RMS
// exceeds it are rejected too and the calibration is repeated once without
// them. The sensor coverage of the corners (report/coverage_image.h) is part
// of the result.
//
// Errors (Status; nothing is written): no files; a file that cannot be read or
// decoded (IoError / InvalidArgument naming it); images of different sizes
// (InvalidArgument naming the file and both sizes); the board found in no
// image, or in fewer than calibration.min_views images, or the calibration
// failing or giving intrinsics beyond the limits a scene JSON accepts
// (NoSolution, naming the rejected views and why).
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/report/coverage_image.h"
#include "opl/vision/board_detection.h"
#include "opl/vision/camera_calibration.h"

namespace opl {

struct CameraImagesOptions {
  CameraCalibrationOptions calibration;  // model (fix_k3, ...), min_views, detection
  // Views whose RMS reprojection error exceeds this are rejected and the
  // calibration repeated once without them [px]; 0 = keep every view; >= 0.
  double max_view_rms_px = 0.0;
  // Coverage grid: cells across the image, in [1, 100].
  int coverage_cells_across = 10;

  Status Validate() const;
};

struct RejectedView {
  std::string file;
  std::string reason;  // e.g. "no board found: the 9 x 6 chessboard was not detected"
};

struct CameraImagesCalibration {
  CalibrationBoard board;
  int width_px = 0;
  int height_px = 0;
  std::vector<std::string> files;      // every image given, in order
  std::vector<BoardView> views;        // the views used (name = file), detected corners
  std::vector<RejectedView> rejected;  // the others, with the reason
  CameraCalibration calibration;       // over `views`
  SensorCoverage coverage;             // of `views`

  // The report on stdout: intrinsics with standard deviations, RMS, per-view
  // RMS and corners, rejected views and why, coverage.
  std::string ToText() const;
  // The same as a JSON document (format "opl.camera_calibration_report",
  // docs/formats.md).
  std::string ToJson() const;
  // The camera named `name` with these intrinsics and the "calibration"
  // record (standard deviations, RMS, views, corners, board).
  SceneCamera ToSceneCamera(const std::string& name) const;
};

// The image files of a folder: regular files whose extension is one of
// .png .jpg .jpeg .tif .tiff .bmp .pgm .ppm (any case), sorted by name.
// IoError when the folder cannot be read or holds no such file.
Result<std::vector<std::string>> ListImageFiles(const std::string& folder);

Result<CameraImagesCalibration> CalibrateCameraFromImageFiles(const std::vector<std::string>& files,
                                                              const CalibrationBoard& board,
                                                              const CameraImagesOptions& options);

}  // namespace opl
