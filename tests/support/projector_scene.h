// Test helpers for the projector adjustment: a virtual-lab scene (its cameras,
// tags and module, lab/render_scene.h's 3D truth) turned into observations
// without rendering: every tag corner and spot projected by the true cameras,
// with optional Gaussian pixel noise of known sigma, so that the truth is
// exact. One pose per camera: each camera sees every grid from where it
// stands. Also the same observations through the two-step path (bundle
// adjustment in an unscaled frame, then MeasureScaleFromFrontEnd), for
// comparison on the same seeds.
#pragma once

#include <array>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "opl/lab/render_scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "opl/vision/projector_adjustment.h"

namespace opl::test {

struct ProjectorLabCase {
  ProjectorAdjustmentData truth;  // true poses, points, depths (mm); noisy observations
  ProjectorAdjustmentData start;  // the same observations, a perturbed start
  // Per tag point: (tag id, corner); per spot its true 3D point (mm).
  std::vector<std::pair<int, int>> point_tag;
  std::vector<Eigen::Vector3d> spot_truth_mm;
  std::array<int, 3> frame_tags = {0, 1, 2};
  // The datum point sets of the frame tags' four corners.
  std::array<std::vector<int>, 3> datum_sets;
};

// `module_moves`: further placements of the module, each the scene's module
// moved by new_from_old (its surface too: the spots land where the moved
// module would put them on the moved surface; the tags stay).
inline ProjectorLabCase MakeProjectorLabCase(const Scene& scene, const ModuleCalibration& calibration,
                                             double tag_sigma_px, double spot_sigma_px,
                                             uint64_t seed,
                                             const std::vector<Rigid3d>& module_moves = {}) {
  ProjectorLabCase c;
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  EXPECT_TRUE(renderer.ok()) << renderer.status().ToString();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  ProjectorAdjustmentData& d = c.truth;
  d.calibration = calibration;
  for (const SceneCamera& cam : scene.cameras) {
    d.bundle.intrinsics.push_back({cam.name, cam.intrinsics, true});
    BundleCamera b;
    b.name = cam.name;
    b.intrinsics_index = static_cast<int>(d.bundle.intrinsics.size()) - 1;
    b.cam_from_scene = *cam.cam_from_scene;
    d.bundle.cameras.push_back(b);
  }
  auto observe = [&](size_t i, const Eigen::Vector3d& x, double sigma, Eigen::Vector2d* px) {
    Camera camera = d.bundle.CameraAt(static_cast<int>(i));
    if (!camera.Project(x, px) || !camera.InImage(*px, 2.0)) return false;
    *px += sigma * Eigen::Vector2d(normal(rng), normal(rng));
    return true;
  };
  if (scene.frame) {
    c.frame_tags = {scene.frame->origin_tag, scene.frame->axis_tag, scene.frame->plane_tag};
  }
  for (size_t k = 0; k < renderer->tags().size(); ++k) {
    const SceneTagTruth& tag = renderer->tags()[k];
    const Eigen::Vector3d z_axis = scene.tags.tags[k].scene_from_tag.rotation * Eigen::Vector3d::UnitZ();
    std::vector<BundleObservation> obs;
    int seen = 0;
    for (size_t i = 0; i < d.bundle.cameras.size(); ++i) {
      const Eigen::Vector3d centre = d.bundle.CameraAt(static_cast<int>(i)).CenterInScene();
      if (!(z_axis.dot(centre - tag.center_in_scene) < 0.0)) continue;
      std::array<Eigen::Vector2d, 4> px;
      bool all = true;
      for (int q = 0; q < 4; ++q) all = all && observe(i, tag.corners_in_scene[static_cast<size_t>(q)], tag_sigma_px, &px[static_cast<size_t>(q)]);
      if (!all) continue;
      ++seen;
      for (int q = 0; q < 4; ++q) {
        BundleObservation o;
        o.camera = static_cast<int>(i);
        o.point = static_cast<int>(d.bundle.points.size()) + q;
        o.pixel_px = px[static_cast<size_t>(q)];
        o.covariance_px2 = Eigen::Matrix2d::Identity() * (tag_sigma_px > 0.0 ? tag_sigma_px * tag_sigma_px : 0.01);
        obs.push_back(o);
      }
    }
    if (seen < 2) continue;
    for (int q = 0; q < 4; ++q) {
      for (size_t a = 0; a < 3; ++a) {
        if (tag.id == c.frame_tags[a]) c.datum_sets[a].push_back(static_cast<int>(d.bundle.points.size()));
      }
      BundlePoint p;
      p.point_in_scene = tag.corners_in_scene[static_cast<size_t>(q)];
      d.bundle.points.push_back(p);
      c.point_tag.emplace_back(tag.id, q);
    }
    d.bundle.observations.insert(d.bundle.observations.end(), obs.begin(), obs.end());
  }
  // The module: calibration frame = design scene frame (ExactCalibration).
  std::vector<Rigid3d> moves = {Rigid3d()};
  moves.insert(moves.end(), module_moves.begin(), module_moves.end());
  for (size_t m = 0; m < moves.size(); ++m) {
    ProjectorPlacement placement;
    placement.name = "placement " + std::to_string(m + 1);
    placement.scene_from_module =
        moves[m] * Rigid3d(Eigen::Quaterniond::Identity(), d.ModuleOriginInCalibration());
    d.placements.push_back(placement);
    Scene moved = scene;
    moved.module = scene.module->Transformed(moves[m]);
    Result<SceneRenderer> spots_of = SceneRenderer::Create(moved);
    EXPECT_TRUE(spots_of.ok()) << spots_of.status().ToString();
    for (const SceneSpotTruth& s : spots_of->spots()) {
      if (s.slice != 0) continue;
      const SourceCalibration* src = calibration.FindSource(s.source);
      const Eigen::Vector3d origin = moves[m] * src->calibration_from_source.translation;
      ProjectorSpot spot;
      spot.placement = static_cast<int>(m);
      spot.source = s.source;
      spot.beam_id = s.beam;
      spot.depth_mm = (s.point_in_scene - origin).norm();
      for (size_t i = 0; i < d.bundle.cameras.size(); ++i) {
        const Eigen::Vector3d centre = d.bundle.CameraAt(static_cast<int>(i)).CenterInScene();
        if (!(s.normal_in_scene.dot(centre - s.point_in_scene) > 0.0)) continue;
        ProjectorSpotObservation o;
        o.camera = static_cast<int>(i);
        if (!observe(i, s.point_in_scene, spot_sigma_px, &o.pixel_px)) continue;
        o.covariance_px2 = Eigen::Matrix2d::Identity() * (spot_sigma_px > 0.0 ? spot_sigma_px * spot_sigma_px : 0.01);
        spot.observations.push_back(o);
      }
      if (spot.observations.size() < 2) continue;
      d.spots.push_back(spot);
      c.spot_truth_mm.push_back(s.point_in_scene);
    }
  }
  // The start: every position off by a few mm and turned a little, the
  // module moved, the depths off.
  c.start = c.truth;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (BundleCamera& cam : c.start.bundle.cameras) {
    const Eigen::Vector3d w(0.003 * u(rng), 0.003 * u(rng), 0.003 * u(rng));
    cam.cam_from_scene = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w.normalized())) *
                                     cam.cam_from_scene.rotation,
                                 cam.cam_from_scene.translation + Eigen::Vector3d(3 * u(rng), 3 * u(rng), 3 * u(rng)));
  }
  for (BundlePoint& p : c.start.bundle.points) p.point_in_scene += Eigen::Vector3d(2 * u(rng), 2 * u(rng), 2 * u(rng));
  for (ProjectorPlacement& m : c.start.placements) {
    m.scene_from_module.translation += Eigen::Vector3d(5 * u(rng), 5 * u(rng), 5 * u(rng));
    m.scene_from_module.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d(u(rng), u(rng), 1).normalized())) *
                                   m.scene_from_module.rotation;
  }
  for (ProjectorSpot& s : c.start.spots) s.depth_mm *= 1.0 + 0.01 * u(rng);
  return c;
}

