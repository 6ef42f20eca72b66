#include "opl/io/module_calibration_json.h"

#include <cmath>
#include <cstring>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io/temp_dir.h"
#include "opl/geometry/rotation.h"
#include "pipeline/synthetic_module.h"

namespace opl {
namespace {

using ::testing::HasSubstr;

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

// A calibration whose numbers do not have short decimal forms.
ModuleCalibration AwkwardCalibration() {
  ModuleCalibration cal = testing_support::SyntheticCalibration(3, 5);
  int k = 1;
  for (SourceCalibration& s : cal.sources) {
    std::vector<Beam> beams = s.pattern.beams();
    beams.erase(beams.begin() + 3);  // a pattern may lack beams
    for (Beam& b : beams) {
      b.az_rad += std::sqrt(2.0) * 1e-5 * k;
      b.el_rad -= 1.0 / (3.0 + k) * 1e-4;
      if (k % 2 == 0) {
        Eigen::Matrix2d C;
        C << 1e-10 / k, 3e-12 / 7.0, 3e-12 / 7.0, 2e-10 / 3.0;
        b.cov_azel_rad2 = C;
      }
      ++k;
    }
    s.pattern = BeamPattern(5, beams);
    s.calibration_from_source.translation += Eigen::Vector3d(M_PI, -M_E, 1.0 / 7.0) * k;
  }
  cal.sources[2].calibration_from_source.translation.z() = -0.0;
  cal.separations = ModuleCalibration::SeparationsFromOrigins(cal.sources);
  cal.separations[0].u_length_mm = 1.0 / 3000.0;
  cal.separations[2].u_length_mm = 0.0;
  return cal;
}

void ExpectBitIdentical(const ModuleCalibration& a, const ModuleCalibration& b) {
  ASSERT_EQ(a.sources.size(), b.sources.size());
  for (size_t i = 0; i < a.sources.size(); ++i) {
    const SourceCalibration& sa = a.sources[i];
    const SourceCalibration& sb = b.sources[i];
    EXPECT_EQ(sa.name, sb.name);
    EXPECT_EQ(sa.pattern.beams_per_side(), sb.pattern.beams_per_side());
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(SameBits(sa.calibration_from_source.translation[k],
                           sb.calibration_from_source.translation[k]));
    }
    for (int k = 0; k < 4; ++k) {
      EXPECT_TRUE(SameBits(sa.calibration_from_source.rotation.coeffs()[k],
                           sb.calibration_from_source.rotation.coeffs()[k]))
          << "source " << i << " quaternion coefficient " << k;
    }
    ASSERT_EQ(sa.pattern.beams().size(), sb.pattern.beams().size());
    for (size_t j = 0; j < sa.pattern.beams().size(); ++j) {
      const Beam& ba = sa.pattern.beams()[j];
      const Beam& bb = sb.pattern.beams()[j];
      EXPECT_EQ(ba.id, bb.id);
      EXPECT_TRUE(SameBits(ba.az_rad, bb.az_rad));
      EXPECT_TRUE(SameBits(ba.el_rad, bb.el_rad));
      ASSERT_EQ(ba.cov_azel_rad2.has_value(), bb.cov_azel_rad2.has_value());
      if (ba.cov_azel_rad2) {
        for (int k = 0; k < 4; ++k) {
          EXPECT_TRUE(SameBits(ba.cov_azel_rad2->data()[k], bb.cov_azel_rad2->data()[k]));
        }
      }
    }
  }
  ASSERT_EQ(a.separations.size(), b.separations.size());
  for (size_t i = 0; i < a.separations.size(); ++i) {
    EXPECT_EQ(a.separations[i].from, b.separations[i].from);
    EXPECT_EQ(a.separations[i].to, b.separations[i].to);
    EXPECT_TRUE(SameBits(a.separations[i].length_mm, b.separations[i].length_mm));
    EXPECT_TRUE(SameBits(a.separations[i].u_length_mm, b.separations[i].u_length_mm));
  }
}

TEST(ModuleCalibrationJson, RoundTripIsBitExact) {
  const ModuleCalibration cal = AwkwardCalibration();
  testing_support::TempDir dir;
  const std::string path = dir.File("cal.json");
  ASSERT_TRUE(WriteModuleCalibrationJson(cal, path).ok());
  Result<ModuleCalibration> back = ReadModuleCalibrationJson(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectBitIdentical(cal, *back);
  // And the file itself is a fixed point: writing what was read gives the same text.
  Result<std::string> again = FormatModuleCalibrationJson(*back);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, testing_support::ReadAll(path));
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"cal.json"});
}

