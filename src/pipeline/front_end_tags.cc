// Image front end, steps 3-4: start poses of images and tags from the tags
// (vision/tag_poses.h), tags seen from one position dropped, the frame
// tags chosen, the adjustment of the tag corners, and the refusal of a
// geometry whose tag corners scatter beyond their model.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>

#include "opl/core/format.h"
#include "opl/geometry/rotation.h"
#include "pipeline/front_end_run.h"

namespace opl {
namespace front_end_internal {

namespace {

Eigen::Matrix2d CornerCovariance(const Eigen::Matrix2d& c) {
  // The edge fit's covariance when it has one, else 0.05 px per coordinate.
  if (c.allFinite() && c.determinant() > 1e-12) return c;
  return Eigen::Matrix2d::Identity() * 0.05 * 0.05;
}

}  // namespace

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
    // Drop tag observations that stay beyond max_tag_residual_px; down-weight
    // those beyond tag_outlier_factor x the median residual (at least
    // min_tag_outlier_residual_px): a corner that a highlight or a lamp
    // pulled off its edge while its edge fit still claims a few hundredths
    // of a pixel gets the variance of its residual.
    const size_t n_obs = adjusted->data.observations.size();
    std::vector<double> residual_px(n_obs, std::numeric_limits<double>::infinity());
    for (size_t k = 0; k < n_obs; ++k) {
      const BundleObservation& ob = adjusted->data.observations[k];
      const Camera cam = adjusted->data.CameraAt(ob.camera);
      Eigen::Vector2d px;
      if (cam.Project(adjusted->data.points[static_cast<size_t>(ob.point)].point_in_scene, &px)) {
        residual_px[k] = (px - ob.pixel_px).norm();
      }
    }
    const double drop_px = options.max_tag_residual_px * std::sqrt(2.0);
    double limit_px = drop_px;
    if (n_obs > 0) {
      std::vector<double> sorted = residual_px;
      std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(n_obs / 2), sorted.end());
      const double median = sorted[n_obs / 2];
      if (std::isfinite(median)) {
        limit_px = std::min(limit_px, std::max(options.min_tag_outlier_residual_px,
                                               options.tag_outlier_factor * median));
      }
    }
    std::vector<BundleObservation> kept;
    std::vector<TagObservationRef> kept_refs;
    for (size_t k = 0; k < n_obs; ++k) {
      const BundleObservation& ob = adjusted->data.observations[k];
      const std::string corner = "tag " + std::to_string(tag_refs[k].tag) + " corner " +
                                 std::to_string(tag_refs[k].corner);
      std::vector<std::string>& notes = result.images[static_cast<size_t>(tag_refs[k].image)].notes;
      if (residual_px[k] > drop_px) {
        notes.push_back(corner + " dropped (residual " + FormatNumber(residual_px[k], 3) + " px > " +
                        FormatNumber(drop_px, 3) + " px)");
        continue;
      }
      kept.push_back(ob);
      kept_refs.push_back(tag_refs[k]);
      if (residual_px[k] > limit_px) {
        // Kept (dropping it could leave a frame tag seen from one position),
        // but weighted as what it is: a corner off by its residual.
        const double v = 0.5 * residual_px[k] * residual_px[k];
        Eigen::Matrix2d& c = kept.back().covariance_px2;
        c = c + (v - std::min(v, c.trace() / 2.0)) * Eigen::Matrix2d::Identity();
        notes.push_back(corner + " down-weighted (residual " + FormatNumber(residual_px[k], 3) +
                        " px > " + FormatNumber(limit_px, 3) + " px)");
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
  if (datum_points[0] >= 0) {  // the COLMAP path: tie points instead of tag corners
    return Status::NoSolution(
        "the COLMAP model's tie points scatter " + FormatNumber(ratio, 2) +
        " times (RMS) what their covariances say (largest RMS: " + names +
        "): wrong intrinsics in the model, or images that do not fit it? "
        "(FrontEndOptions::force, --force: measure anyway)");
  }
  return Status::NoSolution(
      "tag corners scatter " + FormatNumber(ratio, 2) +
      " times (RMS) what their covariances say (largest tag RMS: " + names +
      "): wrong intrinsics, a camera that moved, or tags not flat? (FrontEndOptions::force, --force: measure anyway)");
}

}  // namespace front_end_internal
}  // namespace opl
