#include "opl/sim/simulate_spots.h"

#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <unistd.h>

#include "opl/geometry/rotation.h"
#include "support/prototype_design.h"
#include "opl/geometry/spherical.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;

using test::Prototype;
using test::Source;

// Angle between the ray of the spot's beam and the direction from the source
// origin to `point`, computed from the pattern independently of the simulator.
double AngleFromBeamRad(const ModuleDesign& d, const std::string& source, int beam_id,
                        const Vec3& point) {
  const SourceDesign* s = d.FindSource(source);
  const BeamPattern p = *MakePattern(*s);
  const Vec3 q = s->scene_from_source.Inverse() * point;  // in the source frame
  const Vec3 b = DirectionFromAzElRad(p.Find(beam_id)->az_rad, p.Find(beam_id)->el_rad);
  return std::atan2(q.cross(b).norm(), q.dot(b));
}

TEST(SimulateSpots, NoiseFreeSpotsLieOnTheirRayAndOnTheSurface) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  d.sources[1].pattern = PatternModel::kGrating;
  d.sources[0].scene_from_source =
      Rigid3d(RotationFromXyzAnglesRad({0.05, -0.1, 0.2}), Vec3(3, 27.5, -4));
  const auto spots = SimulateSpots(d, SpotSimulationOptions{});
  ASSERT_TRUE(spots.ok()) << spots.status().ToString();
  ASSERT_EQ(spots->size(), 242u);  // every beam of both sources hits the screen
  double worst_angle = 0.0, worst_surface = 0.0;
  std::set<std::pair<std::string, int>> seen;
  for (const SimulatedSpot& s : *spots) {
    EXPECT_EQ(s.spot.where, "simulated");
    EXPECT_EQ(s.slice, 0);
    EXPECT_FALSE(s.outlier);
    EXPECT_EQ(s.spot.observation.point_in_scene, s.true_point_in_scene);
    ASSERT_TRUE(s.spot.observation.cov_in_scene.has_value());
    EXPECT_TRUE(s.spot.observation.cov_in_scene->isZero());
    EXPECT_TRUE(seen.insert({s.spot.source, s.spot.observation.beam_id}).second);
    worst_angle = std::max(worst_angle, AngleFromBeamRad(d, s.spot.source,
                                                         s.spot.observation.beam_id,
                                                         s.spot.observation.point_in_scene));
    worst_surface = std::max(worst_surface, std::abs(s.true_point_in_scene.x() - 1000.0));
  }
  EXPECT_LT(worst_angle, 1e-12);
  EXPECT_LT(worst_surface, 1e-9);
  // Order: source A beams 1..121, then B.
  EXPECT_EQ((*spots)[0].spot.source, "A");
  EXPECT_EQ((*spots)[0].spot.observation.beam_id, 1);
  EXPECT_EQ((*spots)[241].spot.source, "B");
  EXPECT_EQ((*spots)[241].spot.observation.beam_id, 121);
  // Central beam of B (at y = -27.5) lands straight ahead.
  EXPECT_TRUE((*spots)[121 + 60].true_point_in_scene.isApprox(Vec3(1000, -27.5, 0), 1e-15));
  // B is a grating here: beam 66 (k_y = sin 14.5 deg, k_z = 0) lands at
  // y = -27.5 + 1000 tan(14.5 deg); beam 1 at (y, z) = 1000 (k_y, k_z) / k_x.
  const double sh = std::sin(14.5 * 3.14159265358979323846 / 180);
  EXPECT_NEAR((*spots)[121 + 65].true_point_in_scene.y(), -27.5 + 1000 * sh / std::sqrt(1 - sh * sh),
              1e-9);
  const double kx1 = std::sqrt(1 - 2 * sh * sh);
  EXPECT_NEAR((*spots)[121].true_point_in_scene.y(), -27.5 - 1000 * sh / kx1, 1e-9);
  EXPECT_NEAR((*spots)[121].true_point_in_scene.z(), 1000 * sh / kx1, 1e-9);
}