TEST(ModuleCalibrationJson, QualityAndScalingRoundTripBitExact) {
  ModuleCalibration cal = AwkwardCalibration();
  SourceCalibrationQuality q;
  q.slices = 10;
  q.samples_used = 1089;
  q.samples_flagged = 3;
  q.beams_dropped = 1;
  q.rms_residual_urad = 61.0 / 7.0;
  q.variance_factor = 1.0 / 3.0;
  q.mean_point_to_ray_mm = 0.1 / 9.0;
  q.max_point_to_ray_mm = std::sqrt(0.2);
  q.origin_cov_mm2 << 1e-3 / 3, 1e-5, 2e-5, 1e-5, 2e-4 / 7, 0.0, 2e-5, 0.0, M_PI * 1e-4;
  q.rotation_xyz_cov_rad2 = 1e-9 * Eigen::Matrix3d::Identity() / 3.0;
  cal.sources[1].quality = q;
  CalibrationScaling sc;
  sc.from_target = "T,1";
  sc.to_target = "T\"2";
  sc.artifact_length_mm = 1677.66;
  sc.u_artifact_length_mm = 0.005;
  sc.measured_length = 1342.1 / 3.0;
  sc.u_measured_length = 0.01 / 7.0;
  sc.scale = 1677.66 / sc.measured_length;
  sc.u_scale_relative = 1e-5 / 3.0;
  cal.scaling = sc;
  Result<std::string> text = FormatModuleCalibrationJson(cal);
  ASSERT_TRUE(text.ok());
  Result<ModuleCalibration> back = ParseModuleCalibrationJson(*text, "cal.json");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectBitIdentical(cal, *back);
  EXPECT_FALSE(back->sources[0].quality.has_value());
  ASSERT_TRUE(back->sources[1].quality.has_value());
  const SourceCalibrationQuality& r = *back->sources[1].quality;
  EXPECT_EQ(r.slices, 10);
  EXPECT_EQ(r.samples_used, 1089);
  EXPECT_EQ(r.samples_flagged, 3);
  EXPECT_EQ(r.beams_dropped, 1);
  EXPECT_TRUE(SameBits(r.rms_residual_urad, q.rms_residual_urad));
  EXPECT_TRUE(SameBits(r.variance_factor, q.variance_factor));
  EXPECT_TRUE(SameBits(r.mean_point_to_ray_mm, q.mean_point_to_ray_mm));
  EXPECT_TRUE(SameBits(r.max_point_to_ray_mm, q.max_point_to_ray_mm));
  for (int k = 0; k < 9; ++k) {
    EXPECT_TRUE(SameBits(r.origin_cov_mm2.data()[k], q.origin_cov_mm2.data()[k]));
    EXPECT_TRUE(SameBits(r.rotation_xyz_cov_rad2.data()[k], q.rotation_xyz_cov_rad2.data()[k]));
  }
  ASSERT_TRUE(back->scaling.has_value());
  EXPECT_EQ(back->scaling->from_target, "T,1");
  EXPECT_EQ(back->scaling->to_target, "T\"2");
  EXPECT_TRUE(SameBits(back->scaling->scale, sc.scale));
  EXPECT_TRUE(SameBits(back->scaling->u_scale_relative, sc.u_scale_relative));
  EXPECT_TRUE(SameBits(back->scaling->measured_length, sc.measured_length));
  // A bad quality field is named by its path.
  std::string broken = *text;
  broken.replace(broken.find("\"samples_flagged\": 3"), 20, "\"samples_flagged\": -3");
  Result<ModuleCalibration> bad = ParseModuleCalibrationJson(broken, "cal.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message(), "cal.json: sources[1].quality.samples_flagged: must be >= 0, got -3");
}

TEST(ModuleCalibrationJson, WrittenFileHasTheDocumentedLayout) {
  Result<std::string> text = FormatModuleCalibrationJson(testing_support::SyntheticCalibration(2, 3));
  ASSERT_TRUE(text.ok());
  const nlohmann::json j = nlohmann::json::parse(*text);
  EXPECT_EQ(j["format"], "opl.module_calibration");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["units"], "mm");
  ASSERT_EQ(j["sources"].size(), 2u);
  EXPECT_EQ(j["sources"][1]["name"], "B");
  EXPECT_EQ(j["sources"][1]["beams_per_side"], 3);
  EXPECT_EQ(j["sources"][1]["origin_mm"], nlohmann::json::array({0.5, 55.0, -0.25}));
  const std::vector<double> angles = j["sources"][1]["rotation_xyz_rad"];
  EXPECT_NEAR(angles[0], 0.01, 1e-15);
  EXPECT_NEAR(angles[1], -0.02, 1e-15);
  EXPECT_NEAR(angles[2], 0.03, 1e-15);
  EXPECT_EQ(j["sources"][0]["beams"].size(), 9u);
  EXPECT_EQ(j["sources"][0]["beams"][4]["id"], 5);
  EXPECT_EQ(j["sources"][0]["beams"][4]["az_rad"], 0.0);
  EXPECT_EQ(j["separations"][0]["from"], "A");
  EXPECT_EQ(j["separations"][0]["to"], "B");
  EXPECT_EQ(j["separations"][0]["u_length_mm"], 0.002);
  // One beam per line.
  EXPECT_THAT(*text, HasSubstr("\n        {\"id\": 1, \"az_rad\": "));
}

