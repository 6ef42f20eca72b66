// The COLMAP path of the image front end (pipeline/colmap_measure.h): the
// model's cameras and poses instead of the tags' (steps 3-4), its 3D points
// as tie points, and the model's frame instead of the frame tags' (step 7).
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <string>

#include <Eigen/Geometry>

#include "opl/core/format.h"
#include "opl/pipeline/colmap_measure.h"
#include "opl/vision/scene_frame.h"
#include "pipeline/front_end_run.h"

namespace opl {
namespace front_end_internal {

Status FrontEndRun::UseColmapCameras(const ColmapModel& model) {
  colmap_image_of_shot.assign(static_cast<size_t>(num_images), nullptr);
  for (int i = 0; i < num_images; ++i) {
    const SceneShot& shot = scene.shots[static_cast<size_t>(i)];
    const ColmapImage* image = model.FindImageByName(shot.file);
    if (image == nullptr) continue;
    Result<CameraIntrinsics> in = IntrinsicsFromColmap(model.cameras.at(image->camera_id));
    if (!in.ok()) {
      return Status(in.status().code(), shot.file + ": " + in.status().message());
    }
    intrinsics[static_cast<size_t>(i)] = *in;
    colmap_image_of_shot[static_cast<size_t>(i)] = image;
  }
  return Status::Ok();
}

Status FrontEndRun::PlaceCamerasFromColmap(const ColmapModel& model, double tie_sigma_px,
                                           int max_tie_points) {
  // One intrinsics entry per COLMAP camera, one pose per shot in the model.
  camera_of_image.assign(static_cast<size_t>(num_images), -1);
  std::map<uint32_t, int> intrinsics_of_camera;
  std::map<uint32_t, int> bundle_camera_of_image_id;
  std::map<uint32_t, int> shot_of_image_id;
  for (int i = 0; i < num_images; ++i) {
    const ColmapImage* image = colmap_image_of_shot[static_cast<size_t>(i)];
    if (image == nullptr) {
      result.images[static_cast<size_t>(i)].notes.push_back(
          "not placed: not in the COLMAP model (no image of that NAME)");
      continue;
    }
    if (bundle_camera_of_image_id.count(image->image_id) != 0) {
      return Status::InvalidArgument("shot " + scene.shots[static_cast<size_t>(i)].file +
                                     ": the same COLMAP image as another shot");
    }
    auto found = intrinsics_of_camera.find(image->camera_id);
    if (found == intrinsics_of_camera.end()) {
      found = intrinsics_of_camera.emplace(image->camera_id,
                                           static_cast<int>(bundle.intrinsics.size())).first;
      BundleIntrinsics bi;
      bi.name = "COLMAP camera " + std::to_string(image->camera_id);
      bi.intrinsics = intrinsics[static_cast<size_t>(i)];
      bi.constant = true;
      bundle.intrinsics.push_back(bi);
    }
    BundleCamera camera;
    camera.name = scene.shots[static_cast<size_t>(i)].file;
    camera.intrinsics_index = found->second;
    camera.cam_from_scene = image->CamFromWorld();
    camera_of_image[static_cast<size_t>(i)] = static_cast<int>(bundle.cameras.size());
    bundle_camera_of_image_id[image->image_id] = static_cast<int>(bundle.cameras.size());
    shot_of_image_id[image->image_id] = i;
    bundle.cameras.push_back(camera);
    result.images[static_cast<size_t>(i)].placed = true;
  }
  if (bundle.cameras.size() < 3) {
    return Status::NoSolution("COLMAP model: " + std::to_string(bundle.cameras.size()) +
                              " of the scene's shots are in the model (by file name); at least "
                              "three are needed");
  }

  // Tie points: the model's points seen by two or more of these images,
  // the longest tracks first.
  struct Candidate {
    const ColmapPoint3D* point;
    int views;
  };
  std::vector<Candidate> candidates;
  for (const auto& entry : model.points3D) {
    std::set<int> cameras;
    for (const ColmapTrackElement& e : entry.second.track) {
      const auto c = bundle_camera_of_image_id.find(e.image_id);
      if (c != bundle_camera_of_image_id.end()) cameras.insert(c->second);
    }
    if (cameras.size() >= 2) {
      candidates.push_back({&entry.second, static_cast<int>(cameras.size())});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.views > b.views; });
  if (candidates.size() > static_cast<size_t>(max_tie_points)) {
    candidates.resize(static_cast<size_t>(max_tie_points));
  }
  if (candidates.size() < 3) {
    return Status::NoSolution("COLMAP model: " + std::to_string(candidates.size()) +
                              " points are seen in two or more of the scene's images; at least "
                              "three tie points are needed");
  }
  double sigma = tie_sigma_px;
  if (sigma == 0.0) {
    double sum = 0.0;
    int n = 0;
    for (const Candidate& c : candidates) {
      if (c.point->error_px >= 0.0) {
        sum += c.point->error_px;
        ++n;
      }
    }
    sigma = std::max(0.05, n > 0 ? sum / n / std::sqrt(kPi / 2.0) : 0.5);
  }
  const Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity() * sigma * sigma;
  int dropped_behind = 0;
  int dropped_narrow = 0;
  for (const Candidate& c : candidates) {
    // Observations in front of their camera (else the adjustment refuses).
    std::vector<BundleObservation> observations;
    std::vector<int> images;
    std::set<int> cameras;
    for (const ColmapTrackElement& e : c.point->track) {
      const auto camera = bundle_camera_of_image_id.find(e.image_id);
      if (camera == bundle_camera_of_image_id.end()) continue;
      if ((bundle.cameras[static_cast<size_t>(camera->second)].cam_from_scene *
           c.point->xyz_in_world).z() <= 0.0) {
        ++dropped_behind;
        continue;
      }
      BundleObservation o;
      o.camera = camera->second;
      o.point = static_cast<int>(bundle.points.size());
      o.pixel_px = OplPixelFromColmap(
          model.images.at(e.image_id).points2D[e.point2D_idx].xy_px);
      o.covariance_px2 = covariance;
      observations.push_back(o);
      images.push_back(shot_of_image_id.at(e.image_id));
      cameras.insert(camera->second);
    }
    if (cameras.size() < 2) continue;
    // Two images from one camera position (a camera that shot both grids
    // from where it stood) do not fix the point's depth. The scene says
    // which shots share a camera, and so a position: COLMAP poses each image
    // on its own, and two images of one camera can come out a little apart
    // in the model, enough for a near point's rays to meet at a degree or
    // more there while the adjustment brings the two images together and
    // leaves the depth free (a 3x3 block with a condition number of 6e13,
    // an indefinite reduced camera matrix). So the rays must meet at
    // min_tag_triangulation_angle_deg or more between images of two
    // different scene cameras, as for the tags.
    double max_angle_deg = 0.0;
    for (size_t a = 0; a < observations.size(); ++a) {
      for (size_t b = a + 1; b < observations.size(); ++b) {
        if (scene.shots[static_cast<size_t>(images[a])].camera ==
            scene.shots[static_cast<size_t>(images[b])].camera) {
          continue;
        }
        const Eigen::Vector3d ri =
            c.point->xyz_in_world -
            bundle.cameras[static_cast<size_t>(observations[a].camera)].cam_from_scene.Inverse().translation;
        const Eigen::Vector3d rj =
            c.point->xyz_in_world -
            bundle.cameras[static_cast<size_t>(observations[b].camera)].cam_from_scene.Inverse().translation;
        const double angle =
            std::atan2(ri.cross(rj).norm(), ri.dot(rj)) * 180.0 / kPi;
        max_angle_deg = std::max(max_angle_deg, angle);
      }
    }
    if (max_angle_deg < options.min_tag_triangulation_angle_deg) {
      ++dropped_narrow;
      continue;
    }
    BundlePoint p;
    p.point_in_scene = c.point->xyz_in_world;
    bundle.points.push_back(p);
    for (size_t k = 0; k < observations.size(); ++k) {
      bundle.observations.push_back(observations[k]);
      tag_refs.push_back({images[k], -1, -1});
    }
  }
  num_tag_observations = static_cast<int>(bundle.observations.size());
  const int num_tie_points = static_cast<int>(bundle.points.size());
  if (num_tie_points < 3) {
    return Status::NoSolution("COLMAP model: " + std::to_string(num_tie_points) +
                              " tie points seen from two camera positions; at least three are "
                              "needed");
  }

  // The datum: A the tie point farthest from their centroid, B the farthest
  // from A, C the one farthest from the line AB.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const BundlePoint& p : bundle.points) centroid += p.point_in_scene / num_tie_points;
  const auto farthest = [&](const std::function<double(const Eigen::Vector3d&)>& distance) {
    int best = 0;
    double best_d = -1.0;
    for (int j = 0; j < num_tie_points; ++j) {
      const double d = distance(bundle.points[static_cast<size_t>(j)].point_in_scene);
      if (d > best_d) {
        best_d = d;
        best = j;
      }
    }
    return best;
  };
  const int a = farthest([&](const Eigen::Vector3d& x) { return (x - centroid).norm(); });
  const Eigen::Vector3d xa = bundle.points[static_cast<size_t>(a)].point_in_scene;
  const int b = farthest([&](const Eigen::Vector3d& x) { return (x - xa).norm(); });
  const Eigen::Vector3d ab =
      (bundle.points[static_cast<size_t>(b)].point_in_scene - xa).normalized();
  const int c = farthest([&](const Eigen::Vector3d& x) { return (x - xa).cross(ab).norm(); });
  if (a == b || b == c || a == c) {
    return Status::NoSolution("COLMAP model: the tie points do not span a triangle");
  }
  datum_points = {a, b, c};

  bundle_options.num_threads = threads;
  bundle_options.gauge = BundleGauge::kFixedByCaller;
  tag_bundle = bundle;
  result.frame_description =
      "the COLMAP model's (" + std::to_string(bundle.cameras.size()) + " images, " +
      std::to_string(num_tie_points) + " tie points with " +
      std::to_string(num_tag_observations) + " observations at " + FormatNumber(sigma, 3) +
      " px; the RMS 'tags' of each image are its tie points')";
  if (dropped_narrow > 0) {
    result.warnings.push_back(
        "COLMAP model: " + std::to_string(dropped_narrow) +
        " points not used as tie points: seen from one camera position, or their rays meet at "
        "less than " + FormatNumber(options.min_tag_triangulation_angle_deg) + " deg");
  }
  if (dropped_behind > 0) {
    result.warnings.push_back("COLMAP model: " + std::to_string(dropped_behind) +
                              " tie point observations behind their camera dropped");
  }
  Progress("poses", 1, 1);
  return Status::Ok();
}

Status FrontEndRun::MoveToColmapFrame() {
  // The similarity model_from_datum that maps the adjusted camera centres
  // onto the model's (Umeyama, with scale).
  const int n = static_cast<int>(adjusted->data.cameras.size());
  Eigen::Matrix3Xd datum_centres(3, n), model_centres(3, n);
  int k = 0;
  for (int i = 0; i < num_images; ++i) {
    const int camera = camera_of_image[static_cast<size_t>(i)];
    if (camera < 0) continue;
    datum_centres.col(k) = adjusted->data.cameras[static_cast<size_t>(camera)]
                               .cam_from_scene.Inverse()
                               .translation;
    model_centres.col(k) = colmap_image_of_shot[static_cast<size_t>(i)]->CenterInWorld();
    ++k;
  }
  const Eigen::Matrix4d m = Eigen::umeyama(datum_centres, model_centres, true);
  const Eigen::Matrix3d sr = m.topLeftCorner<3, 3>();
  const double scale = std::cbrt(sr.determinant());
  if (!(std::isfinite(scale) && scale > 0.0)) {
    return Status::NoSolution("COLMAP model: the adjusted camera centres do not determine the "
                              "model's frame");
  }
  const Eigen::Matrix3d r = sr / scale;
  const Eigen::Vector3d t = m.topRightCorner<3, 1>();
  double sum2 = 0.0;
  for (int j = 0; j < n; ++j) {
    sum2 += (sr * datum_centres.col(j) + t - model_centres.col(j)).squaredNorm();
  }
  const double rms = std::sqrt(sum2 / n);
  result.frame_description += "; spots moved into it by the similarity of the adjusted camera "
                              "centres onto the model's (scale " +
                              FormatNumber(scale, 8) + ", RMS " + FormatNumber(rms, 3) +
                              " model units)";

  for (size_t s = 0; s < spot_group.size(); ++s) {
    const size_t p = static_cast<size_t>(first_spot_point) + s;
    FrontEndSpot spot;
    spot.point_in_scene = sr * adjusted->data.points[p].point_in_scene + t;
    const double f = scale * scale * spot_point_scale;
    spot.covariance = f * (r * adjusted->point_covariances[p] * r.transpose());
    spot.own_covariance = f * (r * adjusted->point_own_covariances[p] * r.transpose());
    spot.shared_factor = std::sqrt(f) * (r * adjusted->point_shared_factors[p]);
    spot.group = spot_group[s];
    result.spots.push_back(spot);
  }
  for (size_t j = 0; j < spot_refs.size(); ++j) {
    const BundleObservation& ob =
        adjusted->data.observations[static_cast<size_t>(num_tag_observations) + j];
    const size_t s = static_cast<size_t>(ob.point - first_spot_point);
    result.spots[s].views.emplace_back(spot_refs[j].image, spot_refs[j].spot);
  }
  // The cameras in the model's frame: point_in_model = scale (R x + t / scale).
  const Rigid3d model_from_datum_unscaled(r, t / scale);
  result.cameras.resize(static_cast<size_t>(num_images));
  for (int i = 0; i < num_images; ++i) {
    const int camera = camera_of_image[static_cast<size_t>(i)];
    if (camera < 0) continue;
    Camera c = adjusted->data.CameraAt(camera);
    c.cam_from_scene = CamFromNewScene(c.cam_from_scene, model_from_datum_unscaled, scale);
    result.cameras[static_cast<size_t>(i)] = c;
  }
  return Status::Ok();
}

}  // namespace front_end_internal

Status ColmapMeasureOptions::Validate() const {
  OPL_RETURN_IF_ERROR(image.Validate());
  if (!(std::isfinite(tie_point_sigma_px) && tie_point_sigma_px >= 0.0)) {
    return Status::InvalidArgument("tie_point_sigma_px must be finite and >= 0, got " +
                                   FormatNumber(tie_point_sigma_px));
  }
  if (max_tie_points < 3) {
    return Status::InvalidArgument("max_tie_points must be >= 3, got " +
                                   std::to_string(max_tie_points));
  }
  return Status::Ok();
}

Result<FrontEndResult> RunImageFrontEndFromColmap(const Scene& scene,
                                                  const std::string& images_dir,
                                                  const ColmapModel& model,
                                                  const ColmapMeasureOptions& options) {
  OPL_RETURN_IF_ERROR(scene.Validate());
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(model.Validate());
  const FrontEndOptions& fe = options.image.front_end;
  front_end_internal::FrontEndRun run(scene, images_dir, fe);
  run.Init();
  OPL_RETURN_IF_ERROR(run.UseColmapCameras(model));
  OPL_RETURN_IF_ERROR(run.Detect());
  OPL_RETURN_IF_ERROR(
      run.PlaceCamerasFromColmap(model, options.tie_point_sigma_px, options.max_tie_points));
  run.GroupShots();
  OPL_RETURN_IF_ERROR(run.MatchAndAdjust());
  run.PerImageRms();
  run.WarnOutOfRange();
  OPL_RETURN_IF_ERROR(run.RefuseBrokenGeometry());
  OPL_RETURN_IF_ERROR(run.MoveToColmapFrame());
  return std::move(run.result);
}

Result<ImageMeasureReport> MeasureScaleFromColmap(const Scene& scene,
                                                  const std::string& images_dir,
                                                  const ColmapModel& model,
                                                  const ModuleCalibration& calibration,
                                                  const ColmapMeasureOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (Status st = CheckSceneHasLasers(scene); !st.ok()) {
    return Status::InvalidArgument("scene: " + st.message());
  }
  Result<FrontEndResult> front_end = RunImageFrontEndFromColmap(scene, images_dir, model, options);
  if (!front_end.ok()) return front_end.status();
  return MeasureScaleFromFrontEnd(std::move(*front_end), calibration, options.image);
}

}  // namespace opl
