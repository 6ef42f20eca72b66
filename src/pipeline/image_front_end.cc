#include "opl/pipeline/image_front_end.h"

#include <cmath>
#include <sstream>

#include "opl/core/format.h"
#include "pipeline/front_end_run.h"

namespace opl {

Status FrontEndOptions::Validate() const {
  OPL_RETURN_IF_ERROR(tags.Validate());
  OPL_RETURN_IF_ERROR(spots.Validate());
  OPL_RETURN_IF_ERROR(matching.Validate());
  if (!(std::isfinite(max_tag_residual_px) && max_tag_residual_px > 0.0)) {
    return Status::InvalidArgument("max_tag_residual_px must be finite and > 0, got " +
                                   FormatNumber(max_tag_residual_px));
  }
  if (!(std::isfinite(tag_outlier_factor) && tag_outlier_factor > 0.0)) {
    return Status::InvalidArgument("tag_outlier_factor must be finite and > 0, got " +
                                   FormatNumber(tag_outlier_factor));
  }
  if (!(std::isfinite(min_tag_outlier_residual_px) && min_tag_outlier_residual_px > 0.0)) {
    return Status::InvalidArgument("min_tag_outlier_residual_px must be finite and > 0, got " +
                                   FormatNumber(min_tag_outlier_residual_px));
  }
  if (!(std::isfinite(max_spot_variance_factor) && max_spot_variance_factor > 1.0)) {
    return Status::InvalidArgument("max_spot_variance_factor must be finite and > 1, got " +
                                   FormatNumber(max_spot_variance_factor));
  }
  if (!(std::isfinite(min_spot_sigma_px) && min_spot_sigma_px >= 0.0)) {
    return Status::InvalidArgument("min_spot_sigma_px must be finite and >= 0, got " +
                                   FormatNumber(min_spot_sigma_px));
  }
  if (!(std::isfinite(min_tag_triangulation_angle_deg) && min_tag_triangulation_angle_deg > 0.0 &&
        min_tag_triangulation_angle_deg < 90.0)) {
    return Status::InvalidArgument("min_tag_triangulation_angle_deg must be in (0, 90), got " +
                                   FormatNumber(min_tag_triangulation_angle_deg));
  }
  for (const auto& [name, value] :
       {std::pair<const char*, double>{"warn_rms_ratio", warn_rms_ratio},
        {"warn_unmatched_fraction", warn_unmatched_fraction},
        {"warn_saturated_fraction", warn_saturated_fraction},
        {"warn_blob_ratio", warn_blob_ratio},
        {"warn_camera_spot_rms_ratio", warn_camera_spot_rms_ratio},
        {"warn_camera_spot_rms_min_px", warn_camera_spot_rms_min_px}}) {
    if (!(std::isfinite(value) && value > 0.0)) {
      return Status::InvalidArgument(std::string(name) + " must be finite and > 0, got " +
                                     FormatNumber(value));
    }
  }
  if (!(std::isfinite(max_tag_rms_ratio) && max_tag_rms_ratio > 1.0)) {
    return Status::InvalidArgument("max_tag_rms_ratio must be finite and > 1, got " +
                                   FormatNumber(max_tag_rms_ratio));
  }
  if (!(std::isfinite(min_spot_snr) && min_spot_snr >= 0.0)) {
    return Status::InvalidArgument("min_spot_snr must be finite and >= 0, got " +
                                   FormatNumber(min_spot_snr));
  }
  if (!(std::isfinite(max_spot_center_sigma_px) && max_spot_center_sigma_px > 0.0)) {
    return Status::InvalidArgument("max_spot_center_sigma_px must be finite and > 0, got " +
                                   FormatNumber(max_spot_center_sigma_px));
  }
  if (!(std::isfinite(max_dark_frame_shift_px) && max_dark_frame_shift_px > 0.0)) {
    return Status::InvalidArgument("max_dark_frame_shift_px must be finite and > 0, got " +
                                   FormatNumber(max_dark_frame_shift_px));
  }
  if (!(min_dark_frame_gain > 0.0 && min_dark_frame_gain <= 1.0 && max_dark_frame_gain >= 1.0 &&
        max_dark_frame_gain <= 16.0)) {
    return Status::InvalidArgument("min_dark_frame_gain must be in (0, 1] and max_dark_frame_gain "
                                   "in [1, 16], got " + FormatNumber(min_dark_frame_gain) + " and " +
                                   FormatNumber(max_dark_frame_gain));
  }
  if (num_threads < 0) {
    return Status::InvalidArgument("num_threads must be >= 0, got " +
                                   std::to_string(num_threads));
  }
  if (!(std::isfinite(max_camera_move_mm) && max_camera_move_mm > 0.0)) {
    return Status::InvalidArgument("max_camera_move_mm must be finite and > 0, got " +
                                   FormatNumber(max_camera_move_mm));
  }
  if (!(std::isfinite(max_camera_turn_mrad) && max_camera_turn_mrad > 0.0)) {
    return Status::InvalidArgument("max_camera_turn_mrad must be finite and > 0, got " +
                                   FormatNumber(max_camera_turn_mrad));
  }
  return Status::Ok();
}

std::string FrontEndResult::ToText() const {
  std::ostringstream out;
  out << "images:\n";
  for (const ImageFindings& f : images) {
    out << "  " << f.file << " (" << f.camera << "): " << f.tag_ids.size() << " tags, ";
    if (f.laser_off) {
      out << "lasers off";
    } else {
      out << f.spots_detected << " spots (" << f.blobs_rejected << " other blobs), "
          << f.spots_matched << " matched";
      if (!f.dark_frame.empty()) {
        out << ", minus " << f.dark_frame;
        if (f.dark_frame_gain != 1.0) out << " x " << FormatNumber(f.dark_frame_gain, 4);
      }
    }
    if (f.placed) {
      out << ", RMS tags " << FormatNumber(f.tag_rms_px, 3) << " px, spots "
          << FormatNumber(f.spot_rms_px, 3) << " px";
    } else {
      out << ", NOT placed";
    }
    out << "\n";
    for (const std::string& n : f.notes) out << "    " << n << "\n";
  }
  out << "exposure groups:\n";
  for (size_t g = 0; g < groups.size(); ++g) {
    int n = 0;
    for (const FrontEndSpot& s : spots) n += s.group == static_cast<int>(g) ? 1 : 0;
    out << "  " << g << ": lasers ";
    for (size_t i = 0; i < groups[g].lasers.size(); ++i) {
      out << (i ? "," : "") << groups[g].lasers[i];
    }
    if (groups[g].lasers.empty()) out << "(none)";
    if (!groups[g].placement.empty()) out << ", placement " << groups[g].placement;
    out << ", slice " << groups[g].slice << ", " << groups[g].images.size() << " images, " << n
        << " 3D spots\n";
  }
  if (!frame_description.empty()) {
    out << "scene frame: " << frame_description << "\n";
  } else {
    out << "scene frame: tags " << frame_tags[0] << " (origin), " << frame_tags[1]
        << " (axis), " << frame_tags[2] << " (plane); " << tag_centers.size()
        << " tags placed\n";
  }
  out << "adjustment: RMS " << FormatNumber(rms_reprojection_px, 3)
      << " px, variance factor " << FormatNumber(variance_factor, 3) << "; spots' variance factor "
      << FormatNumber(spot_variance_factor, 3);
  if (spot_extra_sigma_px > 0.0) {
    out << " (spot standard deviations enlarged by " << FormatNumber(spot_extra_sigma_px, 3)
        << " px in quadrature)";
  }
  out << "; tag corners' " << FormatNumber(tag_variance_factor, 3);
  if (tag_extra_sigma_px > 0.0) {
    out << " (enlarged by " << FormatNumber(tag_extra_sigma_px, 3) << " px in quadrature)";
  }
  if (spot_point_covariance_scale != 1.0) {
    out << "; 3D spot covariances scaled by " << FormatNumber(spot_point_covariance_scale, 3);
  }
  out << "\n";
  for (const std::string& w : warnings) out << "warning: " << w << "\n";
  return out.str();
}

namespace front_end_internal {

void FrontEndRun::Init() {
  intrinsics.resize(static_cast<size_t>(num_images));
  result.images.resize(static_cast<size_t>(num_images));
  for (int i = 0; i < num_images; ++i) {
    const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
    intrinsics[static_cast<size_t>(i)] = scene.FindCamera(shot.camera)->intrinsics;
    result.images[static_cast<size_t>(i)].file = shot.file;
    result.images[static_cast<size_t>(i)].camera = shot.camera;
  }
}

}  // namespace front_end_internal

Status CheckSceneHasLasers(const Scene& scene) {
  for (const SceneShot& shot : scene.shots) {
    if (!shot.lasers.empty()) return Status::Ok();
  }
  return Status::InvalidArgument(
      "shots: no shot has a laser on (every shot's 'lasers' is empty or absent): there are no "
      "spots to measure");
}

Result<FrontEndResult> RunImageFrontEnd(const Scene& scene, const std::string& images_dir,
                                        const FrontEndOptions& options) {
  OPL_RETURN_IF_ERROR(scene.Validate());
  OPL_RETURN_IF_ERROR(options.Validate());
  const int num_images = static_cast<int>(scene.shots.size());
  if (num_images < 2) {
    return Status::InvalidArgument("scene: " + std::to_string(num_images) +
                                   " shot(s); at least two images are needed");
  }
  front_end_internal::FrontEndRun run(scene, images_dir, options);
  run.Init();
  OPL_RETURN_IF_ERROR(run.Detect());
  OPL_RETURN_IF_ERROR(run.PlaceCameras());
  OPL_RETURN_IF_ERROR(run.ChooseFrameTags());
  OPL_RETURN_IF_ERROR(run.AdjustTags());
  run.GroupShots();
  OPL_RETURN_IF_ERROR(run.MatchAndAdjust());
  run.PerImageRms();
  run.WarnOutOfRange();
  OPL_RETURN_IF_ERROR(run.RefuseBrokenGeometry());
  OPL_RETURN_IF_ERROR(run.MoveToSceneFrame());
  return std::move(run.result);
}

}  // namespace opl
