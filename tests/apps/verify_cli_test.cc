// opl_verify as a user runs it: opl_simulate renders the bundled small scene
// with seven check lengths added (their true tag-centre distances), and
// opl_verify measures it: exit 0, the table on stdout, the CSV, JSON and PNG
// written (stamped with the provenance); then the errors: bad input exit 3
// with one line naming the file and field, usage exit 2, an output that
// cannot be written exit 5 — and in every failure no output file at all.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli_test_util.h"

namespace opl {
namespace {

using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

const std::string kExamples = OPL_EXAMPLES_DIR;

RunResult Verify(const std::string& args) { return cli_test::Run(OPL_VERIFY_EXE, args); }

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// examples/scene_small.json (module path made absolute) with `checks` as
// check lengths between its tags, each the true distance of the centres.
nlohmann::json SceneWithChecks(const std::vector<std::pair<int, int>>& checks) {
  nlohmann::json scene;
  std::ifstream(kExamples + "/scene_small.json") >> scene;
  scene["module"] = kExamples + "/scene_small_module.json";
  auto centre = [&](int id) {
    for (const auto& t : scene["tags"]["placements"]) {
      if (t["id"] == id) return t["center_mm"].get<std::vector<double>>();
    }
    ADD_FAILURE() << "no tag " << id;
    return std::vector<double>(3, 0.0);
  };
  scene["check_lengths"] = nlohmann::json::array();
  for (const auto& [a, b] : checks) {
    const std::vector<double> ca = centre(a), cb = centre(b);
    const double d = std::sqrt(std::pow(ca[0] - cb[0], 2) + std::pow(ca[1] - cb[1], 2) +
                               std::pow(ca[2] - cb[2], 2));
    scene["check_lengths"].push_back({{"name", "t" + std::to_string(a) + "-t" + std::to_string(b)},
                                      {"tag_1", a},
                                      {"tag_2", b},
                                      {"length_mm", d},
                                      {"length_sigma_mm", 0.002}});
  }
  return scene;
}

const std::vector<std::pair<int, int>> kSevenChecks = {{0, 3}, {1, 2}, {4, 5}, {6, 7},
                                                       {0, 1}, {2, 3}, {8, 5}};

// Everything a run needs, rendered once for the whole suite.
class VerifyCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing_support::TempDir();
    scene_ = dir_->File("scene.json");
    std::ofstream(scene_) << SceneWithChecks(kSevenChecks).dump(2);
    calibration_ = dir_->File("cal.json");
    shots_ = dir_->File("shots");
    RunResult r = Simulate("calibration --design " + kExamples + "/scene_small_module.json --out " +
                           calibration_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = Simulate("images --scene " + scene_ + " --out " + shots_ + " --threads 2");
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string Inputs() {
    return "--scene " + scene_ + " --images " + shots_ + " --calibration " + calibration_ +
           " --threads 2";
  }
  static testing_support::TempDir* dir_;
  static std::string scene_, calibration_, shots_;
};

testing_support::TempDir* VerifyCli::dir_ = nullptr;
std::string VerifyCli::scene_, VerifyCli::calibration_, VerifyCli::shots_;

TEST_F(VerifyCli, MeasuresTheCheckLengthsAndWritesEveryOutput) {
  testing_support::TempDir out;
  const std::string csv = out.File("verify.csv"), json = out.File("verify.json"),
                    plot = out.File("verify.png");
  RunResult r = Verify(Inputs() + " --csv " + csv + " --json " + json + " --plot " + plot);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, StartsWith("Length measurement error E = L - L_cal"));
  EXPECT_THAT(r.out, HasSubstr("OPL: s = "));
  EXPECT_THAT(r.out, HasSubstr("bar: s = "));
  EXPECT_THAT(r.out, Not(HasSubstr("warning:")));

  // CSV: the provenance comment lines, the header, one row per length.
  std::ifstream in(csv);
  std::string line;
  while (std::getline(in, line) && line.rfind("# opl ", 0) == 0) {
  }
  EXPECT_THAT(line, StartsWith("name,tag_1,tag_2,calibrated_mm,"));
  int rows = 0;
  while (std::getline(in, line)) rows += line.empty() ? 0 : 1;
  EXPECT_EQ(rows, 7);

