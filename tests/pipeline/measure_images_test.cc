// From rendered photographs to a scale factor, against the truth of the
// virtual lab (examples/scene_small.json: four 1024 x 768 cameras, tags on
// the walls, a prototype-like module of two 11 x 11 grids, each grid shot by
// every camera). The scale of the photogrammetric frame is unknown to the
// pipeline (it starts from the nominal tag size); the test finds the TRUE
// scale independently, by a similarity fit (Umeyama) of the measured 3D
// spots, matched to their true 3D points by the identified (source, beam), and
// checks s against it. Also the per-image report and the bad-input errors.
#include "opl/pipeline/measure_images.h"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <filesystem>
#include <map>
#include <random>
#include <cmath>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/sim/module_design.h"
#include "support/lab_truth.h"
#include "support/scene_images.h"

namespace opl {
namespace {

using test::FreshTempDir;
using test::SourceDir;

// Renders every shot of `scene` into `dir`; returns the renderer (truth).
SceneRenderer RenderAll(const Scene& scene, const std::filesystem::path& dir) {
  Result<SceneRenderer> renderer = test::RenderShotsTo(scene, dir, 2);
  EXPECT_TRUE(renderer.ok()) << renderer.status().ToString();
  return std::move(renderer).value();
}

Scene SmallScene() {
  Result<Scene> scene = ReadSceneJson(SourceDir() + "/examples/scene_small.json");
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  return std::move(scene).value();
}

// A scene made noise-free: no sensor noise, no speckle, 16 bit (no visible
// quantisation).
Scene NoiseFree(Scene scene) {
  scene.image.read_noise = 0.0;
  scene.image.gain_e_per_dn = 0.0;
  scene.image.bit_depth = 16;
  scene.spots.speckle_contrast = 0.0;
  return scene;
}

Scene NoiseFreeSmallScene() { return NoiseFree(SmallScene()); }

TEST(MeasureScaleFromImages, NoiseFreeRenderGivesTheTrueScale) {
  Scene scene = NoiseFreeSmallScene();
  const std::filesystem::path dir = FreshTempDir("measure_images_clean");
  const SceneRenderer truth = RenderAll(scene, dir);
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ASSERT_TRUE(calibration.ok());
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  Result<ImageMeasureReport> report =
      MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  std::cout << report->ToText();
  for (const ImageFindings& f : report->front_end.images) {
    EXPECT_TRUE(f.placed) << f.file;
    EXPECT_GE(f.tag_ids.size(), 3u) << f.file;
    EXPECT_GT(f.spots_matched, 60) << f.file;
    EXPECT_LT(f.tag_rms_px, 0.1) << f.file;
    EXPECT_LT(f.spot_rms_px, 0.1) << f.file;
  }
  EXPECT_TRUE(report->metadata_conflicts.empty());
  // One laser per exposure group: the other source is reported as off in
  // that group, not as "not found" for want of spots.
  ASSERT_EQ(report->identification.size(), 2u);
  for (size_t g = 0; g < 2; ++g) {
    const std::vector<std::string>& lasers = report->front_end.groups[g].lasers;
    ASSERT_EQ(lasers.size(), 1u);
    for (const IdentifiedSource& source : report->identification[g].sources) {
      if (source.name == lasers[0]) {
        EXPECT_EQ(source.outcome, IdentifyOutcome::kFound) << source.name;
      } else {
        EXPECT_EQ(source.outcome, IdentifyOutcome::kNotFound) << source.name;
        EXPECT_EQ(source.detail, "laser off in these shots: not searched") << source.name;
      }
    }
  }
  const test::TruthFit fit = test::FitToTruth(*report, truth);
  std::cout.precision(10);
  std::cout << "truth fit: " << fit.points << " spots, scale " << fit.scale << ", rms "
            << fit.rms_mm << " mm; s = " << report->measure.scale.scale_factor << " +- "
            << report->measure.scale.u_scale_factor << "\n";
  EXPECT_GE(fit.points, 230);
  const double s = report->measure.scale.scale_factor;
  EXPECT_LT(std::abs(s / fit.scale - 1.0), 2e-5);

  // The spots' shared errors (cameras, datum tags), propagated to s by
  // central differences (ImageMeasureOptions::propagate_shared_errors),
  // against a Monte Carlo of the same: z ~ N(0, I), every assigned spot
  // moved by K_j z, MeasureScale again (M = 300: the std scatters by 4%).
  ASSERT_GT(report->shared_components, 9);
  EXPECT_NEAR(report->measure.scale.u_scale_factor,
              std::hypot(report->u_scale_factor_own, report->u_scale_factor_shared), 1e-12);
  std::vector<Spot> assigned;
  std::vector<const FrontEndSpot*> front;
  for (size_t k = 0; k < report->spots.size(); ++k) {
    if (!report->spots[k].assigned()) continue;
    assigned.push_back(report->spots[k]);
    assigned.back().observation.cov_in_scene = report->front_end.spots[k].own_covariance;
    front.push_back(&report->front_end.spots[k]);
  }
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int draws = 300;
  double sum = 0.0, sum2 = 0.0;
  for (int d = 0; d < draws; ++d) {
    Eigen::VectorXd z(report->shared_components);
    for (Eigen::Index q = 0; q < z.size(); ++q) z(q) = normal(rng);
    std::vector<Spot> moved = assigned;
    for (size_t i = 0; i < moved.size(); ++i) moved[i].observation.point_in_scene += front[i]->shared_factor * z;
    Result<MeasureReport> r = MeasureScale(*calibration, moved, options.measure);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    sum += r->scale.scale_factor;
    sum2 += r->scale.scale_factor * r->scale.scale_factor;
  }
  const double mc_std = std::sqrt((sum2 - sum * sum / draws) / (draws - 1));
  std::cout << "u(s) own " << report->u_scale_factor_own << ", shared " << report->u_scale_factor_shared
            << " (" << report->shared_components << " components); Monte Carlo of the shared part "
            << mc_std << "\n";
  EXPECT_NEAR(mc_std / report->u_scale_factor_shared, 1.0, 0.15);
  // The JSON report carries both parts and the variance components.
  const nlohmann::json doc = nlohmann::json::parse(report->ToJson());
  EXPECT_DOUBLE_EQ(doc.at("u_scale_factor_shared").get<double>(), report->u_scale_factor_shared);
  EXPECT_DOUBLE_EQ(doc.at("u_scale_factor_own").get<double>(), report->u_scale_factor_own);
  EXPECT_DOUBLE_EQ(doc.at("tag_variance_factor").get<double>(),
                   report->front_end.tag_variance_factor);
  EXPECT_DOUBLE_EQ(doc.at("spot_extra_sigma_px").get<double>(),
                   report->front_end.spot_extra_sigma_px);
  std::filesystem::remove_all(dir);
}

// Both lasers on in every photograph (issue 6: "both grids in one image must
// also work"): the two grids of the side-by-side prototype interleave on the
// wall (55 mm apart at a ~101 mm pitch), are matched as one exposure group
// and told apart by the identification alone. Noise-free render.
TEST(MeasureScaleFromImages, BothGridsInOneImage) {
  Scene scene = NoiseFreeSmallScene();
  std::vector<SceneShot> shots;
  for (const SceneShot& shot : scene.shots) {
    if (shot.lasers != std::vector<std::string>{"A"}) continue;
    SceneShot both = shot;
    both.lasers = {"A", "B"};
    both.file = shot.camera + "_AB.png";
    shots.push_back(both);
  }
  ASSERT_EQ(shots.size(), 4u);
  scene.shots = shots;
  const std::filesystem::path dir = FreshTempDir("measure_images_both");
  const SceneRenderer truth = RenderAll(scene, dir);
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ASSERT_TRUE(calibration.ok());
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  Result<ImageMeasureReport> report =
      MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  std::cout << report->ToText();
  ASSERT_EQ(report->front_end.groups.size(), 1u);
  ASSERT_EQ(report->identification.size(), 1u);
  for (const IdentifiedSource& source : report->identification[0].sources) {
    EXPECT_EQ(source.outcome, IdentifyOutcome::kFound) << source.name << ": " << source.detail;
  }
  // Every assigned spot is the right one: its measured point lies on its
  // own true point after the truth fit (a wrong beam is >= 46 mm off).
  const test::TruthFit fit = test::FitToTruth(*report, truth);
  std::cout.precision(10);
  std::cout << "truth fit: " << fit.points << " spots, scale " << fit.scale << ", rms "
            << fit.rms_mm << " mm; s = " << report->measure.scale.scale_factor << " +- "
            << report->measure.scale.u_scale_factor << "\n";
  EXPECT_GE(fit.points, 200);
  EXPECT_LT(fit.rms_mm, 0.05);
  EXPECT_LT(std::abs(report->measure.scale.scale_factor / fit.scale - 1.0), 2e-5);
  std::filesystem::remove_all(dir);
}

TEST(MeasureScaleFromImages, BadInputNamesTheFile) {
  Scene scene = SmallScene();
  const std::filesystem::path dir = FreshTempDir("measure_images_bad");
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ASSERT_TRUE(calibration.ok());
  // Missing images.
  Result<ImageMeasureReport> r = MeasureScaleFromImages(scene, dir.string(), *calibration);
  EXPECT_EQ(r.status().code(), StatusCode::kIoError);
  EXPECT_NE(r.status().message().find(scene.shots[0].file + ": no such image"), std::string::npos)
      << r.status().message();
  // Images of the wrong size.
  const CameraIntrinsics& k = scene.cameras[0].intrinsics;
  for (const SceneShot& shot : scene.shots) {
    cv::imwrite((dir / shot.file).string(), cv::Mat(k.height_px / 2, k.width_px, CV_8UC1, cv::Scalar(60)));
  }
  r = MeasureScaleFromImages(scene, dir.string(), *calibration);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("is " + std::to_string(k.width_px) + " x " +
                                      std::to_string(k.height_px / 2) + " but camera"),
            std::string::npos)
      << r.status().message();
  // Blank images: no tags.
  for (const SceneShot& shot : scene.shots) {
    const CameraIntrinsics& kk = scene.FindCamera(shot.camera)->intrinsics;
    cv::imwrite((dir / shot.file).string(), cv::Mat(kk.height_px, kk.width_px, CV_8UC1, cv::Scalar(60)));
  }
  r = MeasureScaleFromImages(scene, dir.string(), *calibration);
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
  EXPECT_EQ(r.status().message(), "no tag (tag36h11) was found in any of the " +
                                      std::to_string(scene.shots.size()) + " images");
  // Not an image.
  {
    std::ofstream(dir / scene.shots[1].file) << "not a png";
  }
  r = MeasureScaleFromImages(scene, dir.string(), *calibration);
  EXPECT_EQ(r.status().code(), StatusCode::kIoError);
  EXPECT_NE(r.status().message().find(scene.shots[1].file + ": cannot read the image"),
            std::string::npos)
      << r.status().message();
  // Too few shots.
  scene.shots.resize(1);
  r = MeasureScaleFromImages(scene, dir.string(), *calibration);
  EXPECT_EQ(r.status().message(), "scene: 1 shot(s); at least two images are needed");
  std::filesystem::remove_all(dir);
}

// Two module placements (issue 20; examples/scene_small_placements.json):
// each grid is identified and located at each placement, the scale combines
// both, and the projector adjustment poses the module once per placement.
// Noise-free render: both paths agree with the truth fit.
TEST(MeasureScaleFromImages, ModuleAtTwoPlacements) {
  Result<Scene> read = ReadSceneJson(SourceDir() + "/examples/scene_small_placements.json");
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  const Scene scene = NoiseFree(*read);
  const std::filesystem::path dir = FreshTempDir("measure_images_placements");
  const SceneRenderer truth = RenderAll(scene, dir);
  Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
  ASSERT_TRUE(calibration.ok());
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  options.front_end.scale_in_adjustment = true;
  Result<ImageMeasureReport> report = MeasureScaleFromImages(scene, dir.string(), *calibration, options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  std::cout << report->ToText();
  // Four groups (two lasers x two placements), four located sources, one
  // length per placement.
  ASSERT_EQ(report->front_end.groups.size(), 4u);
  const MeasureReport& m = report->measure;
  ASSERT_EQ(m.sources.size(), 4u);
  ASSERT_EQ(m.source_placements.size(), 4u);
  EXPECT_EQ(m.source_placements[0], "centre");
  EXPECT_EQ(m.source_placements[3], "aside");
  ASSERT_EQ(m.scale.lengths.size(), 2u);
  EXPECT_EQ(m.scale.lengths[0].placement, "centre");
  EXPECT_EQ(m.scale.lengths[1].placement, "aside");
  EXPECT_TRUE(report->metadata_conflicts.empty());
  // The located origins of the second placement are the first's moved by
  // the placement's motion (relative to the unscaled scene: compare the
  // baseline's direction, which a similarity keeps).
  const Rigid3d move = scene.module_placements[1].SceneFromDesign(*scene.module);
  const Eigen::Vector3d base_centre = m.sources[1].second.scene_from_source.translation -
                                      m.sources[0].second.scene_from_source.translation;
  const Eigen::Vector3d base_aside = m.sources[3].second.scene_from_source.translation -
                                     m.sources[2].second.scene_from_source.translation;
  const double turn = std::acos(std::clamp(base_centre.normalized().dot(base_aside.normalized()), -1.0, 1.0));
  EXPECT_NEAR(turn * 180.0 / M_PI, Eigen::AngleAxisd(move.rotation).angle() * 180.0 / M_PI, 0.5);
  const test::TruthFit fit = test::FitToTruth(*report, truth);
  std::cout.precision(10);
  std::cout << "truth fit: " << fit.points << " spots (both placements), scale " << fit.scale
            << ", rms " << fit.rms_mm << " mm; s = " << m.scale.scale_factor << " +- "
            << m.scale.u_scale_factor << "; lengths: " << m.scale.lengths[0].scale << ", "
            << m.scale.lengths[1].scale << "\n";
  EXPECT_GE(fit.points, 400);
  EXPECT_EQ(fit.wrong, 0);
  EXPECT_LT(std::abs(m.scale.scale_factor / fit.scale - 1.0), 5e-5);
  ASSERT_TRUE(report->projector.has_value());
  ASSERT_EQ(report->projector->scene_from_module.size(), 2u);
  std::cout << "projector: s = " << report->projector->scale_factor << " +- "
            << report->projector->u_scale_factor << "\n";
  EXPECT_LT(std::abs(report->projector->scale_factor / fit.scale - 1.0), 5e-5);
  // The JSON names the placements.
  const nlohmann::json doc = nlohmann::json::parse(report->ToJson());
  EXPECT_EQ(doc.at("measure").at("sources").at(2).at("placement").get<std::string>(), "aside");
  EXPECT_EQ(doc.at("measure").at("lengths").at(1).at("placement").get<std::string>(), "aside");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace opl
