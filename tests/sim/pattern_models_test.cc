#include "opl/sim/pattern_models.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <unistd.h>

#include "opl/geometry/spherical.h"

namespace opl {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

Eigen::Vector3d Dir(const BeamPattern& p, int id) {
  const Beam* b = p.Find(id);
  EXPECT_NE(b, nullptr) << "beam " << id;
  return b == nullptr ? Eigen::Vector3d::Zero() : b->DirectionInSource();
}

std::string TempDir() {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("opl_sim_pattern_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir.string();
}

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(EqualAnglePattern, NumberingConvention) {
  const BeamPattern p = MakeEqualAnglePattern(11, 29.0 * kDeg);
  ASSERT_TRUE(p.Validate().ok());
  EXPECT_EQ(p.beams_per_side(), 11);
  EXPECT_EQ(p.beams().size(), 121u);
  // Beam 1: top row (el > 0), col 0 = smallest Y (az < 0), "top right" from behind.
  EXPECT_DOUBLE_EQ(p.Find(1)->az_rad, -14.5 * kDeg);
  EXPECT_GT(p.Find(1)->el_rad, 0.0);
  EXPECT_EQ(p.Find(61)->az_rad, 0.0);
  EXPECT_EQ(p.Find(61)->el_rad, 0.0);
  EXPECT_DOUBLE_EQ(p.Find(121)->az_rad, 14.5 * kDeg);
  EXPECT_LT(p.Find(121)->el_rad, 0.0);
  // Beam 11: top row, largest Y.
  EXPECT_GT(p.Find(11)->az_rad, 0.0);
  EXPECT_GT(p.Find(11)->el_rad, 0.0);
  // Central row 56..66: el = 0, az increasing; central column 6, 17, ..., 116: az = 0.
  for (int id = 56; id <= 66; ++id) {
    EXPECT_EQ(p.Find(id)->el_rad, 0.0) << id;
    if (id > 56) {
      EXPECT_GT(p.Find(id)->az_rad, p.Find(id - 1)->az_rad);
    }
  }
  for (int id = 6; id <= 116; id += 11) {
    EXPECT_EQ(p.Find(id)->az_rad, 0.0) << id;
    if (id > 6) {
      EXPECT_LT(p.Find(id)->el_rad, p.Find(id - 11)->el_rad);
    }
  }
}

TEST(EqualAnglePattern, SpotsOnTangentLatticeOfAPlaneNormalToCentralBeam) {
  // The defining formula: direction proportional to (1, tan(i theta0), tan(j theta0)).
  for (int n : {3, 5, 11, 21}) {
    const double full = 29.0 * kDeg;
    const double theta0 = full / (n - 1);
    const int m = (n - 1) / 2;
    const BeamPattern p = MakeEqualAnglePattern(n, full);
    ASSERT_EQ(static_cast<int>(p.beams().size()), n * n);
    for (const Beam& b : p.beams()) {
      const int i = BeamCol(b.id, n) - m;
      const int j = m - BeamRow(b.id, n);
      const Eigen::Vector3d v = b.DirectionInSource();
      EXPECT_NEAR(v.y() / v.x(), std::tan(i * theta0), 1e-14) << "n " << n << " beam " << b.id;
      EXPECT_NEAR(v.z() / v.x(), std::tan(j * theta0), 1e-14) << "n " << n << " beam " << b.id;
    }
  }
}

TEST(EqualAnglePattern, NeighbourAnglesAndFullAngle) {
  const double full = 29.0 * kDeg;
  const BeamPattern p = MakeEqualAnglePattern(11, full);
  const double theta0 = full / 10.0;  // 2.9 deg
  for (int c = 0; c < 10; ++c) {
    EXPECT_NEAR(AngleBetween(Dir(p, BeamId(5, c, 11)), Dir(p, BeamId(5, c + 1, 11))), theta0,
                1e-15);
    EXPECT_NEAR(AngleBetween(Dir(p, BeamId(c, 5, 11)), Dir(p, BeamId(c + 1, 5, 11))), theta0,
                1e-15);
  }
  EXPECT_NEAR(AngleBetween(Dir(p, 56), Dir(p, 66)), full, 1e-15);
  EXPECT_NEAR(AngleBetween(Dir(p, 6), Dir(p, 116)), full, 1e-15);
  EXPECT_EQ(p.Find(66)->az_rad, 0.5 * full);  // exactly
  EXPECT_EQ(p.Find(6)->el_rad, 0.5 * full);
  // Off the central lines a flat lattice brings neighbours closer than theta0.
  const double top_row = AngleBetween(Dir(p, 1), Dir(p, 2));
  EXPECT_LT(top_row, theta0 - 1e-4);
  EXPECT_GT(top_row, 0.95 * theta0);
}

TEST(GratingPattern, DirectionCosinesOnSquareLattice) {
  const double full = 29.0 * kDeg, lambda = 658.0;
  const int n = 11, m = 5;
  const BeamPattern p = MakeGratingPattern(n, full, lambda);
  ASSERT_TRUE(p.Validate().ok());
  ASSERT_EQ(p.beams().size(), 121u);
  const double period = GratingPeriodNm(n, full, lambda);
  EXPECT_NEAR(period, 5 * 658.0 / std::sin(14.5 * kDeg), 1e-9);
  EXPECT_NEAR(period, 13140.03, 0.01);  // 3290 nm / 0.250380: hand figure for 11 x 11, 29 deg, 658 nm
  for (const Beam& b : p.beams()) {
    const int i = BeamCol(b.id, n) - m;
    const int j = m - BeamRow(b.id, n);
    const Eigen::Vector3d k = b.DirectionInSource();
    // Grating equation per axis: sin(theta) = order * lambda / period.
    EXPECT_NEAR(k.y(), i * lambda / period, 1e-15) << b.id;
    EXPECT_NEAR(k.z(), j * lambda / period, 1e-15) << b.id;
    EXPECT_GT(k.x(), 0.0);
  }
  // Full angle reached exactly by the central row and column.
  EXPECT_NEAR(p.Find(56)->az_rad, -0.5 * full, 1e-15);
  EXPECT_NEAR(p.Find(66)->az_rad, 0.5 * full, 1e-15);
  EXPECT_NEAR(p.Find(6)->el_rad, 0.5 * full, 1e-15);
  EXPECT_NEAR(AngleBetween(Dir(p, 56), Dir(p, 66)), full, 1e-15);
  EXPECT_EQ(p.Find(61)->az_rad, 0.0);
  EXPECT_EQ(p.Find(61)->el_rad, 0.0);
  // Numbering: beam 1 az < 0, el > 0.
  EXPECT_LT(p.Find(1)->az_rad, 0.0);
  EXPECT_GT(p.Find(1)->el_rad, 0.0);
  // First orders: sin(theta_1) = lambda / period.
  EXPECT_NEAR(std::sin(p.Find(62)->az_rad), lambda / period, 1e-15);
}

TEST(GratingPattern, WavelengthSensitivityMatchesFiniteDifference) {
  const double full = 29.0 * kDeg, lambda = 658.0, h = 0.01;
  for (int n : {3, 11}) {
    const auto d = GratingDAzElDWavelength(n, full, lambda);
    ASSERT_EQ(d.rows(), n * n);
    const BeamPattern plus = MakeGratingPatternAtWavelength(n, full, lambda, lambda + h);
    const BeamPattern minus = MakeGratingPatternAtWavelength(n, full, lambda, lambda - h);
    ASSERT_EQ(static_cast<int>(plus.beams().size()), n * n);
    double max_abs = 0.0;
    for (int id = 1; id <= n * n; ++id) {
      const double daz = (plus.Find(id)->az_rad - minus.Find(id)->az_rad) / (2 * h);
      const double del = (plus.Find(id)->el_rad - minus.Find(id)->el_rad) / (2 * h);
      EXPECT_NEAR(d(id - 1, 0), daz, 1e-11) << "n " << n << " beam " << id;
      EXPECT_NEAR(d(id - 1, 1), del, 1e-11) << "n " << n << " beam " << id;
      max_abs = std::max(max_abs, std::abs(d(id - 1, 0)));
    }
    // Central row's outermost beam: d az / d lambda = tan(half) / lambda (k_z = 0).
    const int m = (n - 1) / 2;
    EXPECT_NEAR(d(BeamId(m, n - 1, n) - 1, 0), std::tan(0.5 * full) / lambda, 1e-15);
    EXPECT_EQ(d(BeamId(m, m, n) - 1, 0), 0.0);
    EXPECT_EQ(d(BeamId(m, m, n) - 1, 1), 0.0);
    EXPECT_GT(max_abs, 3e-4);  // ~0.39 mrad/nm at the corners: not a trivially small number
  }
}

TEST(GratingPattern, AtDesignWavelengthEqualsDesignPattern) {
  const BeamPattern a = MakeGratingPattern(11, 20 * kDeg, 658.0);
  const BeamPattern b = MakeGratingPatternAtWavelength(11, 20 * kDeg, 658.0, 658.0);
  ASSERT_EQ(a.beams().size(), b.beams().size());
  for (size_t k = 0; k < a.beams().size(); ++k) {
    EXPECT_EQ(a.beams()[k].az_rad, b.beams()[k].az_rad);
    EXPECT_EQ(a.beams()[k].el_rad, b.beams()[k].el_rad);
  }
  // A longer wavelength fans the beams out.
  const BeamPattern red = MakeGratingPatternAtWavelength(11, 20 * kDeg, 658.0, 670.0);
  EXPECT_GT(red.Find(66)->az_rad, a.Find(66)->az_rad);
}

TEST(PatternParameters, InvalidGiveEmptyPatternsAndNamedErrors) {
  EXPECT_EQ(MakeEqualAnglePattern(10, 0.5).beams_per_side(), 0);
  EXPECT_FALSE(MakeEqualAnglePattern(10, 0.5).Validate().ok());
  EXPECT_EQ(MakeEqualAnglePattern(1, 0.5).beams_per_side(), 0);
  EXPECT_EQ(MakeEqualAnglePattern(11, 0.0).beams_per_side(), 0);
  EXPECT_EQ(MakeEqualAnglePattern(11, kPi).beams_per_side(), 0);
  EXPECT_EQ(MakeEqualAnglePattern(11, std::nan("")).beams_per_side(), 0);
  EXPECT_EQ(MakeEqualAnglePattern(11, 179 * kDeg).beams_per_side(), 11);
  EXPECT_EQ(MakeGratingPattern(11, 90 * kDeg, 658).beams_per_side(), 0);
  EXPECT_EQ(MakeGratingPattern(11, 89 * kDeg, 658).beams_per_side(), 11);
  EXPECT_EQ(MakeGratingPattern(11, 29 * kDeg, 0.0).beams_per_side(), 0);
  EXPECT_TRUE(std::isnan(GratingPeriodNm(4, 0.5, 658)));
  EXPECT_EQ(GratingDAzElDWavelength(11, 95 * kDeg, 658).rows(), 0);
  // Off-design wavelength that makes corner orders evanescent.
  EXPECT_EQ(MakeGratingPatternAtWavelength(11, 88 * kDeg, 658, 700).beams_per_side(), 0);

  Status st = CheckPatternParameters(PatternModel::kEqualAngle, 10, 0.5, 658);
  EXPECT_EQ(st.message(), "beams_per_side must be odd and in [3, 201], got 10");
  // Issue 19: a grid beyond the limit is refused before anything is allocated.
  EXPECT_EQ(CheckPatternParameters(PatternModel::kEqualAngle, 46341, 0.5, 658).message(),
            "beams_per_side must be odd and in [3, 201], got 46341");
  EXPECT_EQ(MakeEqualAnglePattern(100001, 0.5).beams_per_side(), 0);
  EXPECT_EQ(BeamPattern::Create(46341, {Beam{1, 0.0, 0.0, std::nullopt}}).status().message(),
            "beams_per_side must be odd and in [3, 201], got 46341");
  EXPECT_TRUE(BeamPattern::Create(201, {Beam{40401, 0.0, 0.0, std::nullopt}}).ok());
  EXPECT_EQ(BeamPattern(201, {}).central_beam_id(), 20201);
  EXPECT_EQ(BeamPattern(100001, {}).central_beam_id(), 0);  // was 705132705 (overflow)
  EXPECT_EQ(BeamPattern(100001, {Beam{1, 0.0, 0.0, std::nullopt}}).Find(1), nullptr);
  st = CheckPatternParameters(PatternModel::kGrating, 11, 95 * kDeg, 658);
  EXPECT_NE(st.message().find("< 90 deg"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("got 95 deg"), std::string::npos) << st.message();
  st = CheckPatternParameters(PatternModel::kGrating, 11, 29 * kDeg, -1);
  EXPECT_EQ(st.message(), "wavelength_nm must be finite and > 0, got -1");
  EXPECT_TRUE(CheckPatternParameters(PatternModel::kFile, 0, 0, 0).ok());
  EXPECT_STREQ(PatternModelName(PatternModel::kGrating), "grating");
}

TEST(PatternCsv, RoundTripIsExact) {
  const BeamPattern p = MakeGratingPattern(7, 25 * kDeg, 658.0);
  const std::string path = TempDir() + "/round_trip.csv";
  ASSERT_TRUE(WritePatternCsv(p, path).ok());
  const Result<BeamPattern> q = ReadPatternCsv(path);
  ASSERT_TRUE(q.ok()) << q.status().ToString();
  EXPECT_EQ(q->beams_per_side(), 7);
  ASSERT_EQ(q->beams().size(), p.beams().size());
  for (size_t k = 0; k < p.beams().size(); ++k) {
    EXPECT_EQ(q->beams()[k].id, p.beams()[k].id);
    EXPECT_EQ(q->beams()[k].az_rad, p.beams()[k].az_rad);
    EXPECT_EQ(q->beams()[k].el_rad, p.beams()[k].el_rad);
  }
}

TEST(PatternCsv, ColumnsByNameAnyOrderExtraColumnsMissingBeams) {
  const std::string path = WriteFile("any_order.csv",
                                     "# a pattern from the lab\r\n"
                                     "#beams_per_side:3\r\n"
                                     "\r\n"
                                     "el_rad, note ,id,az_rad\r\n"
                                     "0.1, top-left?, 3, 0.2\r\n"
                                     "0,central,5,0\r\n"
                                     "-0.1,,7,-0.2\r\n");
  const Result<BeamPattern> p = ReadPatternCsv(path);
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_EQ(p->beams_per_side(), 3);
  ASSERT_EQ(p->beams().size(), 3u);
  EXPECT_EQ(p->Find(3)->az_rad, 0.2);
  EXPECT_EQ(p->Find(3)->el_rad, 0.1);
  EXPECT_EQ(p->Find(7)->az_rad, -0.2);
  EXPECT_EQ(p->Find(1), nullptr);
}

void ExpectCsvError(const std::string& text, StatusCode code, const std::string& expected_tail) {
  const std::string path = WriteFile("bad.csv", text);
  const Result<BeamPattern> p = ReadPatternCsv(path);
  ASSERT_FALSE(p.ok()) << text;
  EXPECT_EQ(p.status().code(), code);
  EXPECT_EQ(p.status().message(), path + expected_tail);
}

TEST(PatternCsv, ErrorsNameFileAndLine) {
  const std::string head = "# beams_per_side: 3\nid,az_rad,el_rad\n";
  ExpectCsvError("id,az_rad,el_rad\n1,0,0\n", StatusCode::kParseError,
                 ":1: missing '# beams_per_side: N' line before the header");
  ExpectCsvError("# beams_per_side: 4\n", StatusCode::kParseError,
                 ":1: beams_per_side must be an odd integer in [3, 201], got '4'");
  ExpectCsvError("# beams_per_side: 100001\n", StatusCode::kParseError,
                 ":1: beams_per_side must be an odd integer in [3, 201], got '100001'");
  ExpectCsvError("# beams_per_side 3\n", StatusCode::kParseError,
                 ":1: expected '# beams_per_side: N'");
  ExpectCsvError("# beams_per_side: 3\nid,az,el_rad\n", StatusCode::kParseError,
                 ":2: header lacks column 'az_rad' (expected id,az_rad,el_rad)");
  ExpectCsvError(head + "1,0.1,0\n2,abc,0\n", StatusCode::kParseError,
                 ":4: field 'az_rad': not a finite number: 'abc'");
  ExpectCsvError(head + "1,0.1,1e999\n", StatusCode::kParseError,
                 ":3: field 'el_rad': not a finite number: '1e999'");
  ExpectCsvError(head + "1.5,0.1,0\n", StatusCode::kParseError,
                 ":3: field 'id': not an integer: '1.5'");
  ExpectCsvError(head + "10,0.1,0\n", StatusCode::kParseError,
                 ":3: field 'id': 10 is outside 1..9");
  ExpectCsvError(head + "1,0.1,0\n\n1,0.2,0\n", StatusCode::kParseError,
                 ":5: duplicate beam id 1 (first on line 3)");
  ExpectCsvError(head + "1,0.1\n", StatusCode::kParseError,
                 ":3: expected 3 fields as in the header, got 2");
  ExpectCsvError(head + "1,0.1,1.6\n", StatusCode::kParseError,
                 ":3: field 'el_rad': 1.6 is outside (-pi/2, pi/2)");
  ExpectCsvError(head, StatusCode::kParseError, ": no beams");
  ExpectCsvError("# beams_per_side: 3\n", StatusCode::kParseError,
                 ": no header line 'id,az_rad,el_rad'");
  const Result<BeamPattern> missing = ReadPatternCsv("/nonexistent/dir/pattern.csv");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_EQ(missing.status().message(), "/nonexistent/dir/pattern.csv: cannot open pattern file");
  // Issue 19: a device never ends; a huge file is refused before reading.
  const Result<BeamPattern> zero = ReadPatternCsv("/dev/zero");
  ASSERT_FALSE(zero.ok());
  EXPECT_EQ(zero.status().code(), StatusCode::kIoError);
  EXPECT_EQ(zero.status().message(), "/dev/zero: cannot read pattern file: not a regular file");
  const std::string big = WriteFile("big.csv", "# beams_per_side: 3\n");
  std::filesystem::resize_file(big, kMaxPatternFileBytes + 1);
  EXPECT_EQ(ReadPatternCsv(big).status().message(),
            big + ": cannot read pattern file: 16777217 bytes, more than the 16777216 a pattern "
                  "file may have (201 x 201 beams need a few MB)");
}

}  // namespace
}  // namespace opl