// A minimal hand-written file: no quaternion, rotation from the angles.
const char* kMinimal = R"({
  "format": "opl.module_calibration", "version": 1, "units": "mm",
  "sources": [
    {"name": "A", "beams_per_side": 3, "origin_mm": [1, 2, 3],
     "rotation_xyz_rad": [0.1, -0.2, 0.3],
     "beams": [{"id": 5, "az_rad": 0, "el_rad": 0},
               {"id": 1, "az_rad": -0.05, "el_rad": 0.05,
                "cov_azel_rad2": [[1e-10, 0], [0, 2e-10]]}]},
    {"name": "B", "beams_per_side": 3, "origin_mm": [1, 57, 3],
     "rotation_xyz_rad": [0, 0, 0], "beams": [{"id": 5, "az_rad": 0, "el_rad": 0}]}
  ],
  "separations": [{"from": "A", "to": "B", "length_mm": 55, "u_length_mm": 0.001}]
})";

TEST(ModuleCalibrationJson, ReadsAHandWrittenFile) {
  Result<ModuleCalibration> cal = ParseModuleCalibrationJson(kMinimal, "cal.json");
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->sources.size(), 2u);
  const SourceCalibration& a = cal->sources[0];
  EXPECT_EQ(a.calibration_from_source.translation, Eigen::Vector3d(1, 2, 3));
  const Eigen::Matrix3d R = RotationFromXyzAnglesRad(Eigen::Vector3d(0.1, -0.2, 0.3));
  EXPECT_LT((a.calibration_from_source.RotationMatrix() - R).norm(), 1e-15);
  ASSERT_EQ(a.pattern.beams().size(), 2u);
  ASSERT_NE(a.pattern.Find(1), nullptr);
  EXPECT_EQ(a.pattern.Find(1)->az_rad, -0.05);
  ASSERT_TRUE(a.pattern.Find(1)->cov_azel_rad2.has_value());
  EXPECT_EQ((*a.pattern.Find(1)->cov_azel_rad2)(1, 1), 2e-10);
  EXPECT_FALSE(a.pattern.Find(5)->cov_azel_rad2.has_value());
  EXPECT_EQ(cal->separations[0].length_mm, 55.0);
}

std::string ErrorOf(const std::string& from, const std::string& to) {
  std::string text = kMinimal;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  Result<ModuleCalibration> r = ParseModuleCalibrationJson(text, "cal.json");
  if (r.ok()) return "(parsed)";
  EXPECT_EQ(r.status().code(), StatusCode::kParseError) << r.status().message();
  return r.status().message();
}