TEST(SimulateSpots, SlicesOfAPlaneList) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  PlaneListSurface list;
  for (double x : {750.0, 900.0, 1050.0, 1200.0, 1350.0}) {
    list.planes.push_back({Vec3(x, 0, 0), Vec3(-1, 0, 0)});
  }
  d.surface = list;
  const auto spots = SimulateSpots(d, {});
  ASSERT_TRUE(spots.ok());
  ASSERT_EQ(spots->size(), 5u * 242u);
  std::map<int, int> per_slice;
  for (const SimulatedSpot& s : *spots) {
    ++per_slice[s.slice];
    EXPECT_NEAR(s.true_point_in_scene.x(), 750.0 + 150.0 * s.slice, 1e-9);
    EXPECT_LT(AngleFromBeamRad(d, s.spot.source, s.spot.observation.beam_id, s.true_point_in_scene),
              1e-12);
  }
  for (int k = 0; k < 5; ++k) EXPECT_EQ(per_slice[k], 242);
  // Order: source, then slice, then beam.
  EXPECT_EQ((*spots)[121].spot.source, "A");
  EXPECT_EQ((*spots)[121].slice, 1);
  EXPECT_EQ((*spots)[121].spot.observation.beam_id, 1);
}

TEST(SimulateSpots, BeamsMissingTheSurfaceAreSkipped) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  // A small sphere ahead of A catches only the beams near the central one.
  d.surface = SphereSurface{Vec3(1000, 27.5, 0), 100.0};
  const auto spots = SimulateSpots(d, {});
  ASSERT_TRUE(spots.ok());
  // Beams of A within asin(100/1000) = 5.74 deg of the axis (the sphere's
  // angular radius seen from A) hit it; theta0 = 2.9 deg, so the central 3 x 3.
  const BeamPattern p = MakeEqualAnglePattern(11, 29.0 * 3.14159265358979323846 / 180);
  int expected_a = 0;
  for (const Beam& b : p.beams()) {
    if (std::acos(b.DirectionInSource().x()) < std::asin(0.1)) ++expected_a;
  }
  int got_a = 0;
  for (const SimulatedSpot& s : *spots) got_a += s.spot.source == "A";
  EXPECT_EQ(got_a, expected_a);
  EXPECT_EQ(expected_a, 9);  // 2 theta0 = 5.8 deg is just outside
  // Nothing hits a plane behind the module.
  d.surface = PlaneSurface{Vec3(-1000, 0, 0), Vec3(1, 0, 0)};
  const auto none = SimulateSpots(d, {});
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.status().code(), StatusCode::kNoSolution);
  EXPECT_EQ(none.status().message(), "no beam of any source hits the surface (plane)");
}

