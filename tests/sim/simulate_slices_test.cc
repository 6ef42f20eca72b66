#include "opl/sim/simulate_slices.h"

#include <cmath>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "opl/sim/random.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;
using test::Prototype;
using test::Source;
using ::testing::HasSubstr;

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

std::vector<double> Depths() {  // 750:65:1335
  std::vector<double> d;
  for (int k = 0; k < 10; ++k) d.push_back(750.0 + 65.0 * k);
  return d;
}

// Distance of `point` from the ray of (source, beam), computed from the
// pattern and the pose independently of the simulator, mm.
double DistanceFromRayMm(const ModuleDesign& d, const std::string& source, int beam_id,
                         const Vec3& point) {
  const SourceDesign* s = d.FindSource(source);
  const BeamPattern p = *MakePattern(*s);
  const Beam* b = p.Find(beam_id);
  const Vec3 dir = s->scene_from_source.RotationMatrix() * DirectionFromAzElRad(b->az_rad, b->el_rad);
  const Vec3 w = point - s->scene_from_source.translation;
  EXPECT_GT(w.dot(dir), 0.0);  // ahead of the origin
  return w.cross(dir.normalized()).norm();
}

TEST(MeanViewpoint, IsTheMeanOriginCentralBeamAndUp) {
  const Result<ModuleViewpoint> vp = MeanViewpoint(Prototype());
  ASSERT_TRUE(vp.ok()) << vp.status().ToString();
  EXPECT_LT(vp->origin_mm.norm(), 1e-15);
  EXPECT_TRUE(vp->viewing_direction.isApprox(Vec3::UnitX(), 1e-15));
  EXPECT_TRUE(vp->up.isApprox(Vec3::UnitZ(), 1e-15));

  // Two sources toed in by +-10 deg about Z and one pitched: the mean of the
  // central beams, normalised; up perpendicular to it.
  ModuleDesign d = Prototype();
  d.sources = {Source("A", {10, 30, 5}, {0, 0, -10 * kDegToRad}),
               Source("B", {-4, -20, 1}, {0.1, 0.2, 10 * kDegToRad})};
  const Vec3 a = RotationFromXyzAnglesRad({0, 0, -10 * kDegToRad}).col(0);
  const Vec3 b = RotationFromXyzAnglesRad({0.1, 0.2, 10 * kDegToRad}).col(0);
  const Result<ModuleViewpoint> vp2 = MeanViewpoint(d);
  ASSERT_TRUE(vp2.ok());
  EXPECT_TRUE(vp2->origin_mm.isApprox(Vec3(3, 5, 3), 1e-15));
  EXPECT_TRUE(vp2->viewing_direction.isApprox((a + b).normalized(), 1e-15));
  EXPECT_NEAR(vp2->up.norm(), 1.0, 1e-15);
  EXPECT_NEAR(vp2->up.dot(vp2->viewing_direction), 0.0, 1e-15);
  EXPECT_GT(vp2->up.z(), 0.9);

  // Looking in opposite directions: no mean viewing direction.
  d.sources = {Source("A", {0, 0, 0}), Source("B", {0, 0, 0}, {0, 0, 180 * kDegToRad})};
  const Result<ModuleViewpoint> bad = MeanViewpoint(d);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.status().message(), HasSubstr("no mean viewing direction"));
}

TEST(MakeCalibrationScreens, FlatScreensNormalToTheViewAtTheDepths) {
  ScreenSlicesOptions o;
  o.depths_mm = Depths();
  const Result<std::vector<Surface>> screens = MakeCalibrationScreens(Prototype(), o);
  ASSERT_TRUE(screens.ok()) << screens.status().ToString();
  ASSERT_EQ(screens->size(), 10u);
  for (size_t k = 0; k < 10; ++k) {
    const auto* plane = std::get_if<PlaneSurface>(&(*screens)[k].shape());
    ASSERT_NE(plane, nullptr);
    EXPECT_EQ(plane->point_mm, Vec3(750.0 + 65.0 * k, 0, 0));
    EXPECT_LT(plane->normal.normalized().cross(Vec3::UnitX()).norm(), 1e-15);
  }
}

