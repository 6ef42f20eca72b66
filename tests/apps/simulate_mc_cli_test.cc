// Runs `opl_simulate mc` as a user would: the Monte Carlo uncertainty of a
// measurement (JCGM 101) of examples/staggered_design.json, as JSON and text,
// with its figure (--plot) and its samples (--samples).
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "support/provenance_strip.h"
#include "cli_test_util.h"

namespace opl {
namespace {

using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kDesign = std::string(OPL_EXAMPLES_DIR) + "/staggered_design.json";

// A failed run: one line on stderr, nothing on stdout.
void ExpectFailure(const RunResult& r, int exit_code, const std::string& err_prefix) {
  EXPECT_EQ(r.exit_code, exit_code) << r.err;
  EXPECT_THAT(r.err, StartsWith(err_prefix));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.out, "");
}

TEST(SimulateMcCli, JsonReportHasTheDocumentedFields) {
  const RunResult r =
      Simulate("mc --design " + kDesign + " --iterations 40 --seed 5 --threads 1 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");  // stderr is not a terminal: no progress bar
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["format"], "opl.monte_carlo_report");
  EXPECT_EQ(j["iterations"], 40);
  EXPECT_EQ(j["succeeded"], 40);
  EXPECT_EQ(j["failed"], 0);
  EXPECT_EQ(j["coverage_interval"], "probabilistically_symmetric");
  ASSERT_EQ(j["lengths"].size(), 1u);
  const nlohmann::json& l = j["lengths"][0];
  EXPECT_EQ(l["from"], "A");
  EXPECT_EQ(l["to"], "B");
  EXPECT_NEAR(l["mean_mm"].get<double>(), 55.154, 0.2);  // std(L) ~ 0.2 mm, 40 draws
  EXPECT_GT(l["std_mm"].get<double>(), 0.0);
  EXPECT_GT(l["first_order_std_mm"].get<double>(), 0.0);
  ASSERT_EQ(l["ci95_mm"].size(), 2u);
  EXPECT_LT(l["ci95_mm"][0].get<double>(), l["mean_mm"].get<double>());
  EXPECT_GT(l["ci95_mm"][1].get<double>(), l["mean_mm"].get<double>());
  ASSERT_EQ(j["sources"].size(), 2u);
  EXPECT_EQ(j["sources"][0]["name"], "A");
  EXPECT_EQ(j["sources"][1]["name"], "B");
  for (const nlohmann::json& s : j["sources"]) {
    ASSERT_EQ(s["origin_std_mm"].size(), 3u);
    ASSERT_EQ(s["rotation_std_rad"].size(), 3u);
    EXPECT_GT(s["origin_std_mm"][0].get<double>(), 0.0);
  }
  EXPECT_NEAR(j["scale_factor"]["mean"].get<double>(), 1.0, 1e-3);
  EXPECT_GT(j["scale_factor"]["std"].get<double>(), 0.0);
}

TEST(SimulateMcCli, SameSeedSameOutputWhateverTheThreads) {
  const std::string args = "mc --design " + kDesign + " --iterations 24 --seed 9 --json";
  const RunResult one = Simulate(args + " --threads 1");
  const RunResult two = Simulate(args + " --threads 2");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  ASSERT_EQ(two.exit_code, 0) << two.err;
  // The same but for the provenance (its command line names the threads).
  EXPECT_EQ(testing_support::StripProvenance(one.out), testing_support::StripProvenance(two.out));
  EXPECT_NE(one.out.find("\"provenance\": {\"tool\":\"opl_simulate\""), std::string::npos);
}

