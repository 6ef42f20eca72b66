#include "opl/sim/module_design.h"

#include <cmath>
#include <filesystem>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <unistd.h>

#include "opl/geometry/rotation.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

using test::Prototype;
using test::Source;

TEST(ModuleDesign, DefaultsAreThePrototype) {
  const SourceDesign s;
  EXPECT_EQ(s.beams_per_side, 11);
  EXPECT_EQ(s.full_angle_deg, 29.0);
  EXPECT_EQ(s.pattern, PatternModel::kEqualAngle);
  EXPECT_EQ(s.wavelength_nm, 658.0);
  const ModuleDesign d = Prototype();
  EXPECT_TRUE(d.Validate().ok()) << d.Validate().ToString();
  EXPECT_EQ(d.surface.type(), SurfaceType::kPlane);  // x = 1000 mm
  EXPECT_TRUE(d.noise_frame_rotation.isIdentity());
}

TEST(ModuleDesign, ValidateNamesSourceAndField) {
  auto message = [](const ModuleDesign& d) { return d.Validate().message(); };
  ModuleDesign d = Prototype();
  d.sources.clear();
  EXPECT_EQ(message(d), "module design has no sources");
  d = Prototype();
  d.sources[1].name = "A";
  EXPECT_EQ(message(d), "duplicate source name 'A'");
  d = Prototype();
  d.sources[0].name = "";
  EXPECT_EQ(message(d), "source 0 has an empty name");
  d = Prototype();
  d.sources[1].beams_per_side = 10;
  EXPECT_EQ(message(d), "source 'B': beams_per_side must be odd and in [3, 201], got 10");
  d = Prototype();
  d.sources[1].full_angle_deg = 0.0;
  EXPECT_EQ(message(d), "source 'B': full angle must be finite, > 0 and < 180 deg, got 0 deg");
  d = Prototype();
  d.sources[0].pattern = PatternModel::kGrating;
  d.sources[0].full_angle_deg = 100.0;
  EXPECT_NE(message(d).find("source 'A': full angle must be finite, > 0 and < 90 deg"),
            std::string::npos);
  d = Prototype();
  d.sources[0].pattern = PatternModel::kFile;
  EXPECT_EQ(message(d), "source 'A': pattern 'file' needs a pattern_file");
  d = Prototype();
  d.sources[0].wavelength_nm = -5;
  EXPECT_EQ(message(d), "source 'A': wavelength_nm must be finite and > 0, got -5");
  d = Prototype();
  d.sources[0].scene_from_source.translation.x() = NAN;
  EXPECT_EQ(message(d), "source 'A': pose is not finite or its quaternion is not unit");
  d = Prototype();
  d.surface = SphereSurface{Eigen::Vector3d::Zero(), -1.0};
  EXPECT_EQ(message(d).rfind("surface (sphere): radius_mm must be finite and > 0", 0), 0u);
  d = Prototype();
  d.spot_noise_mm.y() = -0.1;
  EXPECT_EQ(message(d), "spot_noise_mm must be finite and >= 0, got [0.11, -0.1, 0.073]");
  d = Prototype();
  d.noise_frame_rotation(0, 0) = 2.0;
  EXPECT_EQ(message(d), "noise_frame_rotation is not a proper rotation");
}

TEST(ModuleDesign, SpotCovarianceIsRotatedDiagonal) {
  ModuleDesign d = Prototype();
  d.noise_frame_rotation = RotationZ(0.5 * 3.14159265358979323846);  // noise x -> scene y
  const Eigen::Matrix3d C = d.SpotCovarianceMm2();
  EXPECT_NEAR(C(1, 1), 0.110 * 0.110, 1e-15);
  EXPECT_NEAR(C(0, 0), 0.073 * 0.073, 1e-15);
  EXPECT_NEAR(C(2, 2), 0.073 * 0.073, 1e-15);
  EXPECT_NEAR(C(0, 1), 0.0, 1e-15);
  d.noise_frame_rotation = RotationZ(0.25 * 3.14159265358979323846);  // 45 deg
  const Eigen::Matrix3d C45 = d.SpotCovarianceMm2();
  EXPECT_NEAR(C45(0, 1), 0.5 * (0.110 * 0.110 - 0.073 * 0.073), 1e-15);
}