// Geometry of tilted and curved screens, checked against formulas written
// here: prototype (o = 0, v = +X, up = +Z), screen k normal
// (cos t_k, sin t_k, 0) with t_k = +-tilt, through (depth_k, 0, 0).
TEST(SimulateSlices, NoiseFreeSpotsLieOnTheirRayAndOnTheirScreen) {
  for (const double curvature : {0.0, 2e-4, -3e-4}) {
    SCOPED_TRACE("curvature " + std::to_string(curvature));
    ModuleDesign d = Prototype();
    d.spot_noise_mm.setZero();
    d.sources[1].pattern = PatternModel::kGrating;
    ScreenSlicesOptions o;
    o.depths_mm = Depths();
    o.tilt_deg = 7.0;
    o.curvature_per_mm = curvature;
    const Result<std::vector<Surface>> screens = MakeCalibrationScreens(d, o);
    ASSERT_TRUE(screens.ok()) << screens.status().ToString();
    EXPECT_EQ((*screens)[3].type(), curvature == 0.0 ? SurfaceType::kPlane
                                                     : SurfaceType::kParaboloid);
    const Result<std::vector<SimulatedSpot>> spots =
        SimulateSlices(d, *screens, SpotSimulationOptions{});
    ASSERT_TRUE(spots.ok()) << spots.status().ToString();
    ASSERT_EQ(spots->size(), 2420u);  // every beam of both sources on every screen

    double worst_ray = 0.0, worst_screen = 0.0;
    std::map<int, int> per_slice;
    std::set<std::tuple<int, std::string, int>> seen;
    int previous_slice = 0;
    for (const SimulatedSpot& s : *spots) {
      ASSERT_GE(s.slice, 0);
      ASSERT_LT(s.slice, 10);
      EXPECT_GE(s.slice, previous_slice);  // slice 0 first, then 1, ...
      previous_slice = s.slice;
      ++per_slice[s.slice];
      EXPECT_TRUE(seen.insert({s.slice, s.spot.source, s.spot.observation.beam_id}).second);
      EXPECT_FALSE(s.outlier);
      EXPECT_EQ(s.spot.observation.point_in_scene, s.true_point_in_scene);
      const Vec3& p = s.spot.observation.point_in_scene;
      worst_ray = std::max(worst_ray,
                           DistanceFromRayMm(d, s.spot.source, s.spot.observation.beam_id, p));
      const double t = (s.slice % 2 == 0 ? 7.0 : -7.0) * kDegToRad;
      const Vec3 n(std::cos(t), std::sin(t), 0.0);
      const Vec3 w = p - Vec3(o.depths_mm[s.slice], 0, 0);
      const double z = -n.dot(w);  // along the axis -n, towards the module
      const double r2 = w.squaredNorm() - z * z;
      worst_screen = std::max(worst_screen, std::abs(z - 0.5 * curvature * r2));
    }
    EXPECT_LT(worst_ray, 1e-9);
    EXPECT_LT(worst_screen, 1e-9);
    for (int k = 0; k < 10; ++k) EXPECT_EQ(per_slice[k], 242) << "slice " << k;

    // Source A sits at y = +27.5: on a flat screen its central spot is at
    // x = depth - 27.5 tan(t_k) (t_k > 0 turns the normal towards +Y).
    if (curvature == 0.0) {
      for (const SimulatedSpot& s : *spots) {
        if (s.spot.source != "A" || s.spot.observation.beam_id != 61) continue;
        const double t = (s.slice % 2 == 0 ? 7.0 : -7.0) * kDegToRad;
        EXPECT_NEAR(s.true_point_in_scene.x(), o.depths_mm[s.slice] - 27.5 * std::tan(t), 1e-9);
        EXPECT_NEAR(s.true_point_in_scene.y(), 27.5, 1e-12);
      }
    }
  }
}

// A module at an arbitrary pose, with a source at the mean origin: its
// central spot is at distance depth_k from the mean origin along the viewing
// direction, whatever the tilt and curvature.
TEST(SimulateSlices, CentralSpotOfASourceAtTheMeanOriginIsAtTheDepth) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  d.sources.push_back(Source("C", {0, 0, 0}));  // mean origin stays 0
  const Rigid3d T(RotationFromXyzAnglesRad({0.3, -0.2, 1.1}), Vec3(100, -250, 40));
  d = d.Transformed(T);
  const Vec3 o = T.translation;
  const Vec3 v = T.RotationMatrix().col(0);
  for (const double tilt : {0.0, 12.0, -25.0}) {
    for (const double curvature : {0.0, 5e-4, -5e-4}) {
      ScreenSlicesOptions opt;
      opt.depths_mm = {500.0, 1234.5, 3000.0};
      opt.tilt_deg = tilt;
      opt.curvature_per_mm = curvature;
      const Result<std::vector<Surface>> screens = MakeCalibrationScreens(d, opt);
      ASSERT_TRUE(screens.ok());
      const Result<std::vector<SimulatedSpot>> spots = SimulateSlices(d, *screens, {});
      ASSERT_TRUE(spots.ok()) << spots.status().ToString();
      int found = 0;
      for (const SimulatedSpot& s : *spots) {
        if (s.spot.source != "C" || s.spot.observation.beam_id != 61) continue;
        ++found;
        const Vec3 w = s.true_point_in_scene - o;
        EXPECT_NEAR(w.dot(v), opt.depths_mm[s.slice], 1e-9) << tilt << " " << curvature;
        EXPECT_LT(w.cross(v).norm(), 1e-9);
      }
      EXPECT_EQ(found, 3);
    }
  }
}

