#include "opl/lab/render_scene.h"

#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <type_traits>
#include <variant>

#include "opl/lab/planar_target_image.h"
#include "opl/lab/scene_look.h"
#include "opl/lab/spot_image.h"
#include "opl/model/beam_pattern.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

// Unit normal of slice `slice` of `surface` at its point p (any sign).
Eigen::Vector3d SurfaceNormalAt(const Surface& surface, int slice, const Eigen::Vector3d& p) {
  return std::visit(
      [&](const auto& s) -> Eigen::Vector3d {
        using T = std::decay_t<decltype(s)>;
        if constexpr (std::is_same_v<T, PlaneSurface>) {
          return s.normal.normalized();
        } else if constexpr (std::is_same_v<T, SphereSurface>) {
          return (p - s.center_mm).normalized();
        } else if constexpr (std::is_same_v<T, BoxCornerSurface>) {
          // The quarter plane the point lies on: its box coordinate nearest 0.
          const Eigen::Vector3d q = s.scene_from_box.transpose() * (p - s.corner_mm);
          int k = 0;
          q.cwiseAbs().minCoeff(&k);
          return s.scene_from_box.col(k);
        } else if constexpr (std::is_same_v<T, ParaboloidSurface>) {
          // Gradient of z' - c/2 r'^2: a - c r, r the point's offset across the axis.
          const Eigen::Vector3d a = s.axis.normalized();
          const Eigen::Vector3d d = p - s.vertex_mm;
          const Eigen::Vector3d r = d - d.dot(a) * a;
          return (a - s.curvature_per_mm * r).normalized();
        } else {
          return s.planes[static_cast<size_t>(slice)].normal.normalized();
        }
      },
      surface.shape());
}

// d pixel / d point_in_scene (2 x 3) by central differences.
bool ProjectionJacobian(const Camera& camera, const Eigen::Vector3d& point,
                        Eigen::Matrix<double, 2, 3>* J) {
  const double h = 1e-5 * std::max(1.0, (point - camera.CenterInScene()).norm());
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d step = Eigen::Vector3d::Zero();
    step[k] = h;
    Eigen::Vector2d plus, minus;
    if (!camera.Project(point + step, &plus) || !camera.Project(point - step, &minus)) return false;
    J->col(k) = (plus - minus) / (2.0 * h);
  }
  return true;
}

uint64_t ShotSeed(uint64_t scene_seed, int shot_index) {
  SplitMix64 mix(scene_seed ^ (0xD1B54A32D192ED03ull * static_cast<uint64_t>(shot_index + 1)));
  return mix.Next();
}

}  // namespace

Result<SceneRenderer> SceneRenderer::Create(const Scene& scene) {
  OPL_RETURN_IF_ERROR(scene.ValidateForRendering());
  SceneRenderer r;
  r.scene_ = scene;
  const double h = 0.5 * scene.tags.size_mm;
  for (const SceneTag& tag : scene.tags.tags) {
    SceneTagTruth t;
    t.id = tag.id;
    t.center_in_scene = tag.scene_from_tag.translation;
    const double xs[4] = {-h, h, h, -h};
    const double ys[4] = {-h, -h, h, h};
    for (int c = 0; c < 4; ++c) {
      t.corners_in_scene[c] = tag.scene_from_tag * Eigen::Vector3d(xs[c], ys[c], 0.0);
    }
    r.tags_.push_back(t);
  }
  std::set<int> slices;
  for (const SceneShot& shot : scene.shots) slices.insert(shot.slice);
  const ModuleDesign& module = *scene.module;
  std::vector<SceneModulePlacement> placements = scene.module_placements;
  if (placements.empty()) placements.emplace_back();  // the module as designed, unnamed
  std::vector<BeamPattern> patterns;
  for (const SourceDesign& source : module.sources) {
    Result<BeamPattern> pattern = MakePattern(source);
    if (!pattern.ok()) {
      return Status(pattern.status().code(), "module: source '" + source.name + "': " +
                                                 pattern.status().message());
    }
    patterns.push_back(std::move(*pattern));
  }
  for (const SceneModulePlacement& placement : placements) {
    const Rigid3d scene_from_design = placement.SceneFromDesign(module);
    for (size_t src = 0; src < module.sources.size(); ++src) {
      const SourceDesign& source = module.sources[src];
      const BeamPattern* pattern = &patterns[src];
      const Rigid3d scene_from_source = scene_from_design * source.scene_from_source;
      const Eigen::Matrix3d R = scene_from_source.RotationMatrix();
      const Eigen::Vector3d origin = scene_from_source.translation;
      for (int slice : slices) {
        for (const Beam& beam : pattern->beams()) {
          const Eigen::Vector3d direction = (R * beam.DirectionInSource()).normalized();
          std::optional<Eigen::Vector3d> hit = module.surface.IntersectRaySlice(slice, origin, direction);
          if (!hit) continue;
          SceneSpotTruth spot;
          spot.source = source.name;
          spot.placement = placement.name;
          spot.beam = beam.id;
          spot.slice = slice;
          spot.point_in_scene = *hit;
          spot.normal_in_scene = SurfaceNormalAt(module.surface, slice, *hit);
          if (spot.normal_in_scene.dot(origin - *hit) < 0.0) spot.normal_in_scene = -spot.normal_in_scene;
          r.spots_.push_back(spot);
        }
      }
    }
  }
  if (!scene.image.wall_texture.empty()) {
    Result<cv::Mat> texture = ReadWallTexture(scene.image.wall_texture);
    if (!texture.ok()) {
      return Status(texture.status().code(), "image.wall_texture: " + texture.status().message());
    }
    r.wall_texture_ = std::move(*texture);
  }
  // Distractors belong to the room as each camera sees it: seeded by the
  // scene and the camera, the same in every shot of that camera.
  for (size_t k = 0; k < scene.cameras.size(); ++k) {
    const CameraIntrinsics& in = scene.cameras[k].intrinsics;
    r.distractors_.push_back(MakeDistractors(scene.image.distractors, in.width_px, in.height_px,
                                             scene.seed ^ (0xA24BAED4963EE407ull * (k + 1))));
  }
  return r;
}