TEST(SimulateSpots, EmpiricalNoiseCovarianceMatchesTheModel) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm = Vec3(0.110, 0.073, 0.040);
  d.noise_frame_rotation = RotationFromXyzAnglesRad({0.3, -0.5, 0.9});
  PlaneListSurface list;
  for (int k = 0; k < 60; ++k) list.planes.push_back({Vec3(700 + 10 * k, 0, 0), Vec3(-1, 0, 0)});
  d.surface = list;
  SpotSimulationOptions options;
  options.seed = 42;
  const auto spots = SimulateSpots(d, options);
  ASSERT_TRUE(spots.ok());
  const size_t n = spots->size();
  ASSERT_EQ(n, 60u * 242u);  // 14520 samples
  const Eigen::Matrix3d C = d.SpotCovarianceMm2();
  Vec3 mean = Vec3::Zero();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (const SimulatedSpot& s : *spots) {
    const Vec3 e = s.spot.observation.point_in_scene - s.true_point_in_scene;
    mean += e;
    S += e * e.transpose();
    ASSERT_TRUE(s.spot.observation.cov_in_scene.has_value());
    EXPECT_EQ(*s.spot.observation.cov_in_scene, C);
  }
  mean /= static_cast<double>(n);
  S /= static_cast<double>(n);
  // Whitened: L^-1 S L^-T should be I; each entry has standard error ~ sqrt(2/n) = 1.2%.
  const Eigen::Matrix3d L = C.llt().matrixL();
  const Eigen::Matrix3d W = L.triangularView<Eigen::Lower>().solve(
      L.triangularView<Eigen::Lower>().solve(S).transpose());
  EXPECT_LT((W - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 0.04) << W;
  // Per noise axis: sigma recovered within 2%.
  const Eigen::Matrix3d S_noise = d.noise_frame_rotation.transpose() * S * d.noise_frame_rotation;
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(std::sqrt(S_noise(k, k)) / d.spot_noise_mm[k], 1.0, 0.02) << k;
  }
  // Mean within 4 standard errors.
  const Vec3 whitened_mean = L.triangularView<Eigen::Lower>().solve(mean);
  EXPECT_LT(whitened_mean.cwiseAbs().maxCoeff(), 4.0 / std::sqrt(static_cast<double>(n)));

  options.attach_covariance = false;
  const auto bare = SimulateSpots(d, options);
  ASSERT_TRUE(bare.ok());
  EXPECT_FALSE((*bare)[0].spot.observation.cov_in_scene.has_value());
  EXPECT_EQ((*bare)[7].spot.observation.point_in_scene, (*spots)[7].spot.observation.point_in_scene);
}

TEST(SimulateSpots, MissingAndOutlierCountsAreExact) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  SpotSimulationOptions options;
  options.missing_fraction = 0.3;  // round(0.3 * 242) = round(72.6) = 73 dropped
  options.outlier_fraction = 0.1;  // round(0.1 * 169) = round(16.9) = 17 outliers
  options.outlier_distance_mm = 5.0;
  const auto spots = SimulateSpots(d, options);
  ASSERT_TRUE(spots.ok());
  EXPECT_EQ(spots->size(), 169u);
  int outliers = 0;
  for (const SimulatedSpot& s : *spots) {
    const Vec3 e = s.spot.observation.point_in_scene - s.true_point_in_scene;
    if (!s.outlier) {
      EXPECT_EQ(e.norm(), 0.0);
      continue;
    }
    ++outliers;
    // Exactly 5 mm, perpendicular to the ray from the source origin.
    const Vec3 ray = (s.true_point_in_scene -
                      d.FindSource(s.spot.source)->scene_from_source.translation)
                         .normalized();
    EXPECT_NEAR(e.norm(), 5.0, 1e-12);
    EXPECT_NEAR(e.dot(ray), 0.0, 1e-12);
    // Hence an angular outlier: about 5 mm / ~1 m = ~5 mrad off its beam.
    const double angle = AngleFromBeamRad(d, s.spot.source, s.spot.observation.beam_id,
                                          s.spot.observation.point_in_scene);
    EXPECT_GT(angle, 4e-3);
    EXPECT_LT(angle, 5.1e-3);
  }
  EXPECT_EQ(outliers, 17);

  // Half fractions round half away from zero: 0.5 * 242 = 121 exactly; 1.0 drops all.
  options.outlier_fraction = 0.0;
  options.missing_fraction = 0.5;
  EXPECT_EQ(SimulateSpots(d, options)->size(), 121u);
  options.missing_fraction = 1.0;
  EXPECT_EQ(SimulateSpots(d, options)->size(), 0u);
  options.missing_fraction = 0.0;
  options.outlier_fraction = 1.0;
  const auto all_out = SimulateSpots(d, options);
  int n_out = 0;
  for (const SimulatedSpot& s : *all_out) n_out += s.outlier;
  EXPECT_EQ(n_out, 242);
}