  // JSON: every length within a few U(E) of its calibrated value (this
  // scene's u(s) is about 1 %: U(E) of a 2 m length some tens of mm).
  const nlohmann::json report = nlohmann::json::parse(Slurp(json));
  EXPECT_EQ(report["format"], "opl.verify_report");
  EXPECT_TRUE(report.contains("provenance"));
  ASSERT_EQ(report["lengths"].size(), 7u);
  for (const auto& l : report["lengths"]) {
    const double e = l["opl"]["error_mm"].get<double>();
    const double u = l["opl"]["expanded_u_error_mm"].get<double>();
    EXPECT_GT(u, 0.0) << l["name"];
    EXPECT_LT(std::abs(e), 2.0 * u) << l["name"];
    EXPECT_LT(std::abs(l["bar"]["error_mm"].get<double>()),
              2.0 * l["bar"]["expanded_u_error_mm"].get<double>())
        << l["name"];
  }

  // The plot: a PNG of the figure's size (two 640 x 520 panels, both
  // columns and the bar alone, plus the title's row).
  const cv::Mat image = cv::imread(plot, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 1280);
  EXPECT_GT(image.rows, 520);
}

TEST_F(VerifyCli, BadInputIsExit3WithOneLineAndNoOutput) {
  testing_support::TempDir out;
  const std::string csv = out.File("v.csv"), json = out.File("v.json"), plot = out.File("v.png");
  const std::string outputs = " --csv " + csv + " --json " + json + " --plot " + plot;
  auto expect_no_output = [&] {
    EXPECT_FALSE(std::filesystem::exists(csv));
    EXPECT_FALSE(std::filesystem::exists(json));
    EXPECT_FALSE(std::filesystem::exists(plot));
  };

  // A scene without check lengths (the bundled one): refused before any image is read.
  RunResult r = Verify("--scene " + kExamples + "/scene_small.json --images " + shots_ +
                       " --calibration " + calibration_ + outputs);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_verify: " + kExamples +
                       "/scene_small.json: check_lengths: the scene lists no check length (pairs "
                       "of tags with calibrated distances; docs/verify.md)\n");
  expect_no_output();

  // A check length naming a tag the scene does not have.
  nlohmann::json bad = SceneWithChecks(kSevenChecks);
  bad["check_lengths"][2]["tag_2"] = 42;
  const std::string bad_tag = out.File("bad_tag.json");
  std::ofstream(bad_tag) << bad.dump();
  r = Verify("--scene " + bad_tag + " --images " + shots_ + " --calibration " + calibration_ + outputs);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, StartsWith("opl_verify: " + bad_tag + ": check_lengths[2].tag_2:"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  expect_no_output();

  // A check length with a negative length.
  bad = SceneWithChecks(kSevenChecks);
  bad["check_lengths"][0]["length_mm"] = -5.0;
  const std::string negative = out.File("negative.json");
  std::ofstream(negative) << bad.dump();
  r = Verify("--scene " + negative + " --images " + shots_ + " --calibration " + calibration_ + outputs);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("negative.json: check_lengths[0].length_mm: -5: must be finite and > 0"));
  expect_no_output();

  // A missing calibration file.
  r = Verify("--scene " + scene_ + " --images " + shots_ + " --calibration " +
             out.File("none.json") + outputs);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("none.json"));
  expect_no_output();

  // Missing images.
  const std::string empty = out.File("empty");
  std::filesystem::create_directories(empty);
  r = Verify("--scene " + scene_ + " --images " + empty + " --calibration " + calibration_ + outputs);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr(": no such image"));
  expect_no_output();
}

TEST_F(VerifyCli, UsageAndWriteErrors) {
  testing_support::TempDir out;
  RunResult r = Verify("--scene " + scene_ + " --images " + shots_);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--calibration is required"));
  r = Verify(Inputs() + " --plot " + out.File("plot.jpg"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--plot " + out.File("plot.jpg") +
                               ": a figure must be named .png, .svg or .pdf (got '.jpg')"));
  r = Verify(Inputs() + " --csv " + scene_);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("is the same file as --scene"));
  // --json cannot be written: exit 5, and the CSV staged before it is not left.
  const std::string csv = out.File("v.csv");
  r = Verify(Inputs() + " --csv " + csv + " --json " + out.File("missing/v.json"));
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_FALSE(std::filesystem::exists(csv));
}

}  // namespace
}  // namespace opl
