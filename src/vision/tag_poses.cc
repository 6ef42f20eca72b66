#include "opl/vision/tag_poses.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <utility>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "opl/core/format.h"
#include "opl/vision/triangulation.h"

namespace opl {
namespace {

struct Candidate {
  Rigid3d cam_from_tag;
  double rms_px = 0.0;
};

struct Sighting {
  int image = 0;
  int tag = 0;
  const TagDetection* detection = nullptr;
  std::vector<Candidate> candidates;  // IPPE solutions, best first
};

cv::Mat CameraMatrixOf(const CameraIntrinsics& k) {
  return (cv::Mat_<double>(3, 3) << k.fx_px, 0.0, k.cx_px, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 1.0);
}

cv::Mat DistortionOf(const CameraIntrinsics& k) {
  return (cv::Mat_<double>(1, 5) << k.k1, k.k2, k.p1, k.p2, k.k3);
}

Rigid3d RigidOf(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  cv::cv2eigen(r, rotation);
  return Rigid3d(rotation, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1),
                                           tvec.at<double>(2)));
}

void ToCv(const Rigid3d& pose, cv::Mat* rvec, cv::Mat* tvec) {
  cv::Mat r;
  cv::eigen2cv(Eigen::Matrix3d(pose.RotationMatrix()), r);
  cv::Rodrigues(r, *rvec);
  *tvec = (cv::Mat_<double>(3, 1) << pose.translation.x(), pose.translation.y(),
           pose.translation.z());
}

