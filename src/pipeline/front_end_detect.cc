// Image front end, steps 1-2: every image read and checked against its
// camera, tags and spots detected in parallel, laser-off shots subtracted
// from the lit shots of their camera (vision/dark_frame.h), the spot gates.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>
#include <thread>

#include <Eigen/Eigenvalues>

#include "core/parallel_for.h"
#include "opl/core/format.h"
#include "opl/vision/dark_frame.h"
#include "pipeline/front_end_run.h"

namespace opl {
namespace front_end_internal {

namespace {

// The spot gates of FrontEndOptions (min_spot_snr, max_spot_center_sigma_px).
bool IsLaserSpot(const DetectedSpot& s, const FrontEndOptions& options) {
  if (!(s.snr >= options.min_spot_snr)) return false;
  const Eigen::Matrix2d& c = s.covariance_px2;
  if (!c.allFinite()) return false;
  const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(c).eigenvalues()(1);
  return largest <= options.max_spot_center_sigma_px * options.max_spot_center_sigma_px;
}

// Reads a shot's image (vision/shot_image.h: sensor pixels, tags in luma,
// spots in options.spot_channel) and checks it against its camera's size.
Result<ShotImage> ReadAndCheckShotImage(const std::string& path, const CameraIntrinsics& k,
                                        const std::string& camera_name, const std::string& file,
                                        SpotChannel channel) {
  Result<ShotImage> shot = ReadShotImage(path, channel);
  if (!shot.ok()) return shot.status();
  const cv::Mat& image = shot->for_tags;
  if (image.cols != k.width_px || image.rows != k.height_px) {
    return Status::InvalidArgument(file + ": image is " + std::to_string(image.cols) + " x " +
                                   std::to_string(image.rows) + " but camera '" + camera_name +
                                   "' is calibrated for " + std::to_string(k.width_px) + " x " +
                                   std::to_string(k.height_px) +
                                   " (sensor pixels: an EXIF orientation tag is not applied)");
  }
  return shot;
}

// True when the pixel lies inside the quadrilateral of a tag (grown by
// `margin` of its size about its centre).
bool InsideTag(const TagDetection& tag, const Eigen::Vector2d& p, double margin) {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& c : tag.corners_px) center += c / 4.0;
  std::array<Eigen::Vector2d, 4> q;
  for (size_t i = 0; i < 4; ++i) q[i] = center + (1.0 + margin) * (tag.corners_px[i] - center);
  int sign = 0;
  for (size_t i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = q[(i + 1) % 4] - q[i];
    const Eigen::Vector2d d = p - q[i];
    const double cross = e.x() * d.y() - e.y() * d.x();
    const int s = cross > 0.0 ? 1 : -1;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

}  // namespace

Status FrontEndRun::Detect() {
  // 1-2. Read and detect, in parallel; the first error (in shot order) wins.
  // Laser-off shots first: their images are the lit shots' dark frames.
  data.assign(static_cast<size_t>(num_images), ImageData());
  std::vector<Status> errors(static_cast<size_t>(num_images));
  std::mutex progress_mutex;
  std::atomic<int> done{0};
  threads = options.num_threads > 0
                ? options.num_threads
                : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<int> dark_shots, lit_shots;
  for (int i = 0; i < num_images; ++i) {
    (scene.shots[static_cast<size_t>(i)].lasers.empty() ? dark_shots : lit_shots).push_back(i);
  }
  if (Status st = CheckSceneHasLasers(scene); !st.ok()) {
    return Status::InvalidArgument("scene: " + st.message());
  }
  std::vector<cv::Mat> dark_images(static_cast<size_t>(num_images));
  const auto read_and_find_tags = [&](int i) -> Result<ShotImage> {
    const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
    const std::string path = (std::filesystem::path(images_dir) / shot.file).string();
    Result<ShotImage> image = ReadAndCheckShotImage(path, intrinsics[static_cast<size_t>(i)],
                                                    shot.camera, shot.file, options.spot_channel);
    if (!image.ok()) return image.status();
    Result<std::vector<TagDetection>> tags = DetectTags(image->for_tags, options.tags);
    if (!tags.ok()) return Status(tags.status().code(), shot.file + ": " + tags.status().message());
    ImageData& d = data[static_cast<size_t>(i)];
    d.tags = std::move(*tags);
    d.lossy_jpeg = image->lossy_jpeg;
    d.decode_warnings = image->decode_warnings;
    return image;
  };
  internal::ParallelFor(static_cast<int>(dark_shots.size()), threads, [&](int k) {
    const int i = dark_shots[static_cast<size_t>(k)];
    Result<ShotImage> image = read_and_find_tags(i);
    if (!image.ok()) {
      errors[static_cast<size_t>(i)] = image.status();
      return;
    }
    if (options.use_dark_frames) dark_images[static_cast<size_t>(i)] = std::move(image->for_spots);
    std::lock_guard<std::mutex> lock(progress_mutex);
    Progress("detect", ++done, num_images);
  });
  for (const Status& e : errors) OPL_RETURN_IF_ERROR(e);
  internal::ParallelFor(static_cast<int>(lit_shots.size()), threads, [&](int k) {
    const int i = lit_shots[static_cast<size_t>(k)];
    const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
    Status& error = errors[static_cast<size_t>(i)];
    Result<ShotImage> image = read_and_find_tags(i);
    if (!image.ok()) {
      error = image.status();
      return;
    }
    ImageData& d = data[static_cast<size_t>(i)];
    // The laser-off shot of this camera and slice whose tags moved least.
    // The slice too: in a calibration session the screen moves between
    // slices while the camera does not, so every laser-off shot of the
    // camera shows its tags on the same pixels, but only the one of the
    // shot's own slice shows the screen where the lit shot does.
    int dark = -1;
    double best_shift = std::numeric_limits<double>::infinity();
    for (int j : dark_shots) {
      const SceneShot& off = scene.shots[static_cast<size_t>(j)];
      if (dark_images[static_cast<size_t>(j)].empty() || off.camera != shot.camera ||
          off.slice != shot.slice) {
        continue;
      }
      const double shift = TagShiftPx(d.tags, data[static_cast<size_t>(j)].tags, nullptr);
      d.dark_candidates.push_back({j, shift});
      if (shift < best_shift) {
        best_shift = shift;
        dark = j;
      }
    }
    cv::Mat for_spots = image->for_spots;
    SpotDetectionOptions spot_options = options.spots;
    double gain = 1.0;
    if (dark >= 0 && best_shift <= options.max_dark_frame_shift_px &&
        options.match_dark_frame_exposure) {
      const std::string& dark_file = scene.shots[static_cast<size_t>(dark)].file;
      const Result<DarkFrameGain> g = EstimateDarkFrameGain(
          image->for_spots, dark_images[static_cast<size_t>(dark)], options.spots.saturation_dn);
      if (!g.ok()) {
        d.dark_frame_note = "exposure of laser-off shot " + dark_file +
                            " not measured (" + g.status().message() + "): subtracted as it is";
      } else if (g->gain < options.min_dark_frame_gain || g->gain > options.max_dark_frame_gain) {
        d.dark_frame_note = "laser-off shot " + dark_file + " not subtracted: its light is " +
                            FormatNumber(1.0 / g->gain, 3) + " x this image's (allowed " +
                            FormatNumber(1.0 / options.max_dark_frame_gain, 3) + " to " +
                            FormatNumber(1.0 / options.min_dark_frame_gain, 3) +
                            "): a different light, not an exposure";
        dark = -1;
      } else if (DarkFrameGainMatters(*g, image->for_spots.depth())) {
        gain = g->gain;
        d.dark_frame_note = "laser-off shot " + dark_file + " scaled by " +
                            FormatNumber(gain, 4) + " to this image's exposure (it would have left " +
                            FormatNumber(g->mismatch_dn, 2) +
                            " DN of the scene; automatic exposure or flickering light?)";
      }
    }
    if (dark >= 0 && best_shift <= options.max_dark_frame_shift_px) {
      Result<cv::Mat> difference =
          SubtractDarkFrame(image->for_spots, dark_images[static_cast<size_t>(dark)],
                            options.spots.saturation_dn, gain);
      if (!difference.ok()) {
        error = Status(difference.status().code(),
                       shot.file + " minus " + scene.shots[static_cast<size_t>(dark)].file + ": " +
                           difference.status().message());
        return;
      }
      for_spots = std::move(*difference);
      spot_options.saturation_dn = 0.0;  // SubtractDarkFrame marks saturation at 65535
      d.dark_frame = dark;
      d.dark_frame_gain = gain;
    }
    Result<SpotDetectionResult> spots = DetectSpots(for_spots, spot_options);
    if (!spots.ok()) {
      error = Status(spots.status().code(), shot.file + ": " + spots.status().message());
      return;
    }
    for (const DetectedSpot& s : spots->spots) {
      bool in_tag = false;
      for (const TagDetection& t : d.tags) {
        in_tag = in_tag || InsideTag(t, Eigen::Vector2d(s.u_px, s.v_px), 0.3);
      }
      if (in_tag) continue;
      if (IsLaserSpot(s, options)) {
        d.spots.push_back(s);
        d.spots_saturated += s.has(kSpotSaturated) ? 1 : 0;
      } else {
        ++d.blobs_rejected;
        d.rejected_blobs_px.emplace_back(s.u_px, s.v_px);
      }
    }
    std::lock_guard<std::mutex> lock(progress_mutex);
    Progress("detect", ++done, num_images);
  });
  for (const Status& e : errors) OPL_RETURN_IF_ERROR(e);
  int images_with_tags = 0;
  for (int i = 0; i < num_images; ++i) {
    ImageFindings& f = result.images[static_cast<size_t>(i)];
    for (const TagDetection& t : data[static_cast<size_t>(i)].tags) f.tag_ids.push_back(t.id);
    f.spots_detected = static_cast<int>(data[static_cast<size_t>(i)].spots.size());
    f.blobs_rejected = data[static_cast<size_t>(i)].blobs_rejected;
    f.spots_saturated = data[static_cast<size_t>(i)].spots_saturated;
    f.lossy_jpeg = data[static_cast<size_t>(i)].lossy_jpeg;
    f.decode_warnings = data[static_cast<size_t>(i)].decode_warnings;
    f.laser_off = scene.shots[static_cast<size_t>(i)].lasers.empty();
    f.spots = data[static_cast<size_t>(i)].spots;
    f.rejected_blobs_px = data[static_cast<size_t>(i)].rejected_blobs_px;
    f.tags = data[static_cast<size_t>(i)].tags;
    const ImageData& d = data[static_cast<size_t>(i)];
    if (!d.dark_frame_note.empty()) f.notes.push_back(d.dark_frame_note);
    if (d.dark_frame >= 0) {
      f.dark_frame = scene.shots[static_cast<size_t>(d.dark_frame)].file;
      f.dark_frame_gain = d.dark_frame_gain;
    } else if (!d.dark_frame_note.empty()) {
      // Not subtracted, and the note says why (another light).
    } else if (!d.dark_candidates.empty()) {
      std::string moved;
      for (const auto& [j, shift] : d.dark_candidates) {
        moved += (moved.empty() ? "" : ", ") + scene.shots[static_cast<size_t>(j)].file + " " +
                 (std::isfinite(shift) ? FormatNumber(shift, 3) + " px" : "no common tag");
      }
      f.notes.push_back("laser-off shot of the same camera not subtracted: its tags moved (" +
                        moved + "; at most " + FormatNumber(options.max_dark_frame_shift_px) +
                        " px)");
    } else if (options.use_dark_frames && !f.laser_off) {
      const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
      std::string others;
      for (int j : dark_shots) {
        const SceneShot& off = scene.shots[static_cast<size_t>(j)];
        if (off.camera == shot.camera) others += (others.empty() ? "" : ", ") + off.file;
      }
      if (!others.empty()) {
        f.notes.push_back("no laser-off shot of camera '" + shot.camera + "' on slice " +
                          std::to_string(shot.slice) + ": " + others +
                          " (other slices) not subtracted");
      }
    }
    if (f.tag_ids.empty()) f.notes.push_back("no tag found");
    images_with_tags += f.tag_ids.empty() ? 0 : 1;
  }
  if (images_with_tags == 0) {
    return Status::NoSolution("no tag (tag36h11) was found in any of the " +
                              std::to_string(num_images) + " images");
  }
  return Status::Ok();
}

}  // namespace front_end_internal
}  // namespace opl
