#include "opl/pipeline/image_front_end.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include <Eigen/Eigenvalues>

#include "core/parallel_for.h"
#include "opl/core/format.h"
#include "opl/geometry/rotation.h"
#include "opl/vision/dark_frame.h"
#include "opl/vision/scene_frame.h"
#include "opl/vision/tag_poses.h"

namespace opl {
namespace {

struct ImageData {
  std::vector<TagDetection> tags;
  std::vector<DetectedSpot> spots;
  int blobs_rejected = 0;  // FrontEndOptions' spot gates
  int spots_saturated = 0;
  bool lossy_jpeg = false;
  std::vector<Eigen::Vector2d> rejected_blobs_px;
  int dark_frame = -1;  // laser-off shot subtracted, or -1
  std::vector<std::pair<int, double>> dark_candidates;  // (laser-off shot, tag shift px)
};

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

Eigen::Matrix2d CornerCovariance(const Eigen::Matrix2d& c) {
  // The edge fit's covariance when it has one, else 0.05 px per coordinate.
  if (c.allFinite() && c.determinant() > 1e-12) return c;
  return Eigen::Matrix2d::Identity() * 0.05 * 0.05;
}

// sum_k r_k^T (C_k + extra I)^-1 r_k.
double Chi2WithExtraVariance(const std::vector<Eigen::Vector2d>& residuals,
                             const std::vector<Eigen::Matrix2d>& covariances, double extra_px2) {
  double chi2 = 0.0;
  for (size_t k = 0; k < residuals.size(); ++k) {
    const Eigen::Matrix2d c = covariances[k] + extra_px2 * Eigen::Matrix2d::Identity();
    chi2 += residuals[k].dot(c.ldlt().solve(residuals[k]));
  }
  return chi2;
}

// The variance component: the isotropic variance e >= 0 that, added to every
// covariance, makes chi^2(e) = redundancy. chi^2 falls monotonically in e,
// and chi^2(sum |r|^2 / redundancy) <= redundancy brackets the root.
double ExtraVarianceForUnitFactor(const std::vector<Eigen::Vector2d>& residuals,
                                  const std::vector<Eigen::Matrix2d>& covariances,
                                  int redundancy) {
  if (redundancy <= 0) return 0.0;
  if (Chi2WithExtraVariance(residuals, covariances, 0.0) <= redundancy) return 0.0;
  double sum_r2 = 0.0;
  for (const Eigen::Vector2d& r : residuals) sum_r2 += r.squaredNorm();
  double lo = 0.0, hi = sum_r2 / redundancy;
  for (int it = 0; it < 60 && hi - lo > 1e-9 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (Chi2WithExtraVariance(residuals, covariances, mid) > redundancy ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

Status FrontEndOptions::Validate() const {
  OPL_RETURN_IF_ERROR(tags.Validate());
  OPL_RETURN_IF_ERROR(spots.Validate());
  OPL_RETURN_IF_ERROR(matching.Validate());
  if (!(std::isfinite(max_tag_residual_px) && max_tag_residual_px > 0.0)) {
    return Status::InvalidArgument("max_tag_residual_px must be finite and > 0, got " +
                                   FormatNumber(max_tag_residual_px));
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
        {"warn_blob_ratio", warn_blob_ratio}}) {
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
      if (!f.dark_frame.empty()) out << ", minus " << f.dark_frame;
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
    out << ", slice " << groups[g].slice << ", " << groups[g].images.size() << " images, " << n
        << " 3D spots\n";
  }
  out << "scene frame: tags " << frame_tags[0] << " (origin), " << frame_tags[1] << " (axis), "
      << frame_tags[2] << " (plane); " << tag_centers.size() << " tags placed\n";
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

namespace {

// One run of the front end: its state between the stages, which
// RunImageFrontEnd calls in order (the numbers of the header's steps).
struct FrontEndRun {
  struct TagObservationRef {
    int image;
    int tag;
    int corner;
  };
  struct SpotObservationRef {
    int image;
    int spot;
  };

  FrontEndRun(const Scene& scene_in, const std::string& images_dir_in,
              const FrontEndOptions& options_in)
      : scene(scene_in), images_dir(images_dir_in), options(options_in),
        num_images(static_cast<int>(scene_in.shots.size())) {}

  void Progress(const std::string& stage, int done, int total) const {
    if (options.progress) options.progress(stage, done, total);
  }
  void Init();
  Status Detect();            // 1-2
  Status PlaceCameras();      // 3, and the tags' bundle data
  // A tag whose corners are not seen from two camera positions at least
  // min_tag_triangulation_angle_deg apart (two images of one camera
  // position, or a corner dropped as an outlier) leaves its corners' depth
  // undetermined: its observations are removed and its points made
  // constant (AdjustTags removes them), with a warning.
  void DropTagsSeenFromOnePosition();
  // An image left without a tag observation is not held by the tags: it is
  // reported not placed (camera_of_image -1), with a note saying why.
  void UnplaceImagesWithoutTags();
  Status ChooseFrameTags();
  // NoSolution naming a frame tag that is not (or no longer) adjusted.
  Status CheckFrameTagsUsable(const std::string& when) const;
  Status AdjustTags();        // 4
  void GroupShots();          // 5: the exposure groups
  Status MatchGroups();       // 5: matching, into the bundle
  Status AdjustAll();         // 6
  // The variance components after pass `pass`; true: run 5-6 again.
  bool EstimateVarianceComponents(int pass);
  Status MatchAndAdjust();    // 5-6 with the variance components
  void PerImageRms();
  // The warnings of FrontEndOptions::warn_* (after PerImageRms).
  void WarnOutOfRange();
  // FrontEndOptions::max_tag_rms_ratio, unless force.
  Status RefuseBrokenGeometry() const;
  Status MoveToSceneFrame();  // 7

  const Scene& scene;
  const std::string& images_dir;
  const FrontEndOptions& options;
  const int num_images;
  int threads = 1;
  FrontEndResult result;
  std::vector<CameraIntrinsics> intrinsics;
  std::vector<ImageData> data;
  std::optional<TagPoses> poses;
  BundleData bundle;
  std::vector<int> camera_of_image;
  std::map<int, int> first_corner_point;  // tag id -> index of its corner 0
  std::vector<TagObservationRef> tag_refs;
  std::array<int, 3> frame_tags = {-1, -1, -1};
  BundleOptions bundle_options;
  int num_tag_observations = 0;
  BundleData tag_bundle;  // after step 4
  std::vector<SpotObservationRef> spot_refs;
  std::vector<int> spot_group;
  int first_spot_point = 0;
  Result<BundleResult> adjusted = Status::NoSolution("not run");
  // Variance components added to the spots' and the tag corners' pixel
  // covariances [px^2], and the spots' variance factor of the last pass.
  double spot_extra_var_px2 = 0.0;
  double tag_extra_var_px2 = 0.0;
  double last_spot_variance_factor = 1.0;
  double spot_point_scale = 1.0;  // a posteriori, on the 3D spot covariances
};

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
    // The laser-off shot of this camera whose tags moved least.
    int dark = -1;
    double best_shift = std::numeric_limits<double>::infinity();
    for (int j : dark_shots) {
      if (dark_images[static_cast<size_t>(j)].empty() ||
          scene.shots[static_cast<size_t>(j)].camera != shot.camera) {
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
    if (dark >= 0 && best_shift <= options.max_dark_frame_shift_px) {
      Result<cv::Mat> difference = SubtractDarkFrame(
          image->for_spots, dark_images[static_cast<size_t>(dark)], options.spots.saturation_dn);
      if (!difference.ok()) {
        error = Status(difference.status().code(),
                       shot.file + " minus " + scene.shots[static_cast<size_t>(dark)].file + ": " +
                           difference.status().message());
        return;
      }
      for_spots = std::move(*difference);
      spot_options.saturation_dn = 0.0;  // SubtractDarkFrame marks saturation at 65535
      d.dark_frame = dark;
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
    f.laser_off = scene.shots[static_cast<size_t>(i)].lasers.empty();
    f.spots = data[static_cast<size_t>(i)].spots;
    f.rejected_blobs_px = data[static_cast<size_t>(i)].rejected_blobs_px;
    f.tags = data[static_cast<size_t>(i)].tags;
    const ImageData& d = data[static_cast<size_t>(i)];
    if (d.dark_frame >= 0) {
      f.dark_frame = scene.shots[static_cast<size_t>(d.dark_frame)].file;
    } else if (!d.dark_candidates.empty()) {
      std::string moved;
      for (const auto& [j, shift] : d.dark_candidates) {
        moved += (moved.empty() ? "" : ", ") + scene.shots[static_cast<size_t>(j)].file + " " +
                 (std::isfinite(shift) ? FormatNumber(shift, 3) + " px" : "no common tag");
      }
      f.notes.push_back("laser-off shot of the same camera not subtracted: its tags moved (" +
                        moved + "; at most " + FormatNumber(options.max_dark_frame_shift_px) +
                        " px)");
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

Status FrontEndRun::PlaceCameras() {
  // 3. Start poses.
  std::vector<std::vector<TagDetection>> tags_per_image;
  for (const ImageData& d : data) tags_per_image.push_back(d.tags);
  TagPoseOptions pose_options;
  pose_options.tag_size = scene.tags.size_mm;
  Result<TagPoses> found_poses = PosesFromTags(intrinsics, tags_per_image, pose_options);
  if (!found_poses.ok()) return found_poses.status();
  poses = std::move(*found_poses);
  Progress("poses", 1, 1);
  for (const std::string& w : poses->warnings) result.warnings.push_back("start poses: " + w);

  // Bundle data: one intrinsics entry (held) and one pose per placed image
  // (per camera with one_pose_per_camera), four corner points per placed
  // tag.
  camera_of_image.assign(static_cast<size_t>(num_images), -1);
  std::map<std::string, int> first_image_of_camera;  // one_pose_per_camera
  for (int i = 0; i < num_images; ++i) {
    const auto& pose = poses->cam_from_scene[static_cast<size_t>(i)];
    if (!pose) {
      result.images[static_cast<size_t>(i)].notes.push_back(
          "not placed: it sees no tag that other images see");
      continue;
    }
    result.images[static_cast<size_t>(i)].placed = true;
    const std::string& name = scene.shots[static_cast<size_t>(i)].camera;
    if (options.one_pose_per_camera) {
      const auto first = first_image_of_camera.find(name);
      if (first != first_image_of_camera.end()) {
        // The same camera: its start poses must agree (it did not move).
        const Rigid3d& a = *poses->cam_from_scene[static_cast<size_t>(first->second)];
        const Eigen::Vector3d centre_a = a.Inverse().translation;
        const Eigen::Vector3d centre_b = pose->Inverse().translation;
        const double moved_mm = (centre_b - centre_a).norm();
        const double turned_mrad =
            1e3 * RotationAngleBetweenRad(a.RotationMatrix(), pose->RotationMatrix());
        if (moved_mm > options.max_camera_move_mm || turned_mrad > options.max_camera_turn_mrad) {
          return Status::InvalidArgument(
              "camera '" + name + "' moved between shots " +
              scene.shots[static_cast<size_t>(first->second)].file + " and " +
              scene.shots[static_cast<size_t>(i)].file + " (" +
              FormatNumber(std::round(10.0 * moved_mm) / 10.0, 8) + " mm, " +
              FormatNumber(std::round(100.0 * turned_mrad) / 100.0, 8) +
              " mrad, from the tags): one pose per camera needs cameras that stay put");
        }
        camera_of_image[static_cast<size_t>(i)] =
            camera_of_image[static_cast<size_t>(first->second)];
        continue;
      }
      first_image_of_camera[name] = i;
    }
    camera_of_image[static_cast<size_t>(i)] = static_cast<int>(bundle.cameras.size());
    bundle.intrinsics.push_back(
        {scene.shots[static_cast<size_t>(i)].camera, intrinsics[static_cast<size_t>(i)], true});
    BundleCamera camera;
    camera.name = scene.shots[static_cast<size_t>(i)].file;
    camera.intrinsics_index = static_cast<int>(bundle.intrinsics.size()) - 1;
    camera.cam_from_scene = *pose;
    bundle.cameras.push_back(camera);
  }
  const auto corners_in_tag = TagCornersInTag(scene.tags.size_mm);
  for (const auto& [id, scene_from_tag] : poses->scene_from_tag) {
    first_corner_point[id] = static_cast<int>(bundle.points.size());
    for (const Eigen::Vector3d& c : corners_in_tag) {
      BundlePoint p;
      p.point_in_scene = scene_from_tag * c;
      bundle.points.push_back(p);
    }
  }
  for (int i = 0; i < num_images; ++i) {
    const int camera = camera_of_image[static_cast<size_t>(i)];
    if (camera < 0) continue;
    for (const TagDetection& t : data[static_cast<size_t>(i)].tags) {
      const auto found = first_corner_point.find(t.id);
      if (found == first_corner_point.end()) continue;
      for (int c = 0; c < 4; ++c) {
        BundleObservation o;
        o.camera = camera;
        o.point = found->second + c;
        o.pixel_px = t.corners_px[static_cast<size_t>(c)];
        o.covariance_px2 = CornerCovariance(t.corner_covariance_px2[static_cast<size_t>(c)]);
        bundle.observations.push_back(o);
        tag_refs.push_back({i, t.id, c});
      }
    }
  }
  DropTagsSeenFromOnePosition();
  UnplaceImagesWithoutTags();
  return Status::Ok();
}

void FrontEndRun::DropTagsSeenFromOnePosition() {
  // The cameras (bundle indices) that see each corner point, and each tag's
  // centre (the mean of its corner points).
  std::map<int, std::set<int>> cameras_of_point;
  for (size_t o = 0; o < tag_refs.size(); ++o) {
    const BundleObservation& ob = bundle.observations[o];
    cameras_of_point[ob.point].insert(ob.camera);
  }
  const double min_angle_rad = options.min_tag_triangulation_angle_deg * M_PI / 180.0;
  std::set<int> dropped;
  std::map<int, double> best_angle_deg;
  for (const auto& [id, first] : first_corner_point) {
    Eigen::Vector3d center = Eigen::Vector3d::Zero();
    for (int c = 0; c < 4; ++c) center += bundle.points[static_cast<size_t>(first + c)].point_in_scene / 4.0;
    // Every corner needs two rays at the angle (the weakest corner decides).
    double weakest = M_PI;
    for (int c = 0; c < 4; ++c) {
      const auto found = cameras_of_point.find(first + c);
      double widest = 0.0;
      if (found != cameras_of_point.end()) {
        std::vector<Eigen::Vector3d> rays;
        for (int camera : found->second) {
          const Eigen::Vector3d centre =
              bundle.cameras[static_cast<size_t>(camera)].cam_from_scene.Inverse().translation;
          rays.push_back((centre - center).normalized());
        }
        for (size_t a = 0; a < rays.size(); ++a) {
          for (size_t b = a + 1; b < rays.size(); ++b) {
            widest = std::max(widest, std::acos(std::clamp(rays[a].dot(rays[b]), -1.0, 1.0)));
          }
        }
      }
      weakest = std::min(weakest, widest);
    }
    if (weakest < min_angle_rad) {
      dropped.insert(id);
      best_angle_deg[id] = weakest * 180.0 / M_PI;
    }
  }
  if (dropped.empty()) return;
  std::vector<BundleObservation> kept;
  std::vector<TagObservationRef> kept_refs;
  std::map<int, std::set<std::string>> images_of_dropped;
  for (size_t o = 0; o < tag_refs.size(); ++o) {
    if (dropped.count(tag_refs[o].tag)) {
      images_of_dropped[tag_refs[o].tag].insert(
          scene.shots[static_cast<size_t>(tag_refs[o].image)].file);
      continue;
    }
    kept.push_back(bundle.observations[o]);
    kept_refs.push_back(tag_refs[o]);
  }
  // Spot observations (none yet when called before the matching) follow.
  for (size_t o = tag_refs.size(); o < bundle.observations.size(); ++o) {
    kept.push_back(bundle.observations[o]);
  }
  for (int id : dropped) {
    std::string images;
    for (const std::string& f : images_of_dropped[id]) images += (images.empty() ? "" : ", ") + f;
    const double angle = best_angle_deg[id];
    std::string detail = images;
    if (angle > 0.0) {
      detail += (detail.empty() ? "" : "; ") + std::string("rays meet at ") +
                FormatNumber(angle, 2) + " deg, at least " +
                FormatNumber(options.min_tag_triangulation_angle_deg) + " deg needed";
    }
    result.warnings.push_back("tag " + std::to_string(id) +
                              ": not used, seen from one camera position only" +
                              (detail.empty() ? std::string() : " (" + detail + ")"));
    for (int c = 0; c < 4; ++c) {
      bundle.points[static_cast<size_t>(first_corner_point[id] + c)].constant = true;
    }
    first_corner_point.erase(id);
  }
  bundle.observations = std::move(kept);
  tag_refs = std::move(kept_refs);
}

void FrontEndRun::UnplaceImagesWithoutTags() {
  std::set<int> held;  // bundle cameras with a tag observation
  for (size_t o = 0; o < tag_refs.size(); ++o) held.insert(bundle.observations[o].camera);
  for (int i = 0; i < num_images; ++i) {
    const int camera = camera_of_image[static_cast<size_t>(i)];
    if (camera < 0 || held.count(camera)) continue;
    camera_of_image[static_cast<size_t>(i)] = -1;
    ImageFindings& f = result.images[static_cast<size_t>(i)];
    f.placed = false;
    f.notes.push_back("not placed: none of its tags is seen from another camera position");
  }
}

Status FrontEndRun::CheckFrameTagsUsable(const std::string& when) const {
  const char* role[3] = {"origin", "axis", "plane"};
  for (int r = 0; r < 3; ++r) {
    if (!first_corner_point.count(frame_tags[static_cast<size_t>(r)])) {
      return Status::NoSolution(
          "frame " + std::string(role[r]) + " tag " +
          std::to_string(frame_tags[static_cast<size_t>(r)]) +
          " is not seen from two camera positions (placed images whose rays meet at " +
          FormatNumber(options.min_tag_triangulation_angle_deg) + " deg or more)" + when);
    }
  }
  return Status::Ok();
}

Status FrontEndRun::ChooseFrameTags() {
  // The frame's tags.
  if (scene.frame) {
    frame_tags = {scene.frame->origin_tag, scene.frame->axis_tag, scene.frame->plane_tag};
    OPL_RETURN_IF_ERROR(CheckFrameTagsUsable(""));
  } else {
    // The three placed tags spanning the largest triangle.
    std::vector<std::pair<int, Eigen::Vector3d>> centers;
    for (const auto& [id, first] : first_corner_point) {
      centers.emplace_back(id, poses->scene_from_tag.at(id).translation);
    }
    double best = 0.0;
    for (size_t a = 0; a < centers.size(); ++a) {
      for (size_t b = a + 1; b < centers.size(); ++b) {
        for (size_t c = b + 1; c < centers.size(); ++c) {
          const double area = (centers[b].second - centers[a].second)
                                  .cross(centers[c].second - centers[a].second)
                                  .norm();
          if (area > best) {
            best = area;
            frame_tags = {centers[a].first, centers[b].first, centers[c].first};
          }
        }
      }
    }
    if (best <= 0.0) {
      return Status::NoSolution("fewer than three tags were found in two placed images: the "
                                "scene frame cannot be set");
    }
  }
  result.frame_tags = frame_tags;
  return Status::Ok();
}

Status FrontEndRun::AdjustTags() {
  bundle_options.num_threads = threads;
  bundle_options.gauge = BundleGauge::kFixedByCaller;


  // 4. Tags only, the gauge held by the reference tag's corners (the frame
  // and the scale of the start poses).
  const int reference = poses->reference_tag;
  if (!first_corner_point.count(reference)) {
    return Status::NoSolution("the reference tag " + std::to_string(reference) +
                              " is not seen from two camera positions");
  }
  {
    BundleData tags_only = bundle;
    for (int c = 0; c < 4; ++c) {
      tags_only.points[static_cast<size_t>(first_corner_point[reference] + c)].constant = true;
    }
    BundleOptions o = bundle_options;
    o.loss = BundleLoss::kHuber;
    o.loss_scale_px = 1.0;
    Result<BundleResult> adjusted = BundleAdjust(tags_only, o);
    if (!adjusted.ok()) {
      return Status::NoSolution("bundle adjustment of the tags: " + adjusted.status().message());
    }
    // Drop tag observations that stay far off.
    std::vector<BundleObservation> kept;
    std::vector<TagObservationRef> kept_refs;
    for (size_t k = 0; k < adjusted->data.observations.size(); ++k) {
      const BundleObservation& ob = adjusted->data.observations[k];
      const Camera cam = adjusted->data.CameraAt(ob.camera);
      Eigen::Vector2d px;
      const bool ok = cam.Project(adjusted->data.points[static_cast<size_t>(ob.point)].point_in_scene, &px) &&
                      (px - ob.pixel_px).norm() <= options.max_tag_residual_px * std::sqrt(2.0);
      if (ok) {
        kept.push_back(ob);
        kept_refs.push_back(tag_refs[k]);
      } else {
        result.images[static_cast<size_t>(tag_refs[k].image)].notes.push_back(
            "tag " + std::to_string(tag_refs[k].tag) + " corner " +
            std::to_string(tag_refs[k].corner) + " dropped (residual > " +
            FormatNumber(options.max_tag_residual_px) + " px)");
      }
    }
    for (size_t c = 0; c < bundle.cameras.size(); ++c) {
      bundle.cameras[c].cam_from_scene = adjusted->data.cameras[c].cam_from_scene;
    }
    for (size_t p = 0; p < bundle.points.size(); ++p) {
      bundle.points[p].point_in_scene = adjusted->data.points[p].point_in_scene;
    }
    bundle.observations = std::move(kept);
    tag_refs = std::move(kept_refs);
  }
  // Dropped corners may leave a tag seen from one position only.
  DropTagsSeenFromOnePosition();
  UnplaceImagesWithoutTags();
  OPL_RETURN_IF_ERROR(CheckFrameTagsUsable(" once its outlying corners are dropped"));
  Progress("adjust tags", 1, 1);
  // Unobserved (constant) tag points would break the datum of the final
  // adjustment: remove them.
  {
    std::vector<int> new_index(bundle.points.size(), -1);
    std::vector<BundlePoint> points;
    for (size_t p = 0; p < bundle.points.size(); ++p) {
      if (bundle.points[p].constant) continue;
      new_index[p] = static_cast<int>(points.size());
      points.push_back(bundle.points[p]);
    }
    for (BundleObservation& o : bundle.observations) {
      o.point = new_index[static_cast<size_t>(o.point)];
    }
    for (auto& [id, first] : first_corner_point) first = new_index[static_cast<size_t>(first)];
    bundle.points = std::move(points);
  }
  num_tag_observations = static_cast<int>(bundle.observations.size());
  tag_bundle = bundle;
  return Status::Ok();
}

void FrontEndRun::GroupShots() {
  // 5. Groups and matching.
  {
    std::map<std::pair<std::vector<std::string>, int>, int> group_of_key;
    for (int i = 0; i < num_images; ++i) {
      const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
      if (shot.lasers.empty()) continue;  // a laser-off shot: tags and dark frame only
      std::vector<std::string> lasers = shot.lasers;
      std::sort(lasers.begin(), lasers.end());
      const auto key = std::make_pair(lasers, shot.slice);
      auto found = group_of_key.find(key);
      if (found == group_of_key.end()) {
        found = group_of_key.emplace(key, static_cast<int>(result.groups.size())).first;
        result.groups.push_back({lasers, shot.slice, {}});
      }
      result.groups[static_cast<size_t>(found->second)].images.push_back(i);
    }
  }
}

Status FrontEndRun::MatchGroups() {
  bundle = tag_bundle;
  for (int k = 0; k < num_tag_observations; ++k) {
    bundle.observations[static_cast<size_t>(k)].covariance_px2 +=
        tag_extra_var_px2 * Eigen::Matrix2d::Identity();
  }
  spot_refs.clear();
  spot_group.clear();
  for (ImageFindings& f : result.images) f.spots_matched = 0;
  for (size_t g = 0; g < result.groups.size(); ++g) {
    const ExposureGroup& group = result.groups[g];
    std::vector<Camera> cameras;
    std::vector<std::vector<SpotInView>> spots_per_view;
    std::vector<int> image_of_view;
    for (int i : group.images) {
      const int camera = camera_of_image[static_cast<size_t>(i)];
      if (camera < 0) continue;
      cameras.push_back(bundle.CameraAt(camera));
      image_of_view.push_back(i);
      std::vector<SpotInView> views;
      for (const DetectedSpot& s : data[static_cast<size_t>(i)].spots) {
        SpotInView v;
        v.pixel_px = Eigen::Vector2d(s.u_px, s.v_px);
        // DetectSpots hands on symmetric covariances, positive definite but
        // for a degenerate centroid's; anything else is replaced by the
        // floor rather than refused by the matcher.
        Eigen::Matrix2d c = s.covariance_px2;
        const double floor2 = options.min_spot_sigma_px * options.min_spot_sigma_px;
        if (!(c.allFinite() && c(0, 1) == c(1, 0) && c(0, 0) > 0.0 && c.determinant() > 0.0)) {
          c = Eigen::Matrix2d::Identity() * floor2;
        }
        c += Eigen::Matrix2d::Identity() * floor2;
        v.covariance_px2 = c + spot_extra_var_px2 * Eigen::Matrix2d::Identity();
        views.push_back(v);
      }
      spots_per_view.push_back(std::move(views));
    }
    if (cameras.size() < 2) {
      result.warnings.push_back("exposure group " + std::to_string(g) +
                                ": fewer than two placed images, its spots are not used");
      continue;
    }
    Result<SpotMatchResult> matched = MatchSpots(cameras, spots_per_view, options.matching);
    if (!matched.ok()) {
      return Status(matched.status().code(), "matching the spots of exposure group " +
                                                 std::to_string(g) + ": " +
                                                 matched.status().message());
    }
    for (const SpotTrack& track : matched->tracks) {
      const int point = static_cast<int>(bundle.points.size());
      BundlePoint p;
      p.point_in_scene = track.point.point_in_scene;
      bundle.points.push_back(p);
      spot_group.push_back(static_cast<int>(g));
      for (const SpotRef& ref : track.spots) {
        const int view = ref.view;
        const int index = ref.spot;
        const int image = image_of_view[static_cast<size_t>(view)];
        BundleObservation o;
        o.camera = camera_of_image[static_cast<size_t>(image)];
        o.point = point;
        o.pixel_px = spots_per_view[static_cast<size_t>(view)][static_cast<size_t>(index)].pixel_px;
        o.covariance_px2 =
            spots_per_view[static_cast<size_t>(view)][static_cast<size_t>(index)].covariance_px2;
        bundle.observations.push_back(o);
        spot_refs.push_back({image, index});
        ++result.images[static_cast<size_t>(image)].spots_matched;
      }
    }
    Progress("match", static_cast<int>(g) + 1, static_cast<int>(result.groups.size()));
  }
  return Status::Ok();
}

Status FrontEndRun::AdjustAll() {
  // 6. Everything together, in the datum of the frame tags' first corners.
  // The spot points follow the tag corners.
  first_spot_point = static_cast<int>(bundle.points.size()) -
                     static_cast<int>(spot_group.size());
  BundleOptions final_options = bundle_options;
  final_options.gauge = BundleGauge::kThreePointDatum;
  final_options.datum_points = {first_corner_point.at(frame_tags[0]),
                                first_corner_point.at(frame_tags[1]),
                                first_corner_point.at(frame_tags[2])};
  final_options.compute_point_covariances = true;
  adjusted = BundleAdjust(bundle, final_options);
  if (!adjusted.ok()) {
    return Status::NoSolution("bundle adjustment of tags and spots: " +
                              adjusted.status().message());
  }
  // Without the points' covariances nothing downstream has an uncertainty:
  // say why here rather than let the locate blame a spot.
  if (adjusted->point_covariances.empty()) {
    return Status::NoSolution("bundle adjustment of tags and spots: point covariances " +
                              adjusted->covariance_method);
  }
  return Status::Ok();
}

bool FrontEndRun::EstimateVarianceComponents(int pass) {
  // The spots' variance factor: their chi^2 over their redundancy (2 per
  // observation - 3 per point; the cameras are held by the tags).
  // Residuals and covariances of the observations [first, last).
  auto residuals_of = [&](size_t first, size_t last, std::vector<Eigen::Vector2d>* residuals,
                          std::vector<Eigen::Matrix2d>* covariances) {
    for (size_t k = first; k < last; ++k) {
      const BundleObservation& ob = adjusted->data.observations[k];
      Eigen::Vector2d px;
      if (!adjusted->data.CameraAt(ob.camera).Project(
              adjusted->data.points[static_cast<size_t>(ob.point)].point_in_scene, &px)) {
        continue;
      }
      residuals->push_back(px - ob.pixel_px);
      covariances->push_back(ob.covariance_px2);
    }
  };
  const size_t num_tag = static_cast<size_t>(num_tag_observations);
  std::vector<Eigen::Vector2d> spot_residuals;
  std::vector<Eigen::Matrix2d> spot_covariances;
  residuals_of(num_tag, adjusted->data.observations.size(), &spot_residuals, &spot_covariances);
  const int redundancy = 2 * static_cast<int>(spot_residuals.size()) -
                         3 * static_cast<int>(spot_group.size());
  const double spot_variance_factor =
      redundancy > 0 ? Chi2WithExtraVariance(spot_residuals, spot_covariances, 0.0) / redundancy
                     : 1.0;
  // The same for the tag corners: 2 per observation - 3 per corner - 6 per
  // camera + 7 (the datum).
  std::vector<Eigen::Vector2d> tag_residuals;
  std::vector<Eigen::Matrix2d> tag_covariances;
  residuals_of(0, num_tag, &tag_residuals, &tag_covariances);
  const int tag_redundancy = 2 * static_cast<int>(tag_residuals.size()) -
                             3 * first_spot_point - 6 * static_cast<int>(bundle.cameras.size()) + 7;
  const double tag_variance_factor =
      tag_redundancy > 0
          ? Chi2WithExtraVariance(tag_residuals, tag_covariances, 0.0) / tag_redundancy
          : 1.0;
  if (pass == 0) {
    result.spot_variance_factor = spot_variance_factor;
    result.tag_variance_factor = tag_variance_factor;
  }
  last_spot_variance_factor = spot_variance_factor;
  const bool spots_off = spot_variance_factor > options.max_spot_variance_factor;
  const bool tags_off = tag_variance_factor > options.max_spot_variance_factor;
  if (pass > 0 || !options.rescale_spot_covariances || !(spots_off || tags_off)) return false;
  if (spots_off) {
    spot_extra_var_px2 = ExtraVarianceForUnitFactor(spot_residuals, spot_covariances, redundancy);
    result.spot_extra_sigma_px = std::sqrt(spot_extra_var_px2);
  }
  if (tags_off) {
    tag_extra_var_px2 = ExtraVarianceForUnitFactor(tag_residuals, tag_covariances, tag_redundancy);
    result.tag_extra_sigma_px = std::sqrt(tag_extra_var_px2);
  }
  return true;
}

// 5-6 run twice when the residuals show that the detector's covariances
// are too small (speckle): the second pass matches and adjusts with the
// variance components added.
Status FrontEndRun::MatchAndAdjust() {
  for (int pass = 0; pass < 2; ++pass) {
    OPL_RETURN_IF_ERROR(MatchGroups());
    OPL_RETURN_IF_ERROR(AdjustAll());
    if (!EstimateVarianceComponents(pass)) break;
  }
  // What the last pass still shows (the rematch adds back detections with
  // larger errors, which the first pass had rejected) scales the spots' 3D
  // covariances a posteriori, so that u(s) follows the observed scatter.
  spot_point_scale =
      options.rescale_spot_covariances ? std::max(1.0, last_spot_variance_factor) : 1.0;
  result.spot_point_covariance_scale = spot_point_scale;
  Progress("adjust all", 1, 1);
  result.rms_reprojection_px = adjusted->rms_reprojection_px;
  result.variance_factor = adjusted->variance_factor;
  result.bundle_report = adjusted->Report();
  return Status::Ok();
}

void FrontEndRun::PerImageRms() {
  // Per-image RMS of tags and spots.
  {
    std::vector<double> tag_sum(static_cast<size_t>(num_images), 0.0);
    std::vector<double> spot_sum(static_cast<size_t>(num_images), 0.0);
    std::vector<int> tag_n(static_cast<size_t>(num_images), 0);
    std::vector<int> spot_n(static_cast<size_t>(num_images), 0);
    std::vector<double> tag_model(static_cast<size_t>(num_images), 0.0);
    std::vector<double> spot_model(static_cast<size_t>(num_images), 0.0);
    for (size_t k = 0; k < adjusted->data.observations.size(); ++k) {
      const BundleObservation& ob = adjusted->data.observations[k];
      Eigen::Vector2d px;
      if (!adjusted->data.CameraAt(ob.camera).Project(
              adjusted->data.points[static_cast<size_t>(ob.point)].point_in_scene, &px)) {
        continue;
      }
      const int num_tag = num_tag_observations;
      const size_t image = static_cast<size_t>(
          static_cast<int>(k) < num_tag ? tag_refs[k].image
                                        : spot_refs[k - static_cast<size_t>(num_tag)].image);
      const double e2 = (px - ob.pixel_px).squaredNorm();
      const double model2 = ob.covariance_px2.trace();
      if (static_cast<int>(k) < num_tag_observations) {
        tag_sum[image] += e2;
        tag_model[image] += model2;
        ++tag_n[image];
      } else {
        spot_sum[image] += e2;
        spot_model[image] += model2;
        ++spot_n[image];
      }
    }
    auto rms = [](double sum, int n) { return n ? std::sqrt(sum / (2.0 * n)) : 0.0; };
    for (size_t i = 0; i < static_cast<size_t>(num_images); ++i) {
      ImageFindings& f = result.images[i];
      f.tag_rms_px = rms(tag_sum[i], tag_n[i]);
      f.spot_rms_px = rms(spot_sum[i], spot_n[i]);
      f.tag_model_rms_px = rms(tag_model[i], tag_n[i]);
      // The spots' pixel covariances as the final adjustment used them,
      // times the a posteriori factor that also scales their 3D covariances.
      f.spot_model_rms_px = rms(spot_model[i], spot_n[i]) * std::sqrt(spot_point_scale);
    }
  }
}

void FrontEndRun::WarnOutOfRange() {
  auto median_of = [&](double ImageFindings::*member) {
    std::vector<double> v;
    for (const ImageFindings& f : result.images) {
      if (f.placed && f.*member > 0.0) v.push_back(f.*member);
    }
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double median_spot_rms = median_of(&ImageFindings::spot_rms_px);
  const double median_tag_rms = median_of(&ImageFindings::tag_rms_px);
  if (result.tag_variance_factor > options.warn_rms_ratio * options.warn_rms_ratio) {
    result.warnings.push_back(
        "tag corners scatter " + FormatNumber(std::sqrt(result.tag_variance_factor), 2) +
        " times (RMS) what their covariances say: wrong intrinsics, a camera that moved, or "
        "tags not flat?");
  }
  std::vector<std::string> jpegs;
  for (const ImageFindings& f : result.images) {
    if (f.lossy_jpeg) jpegs.push_back(f.file);
    const std::string at = f.file + ": ";
    // An image's RMS above warn_rms_ratio times its model's, or above its
    // model's and warn_rms_ratio times the median image's (the variance
    // components are common to all images, so one bad camera mostly shows
    // against the others).
    auto check_rms = [&](const char* what, double rms, double model, double median,
                         const char* hint) {
      if (!f.placed || !(rms > 0.0)) return;
      const bool above_model = model > 0.0 && rms > options.warn_rms_ratio * model;
      const bool above_others =
          median > 0.0 && rms > options.warn_rms_ratio * median && rms > model;
      if (!above_model && !above_others) return;
      result.warnings.push_back(
          at + what + " RMS " + FormatNumber(rms, 3) + " px: " +
          (above_model ? FormatNumber(rms / model, 2) + " times its model's " +
                             FormatNumber(model, 3) + " px"
                       : FormatNumber(rms / median, 2) + " times the median image's " +
                             FormatNumber(median, 3) + " px") +
          " (" + hint + ")");
    };
    check_rms("spot", f.spot_rms_px, f.spot_model_rms_px, median_spot_rms,
              "wrong matches, wrong intrinsics or a camera that moved?");
    check_rms("tag", f.tag_rms_px, f.tag_model_rms_px, median_tag_rms,
              "wrong intrinsics, a camera that moved, or tags not flat?");
    if (f.placed && f.spots_detected >= 10 &&
        f.spots_detected - f.spots_matched >
            options.warn_unmatched_fraction * f.spots_detected) {
      result.warnings.push_back(at + std::to_string(f.spots_detected - f.spots_matched) +
                                " of its " + std::to_string(f.spots_detected) +
                                " spots are not matched in other views");
    }
    if (f.spots_detected >= 10 &&
        f.spots_saturated > options.warn_saturated_fraction * f.spots_detected) {
      result.warnings.push_back(at + std::to_string(f.spots_saturated) + " of its " +
                                std::to_string(f.spots_detected) +
                                " spots are saturated (shorten the exposure)");
    }
    if (f.blobs_rejected >= 50 &&
        f.blobs_rejected > options.warn_blob_ratio * std::max(1, f.spots_detected)) {
      result.warnings.push_back(at + std::to_string(f.blobs_rejected) +
                                " blobs that are not laser spots (too faint or no centre) for " +
                                std::to_string(f.spots_detected) +
                                " spots: clutter, noise or compression");
    }
  }
  if (!jpegs.empty()) {
    std::string list;
    for (size_t k = 0; k < jpegs.size() && k < 3; ++k) list += (k ? ", " : "") + jpegs[k];
    if (jpegs.size() > 3) list += ", ...";
    result.warnings.push_back(std::to_string(jpegs.size()) + " lossy JPEG image(s) (" + list +
                              "): compression moves spot and tag centres; prefer PNG or TIFF");
  }
}

Status FrontEndRun::RefuseBrokenGeometry() const {
  const double ratio = std::sqrt(result.tag_variance_factor);
  if (options.force || !(ratio > options.max_tag_rms_ratio)) return Status::Ok();
  std::vector<std::pair<double, std::string>> worst;
  for (const ImageFindings& f : result.images) {
    if (f.placed) worst.emplace_back(f.tag_rms_px, f.file);
  }
  std::sort(worst.rbegin(), worst.rend());
  std::string names;
  for (size_t k = 0; k < worst.size() && k < 3; ++k) {
    names += (k ? ", " : "") + worst[k].second + " " + FormatNumber(worst[k].first, 3) + " px";
  }
  return Status::NoSolution(
      "tag corners scatter " + FormatNumber(ratio, 2) +
      " times (RMS) what their covariances say (largest tag RMS: " + names +
      "): wrong intrinsics, a camera that moved, or tags not flat? (FrontEndOptions::force, --force: measure anyway)");
}

Status FrontEndRun::MoveToSceneFrame() {
  // 7. The frame of the tag centres.
  auto center_of = [&](int id, Eigen::Matrix3d* covariance) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (int k = 0; k < 4; ++k) {
      const size_t p = static_cast<size_t>(first_corner_point.at(id) + k);
      c += adjusted->data.points[p].point_in_scene / 4.0;
      if (!adjusted->point_covariances.empty()) cov += adjusted->point_covariances[p] / 16.0;
    }
    // Corners are correlated; summing their covariances / 16 ignores the
    // cross terms (a lower bound, good enough for reporting).
    if (covariance) *covariance = cov;
    return c;
  };
  Result<Rigid3d> frame = SceneFromThreePoints(center_of(frame_tags[0], nullptr),
                                               center_of(frame_tags[1], nullptr),
                                               center_of(frame_tags[2], nullptr));
  if (!frame.ok()) return Status::NoSolution("scene frame: " + frame.status().message());
  const Eigen::Matrix3d r = frame->RotationMatrix();
  for (const auto& [id, first] : first_corner_point) {
    Eigen::Matrix3d cov;
    const Eigen::Vector3d c = center_of(id, &cov);
    result.tag_centers[id] = *frame * c;
    result.tag_center_covariances[id] = r * cov * r.transpose();
  }
  for (size_t s = 0; s < spot_group.size(); ++s) {
    const size_t p = static_cast<size_t>(first_spot_point) + s;
    FrontEndSpot spot;
    spot.point_in_scene = *frame * adjusted->data.points[p].point_in_scene;
    if (!adjusted->point_covariances.empty()) {
      spot.covariance = spot_point_scale * (r * adjusted->point_covariances[p] * r.transpose());
      spot.own_covariance =
          spot_point_scale * (r * adjusted->point_own_covariances[p] * r.transpose());
      spot.shared_factor = std::sqrt(spot_point_scale) * (r * adjusted->point_shared_factors[p]);
    }
    spot.group = spot_group[s];
    result.spots.push_back(spot);
  }
  for (size_t k = 0; k < spot_refs.size(); ++k) {
    const BundleObservation& ob = adjusted->data.observations[static_cast<size_t>(num_tag_observations) + k];
    const size_t s = static_cast<size_t>(ob.point - first_spot_point);
    result.spots[s].views.emplace_back(spot_refs[k].image, spot_refs[k].spot);
  }
  result.cameras.resize(static_cast<size_t>(num_images));
  for (int i = 0; i < num_images; ++i) {
    const int camera = camera_of_image[static_cast<size_t>(i)];
    if (camera < 0) continue;
    Camera c = adjusted->data.CameraAt(camera);
    c.cam_from_scene = CamFromNewScene(c.cam_from_scene, *frame, 1.0);
    result.cameras[static_cast<size_t>(i)] = c;
  }
  return Status::Ok();
}

}  // namespace

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
  FrontEndRun run(scene, images_dir, options);
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