TEST(ModuleDesign, MakePatternPerModel) {
  SourceDesign s = Source("A", Eigen::Vector3d::Zero());
  Result<BeamPattern> p = MakePattern(s);
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->Find(66)->az_rad, MakeEqualAnglePattern(11, 29 * kDeg).Find(66)->az_rad);
  EXPECT_EQ(p->Find(1)->el_rad, MakeEqualAnglePattern(11, 29 * kDeg).Find(1)->el_rad);
  s.pattern = PatternModel::kGrating;
  s.beams_per_side = 7;
  s.full_angle_deg = 20.0;
  p = MakePattern(s);
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->beams_per_side(), 7);
  EXPECT_EQ(p->Find(1)->el_rad, MakeGratingPattern(7, 20 * kDeg, 658).Find(1)->el_rad);
  s.beams_per_side = 8;
  p = MakePattern(s);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().message(), "source 'A': beams_per_side must be odd and in [3, 201], got 8");

  // A file pattern, and a design that disagrees with it.
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("opl_sim_design_test_" + std::to_string(::getpid()) + ".csv"))
                               .string();
  ASSERT_TRUE(WritePatternCsv(MakeGratingPattern(5, 10 * kDeg, 658), path).ok());
  s.pattern = PatternModel::kFile;
  s.pattern_file = path;
  s.beams_per_side = 5;
  p = MakePattern(s);
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_EQ(p->Find(25)->az_rad, MakeGratingPattern(5, 10 * kDeg, 658).Find(25)->az_rad);
  s.beams_per_side = 11;
  p = MakePattern(s);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().message(),
            "source 'A': " + path + " has beams_per_side 5 but the design says 11");
  s.pattern_file = path + ".missing";
  p = MakePattern(s);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().code(), StatusCode::kIoError);
  EXPECT_EQ(p.status().message(), "source 'A': " + path + ".missing: cannot open pattern file");
  std::filesystem::remove(path);
}

// Fabrication error: fixed per source (seed and name), sigma as asked, the
// central beam exact and the central row level (the calibration gauge).
TEST(ModuleDesign, BeamErrorKeepsTheGaugeAndHasItsSigma) {
  SourceDesign s = Source("A", Eigen::Vector3d::Zero());
  Result<BeamPattern> ideal = MakePattern(s);
  s.beam_error_mrad = 0.5;
  s.beam_error_seed = 7;
  Result<BeamPattern> real = MakePattern(s);
  Result<BeamPattern> again = MakePattern(s);
  ASSERT_TRUE(ideal.ok() && real.ok() && again.ok());
  const int n = 11, central_row = 5;
  double sum_sq = 0.0, level = 0.0;
  int count = 0;
  for (const Beam& b : real->beams()) {
    const Beam* i = ideal->Find(b.id);
    EXPECT_EQ(b.az_rad, again->Find(b.id)->az_rad);  // repeatable
    if (b.id == real->central_beam_id()) {
      EXPECT_EQ(b.az_rad, 0.0);
      EXPECT_EQ(b.el_rad, 0.0);
      continue;
    }
    if (BeamRow(b.id, n) == central_row) level += b.az_rad * b.el_rad;
    sum_sq += (b.az_rad - i->az_rad) * (b.az_rad - i->az_rad) +
              (b.el_rad - i->el_rad) * (b.el_rad - i->el_rad);
    count += 2;
  }
  EXPECT_NEAR(level, 0.0, 1e-18);
  // 240 draws: the RMS is within 15 % of sigma (4.5 standard errors).
  EXPECT_NEAR(std::sqrt(sum_sq / count), 0.5e-3, 0.075e-3);
  // Another name, another element.
  s.name = "B";
  Result<BeamPattern> other = MakePattern(s);
  ASSERT_TRUE(other.ok());
  EXPECT_NE(other->Find(1)->az_rad, real->Find(1)->az_rad);
  s.beam_error_mrad = -1.0;
  ModuleDesign d = Prototype();
  d.sources[1].beam_error_mrad = -1.0;
  EXPECT_EQ(d.Validate().message(),
            "source 'B': beam_error_mrad must be finite, >= 0 and < 100, got -1");
}