TEST(SimulateSlices, TiltedScreensAreNotParallelAndAlternate) {
  ScreenSlicesOptions o;
  o.depths_mm = {800, 900, 1000};
  o.tilt_deg = 10.0;
  const Result<std::vector<Surface>> screens = MakeCalibrationScreens(Prototype(), o);
  ASSERT_TRUE(screens.ok());
  std::vector<Vec3> normals;
  for (const Surface& s : *screens) {
    normals.push_back(std::get<PlaneSurface>(s.shape()).normal.normalized());
  }
  // Angle between neighbours: 20 deg; slices 0 and 2 are parallel.
  EXPECT_NEAR(std::acos(std::abs(normals[0].dot(normals[1]))), 20.0 * kDegToRad, 1e-12);
  EXPECT_NEAR(std::abs(normals[0].dot(normals[2])), 1.0, 1e-15);
  // Turned about up = +Z only; + turns the normal's line towards +Y.
  for (const Vec3& n : normals) EXPECT_NEAR(n.z(), 0.0, 1e-15);
  EXPECT_NEAR(std::abs(normals[0].y()), std::sin(10.0 * kDegToRad), 1e-15);
  EXPECT_GT(normals[0].y() * normals[0].x(), 0.0);
  EXPECT_LT(normals[1].y() * normals[1].x(), 0.0);
}

TEST(SimulateSlices, EachSliceIsSimulateSpotsWithItsOwnSeed) {
  ModuleDesign d = Prototype();
  ScreenSlicesOptions so;
  so.depths_mm = Depths();
  so.tilt_deg = 3.0;
  so.curvature_per_mm = 1e-5;
  const std::vector<Surface> screens = *MakeCalibrationScreens(d, so);
  SpotSimulationOptions o;
  o.seed = 42;
  o.missing_fraction = 0.1;
  o.outlier_fraction = 0.02;
  const Result<std::vector<SimulatedSpot>> all = SimulateSlices(d, screens, o);
  ASSERT_TRUE(all.ok()) << all.status().ToString();

  // Per slice: exactly round(0.1 * 242) = 24 missing, round(0.02 * 218) = 4 outliers.
  std::map<int, std::set<std::pair<std::string, int>>> present;
  std::map<int, int> outliers;
  for (const SimulatedSpot& s : *all) {
    present[s.slice].insert({s.spot.source, s.spot.observation.beam_id});
    outliers[s.slice] += s.outlier ? 1 : 0;
  }
  ASSERT_EQ(present.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(present[k].size(), 218u) << "slice " << k;
    EXPECT_EQ(outliers[k], 4) << "slice " << k;
  }
  // Different spots are missing from different slices.
  EXPECT_NE(present[0], present[1]);

  // Slice k alone, from its seed, is the same as in the session.
  size_t offset = 0;
  for (int k = 0; k < 10; ++k) {
    ModuleDesign one = d;
    one.surface = screens[k];
    SpotSimulationOptions ok = o;
    ok.seed = SliceSeed(o.seed, k);
    const Result<std::vector<SimulatedSpot>> alone = SimulateSpots(one, ok);
    ASSERT_TRUE(alone.ok());
    for (const SimulatedSpot& s : *alone) {
      ASSERT_LT(offset, all->size());
      const SimulatedSpot& t = (*all)[offset++];
      EXPECT_EQ(t.slice, k);
      EXPECT_EQ(t.spot.source, s.spot.source);
      EXPECT_EQ(t.spot.observation.beam_id, s.spot.observation.beam_id);
      EXPECT_EQ(t.spot.observation.point_in_scene, s.spot.observation.point_in_scene);
      EXPECT_EQ(t.outlier, s.outlier);
    }
  }
  EXPECT_EQ(offset, all->size());
  // SliceSeed: the stream of SplitMix64(seed).
  SplitMix64 mix(42);
  EXPECT_EQ(SliceSeed(42, 0), mix.Next());
  EXPECT_EQ(SliceSeed(42, 1), mix.Next());
}