TEST(SimulateSpots, OutlierDirectionsAreSpreadAroundTheRay) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  SpotSimulationOptions options;
  options.outlier_fraction = 1.0;
  const auto spots = SimulateSpots(d, options);
  ASSERT_TRUE(spots.ok());
  // On the screen x = 1000 near the centre, the offsets' (y, z) directions
  // should cover all quadrants roughly equally.
  int quadrant[4] = {0, 0, 0, 0};
  for (const SimulatedSpot& s : *spots) {
    const Vec3 e = s.spot.observation.point_in_scene - s.true_point_in_scene;
    ++quadrant[(e.y() > 0 ? 1 : 0) + (e.z() > 0 ? 2 : 0)];
  }
  for (int q : quadrant) {
    EXPECT_GT(q, 35);
    EXPECT_LT(q, 85);
  }
}

TEST(SimulateSpots, SeedDeterminesTheOutput) {
  const ModuleDesign d = Prototype();
  SpotSimulationOptions options;
  options.missing_fraction = 0.2;
  options.outlier_fraction = 0.05;
  const auto a = SimulateSpots(d, options);
  const auto b = SimulateSpots(d, options);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->size(), b->size());
  for (size_t k = 0; k < a->size(); ++k) {
    EXPECT_EQ((*a)[k].spot.source, (*b)[k].spot.source);
    EXPECT_EQ((*a)[k].spot.observation.beam_id, (*b)[k].spot.observation.beam_id);
    EXPECT_EQ((*a)[k].spot.observation.point_in_scene, (*b)[k].spot.observation.point_in_scene);
    EXPECT_EQ((*a)[k].outlier, (*b)[k].outlier);
  }
  options.seed = 2;
  const auto c = SimulateSpots(d, options);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->size(), a->size());  // counts depend on the fractions only
  int same_beam = 0, same_point = 0;
  for (size_t k = 0; k < a->size(); ++k) {
    same_beam += (*a)[k].spot.observation.beam_id == (*c)[k].spot.observation.beam_id &&
                 (*a)[k].spot.source == (*c)[k].spot.source;
    same_point += (*a)[k].spot.observation.point_in_scene == (*c)[k].spot.observation.point_in_scene;
  }
  EXPECT_LT(same_beam, static_cast<int>(a->size()));  // a different missing set
  EXPECT_EQ(same_point, 0);
}

TEST(SimulateSpots, NoiseOfASpotDoesNotDependOnWhichOthersAreMissing) {
  const ModuleDesign d = Prototype();
  SpotSimulationOptions full;
  full.seed = 9;
  SpotSimulationOptions thinned = full;
  thinned.missing_fraction = 0.6;
  const auto a = SimulateSpots(d, full);
  const auto b = SimulateSpots(d, thinned);
  ASSERT_TRUE(a.ok() && b.ok());
  std::map<std::pair<std::string, int>, Vec3> by_beam;
  for (const SimulatedSpot& s : *a) {
    by_beam[{s.spot.source, s.spot.observation.beam_id}] = s.spot.observation.point_in_scene;
  }
  ASSERT_EQ(b->size(), 97u);  // 242 - round(145.2)
  for (const SimulatedSpot& s : *b) {
    EXPECT_EQ(s.spot.observation.point_in_scene,
              (by_beam[{s.spot.source, s.spot.observation.beam_id}]));
  }
}

TEST(SimulateSpots, TransformedDesignGivesTransformedSpots) {
  ModuleDesign d = Prototype();
  d.surface = SphereSurface{Vec3(1600, 0, 0), 900.0};
  const Rigid3d T(RotationFromXyzAnglesRad({-2.0, 0.7, 1.9}), Vec3(-300, 1200, 50));
  const ModuleDesign m = d.Transformed(T);
  SpotSimulationOptions options;
  options.seed = 5;
  options.missing_fraction = 0.1;
  options.outlier_fraction = 0.1;
  const auto a = SimulateSpots(d, options);
  const auto b = SimulateSpots(m, options);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->size(), b->size());
  for (size_t k = 0; k < a->size(); ++k) {
    EXPECT_EQ((*a)[k].spot.observation.beam_id, (*b)[k].spot.observation.beam_id);
    EXPECT_LT(((*b)[k].true_point_in_scene - T * (*a)[k].true_point_in_scene).norm(), 1e-9);
    // Noise is drawn in the (moved) noise frame, so the noisy points move rigidly too.
    EXPECT_LT(((*b)[k].spot.observation.point_in_scene - T * (*a)[k].spot.observation.point_in_scene)
                  .norm(),
              1e-9);
  }
}