TEST(SimulateMcCli, TextSummary) {
  const RunResult r = Simulate("mc --design " + kDesign + " --iterations 30 --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, StartsWith("Monte Carlo (JCGM 101): 30 iterations, 30 located, 0 failed"));
  EXPECT_THAT(r.out, HasSubstr("probabilistically symmetric"));
  EXPECT_THAT(r.out, HasSubstr("A-B: true 55.1543"));
  EXPECT_THAT(r.out, HasSubstr("Scale factor s: mean"));
  EXPECT_THAT(r.out, HasSubstr("rotation std MC"));
}

TEST(SimulateMcCli, Errors) {
  ExpectFailure(Simulate("mc --design " + kDesign), 2, "opl_simulate: ");  // --iterations required
  ExpectFailure(Simulate("mc --design " + kDesign + " --iterations 0"), 3,
                "opl_simulate: invalid option: --iterations must be >= 1");
  ExpectFailure(Simulate("mc --design " + kDesign + " --iterations 5 --threads -2"), 3,
                "opl_simulate: invalid option: --threads");
  ExpectFailure(Simulate("mc --design " + kDesign + " --iterations 5 --noise-scale 0"), 3,
                "opl_simulate: spot_noise_mm is zero");
  ExpectFailure(Simulate("mc --design /nonexistent/d.json --iterations 5"), 3, "opl_simulate: ");
}

// The calibration Monte Carlo: a session of 4 screens, 30 iterations.
TEST(SimulateMcCli, CalibrationSession) {
  const RunResult r = Simulate("mc --design " + kDesign +
                               " --iterations 30 --threads 2 --calibration --depths 800:150:1250 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["format"], "opl.calibration_monte_carlo_report");
  EXPECT_EQ(j["depths_mm"].size(), 4u);
  ASSERT_EQ(j["lengths"].size(), 1u);
  // The separation: std from 30 draws within 40 % of first order (4 screens).
  const double ratio = j["lengths"][0]["std_mm"].get<double>() /
                       j["lengths"][0]["first_order_std_mm"].get<double>();
  EXPECT_GT(ratio, 0.6);
  EXPECT_LT(ratio, 1.4);
  ASSERT_EQ(j["sources"].size(), 2u);
  EXPECT_EQ(j["sources"][0]["beams"].size(), 121u);
}

TEST(SimulateMcCli, CalibrationOptionsNeedCalibration) {
  ExpectFailure(Simulate("mc --design " + kDesign + " --iterations 5 --depths 800,900"), 2,
                "opl_simulate: --depths, --tilt-deg and --curvature need --calibration");
  ExpectFailure(Simulate("mc --design " + kDesign +
                         " --iterations 5 --calibration --weighting unweighted"),
                2, "opl_simulate: --weighting applies to a measurement");
  ExpectFailure(Simulate("mc --design " + kDesign + " --iterations 5 --calibration --depths 800:x:900"),
                2, "opl_simulate: --depths: depth list '800:x:900'");
  ExpectFailure(Simulate("mc --design " + kDesign + " --iterations 5 --weighting best"), 2,
                "opl_simulate: --weighting: unknown weighting 'best'");
}

// --plot: the figure, written before the report is printed; --samples: every
// iteration's values in the JSON.
TEST(SimulateMcCli, PlotAndSamples) {
  testing_support::TempDir dir;
  const std::string png = dir.File("mc.png");
  const RunResult r = Simulate("mc --design " + kDesign +
                               " --iterations 60 --seed 5 --threads 2 --json --samples --plot " + png);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const cv::Mat image = cv::imread(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 1280);  // two panels: L of A-B and s
  EXPECT_GE(image.rows, 480);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["sample_iterations"].size(), 60u);
  EXPECT_EQ(j["sample_iterations"][59], 59);
  ASSERT_EQ(j["lengths"][0]["samples_mm"].size(), 60u);
  EXPECT_EQ(j["scale_factor"]["samples"].size(), 60u);
  ASSERT_EQ(j["sources"][1]["origin_samples_mm"].size(), 60u);
  EXPECT_EQ(j["sources"][1]["origin_samples_mm"][0].size(), 3u);
  EXPECT_EQ(j["sources"][0]["rotation_samples_rad"].size(), 60u);
  // The sample mean is the reported mean.
  double sum = 0.0;
  for (const nlohmann::json& v : j["lengths"][0]["samples_mm"]) sum += v.get<double>();
  EXPECT_NEAR(sum / 60.0, j["lengths"][0]["mean_mm"].get<double>(), 1e-12);
  // The same run without --samples: the same report without the samples.
  const RunResult plain =
      Simulate("mc --design " + kDesign + " --iterations 60 --seed 5 --threads 2 --json");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  const nlohmann::json p = nlohmann::json::parse(plain.out);
  EXPECT_FALSE(p.contains("sample_iterations"));
  EXPECT_EQ(p["lengths"][0]["std_mm"], j["lengths"][0]["std_mm"]);
  EXPECT_FALSE(p["lengths"][0].contains("samples_mm"));
}

// The figure as SVG and PDF: the format follows the name; the SVG carries
// the run's provenance and the PDF its creator.
TEST(SimulateMcCli, PlotAsSvgAndPdf) {
  testing_support::TempDir dir;
  const std::string base = "mc --design " + kDesign + " --iterations 60 --seed 5 --threads 2 --plot ";
  RunResult r = Simulate(base + dir.File("mc.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream svg_in(dir.File("mc.svg"));
  const std::string svg((std::istreambuf_iterator<char>(svg_in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_THAT(svg, HasSubstr("<svg"));
  EXPECT_THAT(svg, HasSubstr("opl-provenance"));
  EXPECT_THAT(svg, HasSubstr("opl_simulate"));
  r = Simulate(base + dir.File("mc.PDF"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream pdf_in(dir.File("mc.PDF"), std::ios::binary);
  const std::string pdf((std::istreambuf_iterator<char>(pdf_in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(pdf.rfind("%PDF-", 0), 0u);
  // cairo writes the document info as UTF-16BE hex: "opl_simulate" in the Creator.
  EXPECT_THAT(pdf, HasSubstr("/Creator <FEFF004F0050004C0020006F0070006C005F00730069006D0075006C006100740065"));
}

// A bad --plot: the documented exit code, one line on stderr, nothing on
// stdout and no file.
TEST(SimulateMcCli, PlotErrorsWriteNothing) {
  testing_support::TempDir dir;
  const std::string base = "mc --design " + kDesign + " --iterations 30 --threads 2";
  ExpectFailure(Simulate(base + " --plot " + dir.File("missing/mc.png")), 5, "opl_simulate: ");
  ExpectFailure(Simulate(base + " --json --plot " + dir.File("missing/mc.png")), 5,
                "opl_simulate: ");
  ExpectFailure(Simulate(base + " --plot " + dir.File("mc.txt")), 2,
                "opl_simulate: --plot " + dir.File("mc.txt") +
                    ": a figure must be named .png, .svg or .pdf (got '.txt')");
  ExpectFailure(Simulate(base + " --samples"), 2, "opl_simulate: ");  // --samples needs --json
  ExpectFailure(Simulate(base + " --calibration --plot " + dir.File("mc.png")), 2,
                "opl_simulate: --plot and --samples apply to a measurement, not to --calibration");
  // A folder in the way of the figure.
  ASSERT_TRUE(std::filesystem::create_directory(dir.File("taken.png")));
  ExpectFailure(Simulate(base + " --plot " + dir.File("taken.png")), 5, "opl_simulate: ");
  // A run that fails (no such design) leaves no figure either.
  ExpectFailure(Simulate("mc --design /nonexistent/d.json --iterations 5 --plot " +
                         dir.File("mc.png")),
                3, "opl_simulate: ");
  std::vector<std::string> left = dir.Entries();
  EXPECT_EQ(left, std::vector<std::string>{"taken.png"});
  EXPECT_TRUE(std::filesystem::is_empty(dir.File("taken.png")));
}

TEST(SimulateMcCli, HelpTeaches) {
  const RunResult r = Simulate("mc --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("JCGM 101"));
  EXPECT_THAT(r.out, HasSubstr("--iterations"));
  EXPECT_THAT(r.out, HasSubstr("--threads"));
  EXPECT_THAT(r.out, HasSubstr("probabilistically symmetric"));
  EXPECT_THAT(r.out, HasSubstr("--plot"));
  EXPECT_THAT(r.out, HasSubstr("Freedman-Diaconis"));
  EXPECT_THAT(r.out, HasSubstr("--samples"));
}

}  // namespace
}  // namespace opl
