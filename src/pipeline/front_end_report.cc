// Image front end, step 7 and the report: per-image RMS against the model,
// the warnings of FrontEndOptions::warn_*, and the move into the scene
// frame of the three frame tags (vision/scene_frame.h).
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/vision/scene_frame.h"
#include "pipeline/front_end_run.h"

namespace opl {
namespace front_end_internal {

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
    spot_residual_sum_px2 = spot_sum;
    spot_residual_count = spot_n;
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
    if (!f.decode_warnings.empty()) {
      // The decoder's own words, each already one safe line; the whole cut.
      std::string said;
      for (const std::string& w : f.decode_warnings) said += (said.empty() ? "" : "; ") + w;
      result.warnings.push_back(SafeForMessage(f.file, 120) +
                                ": damaged image file, decoded anyway (" +
                                SafeForMessage(said, 300) +
                                "): its pixels after the damage may be wrong or grey; check the "
                                "file or shoot it again");
    }
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
  WarnCameraSpotRms();
  if (!jpegs.empty()) {
    std::string list;
    for (size_t k = 0; k < jpegs.size() && k < 3; ++k) list += (k ? ", " : "") + jpegs[k];
    if (jpegs.size() > 3) list += ", ...";
    // Figures: tests/studies/jpeg_spot_offsets_test.cc (docs/images.md, "The
    // JPEG bias").
    result.warnings.push_back(
        std::to_string(jpegs.size()) + " lossy JPEG image(s) (" + list +
        "): compression moves spot centres, at quality 90 by 0.14 px rms in the red channel "
        "with 4:2:0 chroma (most cameras' JPEG: red detail is mostly chroma, kept at half "
        "resolution), 0.08 px with 4:4:4, 0.05 px in luma; a random error, not a bias, that "
        "u(s) carries (noise-free: s off by 3e-4 rms against 6e-6 lossless); prefer PNG or TIFF");
  }
  // Laser-off frames whose exposure differed by more than 5% from their lit
  // shot's (FrontEndOptions::match_dark_frame_exposure): the match removes
  // the scene to first order, but the frames' clipping and camera curve
  // differ too.
  int rescaled = 0;
  double worst = 0.0;
  std::string worst_file;
  for (const ImageFindings& f : result.images) {
    const double off = std::abs(f.dark_frame_gain - 1.0);
    if (f.dark_frame.empty() || off <= 0.05) continue;
    ++rescaled;
    if (off > worst) {
      worst = off;
      worst_file = f.file;
    }
  }
  if (rescaled > 0) {
    result.warnings.push_back(
        std::to_string(rescaled) + " image(s) differ in exposure from their laser-off shot by " +
        "more than 5% (up to " + FormatNumber(100.0 * worst, 3) + "%, " + worst_file +
        "): the laser-off frames were rescaled to match; set the cameras to manual exposure "
        "and avoid flickering light (docs/images.md, 'Laser-off frames')");
  }
}

void FrontEndRun::WarnCameraSpotRms() {
  struct CameraRms {
    double sum_px2 = 0.0;
    int count = 0;
    int images = 0;
    int detected = 0, matched = 0;
    double rms = 0.0;
  };
  std::map<std::string, CameraRms> cameras;  // by name: a stable order
  for (size_t i = 0; i < result.images.size() && i < spot_residual_count.size(); ++i) {
    const ImageFindings& f = result.images[i];
    if (!f.placed || spot_residual_count[i] == 0) continue;
    CameraRms& c = cameras[f.camera];
    c.sum_px2 += spot_residual_sum_px2[i];
    c.count += spot_residual_count[i];
    c.detected += f.spots_detected;
    c.matched += f.spots_matched;
    ++c.images;
  }
  std::vector<std::pair<std::string, CameraRms*>> used;
  for (auto& [name, c] : cameras) {
    if (c.count < 10) continue;
    c.rms = std::sqrt(c.sum_px2 / (2.0 * c.count));
    used.emplace_back(name, &c);
  }
  if (used.size() < 3) return;
  const auto percent = [](int part, int whole) {
    return std::to_string(whole > 0 ? static_cast<int>(std::lround(100.0 * part / whole)) : 0);
  };
  for (const auto& [name, c] : used) {
    std::vector<double> others;
    int others_detected = 0, others_matched = 0;
    for (const auto& [other_name, other] : used) {
      if (other_name == name) continue;
      others.push_back(other->rms);
      others_detected += other->detected;
      others_matched += other->matched;
    }
    std::sort(others.begin(), others.end());
    const size_t n = others.size();
    const double median = n % 2 ? others[n / 2] : 0.5 * (others[n / 2 - 1] + others[n / 2]);
    if (!(c->rms > options.warn_camera_spot_rms_ratio * median &&
          c->rms > options.warn_camera_spot_rms_min_px)) {
      continue;
    }
    result.warnings.push_back(
        "camera " + name + ": spot RMS " + FormatNumber(c->rms, 3) + " px over its " +
        std::to_string(c->images) + " image(s), " +
        (median > 0.0 ? FormatNumber(c->rms / median, 2) + " times" : std::string("far above")) +
        " the median of the other cameras' " + FormatNumber(median, 3) + " px; " +
        percent(c->matched, c->detected) + "% of its spots matched, " +
        percent(others_matched, others_detected) +
        "% of theirs (out of focus, shaken, moved during the shots, or wrong intrinsics?)");
  }
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
    if (adjusted->point_own_covariances.empty() || adjusted->point_shared_factors.empty()) continue;
    Eigen::Matrix3d own = Eigen::Matrix3d::Zero();
    Eigen::MatrixXd shared;
    for (int k = 0; k < 4; ++k) {
      const size_t p = static_cast<size_t>(first + k);
      own += adjusted->point_own_covariances[p] / 16.0;
      const Eigen::MatrixXd& K = adjusted->point_shared_factors[p];
      if (k == 0) shared = Eigen::MatrixXd::Zero(3, K.cols());
      shared += K / 4.0;
    }
    result.tag_center_own_covariances[id] = r * own * r.transpose();
    result.tag_center_shared_factors[id] = r * shared;
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
  result.adjustment = adjusted->data;
  for (BundleCamera& cam : result.adjustment.cameras) {
    cam.cam_from_scene = CamFromNewScene(cam.cam_from_scene, *frame, 1.0);
  }
  for (BundlePoint& p : result.adjustment.points) p.point_in_scene = *frame * p.point_in_scene;
  result.first_spot_point = first_spot_point;
  result.tag_first_point = first_corner_point;
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

}  // namespace front_end_internal
}  // namespace opl