TEST(ModuleCalibrationJson, ErrorsNameFileAndFieldPath) {
  EXPECT_EQ(ErrorOf("\"opl.module_calibration\"", "\"opl.module_design\""),
            "cal.json: format: expected \"opl.module_calibration\", got \"opl.module_design\"");
  EXPECT_EQ(ErrorOf("\"version\": 1", "\"version\": 2"),
            "cal.json: version: unsupported version 2 (this build reads 1)");
  EXPECT_EQ(ErrorOf("\"units\": \"mm\"", "\"units\": \"m\""),
            "cal.json: units: expected \"mm\", got \"m\"");
  EXPECT_EQ(ErrorOf("\"beams_per_side\": 3, \"origin_mm\": [1, 57, 3]", "\"beams_per_side\": 3"),
            "cal.json: sources[1].origin_mm: missing");
  EXPECT_EQ(ErrorOf("\"az_rad\": -0.05", "\"az_rad\": \"-0.05\""),
            "cal.json: sources[0].beams[1].az_rad: expected a finite number, got string");
  EXPECT_EQ(ErrorOf("\"origin_mm\": [1, 2, 3]", "\"origin_mm\": [1, 2]"),
            "cal.json: sources[0].origin_mm: expected an array of 3 numbers, got 2 elements");
  EXPECT_EQ(ErrorOf("\"origin_mm\": [1, 2, 3]", "\"origin_mm\": [1, 2, 1e999]"),
            "cal.json: JSON error: number overflow parsing '1e999'");
  EXPECT_EQ(ErrorOf("{\"id\": 1,", "{\"id\": 5,"),
            "cal.json: sources[0].beams[1].id: duplicate beam id 5 (also beams[0])");
  EXPECT_EQ(ErrorOf("{\"id\": 1,", "{\"id\": 10,"),
            "cal.json: sources[0].beams[1].id: beam id 10 is outside 1..9");
  EXPECT_EQ(ErrorOf("{\"id\": 1,", "{\"id\": 1.5,"),
            "cal.json: sources[0].beams[1].id: expected an integer, got 1.5");
  EXPECT_EQ(ErrorOf("\"to\": \"B\"", "\"to\": \"C\""),
            "cal.json: separations[0].to: unknown source 'C'");
  EXPECT_EQ(ErrorOf("\"to\": \"B\"", "\"to\": \"A\""),
            "cal.json: separations[0].to: joins source 'A' to itself");
  EXPECT_EQ(ErrorOf("\"length_mm\": 55", "\"length_mm\": -55"),
            "cal.json: separations[0].length_mm: must be > 0, got -55");
  EXPECT_EQ(ErrorOf("\"name\": \"B\"", "\"name\": \"A\""),
            "cal.json: sources[1].name: duplicate source name 'A' (also sources[0])");
  EXPECT_EQ(ErrorOf("\"beams_per_side\": 3, \"origin_mm\": [1, 2, 3]",
                    "\"beams_per_side\": 4, \"origin_mm\": [1, 2, 3]"),
            "cal.json: sources[0].beams_per_side: must be odd and in [3, 201], got 4");
  // Issue 19: grids beyond 201 x 201 (n^2 overflowed int at 46341).
  for (const char* n : {"203", "46341", "100001"}) {
    EXPECT_EQ(ErrorOf("\"beams_per_side\": 3, \"origin_mm\": [1, 2, 3]",
                      std::string("\"beams_per_side\": ") + n + ", \"origin_mm\": [1, 2, 3]"),
              std::string("cal.json: sources[0].beams_per_side: must be odd and in [3, 201], got ") +
                  n);
  }
  EXPECT_EQ(ErrorOf("[[1e-10, 0], [0, 2e-10]]", "[[1e-10, 0], [0, -2e-10]]"),
            "cal.json: sources[0].beams: beam 1: covariance is not symmetric positive "
            "semi-definite");
  EXPECT_EQ(ErrorOf("\"sources\": [", "\"sourcez\": ["), "cal.json: sources: missing");
}

