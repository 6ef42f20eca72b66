// Image front end, steps 5-6: the exposure groups, the spots matched across
// the images of each (vision/spot_matching.h), the joint adjustment of tags
// and spots, and the variance components that make the spots' and tag
// corners' covariances follow their observed scatter.
#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <string>

#include "opl/core/format.h"
#include "pipeline/front_end_run.h"

namespace opl {
namespace front_end_internal {

namespace {

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

void FrontEndRun::GroupShots() {
  // 5. Groups and matching.
  {
    std::map<std::tuple<std::vector<std::string>, int, std::string>, int> group_of_key;
    for (int i = 0; i < num_images; ++i) {
      const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
      if (shot.lasers.empty()) continue;  // a laser-off shot: tags and dark frame only
      std::vector<std::string> lasers = shot.lasers;
      std::sort(lasers.begin(), lasers.end());
      const auto key = std::make_tuple(lasers, shot.slice, shot.placement);
      auto found = group_of_key.find(key);
      if (found == group_of_key.end()) {
        found = group_of_key.emplace(key, static_cast<int>(result.groups.size())).first;
        result.groups.push_back({lasers, shot.slice, {}, shot.placement});
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
  final_options.datum_points = datum_points[0] >= 0
                                   ? datum_points
                                   : std::array<int, 3>{first_corner_point.at(frame_tags[0]),
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

}  // namespace front_end_internal
}  // namespace opl