Result<RenderedShot> SceneRenderer::RenderShot(int shot_index) const {
  if (shot_index < 0 || shot_index >= static_cast<int>(scene_.shots.size())) {
    return Status::InvalidArgument("shot index " + std::to_string(shot_index) + ": the scene has " +
                                   std::to_string(scene_.shots.size()) + " shots");
  }
  const SceneShot& shot = scene_.shots[static_cast<size_t>(shot_index)];
  const SceneCamera& scene_camera = *scene_.FindCamera(shot.camera);
  const Camera camera{scene_camera.name, scene_camera.intrinsics, *scene_camera.cam_from_scene};
  const Eigen::Vector3d camera_center = camera.CenterInScene();
  const ImageLook& look = scene_.image;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  RenderedShot out;
  out.shot_index = shot_index;

  // 1. Tags.
  std::vector<PlanarTarget> targets;
  for (size_t k = 0; k < scene_.tags.tags.size(); ++k) {
    const SceneTag& tag = scene_.tags.tags[k];
    const SceneTagTruth& truth = tags_[k];
    TagView view;
    view.id = tag.id;
    // The tag's z axis points into the wall: the face is seen from -z.
    const Eigen::Vector3d z_axis = tag.scene_from_tag.rotation * Eigen::Vector3d::UnitZ();
    view.facing = z_axis.dot(camera_center - truth.center_in_scene) < 0.0;
    view.in_image = view.facing;
    bool any_in_front = false;
    for (int c = 0; c < 4; ++c) {
      if (!camera.Project(truth.corners_in_scene[c], &view.corners_px[c])) {
        view.corners_px[c] = Eigen::Vector2d(nan, nan);
        view.in_image = false;
      } else {
        any_in_front = true;
        if (!camera.InImage(view.corners_px[c])) view.in_image = false;
      }
    }
    out.tags.push_back(view);
    if (!view.facing || !any_in_front) continue;
    Result<PlanarTarget> target =
        MakeTagTarget(tag.id, scene_.tags.size_mm, tag.scene_from_tag, kSceneTagQuietZoneCells);
    if (!target.ok()) return target.status();
    targets.push_back(std::move(*target));
  }
  Result<PlanarTargetRenderer> renderer =
      PlanarTargetRenderer::CreateOnDemand(camera, look.subpixels_per_axis);
  if (!renderer.ok()) return renderer.status();
  TargetRenderOptions target_options;
  target_options.background_level = look.background_level;
  target_options.black_level = look.black_level;
  target_options.white_level = look.white_level;
  target_options.blur_sigma_px = look.blur_sigma_px;
  target_options.noise_sigma = 0.0;
  target_options.bit_depth = look.bit_depth;
  target_options.keep_levels = true;
  Result<RenderedTargetImage> tag_image = renderer->Render(targets, target_options);
  if (!tag_image.ok()) return tag_image.status();

  // 2. Spots.
  const bool scene_look = look.HasSceneLook();
  SpotImageOptions spot_options;
  spot_options.width_px = camera.intrinsics.width_px;
  spot_options.height_px = camera.intrinsics.height_px;
  spot_options.bit_depth = look.bit_depth;
  const double full_scale = SpotImageFullScale(spot_options);
  SceneImageLayers layers;
  if (scene_look) {
    layers.tag_levels = std::move(tag_image->levels);
  } else {
    tag_image->levels.convertTo(spot_options.background_image_dn, CV_32FC1, full_scale);
  }
  tag_image->levels.release();
  tag_image->image.release();
  spot_options.speckle_contrast = scene_.spots.speckle_contrast;
  spot_options.speckle_grain_px = scene_.spots.speckle_grain_px;
  spot_options.gain_e_per_dn = look.gain_e_per_dn;
  spot_options.read_noise_dn = look.read_noise * full_scale;
  spot_options.seed = ShotSeed(scene_.seed, shot_index);

  const std::set<std::string> lit(shot.lasers.begin(), shot.lasers.end());
  const double sigma_mm = scene_.spots.diameter_mm / 4.0;
  std::vector<SpotToRender> to_render;
  std::vector<size_t> view_of_rendered;
  for (size_t k = 0; k < spots_.size(); ++k) {
    const SceneSpotTruth& spot = spots_[k];
    if (spot.slice != shot.slice || spot.placement != shot.placement ||
        lit.count(spot.source) == 0) {
      continue;
    }
    SpotView view;
    view.spot_index = static_cast<int>(k);
    if (!camera.Project(spot.point_in_scene, &view.center_px)) {
      view.center_px = Eigen::Vector2d(nan, nan);
      out.spots.push_back(view);
      continue;
    }
    const bool facing = spot.normal_in_scene.dot(camera_center - spot.point_in_scene) > 0.0;
    Eigen::Matrix<double, 2, 3> J;
    if (facing && ProjectionJacobian(camera, spot.point_in_scene, &J)) {
      const Eigen::Vector3d& n = spot.normal_in_scene;
      const Eigen::Matrix3d S = sigma_mm * sigma_mm * (Eigen::Matrix3d::Identity() - n * n.transpose());
      Eigen::Matrix2d C = J * S * J.transpose();
      C = 0.5 * (C + C.transpose());
      // Defocus widens the spot's Gaussian exactly (lab/scene_look.h, step 4).
      C += look.defocus_sigma_px * look.defocus_sigma_px * Eigen::Matrix2d::Identity();
      const double smin = std::sqrt(std::min(C(0, 0), C(1, 1)));
      const double smax = std::sqrt(std::max(C(0, 0), C(1, 1)));
      // RenderSpotImage's domain; a spot seen so edge-on that it leaves it is
      // not drawn (it would not be measurable anyway).
      // A spot whose centre is just outside the image still lights its
      // border: drawn (not visible) when its centre is within 5 sigma of it.
      if (C.determinant() > 0.0 && smin >= 0.05 && smax <= 1000.0 &&
          std::sqrt(C.determinant()) / (smax * smax) >= 1e-6 &&
          camera.InImage(view.center_px, -5.0 * smax)) {
        view.visible = camera.InImage(view.center_px);
        view.shape_covariance_px2 = C;
        SpotToRender r;
        r.u_px = view.center_px.x();
        r.v_px = view.center_px.y();
        r.shape_covariance_px2 = C;
        r.peak_dn = scene_.spots.peak_fraction * full_scale;
        to_render.push_back(r);
        view_of_rendered.push_back(out.spots.size());
      }
    }
    out.spots.push_back(view);
  }

  // 3. Sensor.
  if (scene_look) {
    // The laser light alone, then the room, lens and sensor around it.
    SpotImageOptions light = spot_options;
    light.background_dn = 0.0;
    light.gain_e_per_dn = 0.0;
    light.read_noise_dn = 0.0;
    light.keep_clean = true;
    Result<SpotImage> spot_light = RenderSpotImage(to_render, light);
    if (!spot_light.ok()) return spot_light.status();
    spot_light->image.release();
    layers.spot_light = spot_light->clean_dn / full_scale;
    spot_light->clean_dn.release();
    layers.wall_texture = wall_texture_;
    layers.exposure = shot.exposure;
    layers.distractors = distractors_[static_cast<size_t>(scene_.FindCamera(shot.camera) -
                                                          scene_.cameras.data())];
    out.distractors = layers.distractors;
    Result<SceneImage> image = ComposeSceneImage(layers, look, camera.intrinsics,
                                                 SplitMix64(spot_options.seed).Next() ^ 0x5EEDull);
    if (!image.ok()) return image.status();
    for (size_t k = 0; k < view_of_rendered.size(); ++k) {
      const cv::Rect& window = spot_light->spots[k].window;
      out.spots[view_of_rendered[k]].saturated_pixels =
          window.area() > 0 ? cv::countNonZero(image->saturated_mask(window)) : 0;
    }
    out.image = std::move(image->image);
    return out;
  }
  Result<SpotImage> image = RenderSpotImage(to_render, spot_options);
  if (!image.ok()) return image.status();
  for (size_t k = 0; k < view_of_rendered.size(); ++k) {
    out.spots[view_of_rendered[k]].saturated_pixels = image->spots[k].saturated_pixels;
  }
  out.image = std::move(image->image);
  return out;
}

Result<RenderedShot> RenderShot(const Scene& scene, int shot_index) {
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  if (!renderer.ok()) return renderer.status();
  return renderer->RenderShot(shot_index);
}

}  // namespace opl