// Squared reprojection errors of the four corners of a tag at cam_from_tag;
// a corner behind the camera counts as a huge error.
std::array<double, 4> CornerErrors2(const Camera& camera_at_tag,
                                    const std::array<Eigen::Vector3d, 4>& corners,
                                    const TagDetection& detection) {
  std::array<double, 4> e{};
  for (int c = 0; c < 4; ++c) {
    Eigen::Vector2d pixel;
    e[static_cast<size_t>(c)] =
        camera_at_tag.Project(corners[static_cast<size_t>(c)], &pixel)
            ? (pixel - detection.corners_px[static_cast<size_t>(c)]).squaredNorm()
            : 1e12;
  }
  return e;
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::infinity();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

Status TagPoseOptions::Validate() const {
  if (!(std::isfinite(tag_size) && tag_size > 0.0)) {
    return Status::InvalidArgument("tag_size must be finite and > 0, got " +
                                   FormatNumber(tag_size));
  }
  if (refinement_rounds < 0) {
    return Status::InvalidArgument("refinement_rounds must be >= 0, got " +
                                   std::to_string(refinement_rounds));
  }
  if (!(std::isfinite(warn_rms_px) && warn_rms_px > 0.0)) {
    return Status::InvalidArgument("warn_rms_px must be finite and > 0, got " +
                                   FormatNumber(warn_rms_px));
  }
  return Status::Ok();
}

std::array<Eigen::Vector3d, 4> TagCornersInTag(double tag_size) {
  const double h = tag_size / 2.0;
  return {Eigen::Vector3d(-h, -h, 0.0), Eigen::Vector3d(h, -h, 0.0), Eigen::Vector3d(h, h, 0.0),
          Eigen::Vector3d(-h, h, 0.0)};
}

Result<TagPoses> PosesFromTags(const std::vector<CameraIntrinsics>& intrinsics_per_image,
                               const std::vector<std::vector<TagDetection>>& tags_per_image,
                               const TagPoseOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  const int num_images = static_cast<int>(intrinsics_per_image.size());
  if (tags_per_image.size() != intrinsics_per_image.size()) {
    return Status::InvalidArgument("PosesFromTags: " + std::to_string(num_images) +
                                   " intrinsics but " + std::to_string(tags_per_image.size()) +
                                   " tag lists");
  }
  for (int i = 0; i < num_images; ++i) {
    const Status s = intrinsics_per_image[static_cast<size_t>(i)].Validate();
    if (!s.ok()) return Status::InvalidArgument("image " + std::to_string(i) + ": " + s.message());
  }
  const std::array<Eigen::Vector3d, 4> corners = TagCornersInTag(options.tag_size);
  std::vector<cv::Point3d> object_points;
  for (const Eigen::Vector3d& c : corners) object_points.emplace_back(c.x(), c.y(), c.z());

  // 1. Candidate poses of every sighting.
  std::vector<Sighting> sightings;
  std::map<int, std::vector<int>> sightings_of_tag;
  std::vector<std::vector<int>> sightings_of_image(static_cast<size_t>(num_images));
  for (int i = 0; i < num_images; ++i) {
    const CameraIntrinsics& k = intrinsics_per_image[static_cast<size_t>(i)];
    const cv::Mat camera_matrix = CameraMatrixOf(k);
    const cv::Mat distortion = DistortionOf(k);
    std::set<int> seen;
    for (const TagDetection& d : tags_per_image[static_cast<size_t>(i)]) {
      if (!seen.insert(d.id).second) continue;  // an id twice in one image: keep the first
      std::vector<cv::Point2d> image_points;
      for (const Eigen::Vector2d& p : d.corners_px) image_points.emplace_back(p.x(), p.y());
      std::vector<cv::Mat> rvecs, tvecs;
      cv::Mat errors;
      cv::solvePnPGeneric(object_points, image_points, camera_matrix, distortion, rvecs, tvecs,
                          false, cv::SOLVEPNP_IPPE, cv::noArray(), cv::noArray(), errors);
      Sighting s{i, d.id, &d, {}};
      const Camera camera_i{"", k, Rigid3d()};
      for (size_t r = 0; r < rvecs.size(); ++r) {
        Camera at_tag = camera_i;
        at_tag.cam_from_scene = RigidOf(rvecs[r], tvecs[r]);
        const std::array<double, 4> e = CornerErrors2(at_tag, corners, d);
        const double rms = std::sqrt((e[0] + e[1] + e[2] + e[3]) / 8.0);
        if (std::isfinite(rms) && at_tag.cam_from_scene.translation.z() > 0.0) {
          s.candidates.push_back({at_tag.cam_from_scene, rms});
        }
      }
      if (s.candidates.empty()) continue;
      std::sort(s.candidates.begin(), s.candidates.end(),
                [](const Candidate& a, const Candidate& b) { return a.rms_px < b.rms_px; });
      sightings_of_tag[d.id].push_back(static_cast<int>(sightings.size()));
      sightings_of_image[static_cast<size_t>(i)].push_back(static_cast<int>(sightings.size()));
      sightings.push_back(std::move(s));
    }
  }
  // The detection pointers stay valid: tags_per_image is not modified.

  // 2. Reference tag: seen in most images (ties: the lower id).
  int reference = -1;
  size_t most = 0;
  for (const auto& [id, list] : sightings_of_tag) {
    if (list.size() > most) {
      most = list.size();
      reference = id;
    }
  }
  if (reference < 0 || most < 2) {
    return Status::NoSolution(
        "PosesFromTags: no tag is seen in two images (the images cannot be related)");
  }

  TagPoses result;
  result.cam_from_scene.assign(static_cast<size_t>(num_images), std::nullopt);
  result.image_rms_px.assign(static_cast<size_t>(num_images), 0.0);
  result.reference_tag = reference;
  result.scene_from_tag[reference] = Rigid3d();

  auto camera_of = [&](int image, const Rigid3d& cam_from_scene) {
    return Camera{"", intrinsics_per_image[static_cast<size_t>(image)], cam_from_scene};
  };
  // Squared corner errors of every placed tag seen by `image` at a pose.
  auto image_errors = [&](int image, const Rigid3d& cam_from_scene) {
    std::vector<double> e2;
    for (int si : sightings_of_image[static_cast<size_t>(image)]) {
      const Sighting& s = sightings[static_cast<size_t>(si)];
      const auto placed = result.scene_from_tag.find(s.tag);
      if (placed == result.scene_from_tag.end()) continue;
      const Camera at_tag = camera_of(image, cam_from_scene * placed->second);
      for (double e : CornerErrors2(at_tag, corners, *s.detection)) e2.push_back(e);
    }
    return e2;
  };
  // Mean squared corner error of `tag` at a pose over the placed images.
  auto tag_error = [&](int tag, const Rigid3d& scene_from_tag) {
    double sum = 0.0;
    int n = 0;
    for (int si : sightings_of_tag[tag]) {
      const Sighting& s = sightings[static_cast<size_t>(si)];
      const auto& pose = result.cam_from_scene[static_cast<size_t>(s.image)];
      if (!pose) continue;
      const Camera at_tag = camera_of(s.image, *pose * scene_from_tag);
      for (double e : CornerErrors2(at_tag, corners, *s.detection)) sum += e;
      n += 4;
    }
    return n > 0 ? sum / n : std::numeric_limits<double>::infinity();
  };

  // Levenberg-Marquardt on every placed tag's corners seen by `image`, from
  // `start`; keeps `start` when that does not lower the error.
  auto refine_image = [&](int i, Rigid3d best) {
    std::vector<cv::Point3d> points;
    std::vector<cv::Point2d> pixels;
    for (int si : sightings_of_image[static_cast<size_t>(i)]) {
      const Sighting& s = sightings[static_cast<size_t>(si)];
      const auto placed = result.scene_from_tag.find(s.tag);
      if (placed == result.scene_from_tag.end()) continue;
      for (size_t c = 0; c < 4; ++c) {
        const Eigen::Vector3d x = placed->second * corners[c];
        points.emplace_back(x.x(), x.y(), x.z());
        pixels.emplace_back(s.detection->corners_px[c].x(), s.detection->corners_px[c].y());
      }
    }
    const CameraIntrinsics& k = intrinsics_per_image[static_cast<size_t>(i)];
    cv::Mat rvec, tvec;
    ToCv(best, &rvec, &tvec);
    if (cv::solvePnP(points, pixels, CameraMatrixOf(k), DistortionOf(k), rvec, tvec, true,
                     cv::SOLVEPNP_ITERATIVE)) {
      const Rigid3d refined = RigidOf(rvec, tvec);
      const std::vector<double> e_best = image_errors(i, best);
      const std::vector<double> e_refined = image_errors(i, refined);
      double s_best = 0.0, s_refined = 0.0;
      for (double e : e_best) s_best += e;
      for (double e : e_refined) s_refined += e;
      if (s_refined <= s_best) best = refined;
    }
    return best;
  };
  // With two or more placed views: the corners triangulated and the nominal
  // square fitted to them (usually much better than one view's planar pose,
  // whose depth is poorly determined); nullopt otherwise.
  auto triangulated_tag = [&](int id) -> std::optional<Rigid3d> {
    std::vector<Camera> views;
    std::vector<const TagDetection*> view_detections;
    for (int si : sightings_of_tag[id]) {
      const Sighting& s = sightings[static_cast<size_t>(si)];
      const auto& pose = result.cam_from_scene[static_cast<size_t>(s.image)];
      if (!pose) continue;
      views.push_back(camera_of(s.image, *pose));
      view_detections.push_back(s.detection);
    }
    if (views.size() < 2) return std::nullopt;
    Eigen::Matrix<double, 3, 4> in_tag, in_scene;
    for (size_t c = 0; c < 4; ++c) {
      std::vector<PointObservation> observations;
      for (size_t v = 0; v < views.size(); ++v) {
        observations.push_back(
            {&views[v], view_detections[v]->corners_px[c], Eigen::Matrix2d::Identity()});
      }
      const Result<TriangulatedPoint> x = TriangulatePoint(observations);
      if (!x.ok()) return std::nullopt;
      in_tag.col(static_cast<Eigen::Index>(c)) = corners[c];
      in_scene.col(static_cast<Eigen::Index>(c)) = x->point_in_scene;
    }
    const Eigen::Matrix4d fit = Eigen::umeyama(in_tag, in_scene, false);
    return Rigid3d(Eigen::Matrix3d(fit.topLeftCorner<3, 3>()),
                   Eigen::Vector3d(fit.topRightCorner<3, 1>()));
  };

  // 3. Alternate: place images, then tags, best connected first.
  for (bool changed = true; changed;) {
    changed = false;
    // Images.
    std::vector<std::pair<int, int>> image_order;  // (-placed tags seen, image)
    for (int i = 0; i < num_images; ++i) {
      if (result.cam_from_scene[static_cast<size_t>(i)]) continue;
      int n = 0;
      for (int si : sightings_of_image[static_cast<size_t>(i)]) {
        n += result.scene_from_tag.count(sightings[static_cast<size_t>(si)].tag) ? 1 : 0;
      }
      if (n > 0) image_order.emplace_back(-n, i);
    }
    std::sort(image_order.begin(), image_order.end());
    for (const auto& [neg_n, i] : image_order) {
      double best_score = std::numeric_limits<double>::infinity();
      Rigid3d best;
      for (int si : sightings_of_image[static_cast<size_t>(i)]) {
        const Sighting& s = sightings[static_cast<size_t>(si)];
        const auto placed = result.scene_from_tag.find(s.tag);
        if (placed == result.scene_from_tag.end()) continue;
        for (const Candidate& c : s.candidates) {
          const Rigid3d cam_from_scene = c.cam_from_tag * placed->second.Inverse();
          const double score = Median(image_errors(i, cam_from_scene));
          if (score < best_score) {
            best_score = score;
            best = cam_from_scene;
          }
        }
      }
      result.cam_from_scene[static_cast<size_t>(i)] = refine_image(i, best);
      changed = true;
    }
    // Tags.
    std::vector<std::pair<int, int>> tag_order;  // (-placed images seeing it, tag)
    for (const auto& [id, list] : sightings_of_tag) {
      if (result.scene_from_tag.count(id)) continue;
      int n = 0;
      for (int si : list) {
        n += result.cam_from_scene[static_cast<size_t>(sightings[static_cast<size_t>(si)].image)]
                 ? 1
                 : 0;
      }
      if (n > 0) tag_order.emplace_back(-n, id);
    }
    std::sort(tag_order.begin(), tag_order.end());
    for (const auto& [neg_n, id] : tag_order) {
      double best_score = std::numeric_limits<double>::infinity();
      Rigid3d best;
      for (int si : sightings_of_tag[id]) {
        const Sighting& s = sightings[static_cast<size_t>(si)];
        const auto& pose = result.cam_from_scene[static_cast<size_t>(s.image)];
        if (!pose) continue;
        for (const Candidate& c : s.candidates) {
          const Rigid3d scene_from_tag = pose->Inverse() * c.cam_from_tag;
          const double score = tag_error(id, scene_from_tag);
          if (score < best_score) {
            best_score = score;
            best = scene_from_tag;
          }
        }
      }
      if (const std::optional<Rigid3d> fitted = triangulated_tag(id)) {
        const double score = tag_error(id, *fitted);
        if (score < best_score) {
          best_score = score;
          best = *fitted;
        }
      }
      result.scene_from_tag[id] = best;
      changed = true;
    }
  }

  // Then a few rounds of alternating refinement (a poor man's bundle
  // adjustment: every image on all its tags, every tag but the reference from
  // all its images), which spreads the information of all views.
  for (int round = 0; round < options.refinement_rounds; ++round) {
    for (int i = 0; i < num_images; ++i) {
      auto& pose = result.cam_from_scene[static_cast<size_t>(i)];
      if (pose) pose = refine_image(i, *pose);
    }
    for (auto& [id, pose] : result.scene_from_tag) {
      if (id == reference) continue;
      if (const std::optional<Rigid3d> fitted = triangulated_tag(id)) {
        if (tag_error(id, *fitted) < tag_error(id, pose)) pose = *fitted;
      }
    }
  }

  // 4. Report.
  int placed_images = 0;
  for (int i = 0; i < num_images; ++i) {
    const auto& pose = result.cam_from_scene[static_cast<size_t>(i)];
    if (!pose) {
      result.warnings.push_back("image " + std::to_string(i) +
                                ": not placed (it sees no tag connected to the others)");
      continue;
    }
    ++placed_images;
    const std::vector<double> e2 = image_errors(i, *pose);
    double sum = 0.0;
    for (double e : e2) sum += e;
    result.image_rms_px[static_cast<size_t>(i)] =
        e2.empty() ? 0.0 : std::sqrt(sum / (2.0 * static_cast<double>(e2.size())));
    if (result.image_rms_px[static_cast<size_t>(i)] > options.warn_rms_px) {
      result.warnings.push_back("image " + std::to_string(i) + ": RMS corner error " +
                                FormatNumber(result.image_rms_px[static_cast<size_t>(i)], 3) +
                                " px at its start pose");
    }
  }
  for (const auto& [id, list] : sightings_of_tag) {
    const auto placed = result.scene_from_tag.find(id);
    if (placed == result.scene_from_tag.end()) {
      result.warnings.push_back("tag " + std::to_string(id) + ": not placed");
      continue;
    }
    const double rms = std::sqrt(tag_error(id, placed->second) / 2.0);
    if (rms > options.warn_rms_px) {
      result.warnings.push_back("tag " + std::to_string(id) + ": RMS corner error " +
                                FormatNumber(rms, 3) + " px at its start pose");
    }
  }
  if (placed_images < 2) {
    return Status::NoSolution("PosesFromTags: fewer than two images could be placed");
  }
  return result;
}

}  // namespace opl