TEST(SimulateSpots, FilePatternSource) {
  ModuleDesign d = Prototype();
  d.spot_noise_mm.setZero();
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("opl_sim_spots_test_" + std::to_string(::getpid()) + ".csv"))
                               .string();
  std::vector<Beam> beams;
  for (int id : {1, 5, 13, 21, 25}) beams.push_back({id, 0.01 * id - 0.13, 0.1 - 0.008 * id, {}});
  ASSERT_TRUE(WritePatternCsv(BeamPattern(5, beams), path).ok());
  d.sources[0].pattern = PatternModel::kFile;
  d.sources[0].pattern_file = path;
  d.sources[0].beams_per_side = 5;
  const auto spots = SimulateSpots(d, {});
  ASSERT_TRUE(spots.ok()) << spots.status().ToString();
  EXPECT_EQ(spots->size(), 5u + 121u);
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ((*spots)[k].spot.observation.beam_id, beams[k].id);
    EXPECT_LT(AngleFromBeamRad(d, "A", beams[k].id, (*spots)[k].true_point_in_scene), 1e-12);
  }
  std::filesystem::remove(path);
}

TEST(SimulateSpots, InvalidOptionsAndDesignsAreErrors) {
  const ModuleDesign d = Prototype();
  SpotSimulationOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.missing_fraction = 1.5;
  EXPECT_EQ(SimulateSpots(d, o).status().message(), "missing_fraction must be in [0, 1], got 1.5");
  o = {};
  o.outlier_fraction = NAN;
  EXPECT_EQ(o.Validate().message(), "outlier_fraction must be in [0, 1], got nan");
  o = {};
  o.outlier_distance_mm = 0.0;
  EXPECT_EQ(o.Validate().message(), "outlier_distance_mm must be finite and > 0, got 0");
  ModuleDesign bad = d;
  bad.sources[0].beams_per_side = 4;
  const auto r = SimulateSpots(bad, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(), "source 'A': beams_per_side must be odd and in [3, 201], got 4");
}

TEST(Random, PortableGeneratorsHaveTheRightMoments) {
  std::mt19937_64 rng(1);
  NormalGenerator normal;
  double s1 = 0, s2 = 0, s4 = 0;
  const int n = 200000;
  for (int k = 0; k < n; ++k) {
    const double z = normal(rng);
    s1 += z;
    s2 += z * z;
    s4 += z * z * z * z;
  }
  EXPECT_NEAR(s1 / n, 0.0, 0.01);
  EXPECT_NEAR(s2 / n, 1.0, 0.01);
  EXPECT_NEAR(s4 / n, 3.0, 0.05);  // Gaussian kurtosis
  int counts[7] = {0};
  for (int k = 0; k < 70000; ++k) ++counts[UniformIndex(7, rng)];
  for (int c : counts) EXPECT_NEAR(c, 10000, 400);
  const auto sample = SampleWithoutReplacement(10, 10, rng);
  EXPECT_EQ(std::set<size_t>(sample.begin(), sample.end()).size(), 10u);
  // Fixed output of a fixed seed (mt19937_64 is specified by the standard).
  std::mt19937_64 fixed(5489u);
  for (int k = 1; k < 10000; ++k) fixed();
  EXPECT_EQ(fixed(), 9981545732273789042ull);  // the standard's check value
}

}  // namespace
}  // namespace opl