// The two-step path on the same observations: one bundle adjustment of tags
// and spot points in the unscaled frame of `unscaled_per_mm` (start: the
// true positions times it), three-point datum on the frame tags' corner 0,
// then identification, location and s (MeasureScaleFromFrontEnd, with the
// spots' own / shared split). Returns the report, and the datum length |AB|
// of the frame tags' centres in the unscaled solution.
struct TwoStepResult {
  ImageMeasureReport report;
  double unscaled_datum_length = 0.0;   // |B - A|, centres of the frame tags' corners
  BundleResult bundle;
};

inline Result<TwoStepResult> RunTwoStep(const ProjectorLabCase& c, double unscaled_per_mm) {
  BundleData b = c.start.bundle;
  for (BundleCamera& cam : b.cameras) cam.cam_from_scene.translation *= unscaled_per_mm;
  for (BundlePoint& p : b.points) p.point_in_scene *= unscaled_per_mm;
  const int first_spot = static_cast<int>(b.points.size());
  for (size_t k = 0; k < c.start.spots.size(); ++k) {
    BundlePoint p;
    p.point_in_scene = c.spot_truth_mm[k] * unscaled_per_mm;
    b.points.push_back(p);
    for (const ProjectorSpotObservation& o : c.start.spots[k].observations) {
      b.observations.push_back({o.camera, first_spot + static_cast<int>(k), o.pixel_px, o.covariance_px2});
    }
  }
  BundleOptions options;
  options.gauge = BundleGauge::kThreePointDatum;
  options.datum_points = {c.datum_sets[0][0], c.datum_sets[1][0], c.datum_sets[2][0]};
  options.compute_point_covariances = true;
  Result<BundleResult> adjusted = BundleAdjust(b, options);
  if (!adjusted.ok()) return adjusted.status();
  if (adjusted->point_covariances.empty()) {
    return Status::NoSolution("two-step bundle adjustment: covariances " + adjusted->covariance_method);
  }
  // One exposure group per (placement, source); with several placements
  // each group names its placement, so that each grid is located on its
  // own and the scale combines them (pipeline/measure.h).
  FrontEndResult fe;
  std::map<std::pair<int, std::string>, int> group_of;
  const bool named = c.start.placements.size() > 1;
  for (const ProjectorSpot& s : c.start.spots) {
    if (group_of.count({s.placement, s.source})) continue;
    group_of[{s.placement, s.source}] = static_cast<int>(fe.groups.size());
    ExposureGroup g;
    g.lasers = {s.source};
    if (named) g.placement = c.start.placements[static_cast<size_t>(s.placement)].name;
    fe.groups.push_back(g);
  }
  for (size_t k = 0; k < c.start.spots.size(); ++k) {
    const size_t p = static_cast<size_t>(first_spot) + k;
    FrontEndSpot s;
    s.point_in_scene = adjusted->data.points[p].point_in_scene;
    s.covariance = adjusted->point_covariances[p];
    s.own_covariance = adjusted->point_own_covariances[p];
    s.shared_factor = adjusted->point_shared_factors[p];
    s.group = group_of.at({c.start.spots[k].placement, c.start.spots[k].source});
    fe.spots.push_back(s);
  }
  TwoStepResult out;
  Result<ImageMeasureReport> report = MeasureScaleFromFrontEnd(fe, c.truth.calibration);
  if (!report.ok()) return report.status();
  out.report = std::move(*report);
  std::array<Eigen::Vector3d, 3> abc;
  for (size_t a = 0; a < 2; ++a) {
    abc[a].setZero();
    for (int j : c.datum_sets[a]) abc[a] += adjusted->data.points[static_cast<size_t>(j)].point_in_scene / 4.0;
  }
  out.unscaled_datum_length = (abc[1] - abc[0]).norm();
  out.bundle = std::move(*adjusted);
  return out;
}

}  // namespace opl::test
