// opl_calibrate --images as a user runs it: opl_simulate images renders the
// bundled calibration session (examples/calibration_session_small.json, 18
// images with light speckle and sensor noise), opl_calibrate --images
// calibrates the module from them against its nominal design (exit 0, a
// module calibration JSON whose separation is the design's 55 mm within its
// uncertainty, the per-image report, the heat maps); and the usage errors of
// --images.
#include <filesystem>
#include <set>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "apps/cli_test_util.h"
#include "opl/io/module_calibration_json.h"

namespace opl {
namespace {

using cli_test::Calibrate;
using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;
using testing_support::ReadAll;

const std::string kExamples = OPL_EXAMPLES_DIR;
const std::string kScene = kExamples + "/calibration_session_small.json";
const std::string kDesign = kExamples + "/calibration_session_small_module.json";

TEST(CalibrateImagesCli, SimulateThenCalibrate) {
  testing_support::TempDir dir;
  const std::string shots = dir.File("shots");
  RunResult r = Simulate("images --scene " + kScene + " --out " + shots + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string out = dir.File("cal.json");
  const std::string report = dir.File("rep");
  r = Calibrate("--images " + shots + " --scene " + kScene + " --design " + kDesign +
                " --out " + out + " --report " + report + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The per-image report names every image, then the artifact's scale.
  for (const char* file : {"s0_A_cam0.png", "s1_B_cam1.png", "s2_A_cam2.png"}) {
    EXPECT_THAT(r.out, HasSubstr(file));
  }
  EXPECT_THAT(r.out, HasSubstr("artifact: tags tag 8 - tag 9"));
  EXPECT_THAT(r.out, HasSubstr("A-B"));

  const nlohmann::json json = nlohmann::json::parse(ReadAll(out));
  EXPECT_EQ(json["format"], "opl.module_calibration");
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(out);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->sources.size(), 2u);
  EXPECT_EQ(cal->sources[0].pattern.beams().size(), 121u);
  EXPECT_EQ(cal->sources[1].pattern.beams().size(), 121u);
  ASSERT_EQ(cal->separations.size(), 1u);
  const double length = cal->separations[0].length_mm;
  const double u = cal->separations[0].u_length_mm;
  std::printf("separation %.4f mm +- %.4f mm\n", length, u);
  // Not a vacuous interval: speckled 1024 x 768 images give u of a few
  // hundredths of a mm.
  EXPECT_GT(u, 0.002);
  EXPECT_LT(u, 0.1);
  EXPECT_NEAR(length, 55.0, 3.0 * u);
  ASSERT_TRUE(cal->scaling.has_value());
  EXPECT_NEAR(cal->scaling->artifact_length_mm, 800.0, 1e-12);
  EXPECT_NEAR(cal->scaling->scale, 1.0, 3.0 * cal->scaling->u_scale_relative + 1e-12);

  std::set<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(report)) {
    files.insert(e.path().filename().string());
  }
  EXPECT_EQ(files,
            (std::set<std::string>{"beams.csv", "heatmap_A.png", "heatmap_B.png", "samples.csv"}));
  EXPECT_EQ(ReadAll(report + "/heatmap_B.png").substr(0, 8), "\x89PNG\r\n\x1a\n");
}

TEST(CalibrateImagesCli, UsageErrors) {
  testing_support::TempDir dir;
  const std::string out = dir.File("cal.json");
  RunResult r = Calibrate("--images " + dir.File("shots") + " --scene " + kScene + " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--images needs --design"));
  r = Calibrate("--images " + dir.File("shots") + " --design " + kDesign + " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--images requires --scene"));
  r = Calibrate("--images " + dir.File("shots") + " --scene " + kScene + " --design " + kDesign +
                " --targets t.csv --artifact T1,T2 --artifact-length-mm 800 --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--targets/--artifact are for --spots"));
  r = Calibrate("--spots s.csv --one-pose-per-camera --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--one-pose-per-camera requires --images"));
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace opl
