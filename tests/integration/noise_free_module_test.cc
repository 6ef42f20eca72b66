// The foundation issue's noise-free acceptance test, through the simulation and
// the measure pipeline: for random module poses (any rotation), every surface
// model a measurement can land on, both pattern models, three sources, 30% of
// spots missing, no starting guess: origins within 1e-6 mm, rotations within
// 1e-9 rad, s within 1e-8 relative. The scene is also rescaled by an arbitrary
// factor (an unscaled photogrammetry frame), so s must come out as its inverse.
// (The list-of-planes surface is for calibration sessions: one spot per beam
// and plane, which a measurement does not take; it is covered by tests/sim.)
#include <random>

#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/pipeline/measure.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_spots.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

Surface SurfaceOfType(SurfaceType type) {
  switch (type) {
    case SurfaceType::kPlane:
      return PlaneSurface{Eigen::Vector3d(1000, 0, 0), Eigen::Vector3d(-1, 0.2, 0.1)};
    case SurfaceType::kSphere:
      return SphereSurface{Eigen::Vector3d(1600, 0, 0), 700.0};
    case SurfaceType::kBoxCorner: {
      // A room corner 1.2 m ahead, its open octant facing the module.
      const Eigen::Matrix3d B =
          Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(1, 1, 1).normalized(), -Eigen::Vector3d::UnitX())
              .toRotationMatrix();
      return BoxCornerSurface{Eigen::Vector3d(1200, 0, 0), B};
    }
    case SurfaceType::kParaboloid:
      return ParaboloidSurface{Eigen::Vector3d(1000, 0, 0), Eigen::Vector3d(-1, 0, 0), 1.0 / 1500.0};
    case SurfaceType::kPlanes:
      break;
  }
  return Surface();
}

ModuleDesign ThreeSourceDesign(PatternModel model, SurfaceType surface) {
  ModuleDesign design;
  const double toe = 0.03;  // each source slightly rotated in the module
  design.sources = {
      {"A", 11, 29.0, model, 658.0, "", Rigid3d(RotationFromXyzAnglesRad({0.01, toe, -toe}), Eigen::Vector3d(0, 27.5, 0))},
      {"B", 11, 29.0, model, 658.0, "", Rigid3d(RotationFromXyzAnglesRad({-0.02, 0.0, toe}), Eigen::Vector3d(0, -27.5, 0))},
      {"C", 9, 24.0, model, 658.0, "", Rigid3d(RotationFromXyzAnglesRad({0.0, -toe, 0.0}), Eigen::Vector3d(39, 0, 39))},
  };
  design.surface = SurfaceOfType(surface);
  return design;
}

struct Case {
  PatternModel model;
  SurfaceType surface;
};

class NoiseFreeModule : public ::testing::TestWithParam<Case> {};

TEST_P(NoiseFreeModule, ExactPosesAndScale) {
  const Case c = GetParam();
  const ModuleDesign module_frame = ThreeSourceDesign(c.model, c.surface);
  ASSERT_TRUE(module_frame.Validate().ok()) << module_frame.Validate().ToString();
  auto calibration = ExactCalibration(module_frame);
  ASSERT_TRUE(calibration.ok()) << calibration.status().ToString();

  std::mt19937_64 rng(61 + 7 * static_cast<int>(c.surface) + static_cast<int>(c.model));
  std::uniform_real_distribution<double> u(-2000.0, 2000.0), scale(0.2, 5.0);
  double worst_origin_mm = 0, worst_rot = 0, worst_s = 0;
  for (int trial = 0; trial < 25; ++trial) {
    const Rigid3d scene_from_module(test::RandomRotation(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)));
    const ModuleDesign design = module_frame.Transformed(scene_from_module);
    SpotSimulationOptions sim;
    sim.seed = 1000 + trial;
    sim.missing_fraction = 0.3;
    sim.attach_covariance = false;
    auto simulated = SimulateSpots(design, sim);
    ASSERT_TRUE(simulated.ok()) << simulated.status().ToString();
    // Unscaled scene: every coordinate times k (scene units = mm * k).
    const double k = scale(rng);
    std::vector<Spot> spots = SpotsOf(*simulated);
    for (Spot& s : spots) s.observation.point_in_scene *= k;

    auto report = MeasureScale(*calibration, spots, MeasureOptions());
    ASSERT_TRUE(report.ok()) << report.status().ToString();
    ASSERT_EQ(report->sources.size(), 3u);
    for (const auto& [name, located] : report->sources) {
      const SourceDesign* truth = design.FindSource(name);
      ASSERT_NE(truth, nullptr);
      worst_origin_mm = std::max(worst_origin_mm,
          (located.scene_from_source.translation / k - truth->scene_from_source.translation).norm());
      worst_rot = std::max(worst_rot, RotationAngleBetweenRad(located.scene_from_source.RotationMatrix(),
                                                              truth->scene_from_source.RotationMatrix()));
      EXPECT_TRUE(located.OutlierBeamIds().empty());
    }
    worst_s = std::max(worst_s, std::abs(report->scale.scale_factor * k - 1.0));
  }
  EXPECT_LT(worst_origin_mm, 1e-6);
  EXPECT_LT(worst_rot, 1e-9);
  EXPECT_LT(worst_s, 1e-8);
  RecordProperty("worst_origin_mm", std::to_string(worst_origin_mm));
}

INSTANTIATE_TEST_SUITE_P(
    EverySurfaceBothPatterns, NoiseFreeModule,
    ::testing::Values(Case{PatternModel::kEqualAngle, SurfaceType::kPlane},
                      Case{PatternModel::kEqualAngle, SurfaceType::kSphere},
                      Case{PatternModel::kEqualAngle, SurfaceType::kBoxCorner},
                      Case{PatternModel::kEqualAngle, SurfaceType::kParaboloid},
                      Case{PatternModel::kGrating, SurfaceType::kPlane},
                      Case{PatternModel::kGrating, SurfaceType::kSphere},
                      Case{PatternModel::kGrating, SurfaceType::kBoxCorner},
                      Case{PatternModel::kGrating, SurfaceType::kParaboloid}));

}  // namespace
}  // namespace opl