TEST(ModuleDesign, ExactCalibrationOfPrototype) {
  const Result<ModuleCalibration> cal = ExactCalibration(Prototype());
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->sources.size(), 2u);
  EXPECT_EQ(cal->sources[0].name, "A");
  EXPECT_EQ(cal->sources[0].pattern.beams().size(), 121u);
  EXPECT_EQ(cal->sources[1].calibration_from_source.translation, Eigen::Vector3d(0, -27.5, 0));
  ASSERT_EQ(cal->separations.size(), 1u);
  EXPECT_EQ(cal->separations[0].from, "A");
  EXPECT_EQ(cal->separations[0].to, "B");
  EXPECT_EQ(cal->separations[0].length_mm, 55.0);
  EXPECT_EQ(cal->separations[0].u_length_mm, 0.0);
  EXPECT_TRUE(cal->Validate().ok());
}

TEST(ModuleDesign, ExactCalibrationOfThreeStaggeredSources) {
  ModuleDesign d = Prototype();
  d.sources = {Source("A", {0, 0, 0}, {0.1, 0.2, 0.3}), Source("B", {39, 39, 0}),
               Source("C", {3, 4, 12})};
  d.sources[2].pattern = PatternModel::kGrating;
  const Result<ModuleCalibration> cal = ExactCalibration(d);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->separations.size(), 3u);
  EXPECT_NEAR(cal->separations[0].length_mm, 39.0 * std::sqrt(2.0), 1e-12);  // A-B
  EXPECT_NEAR(cal->separations[1].length_mm, 13.0, 1e-12);                   // A-C: 3-4-12
  EXPECT_EQ(cal->separations[2].from, "B");
  EXPECT_EQ(cal->separations[2].to, "C");
  EXPECT_TRUE(cal->sources[0].calibration_from_source.RotationMatrix().isApprox(
      RotationFromXyzAnglesRad({0.1, 0.2, 0.3}), 1e-15));
  d.sources[1].full_angle_deg = -1;
  const Result<ModuleCalibration> bad = ExactCalibration(d);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
}

TEST(ModuleDesign, TransformedMovesSourcesSurfaceAndNoiseFrame) {
  ModuleDesign d = Prototype();
  d.sources[0].scene_from_source = Rigid3d(RotationFromXyzAnglesRad({0.0, 0.1, -0.05}),
                                           Eigen::Vector3d(0, 27.5, 0));
  const Rigid3d T(RotationFromXyzAnglesRad({0.4, -1.2, 2.5}), Eigen::Vector3d(100, -2000, 350));
  const ModuleDesign m = d.Transformed(T);
  ASSERT_TRUE(m.Validate().ok());
  for (size_t k = 0; k < d.sources.size(); ++k) {
    EXPECT_TRUE(m.sources[k].scene_from_source.translation.isApprox(
        T * d.sources[k].scene_from_source.translation, 1e-15));
    EXPECT_TRUE(m.sources[k].scene_from_source.RotationMatrix().isApprox(
        T.RotationMatrix() * d.sources[k].scene_from_source.RotationMatrix(), 1e-15));
  }
  // Separations are invariant under a rigid motion.
  EXPECT_NEAR(ExactCalibration(m)->separations[0].length_mm, 55.0, 1e-12);
  // The surface moved with it: the central beam of A still hits it 1000 mm ahead in x.
  const Eigen::Vector3d o = m.sources[1].scene_from_source.translation;
  const Eigen::Vector3d dir = m.sources[1].scene_from_source.rotation * Eigen::Vector3d::UnitX();
  EXPECT_NEAR((*m.surface.IntersectRay(o, dir) - o).norm(), 1000.0, 1e-9);
  EXPECT_TRUE(m.noise_frame_rotation.isApprox(T.RotationMatrix(), 1e-15));
  EXPECT_TRUE(m.SpotCovarianceMm2().isApprox(
      T.RotationMatrix() * d.SpotCovarianceMm2() * T.RotationMatrix().transpose(), 1e-12));
  EXPECT_EQ(m.FindSource("B")->name, "B");
  EXPECT_EQ(m.FindSource("Z"), nullptr);
}

}  // namespace
}  // namespace opl
