// The scene renderer against independent measurements of its images: the tag
// corners DetectTags finds and the spot centres DetectSpots finds agree with
// the truth; an oblique spot's shape is the projected disc's (computed here
// by projecting points of the disc's rim, not by the renderer's Jacobian); a
// spot behind the camera, outside the image or on a back-facing surface is not
// drawn. Also: the on-demand target renderer gives the same image as the
// precomputed one, and a background image gives the same spot image as the
// equal scalar background.
#include "opl/lab/render_scene.h"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <tuple>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "opl/io/scene_json.h"
#include "opl/lab/planar_target_image.h"
#include "opl/lab/spot_image.h"
#include "opl/vision/spot_detection.h"
#include "opl/vision/tag_detection.h"
#include "support/wall_scene.h"

namespace opl {
namespace {

using test::WallScene;

Camera CameraOf(const Scene& s, int k = 0) {
  const SceneCamera& c = s.cameras[static_cast<size_t>(k)];
  return Camera{c.name, c.intrinsics, *c.cam_from_scene};
}

TEST(RenderScene, TagCornersAgreeWithDetection) {
  Scene scene = WallScene();
  scene.shots[0].lasers.clear();  // tags only
  Result<RenderedShot> shot = RenderShot(scene, 0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  ASSERT_EQ(shot->image.type(), CV_16UC1);
  Result<std::vector<TagDetection>> tags = DetectTags(shot->image);
  ASSERT_TRUE(tags.ok()) << tags.status().message();
  ASSERT_EQ(tags->size(), 4u);
  double worst = 0.0;
  for (const TagDetection& d : *tags) {
    const TagView* truth = nullptr;
    for (const TagView& v : shot->tags) {
      if (v.id == d.id) truth = &v;
    }
    ASSERT_NE(truth, nullptr) << d.id;
    EXPECT_TRUE(truth->in_image);
    for (int c = 0; c < 4; ++c) worst = std::max(worst, (d.corners_px[c] - truth->corners_px[c]).norm());
  }
  EXPECT_LT(worst, 0.1);
  std::printf("worst tag corner error %.4f px\n", worst);
  // The truth is the camera model applied to the tag's corner.
  const Camera camera = CameraOf(scene);
  Eigen::Vector2d px;
  ASSERT_TRUE(camera.Project(scene.tags.tags[0].scene_from_tag * Eigen::Vector3d(-50, -50, 0), &px));
  EXPECT_LT((px - shot->tags[0].corners_px[0]).norm(), 1e-12);
}

TEST(RenderScene, SpotCentresAgreeWithDetection) {
  Scene scene = WallScene();
  scene.tags.tags.clear();  // spots only
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().message();
  ASSERT_EQ(renderer->spots().size(), 25u);
  // The 3D truth is the beam ray's hit: x = 1000 on the wall.
  for (const SceneSpotTruth& s : renderer->spots()) EXPECT_NEAR(s.point_in_scene.x(), 1000.0, 1e-9);
  Result<RenderedShot> shot = renderer->RenderShot(0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  Result<SpotDetectionResult> detected = DetectSpots(shot->image);
  ASSERT_TRUE(detected.ok()) << detected.status().message();
  ASSERT_EQ(detected->spots.size(), 25u);
  double worst = 0.0;
  for (const SpotView& v : shot->spots) {
    ASSERT_TRUE(v.visible);
    double best = 1e9;
    for (const DetectedSpot& d : detected->spots) {
      best = std::min(best, (Eigen::Vector2d(d.u_px, d.v_px) - v.center_px).norm());
    }
    worst = std::max(worst, best);
  }
  std::printf("worst spot centre error %.4f px\n", worst);
  EXPECT_LT(worst, 0.05);
  // Spot size: a disc of 8 mm at ~1 m seen frontally by fx = 600: sigma = 2 mm * 600 / 1000.
  const SpotView& central = shot->spots[12];
  EXPECT_NEAR(std::sqrt(central.shape_covariance_px2(0, 0)), 1.2, 0.02);
}

// Covariance of the projection of a disc of 1/e^2 diameter D in the plane
// with normal n at p: the rim of a small circle projected point by point
// (second moments of a circle of radius r: r^2 / 2 per axis).
Eigen::Matrix2d ProjectedDiscCovariance(const Camera& camera, const Eigen::Vector3d& p,
                                        const Eigen::Vector3d& n, double diameter_mm) {
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1).normalized();
  const double r = 0.01;  // mm: small enough for the projection to be affine
  Eigen::Vector2d centre;
  camera.Project(p, &centre);
  Eigen::Matrix2d M = Eigen::Matrix2d::Zero();
  constexpr int kN = 64;
  for (int k = 0; k < kN; ++k) {
    const double t = 2.0 * 3.14159265358979 * k / kN;
    Eigen::Vector2d px;
    camera.Project(p + r * (std::cos(t) * e1 + std::sin(t) * e2), &px);
    M += (px - centre) * (px - centre).transpose() / kN;
  }
  const double sigma = diameter_mm / 4.0;
  return M * 2.0 * (sigma / r) * (sigma / r);
}

TEST(RenderScene, ObliqueSpotsAreTheProjectedDisc) {
  Scene scene = WallScene();
  scene.tags.tags.clear();
  // The wall turned 60 deg about Z: seen obliquely by the camera.
  const Eigen::Vector3d normal(-std::cos(60.0 * 3.14159265358979 / 180.0),
                               std::sin(60.0 * 3.14159265358979 / 180.0), 0.0);
  scene.module->surface = PlaneSurface{Eigen::Vector3d(1000.0, 0.0, 0.0), normal};
  scene.module->sources[0].beams_per_side = 3;
  scene.spots.diameter_mm = 12.0;
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().message();
  Result<RenderedShot> shot = renderer->RenderShot(0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  Result<SpotDetectionResult> detected = DetectSpots(shot->image);
  ASSERT_TRUE(detected.ok());
  ASSERT_EQ(detected->spots.size(), 9u);
  const Camera camera = CameraOf(scene);
  for (const SpotView& v : shot->spots) {
    ASSERT_TRUE(v.visible);
    const SceneSpotTruth& truth = renderer->spots()[static_cast<size_t>(v.spot_index)];
    const Eigen::Matrix2d expected = ProjectedDiscCovariance(camera, truth.point_in_scene, normal, 12.0);
    EXPECT_LT((v.shape_covariance_px2 - expected).norm(), 1e-3 * expected.norm());
    const DetectedSpot* d = nullptr;
    for (const DetectedSpot& s : detected->spots) {
      if ((Eigen::Vector2d(s.u_px, s.v_px) - v.center_px).norm() < 0.1) d = &s;
    }
    ASSERT_NE(d, nullptr);
    // The fit of a point-sampled Gaussian to pixel-integrated light: C + I/12.
    const Eigen::Matrix2d measured = d->shape_px2 - Eigen::Matrix2d::Identity() / 12.0;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> m(measured), e(expected);
    const double ratio_measured = std::sqrt(m.eigenvalues()(1) / m.eigenvalues()(0));
    const double ratio_expected = std::sqrt(e.eigenvalues()(1) / e.eigenvalues()(0));
    EXPECT_GT(ratio_expected, 1.8);  // cos(60 deg) foreshortening: ~2
    EXPECT_NEAR(ratio_measured, ratio_expected, 0.02 * ratio_expected);
  }
}

TEST(RenderScene, SpotsBehindOutsideOrOnBackFacingSurfacesAreNotDrawn) {
  // Behind: the camera looks away from the wall.
  {
    Scene scene = WallScene(320, 240);
    scene.cameras[0].cam_from_scene =
        *CamFromSceneLookingAt(Eigen::Vector3d::Zero(), Eigen::Vector3d(-1000, 0, 0));
    Result<RenderedShot> shot = RenderShot(scene, 0);
    ASSERT_TRUE(shot.ok()) << shot.status().message();
    for (const SpotView& v : shot->spots) {
      EXPECT_FALSE(v.visible);
      EXPECT_TRUE(std::isnan(v.center_px.x()));
    }
    double lo = 0, hi = 0;
    cv::minMaxLoc(shot->image, &lo, &hi);
    EXPECT_EQ(lo, hi);  // nothing drawn: the flat wall level
    EXPECT_EQ(hi, std::round(0.25 * 65535));
  }
  // Outside: the camera looks 40 deg to the side; the grid projects beyond the image.
  {
    Scene scene = WallScene(320, 240);
    scene.tags.tags.clear();
    scene.cameras[0].cam_from_scene =
        *CamFromSceneLookingAt(Eigen::Vector3d::Zero(), Eigen::Vector3d(1000, 840, 0));
    Result<RenderedShot> shot = RenderShot(scene, 0);
    ASSERT_TRUE(shot.ok());
    const Camera camera = CameraOf(scene);
    for (const SpotView& v : shot->spots) {
      EXPECT_FALSE(v.visible);
      ASSERT_TRUE(std::isfinite(v.center_px.x()));
      EXPECT_FALSE(camera.InImage(v.center_px));
    }
    double lo = 0, hi = 0;
    cv::minMaxLoc(shot->image, &lo, &hi);
    EXPECT_LT(hi - lo, 2.0);  // at most the faint tail of a spot just outside: none here
  }
  // Just outside: the principal point moved so that the leftmost spot
  // projects to u = -1 (a pure shift of u): it is not visible but its light
  // reaches the image's first column, as a real camera's would.
  {
    Scene scene = WallScene(320, 240);
    scene.tags.tags.clear();
    Result<RenderedShot> before = RenderShot(scene, 0);
    ASSERT_TRUE(before.ok());
    double umin = 1e9;
    for (const SpotView& v : before->spots) umin = std::min(umin, v.center_px.x());
    scene.cameras[0].intrinsics.cx_px -= umin + 1.0;
    Result<RenderedShot> shot = RenderShot(scene, 0);
    ASSERT_TRUE(shot.ok());
    int outside = 0;
    for (const SpotView& v : shot->spots) {
      if (v.center_px.x() < -0.5) {
        EXPECT_FALSE(v.visible);
      }
      if (std::abs(v.center_px.x() + 1.0) > 1e-6) continue;  // the leftmost spot
      ++outside;
      EXPECT_FALSE(v.visible);
      const int row = static_cast<int>(std::lround(v.center_px.y()));
      // Background 0.25 of 65535 = 16384; the spot (sigma 1.2 px, peak 0.5 of
      // full scale) adds about exp(-1/2 (1/1.2)^2) * 0.5 * 65535 ~ 23000 at u = 0.
      EXPECT_GT(shot->image.at<uint16_t>(row, 0), 16384 + 10000);
    }
    EXPECT_EQ(outside, 1);
  }
  // Back-facing: the camera behind the wall, looking back at it.
  {
    Scene scene = WallScene(320, 240);
    scene.cameras[0].cam_from_scene =
        *CamFromSceneLookingAt(Eigen::Vector3d(2000, 0, 0), Eigen::Vector3d(1000, 0, 0));
    Result<RenderedShot> shot = RenderShot(scene, 0);
    ASSERT_TRUE(shot.ok());
    const Camera camera = CameraOf(scene);
    int in_image = 0;
    for (const SpotView& v : shot->spots) {
      EXPECT_FALSE(v.visible);
      in_image += camera.InImage(v.center_px) ? 1 : 0;
    }
    EXPECT_EQ(in_image, 25);  // they would be in view but for the wall
    for (const TagView& t : shot->tags) EXPECT_FALSE(t.facing);
    double lo = 0, hi = 0;
    cv::minMaxLoc(shot->image, &lo, &hi);
    EXPECT_EQ(lo, hi);
  }
}

TEST(RenderScene, OnDemandRaysGiveTheSameImage) {
  const Scene scene = WallScene(320, 240);
  std::vector<PlanarTarget> targets;
  for (const SceneTag& t : scene.tags.tags) {
    targets.push_back(*MakeTagTarget(t.id, 100.0, t.scene_from_tag, 2));
  }
  TargetRenderOptions options;
  options.bit_depth = 16;
  options.blur_sigma_px = 0.7;
  options.keep_levels = true;
  Result<PlanarTargetRenderer> full = PlanarTargetRenderer::Create(CameraOf(scene), 3);
  Result<PlanarTargetRenderer> lazy = PlanarTargetRenderer::CreateOnDemand(CameraOf(scene), 3);
  ASSERT_TRUE(full.ok() && lazy.ok());
  Result<RenderedTargetImage> a = full->Render(targets, options);
  Result<RenderedTargetImage> b = lazy->Render(targets, options);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(cv::norm(a->image, b->image, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a->levels, b->levels, cv::NORM_INF), 0.0);
  // levels is the image before quantisation.
  cv::Mat quantised;
  a->levels.convertTo(quantised, CV_16UC1, 65535.0);
  EXPECT_LE(cv::norm(quantised, a->image, cv::NORM_INF), 1.0);
}

TEST(RenderScene, BackgroundImageEqualsScalarBackground) {
  SpotImageOptions options;
  options.width_px = 64;
  options.height_px = 48;
  options.background_dn = 321.0;
  options.read_noise_dn = 3.0;
  options.gain_e_per_dn = 2.0;
  std::vector<SpotToRender> spots(1);
  spots[0].u_px = 30.3;
  spots[0].v_px = 20.6;
  spots[0].shape_covariance_px2 = RoundSpotShape(5.0);
  Result<SpotImage> scalar = RenderSpotImage(spots, options);
  options.background_image_dn = cv::Mat(48, 64, CV_32FC1, cv::Scalar(321.0));
  options.background_dn = 0.0;
  Result<SpotImage> image = RenderSpotImage(spots, options);
  ASSERT_TRUE(scalar.ok() && image.ok());
  EXPECT_EQ(cv::norm(scalar->image, image->image, cv::NORM_INF), 0.0);
  options.background_image_dn = cv::Mat(47, 64, CV_32FC1, cv::Scalar(321.0));
  Result<SpotImage> bad = RenderSpotImage(spots, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("background_image_dn"), std::string::npos);
}

// The example scene as the front end will see it (speckle, noise, blur, 8
// bits): every tag and every spot is found near its truth. Prints the figures.
TEST(RenderScene, ExampleSceneIsMeasurable) {
  const char* root = std::getenv("OPL_SOURCE_DIR");
  ASSERT_NE(root, nullptr);
  Result<Scene> scene = ReadSceneJson(std::string(root) + "/examples/scene_small.json");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  Result<RenderedShot> shot = RenderShot(*scene, 1);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  Result<std::vector<TagDetection>> tags = DetectTags(shot->image);
  ASSERT_TRUE(tags.ok());
  EXPECT_EQ(tags->size(), 10u);
  double tag_sum2 = 0.0;
  int corners = 0;
  for (const TagDetection& d : *tags) {
    for (const TagView& v : shot->tags) {
      if (v.id != d.id) continue;
      for (int c = 0; c < 4; ++c, ++corners) tag_sum2 += (d.corners_px[c] - v.corners_px[c]).squaredNorm();
    }
  }
  ASSERT_EQ(corners, 40);
  const double tag_rms = std::sqrt(tag_sum2 / corners);
  SpotDetectionOptions spot_options;
  spot_options.speckle_contrast = scene->spots.speckle_contrast;
  spot_options.speckle_grain_px = scene->spots.speckle_grain_px;
  Result<SpotDetectionResult> spots = DetectSpots(shot->image, spot_options);
  ASSERT_TRUE(spots.ok());
  double spot_sum2 = 0.0;
  int matched = 0;
  for (const SpotView& v : shot->spots) {
    ASSERT_TRUE(v.visible);
    double best = 1e9;
    for (const DetectedSpot& d : spots->spots) {
      best = std::min(best, (Eigen::Vector2d(d.u_px, d.v_px) - v.center_px).norm());
    }
    if (best < 1.0) {
      ++matched;
      spot_sum2 += best * best;
    }
  }
  const double spot_rms = std::sqrt(spot_sum2 / std::max(1, matched));
  std::printf("example shot 1: tag corner RMS %.4f px (40 corners); spots matched %d/121, "
              "centre RMS %.4f px (speckle %.2f)\n",
              tag_rms, matched, spot_rms, scene->spots.speckle_contrast);
  EXPECT_LT(tag_rms, 0.1);
  EXPECT_EQ(matched, 121);
  EXPECT_LT(spot_rms, 0.3);
}

TEST(RenderScene, ErrorsNameTheField) {
  Scene scene = WallScene(320, 240);
  scene.cameras[0].cam_from_scene.reset();
  Result<RenderedShot> shot = RenderShot(scene, 0);
  ASSERT_FALSE(shot.ok());
  EXPECT_EQ(shot.status().message(),
            "cameras[0]: camera 'cam0' has no pose (rendering needs every camera's true pose)");
  scene = WallScene(320, 240);
  scene.module.reset();
  EXPECT_EQ(RenderShot(scene, 0).status().message(),
            "module: missing (rendering needs the module and its surface)");
  scene = WallScene(320, 240);
  EXPECT_EQ(RenderShot(scene, 1).status().message(), "shot index 1: the scene has 1 shots");
}

// Module placements (issue 20): at each placement the module's rays leave
// the moved origins along the moved directions and hit the unmoved wall; a
// shot shows only its placement's spots.
TEST(RenderScene, ModulePlacementsMoveTheModuleNotTheWall) {
  const char* root = std::getenv("OPL_SOURCE_DIR");
  ASSERT_NE(root, nullptr);
  Result<Scene> read = ReadSceneJson(std::string(root) + "/examples/scene_small.json");
  ASSERT_TRUE(read.ok()) << read.status().message();
  Scene scene = *read;
  SceneModulePlacement p1, p2, p3;
  p1.name = "P1";
  p2.name = "P2";
  p2.translation_mm = Eigen::Vector3d(0.0, 200.0, 100.0);  // parallel to the wall x = 2000
  p3.name = "P3";
  p3.rotation_deg = Eigen::Vector3d(0.0, 3.0, 10.0);
  p3.translation_mm = Eigen::Vector3d(150.0, -100.0, 50.0);
  scene.module_placements = {p1, p2, p3};
  for (SceneShot& shot : scene.shots) shot.placement = shot.lasers.empty() ? "" : "P2";
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().message();
  std::map<std::tuple<std::string, std::string, int>, Eigen::Vector3d> hit;
  for (const SceneSpotTruth& s : renderer->spots()) hit[{s.placement, s.source, s.beam}] = s.point_in_scene;
  ASSERT_EQ(hit.size(), 3u * 2u * 121u);
  // P2: every spot moves by the translation, exactly (a plane wall).
  for (const auto& [key, p] : hit) {
    if (std::get<0>(key) != "P1") continue;
    const Eigen::Vector3d& q = hit.at({"P2", std::get<1>(key), std::get<2>(key)});
    EXPECT_LT((q - p - p2.translation_mm).norm(), 1e-9);
  }
  // P3: the spot lies on the wall, on the ray from the moved origin along
  // the moved beam (R = Rx Ry Rz about the sources' centroid, here the
  // origin of the design frame).
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();  // Rx(0) Ry(3 deg) Rz(10 deg)
  for (const SourceDesign& source : scene.module->sources) {
    Result<BeamPattern> pattern = MakePattern(source);
    ASSERT_TRUE(pattern.ok());
    const Eigen::Vector3d origin = R * source.scene_from_source.translation + p3.translation_mm;
    for (const Beam& beam : pattern->beams()) {
      const Eigen::Vector3d d = R * (source.scene_from_source.RotationMatrix() * beam.DirectionInSource());
      const Eigen::Vector3d q = hit.at({"P3", source.name, beam.id});
      EXPECT_NEAR(q.x(), 2000.0, 1e-9);
      EXPECT_LT((q - origin).normalized().cross(d.normalized()).norm(), 1e-12);
    }
  }
  // A lit shot at P2 shows P2's spots only.
  int lit = -1;
  for (size_t k = 0; k < scene.shots.size() && lit < 0; ++k) {
    if (!scene.shots[k].lasers.empty()) lit = static_cast<int>(k);
  }
  ASSERT_GE(lit, 0);
  Result<RenderedShot> shot = renderer->RenderShot(lit);
  ASSERT_TRUE(shot.ok());
  ASSERT_EQ(shot->spots.size(), 121u);
  for (const SpotView& v : shot->spots) {
    EXPECT_EQ(renderer->spots()[static_cast<size_t>(v.spot_index)].placement, "P2");
  }
}

}  // namespace
}  // namespace opl