TEST(ModuleCalibrationJson, OneSeparationPerPair) {
  // Issue 19: A-B listed twice (55 and 66 mm) was read, and a measurement used
  // one of them silently.
  const std::string sep = R"({"from": "A", "to": "B", "length_mm": 55, "u_length_mm": 0.001})";
  EXPECT_EQ(ErrorOf(sep, sep + R"(, {"from": "A", "to": "B", "length_mm": 66, "u_length_mm": 0.001})"),
            "cal.json: separations[1]: A-B 66 mm contradicts separations[0], A-B 55 mm (each pair "
            "of sources may have one separation)");
  EXPECT_EQ(ErrorOf(sep, sep + R"(, {"from": "B", "to": "A", "length_mm": 55, "u_length_mm": 0.001})"),
            "cal.json: separations[1]: B-A 55 mm duplicates separations[0], A-B 55 mm (each pair "
            "of sources may have one separation)");
  ModuleCalibration calibration = testing_support::SyntheticCalibration(3, 5);
  ASSERT_FALSE(calibration.separations.empty());
  calibration.separations.push_back(calibration.separations.front());
  EXPECT_THAT(calibration.Validate().message(), ::testing::HasSubstr("is given twice"));
}

TEST(ModuleCalibrationJson, NestingIsCappedAt64Levels) {
  // Issue 19: 80 KB of '[' took GBs; refused at the bracket opening level 65.
  Result<ModuleCalibration> r = ParseModuleCalibrationJson("\n" + std::string(80000, '['), "c.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kParseError);
  EXPECT_EQ(r.status().message(), "c.json:2:65: invalid JSON: nested deeper than 64 levels");
}

TEST(ModuleCalibrationJson, SyntaxErrorsGiveLineAndColumn) {
  Result<ModuleCalibration> r =
      ParseModuleCalibrationJson("{\n  \"format\": \"opl.module_calibration\",\n  oops\n}", "c.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kParseError);
  EXPECT_THAT(r.status().message(), ::testing::StartsWith("c.json:3:3: JSON syntax error: "));
  EXPECT_THAT(ParseModuleCalibrationJson("", "c.json").status().message(),
              ::testing::StartsWith("c.json:1:1: JSON syntax error: "));
  EXPECT_EQ(ParseModuleCalibrationJson("[1, 2]", "c.json").status().message(),
            "c.json: expected a JSON object at the top level, got array");
  // NaN is not JSON.
  EXPECT_THAT(ErrorOf("\"az_rad\": -0.05", "\"az_rad\": NaN"), HasSubstr("JSON syntax error"));
}

TEST(ModuleCalibrationJson, QuaternionMustAgreeWithTheAngles) {
  EXPECT_EQ(ErrorOf("\"rotation_xyz_rad\": [0, 0, 0]",
                    "\"rotation_xyz_rad\": [0, 0, 0], \"rotation_quaternion_wxyz\": [1, 0, 0, 0]"),
            "(parsed)");
  EXPECT_EQ(ErrorOf("\"rotation_xyz_rad\": [0, 0, 0]",
                    "\"rotation_xyz_rad\": [0, 0, 0], \"rotation_quaternion_wxyz\": [0, 1, 0, 0]"),
            "cal.json: sources[1].rotation_quaternion_wxyz: disagrees with rotation_xyz_rad by "
            "3.141592653589793 rad");
  EXPECT_EQ(ErrorOf("\"rotation_xyz_rad\": [0, 0, 0]",
                    "\"rotation_xyz_rad\": [0, 0, 0], \"rotation_quaternion_wxyz\": [2, 0, 0, 0]"),
            "cal.json: sources[1].rotation_quaternion_wxyz: not a unit quaternion (norm 2)");
}

TEST(ModuleCalibrationJson, UnreadableFileIsAnIoError) {
  Result<ModuleCalibration> r = ReadModuleCalibrationJson("/nonexistent/cal.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kIoError);
  EXPECT_EQ(r.status().message(), "/nonexistent/cal.json: cannot open: No such file or directory");
}

TEST(ModuleCalibrationJson, InvalidCalibrationIsNotWritten) {
  ModuleCalibration cal = testing_support::SyntheticCalibration(2, 3);
  cal.separations[0].length_mm = -1.0;
  testing_support::TempDir dir;
  const Status st = WriteModuleCalibrationJson(cal, dir.File("cal.json"));
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(dir.Entries().empty());
}

}  // namespace
}  // namespace opl
