#include "opl/pipeline/calibrate_camera_images.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "opl/io/board_json.h"
#include "opl/vision/intrinsics_limits.h"
#include "opl/vision/shot_image.h"

namespace opl {
namespace {

constexpr const char* kParameterNames[kNumCameraParameters] = {"fx", "fy", "cx", "cy", "k1",
                                                               "k2", "p1", "p2", "k3"};

std::string JoinRejected(const std::vector<RejectedView>& rejected, size_t max_listed) {
  std::string out;
  for (size_t k = 0; k < rejected.size() && k < max_listed; ++k) {
    out += (k ? "; " : "") + rejected[k].file + ": " + rejected[k].reason;
  }
  if (rejected.size() > max_listed) out += "; and " + std::to_string(rejected.size() - max_listed) + " more";
  return out;
}

}  // namespace

Status CameraImagesOptions::Validate() const {
  OPL_RETURN_IF_ERROR(calibration.Validate());
  if (!(max_view_rms_px >= 0.0 && std::isfinite(max_view_rms_px))) {
    return Status::InvalidArgument("CameraImagesOptions.max_view_rms_px = " + FormatNumber(max_view_rms_px) +
                                   ": must be finite and >= 0");
  }
  if (coverage_cells_across < 1 || coverage_cells_across > 100) {
    return Status::InvalidArgument("CameraImagesOptions.coverage_cells_across = " +
                                   std::to_string(coverage_cells_across) + ": must be in [1, 100]");
  }
  return Status::Ok();
}

Result<std::vector<std::string>> ListImageFiles(const std::string& folder) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return Status::IoError(folder + ": not a folder");
  std::vector<std::string> files;
  fs::directory_iterator it(folder, ec);
  if (ec) return Status::IoError(folder + ": cannot list the folder: " + ec.message());
  for (const fs::directory_entry& entry : it) {
    if (!entry.is_regular_file(ec)) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    for (const char* known : {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm"}) {
      if (ext == known) {
        files.push_back(entry.path().string());
        break;
      }
    }
  }
  if (files.empty()) {
    return Status::IoError(folder + ": no image files (.png .jpg .jpeg .tif .tiff .bmp .pgm .ppm) in the folder");
  }
  std::sort(files.begin(), files.end());
  return files;
}

Result<CameraImagesCalibration> CalibrateCameraFromImageFiles(const std::vector<std::string>& files,
                                                              const CalibrationBoard& board,
                                                              const CameraImagesOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(board.Validate());
  if (files.empty()) return Status::InvalidArgument("no images given");
  CameraImagesCalibration out;
  out.board = board;
  out.files = files;
  std::string first_file;
  for (const std::string& file : files) {
    Result<ShotImage> shot = ReadShotImage(file, SpotChannel::kLuma);
    if (!shot.ok()) return shot.status();
    const cv::Mat& image = shot->for_tags;
    if (first_file.empty()) {
      first_file = file;
      out.width_px = image.cols;
      out.height_px = image.rows;
    } else if (image.cols != out.width_px || image.rows != out.height_px) {
      return Status::InvalidArgument(file + ": " + std::to_string(image.cols) + " x " + std::to_string(image.rows) +
                                     " pixels, but " + first_file + " has " + std::to_string(out.width_px) + " x " +
                                     std::to_string(out.height_px) +
                                     ": the images of one calibration come from one camera at one size");
    }
    if (!shot->decode_warnings.empty()) {
      // A damaged file (a JPEG cut short, corrupt data): its pixels after
      // the damage are the decoder's fill, not the board. Not used, and
      // reported as a rejected view with the decoder's word.
      out.rejected.push_back({file, "damaged image file (" + shot->decode_warnings.front() +
                                        "): not used"});
      continue;
    }
    Result<BoardView> view = DetectCalibrationBoard(image, board, options.calibration);
    if (!view.ok()) {
      if (view.status().code() != StatusCode::kNoSolution) {
        return Status(view.status().code(), file + ": " + view.status().message());
      }
      out.rejected.push_back({file, view.status().message()});
      continue;
    }
    view->name = file;
    out.views.push_back(std::move(*view));
  }
  const int min_views = options.calibration.min_views;
  if (out.views.empty()) {
    return Status::NoSolution("no board found in any of the " + std::to_string(files.size()) + " images (" +
                              board.Describe() + "): " + JoinRejected(out.rejected, 2));
  }
  if (static_cast<int>(out.views.size()) < min_views) {
    return Status::NoSolution("the board was found in " + std::to_string(out.views.size()) + " of " +
                              std::to_string(files.size()) + " images, at least " + std::to_string(min_views) +
                              " views are needed (" + board.Describe() + "); rejected: " +
                              JoinRejected(out.rejected, 2));
  }
  Result<CameraCalibration> cal = CalibrateCamera(out.views, out.width_px, out.height_px, options.calibration);
  if (!cal.ok()) return Status::NoSolution(cal.status().message());
  if (options.max_view_rms_px > 0.0) {
    std::vector<BoardView> kept;
    for (size_t v = 0; v < out.views.size(); ++v) {
      const double rms = cal->view_rms_px[v];
      if (rms > options.max_view_rms_px) {
        out.rejected.push_back({out.views[v].name, "RMS reprojection error " + FormatPrintf("%.3f", rms) +
                                                       " px exceeds max_view_rms_px = " +
                                                       FormatNumber(options.max_view_rms_px) + " px"});
      } else {
        kept.push_back(std::move(out.views[v]));
      }
    }
    if (kept.size() != out.views.size()) {
      out.views = std::move(kept);
      if (static_cast<int>(out.views.size()) < min_views) {
        return Status::NoSolution("after rejecting views above the RMS limit " + std::to_string(out.views.size()) +
                                  " views remain, at least " + std::to_string(min_views) +
                                  " are needed; rejected: " + JoinRejected(out.rejected, 3));
      }
      cal = CalibrateCamera(out.views, out.width_px, out.height_px, options.calibration);
      if (!cal.ok()) return Status::NoSolution(cal.status().message());
    }
  }
  out.calibration = std::move(*cal);
  if (const IntrinsicsFault fault = FindImplausibleIntrinsics(out.calibration.intrinsics); !fault.field.empty()) {
    return Status::NoSolution("the calibration gave implausible intrinsics (" + fault.field + ": " + fault.what +
                              "): too few or too similar views?");
  }
  Result<SensorCoverage> coverage =
      ComputeSensorCoverage(out.width_px, out.height_px, out.views, options.coverage_cells_across);
  if (!coverage.ok()) return coverage.status();
  out.coverage = std::move(*coverage);
  return out;
}

std::string CameraImagesCalibration::ToText() const {
  std::ostringstream o;
  const CameraCalibration& c = calibration;
  o << "Camera calibration: " << views.size() << " of " << files.size() << " images used, " << c.num_corners
    << " corners, image " << width_px << " x " << height_px << " px\n";
  o << "  board: " << board.Describe() << "\n";
  o << "  RMS reprojection error " << FormatPrintf("%.4f", c.rms_px) << " px\n";
  const auto packed = c.intrinsics.Packed();
  for (int k = 0; k < kNumCameraParameters; ++k) {
    o << "  " << kParameterNames[k] << " = " << FormatNumber(packed[static_cast<size_t>(k)], 8);
    const double s = c.intrinsics_std[static_cast<size_t>(k)];
    if (s > 0.0) {
      o << " +- " << FormatNumber(s, 3) << (k < 4 ? " px" : "") << " (1 sigma)";
    } else {
      o << (k < 4 ? " px" : "") << " (held fixed)";
    }
    o << "\n";
  }
  o << "  per view (RMS px, corners):\n";
  for (size_t v = 0; v < views.size(); ++v) {
    o << "    " << views[v].name << "  " << FormatPrintf("%.4f", c.view_rms_px[v]) << "  "
      << c.view_num_corners[v] << "\n";
  }
  if (!rejected.empty()) {
    o << "  rejected (" << rejected.size() << "):\n";
    for (const RejectedView& r : rejected) o << "    " << r.file << ": " << r.reason << "\n";
  }
  o << "  coverage: " << coverage.Summary() << "\n";
  return o.str();
}

std::string CameraImagesCalibration::ToJson() const {
  using ojson = nlohmann::ordered_json;
  const CameraCalibration& c = calibration;
  ojson root;
  root["format"] = "opl.camera_calibration_report";
  root["version"] = 1;
  root["image"] = {{"width_px", width_px}, {"height_px", height_px}};
  root["board"] = ojson::parse(FormatBoardJson(board));
  root["board_description"] = board.Describe();
  const auto packed = c.intrinsics.Packed();
  ojson intrinsics = ojson::object(), stds = ojson::object(), fixed = ojson::array();
  for (int k = 0; k < kNumCameraParameters; ++k) {
    intrinsics[kParameterNames[k]] = packed[static_cast<size_t>(k)];
    stds[kParameterNames[k]] = c.intrinsics_std[static_cast<size_t>(k)];
    if (c.intrinsics_std[static_cast<size_t>(k)] == 0.0) fixed.push_back(kParameterNames[k]);
  }
  root["intrinsics"] = intrinsics;
  root["intrinsics_std"] = stds;
  root["held_fixed"] = fixed;
  root["rms_px"] = c.rms_px;
  root["corners"] = c.num_corners;
  ojson view_list = ojson::array();
  for (size_t v = 0; v < views.size(); ++v) {
    view_list.push_back({{"file", views[v].name}, {"rms_px", c.view_rms_px[v]}, {"corners", c.view_num_corners[v]}});
  }
  root["views"] = view_list;
  ojson rejected_list = ojson::array();
  for (const RejectedView& r : rejected) rejected_list.push_back({{"file", r.file}, {"reason", r.reason}});
  root["rejected"] = rejected_list;
  root["coverage"] = {{"cells_across", coverage.cells_across},
                      {"cells_down", coverage.cells_down},
                      {"fraction_covered", coverage.fraction_covered},
                      {"corners_per_cell", coverage.corners_per_cell}};
  return root.dump(2) + "\n";
}

SceneCamera CameraImagesCalibration::ToSceneCamera(const std::string& name) const {
  SceneCamera camera;
  camera.name = name;
  camera.intrinsics = calibration.intrinsics;
  SceneCameraCalibration record;
  record.intrinsics_std = calibration.intrinsics_std;
  record.rms_px = calibration.rms_px;
  record.num_views = calibration.num_views;
  record.num_corners = calibration.num_corners;
  record.board = board.Describe();
  camera.calibration = record;
  return camera;
}

}  // namespace opl