TEST(SimulateSlices, SameSeedSameSpotsOtherSeedOtherSpots) {
  ModuleDesign d = Prototype();
  ScreenSlicesOptions so;
  so.depths_mm = Depths();
  const std::vector<Surface> screens = *MakeCalibrationScreens(d, so);
  SpotSimulationOptions o;
  o.missing_fraction = 0.05;
  o.outlier_fraction = 0.01;
  auto run = [&](uint64_t seed) {
    o.seed = seed;
    const Result<std::vector<SimulatedSpot>> r = SimulateSlices(d, screens, o);
    EXPECT_TRUE(r.ok());
    std::vector<std::tuple<int, std::string, int, double, double, double, bool>> key;
    for (const SimulatedSpot& s : *r) {
      const Vec3& p = s.spot.observation.point_in_scene;
      key.emplace_back(s.slice, s.spot.source, s.spot.observation.beam_id, p.x(), p.y(), p.z(),
                       s.outlier);
    }
    return key;
  };
  EXPECT_EQ(run(7), run(7));
  EXPECT_NE(run(7), run(8));
}

TEST(SimulateSlices, SlicesOfAPlaneListAndOfOtherSurfaces) {
  PlaneListSurface list;
  list.planes = {PlaneSurface{Vec3(900, 0, 0), Vec3(-1, 0, 0)},
                 PlaneSurface{Vec3(1100, 0, 0), Vec3(-1, 0.1, 0)}};
  const std::vector<Surface> slices = SlicesOf(list);
  ASSERT_EQ(slices.size(), 2u);
  EXPECT_EQ(std::get<PlaneSurface>(slices[1].shape()).normal, Vec3(-1, 0.1, 0));
  EXPECT_EQ(SlicesOf(SphereSurface{}).size(), 1u);
  EXPECT_EQ(SlicesOf(SphereSurface{}).front().type(), SurfaceType::kSphere);

  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  const Result<std::vector<SimulatedSpot>> spots = SimulateSlices(d, slices, {});
  ASSERT_TRUE(spots.ok());
  ASSERT_EQ(spots->size(), 484u);
  EXPECT_EQ(spots->front().slice, 0);
  EXPECT_NEAR(spots->front().true_point_in_scene.x(), 900.0, 1e-9);
  EXPECT_EQ(spots->back().slice, 1);
}

TEST(SimulateSlices, TheDesignsOwnSurfaceIsNotUsed) {
  ModuleDesign d = Prototype();
  d.surface = PlaneSurface{Vec3(1000, 0, 0), Vec3::Zero()};  // invalid, ignored
  ScreenSlicesOptions o;
  o.depths_mm = {900};
  const Result<std::vector<Surface>> screens = MakeCalibrationScreens(d, o);
  ASSERT_TRUE(screens.ok()) << screens.status().ToString();
  const Result<std::vector<SimulatedSpot>> spots = SimulateSlices(d, *screens, {});
  ASSERT_TRUE(spots.ok()) << spots.status().ToString();
  EXPECT_EQ(spots->size(), 242u);
  // An invalid source is still an error.
  d.sources[1].beams_per_side = 4;
  EXPECT_FALSE(MakeCalibrationScreens(d, o).ok());
  EXPECT_FALSE(SimulateSlices(d, *screens, {}).ok());
}

