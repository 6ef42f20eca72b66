#include "opl/pipeline/shot_overlays.h"

#include <filesystem>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "core/parallel_for.h"
#include "opl/vision/shot_image.h"

namespace opl {

ShotOverlay OverlayOfImage(const FrontEndResult& fe, const std::vector<std::string>& spot_labels,
                           int image_index) {
  ShotOverlay overlay;
  if (image_index < 0 || image_index >= static_cast<int>(fe.images.size())) return overlay;
  const ImageFindings& f = fe.images[static_cast<size_t>(image_index)];
  overlay.title = f.file;
  for (const TagDetection& t : f.tags) overlay.tags.push_back({t.id, t.corners_px});
  for (const DetectedSpot& s : f.spots) {
    ShotOverlay::Spot spot;
    spot.center_px = Eigen::Vector2d(s.u_px, s.v_px);
    overlay.spots.push_back(spot);
  }
  for (size_t k = 0; k < fe.spots.size(); ++k) {
    const bool identified = k < spot_labels.size() && !spot_labels[k].empty();
    for (const auto& [image, index] : fe.spots[k].views) {
      if (image != image_index || index < 0 || index >= static_cast<int>(overlay.spots.size())) {
        continue;
      }
      ShotOverlay::Spot& spot = overlay.spots[static_cast<size_t>(index)];
      if (identified) {
        spot.state = ShotOverlay::SpotState::kIdentified;
        spot.label = spot_labels[k];
      } else {
        spot.state = ShotOverlay::SpotState::kMatched;
      }
    }
  }
  overlay.rejected_px = f.rejected_blobs_px;
  return overlay;
}

std::string OverlayFileName(const std::string& shot_file) {
  const std::filesystem::path p(shot_file);
  return (p.parent_path() / (p.stem().string() + "_overlay.jpg")).string();
}

Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const FrontEndResult& front_end,
    const std::vector<std::string>& spot_labels, int threads) {
  const int n = static_cast<int>(scene.shots.size());
  std::vector<std::pair<std::string, std::string>> out(static_cast<size_t>(n));
  std::vector<Status> errors(static_cast<size_t>(n));
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  internal::ParallelFor(n, threads, [&](int i) {
    const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
    const std::string path = (std::filesystem::path(images_dir) / shot.file).string();
    // Its decode warnings, if any, are already in the report's (the front end's).
    Result<ShotImage> image = ReadShotImage(path, SpotChannel::kLuma);
    if (!image.ok()) {
      errors[static_cast<size_t>(i)] = image.status();
      return;
    }
    Result<cv::Mat> drawn = DrawShotOverlay(image->for_tags, OverlayOfImage(front_end, spot_labels, i));
    if (!drawn.ok()) {
      errors[static_cast<size_t>(i)] = Status(drawn.status().code(), shot.file + ": " +
                                                                         drawn.status().message());
      return;
    }
    std::vector<unsigned char> jpeg;
    if (!cv::imencode(".jpg", *drawn, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90})) {
      errors[static_cast<size_t>(i)] = Status::IoError(shot.file + ": cannot encode its overlay");
      return;
    }
    out[static_cast<size_t>(i)] = {OverlayFileName(shot.file), std::string(jpeg.begin(), jpeg.end())};
  });
  for (const Status& e : errors) OPL_RETURN_IF_ERROR(e);
  return out;
}

}  // namespace opl