TEST(SimulateSlices, InvalidInputsAreErrorsNamingTheField) {
  const ModuleDesign d = Prototype();
  auto screens_error = [&](ScreenSlicesOptions o) {
    const Result<std::vector<Surface>> r = MakeCalibrationScreens(d, o);
    EXPECT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    return r.status().message();
  };
  ScreenSlicesOptions o;
  EXPECT_THAT(screens_error(o), HasSubstr("depths_mm is empty"));
  o.depths_mm = {800, -5, 900};
  EXPECT_EQ(screens_error(o), "depths_mm[1] must be finite and > 0, got -5");
  o.depths_mm = {800, 0};
  EXPECT_EQ(screens_error(o), "depths_mm[1] must be finite and > 0, got 0");
  o.depths_mm = {std::nan("")};
  EXPECT_EQ(screens_error(o), "depths_mm[0] must be finite and > 0, got nan");
  o.depths_mm = {800};
  o.tilt_deg = 90;
  EXPECT_EQ(screens_error(o), "tilt_deg must be finite and in (-90, 90), got 90");
  o.tilt_deg = 0;
  o.curvature_per_mm = INFINITY;
  EXPECT_EQ(screens_error(o), "curvature_per_mm must be finite, got inf");

  auto slices_error = [&](const std::vector<Surface>& screens, StatusCode code) {
    const Result<std::vector<SimulatedSpot>> r = SimulateSlices(d, screens, {});
    EXPECT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), code);
    return r.status().message();
  };
  EXPECT_THAT(slices_error({}, StatusCode::kInvalidArgument), HasSubstr("screens is empty"));
  EXPECT_EQ(slices_error({Surface(), PlaneSurface{Vec3(1, 0, 0), Vec3::Zero()}},
                         StatusCode::kInvalidArgument),
            "screens[1]: normal is zero");
  PlaneListSurface two;
  two.planes = {PlaneSurface{}, PlaneSurface{}};
  EXPECT_THAT(slices_error({two}, StatusCode::kInvalidArgument),
              HasSubstr("screens[0] is a list of 2 planes"));
  // A screen behind the module gets no spot.
  EXPECT_EQ(slices_error({Surface(), PlaneSurface{Vec3(-500, 0, 0), Vec3(1, 0, 0)}},
                         StatusCode::kNoSolution),
            "screen 1: no beam of any source hits the surface (plane)");
  SpotSimulationOptions bad;
  bad.missing_fraction = 2;
  const Result<std::vector<SimulatedSpot>> r = SimulateSlices(d, {Surface()}, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "missing_fraction must be in [0, 1], got 2");
}

TEST(ParseDepthList, RangesAndLists) {
  Result<std::vector<double>> r = ParseDepthList("750:65:1335");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(*r, Depths());
  r = ParseDepthList("0.1:0.1:0.3");  // (0.3 - 0.1) / 0.1 = 1.9999999999999998
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->size(), 3u);
  EXPECT_EQ(r->back(), 0.3);
  r = ParseDepthList("750:100:1335");  // 1335 not reached: stops at 1250
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(*r, (std::vector<double>{750, 850, 950, 1050, 1150, 1250}));
  r = ParseDepthList(" 1000 : 5 : 1000 ");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(*r, std::vector<double>{1000});
  r = ParseDepthList("1000");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(*r, std::vector<double>{1000});
  r = ParseDepthList("+880, 750 ,1e3,815.5");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(*r, (std::vector<double>{880, 750, 1000, 815.5}));
  r = ParseDepthList("-5,100");  // the sign is checked by ScreenSlicesOptions
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->front(), -5.0);
}

TEST(ParseDepthList, ErrorsAreOneLineNamingTheText) {
  auto error = [](const std::string& text) {
    const Result<std::vector<double>> r = ParseDepthList(text);
    EXPECT_FALSE(r.ok()) << text;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(r.status().message().find('\n'), std::string::npos);
    return r.status().message();
  };
  EXPECT_THAT(error(""), HasSubstr("empty depth list (expected first:step:last"));
  EXPECT_THAT(error("  "), HasSubstr("empty depth list"));
  EXPECT_THAT(error("750:65"), HasSubstr("depth list '750:65': a range has three fields"));
  EXPECT_THAT(error("750:65:1335:1400"), HasSubstr("a range has three fields"));
  EXPECT_EQ(error("750:0:1335"), "depth list '750:0:1335': step must be > 0, got 0");
  EXPECT_EQ(error("750:-65:1335"), "depth list '750:-65:1335': step must be > 0, got -65");
  EXPECT_EQ(error("1335:65:750"), "depth list '1335:65:750': first (1335) must be <= last (750)");
  EXPECT_EQ(error("750:x:1335"), "depth list '750:x:1335': 'x' is not a finite number");
  EXPECT_EQ(error("750,,880"), "depth list '750,,880': '' is not a finite number");
  EXPECT_EQ(error("750,880,"), "depth list '750,880,': '' is not a finite number");
  EXPECT_EQ(error("750mm"), "depth list '750mm': '750mm' is not a finite number");
  EXPECT_EQ(error("+-5"), "depth list '+-5': '+-5' is not a finite number");
  EXPECT_EQ(error("nan"), "depth list 'nan': 'nan' is not a finite number");
  EXPECT_EQ(error("1,inf"), "depth list '1,inf': 'inf' is not a finite number");
  EXPECT_THAT(error("750:65:1335,1400"), HasSubstr("mixes ':' and ','"));
  EXPECT_THAT(error("1:1e-6:1e9"), HasSubstr("gives more than 10000 depths"));
}

}  // namespace
}  // namespace opl
