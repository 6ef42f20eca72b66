// Runs `opl_simulate sweep` as a user would: a design study of
// examples/staggered_design.json over the spot noise, its CSV, its PNG plot,
// its table and its errors (nothing written when the command fails).
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "cli_test_util.h"

namespace opl {
namespace {

using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kDesign = std::string(OPL_EXAMPLES_DIR) + "/staggered_design.json";

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind('#', 0) != 0) lines.push_back(line);  // '#': OPL's provenance lines
  }
  return lines;
}

std::vector<std::string> Fields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  for (std::string f; std::getline(in, f, ',');) fields.push_back(f);
  return fields;
}

TEST(SimulateSweepCli, NoiseSweepWritesCsvAndPlot) {
  testing_support::TempDir dir;
  const RunResult r = Simulate("sweep --design " + kDesign +
                               " --param noise_mm --values 0.1,0.2,0.4 --iterations 60 --seed 3"
                               " --threads 2 --out " + dir.File("s.csv") + " --plot " +
                               dir.File("s.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, StartsWith("noise_mm"));
  EXPECT_THAT(r.out, HasSubstr("MC/CRB"));

  const std::vector<std::string> lines = Lines(dir.File("s.csv"));
  ASSERT_EQ(lines.size(), 4u);
  const std::vector<std::string> header = Fields(lines[0]);
  ASSERT_EQ(header.size(), 18u);
  EXPECT_EQ(header[6], "std_mm");
  std::vector<double> std_mm;
  for (size_t i = 1; i < 4; ++i) {
    const std::vector<std::string> f = Fields(lines[i]);
    ASSERT_EQ(f.size(), 18u) << lines[i];
    EXPECT_EQ(f[0], "noise_mm");
    EXPECT_EQ(f[2], "A");
    EXPECT_EQ(f[3], "B");
    std_mm.push_back(std::stod(f[6]));
    // Linear in the noise: first order and bound double exactly with it.
    EXPECT_NEAR(std::stod(f[8]) / std::stod(f[9]), 1.0, 1e-6);
  }
  EXPECT_NEAR(std_mm[1] / std_mm[0], 2.0, 0.04);  // the same draws at every value
  EXPECT_NEAR(std_mm[2] / std_mm[0], 4.0, 0.08);

  const cv::Mat png = cv::imread(dir.File("s.png"), cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_GE(png.cols, 1280);  // two panels side by side
  EXPECT_GE(png.rows, 480);
}

// layout: the table and the CSV name the parameter as given, the table the
// values by their words; the plot is written.
TEST(SimulateSweepCli, LayoutSweep) {
  testing_support::TempDir dir;
  const RunResult r = Simulate("sweep --design " + kDesign +
                               " --param layout --values side_by_side,staggered --iterations 30"
                               " --threads 2 --out " + dir.File("l.csv") + " --plot " +
                               dir.File("l.pdf"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, StartsWith("layout "));
  EXPECT_THAT(r.out, HasSubstr("\nside_by_side     A-B "));
  EXPECT_THAT(r.out, HasSubstr("\nstaggered        A-B "));
  const std::vector<std::string> lines = Lines(dir.File("l.csv"));
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[1].substr(0, 13), "layout,0,A,B,");
  EXPECT_EQ(lines[2].substr(0, 14), "layout,45,A,B,");
  // A PDF, as the name asks, with the tool named in its metadata (cairo
  // writes the document info as UTF-16BE hex: "OPL opl_simulate").
  const std::vector<std::string> pdf = Lines(dir.File("l.pdf"));
  ASSERT_FALSE(pdf.empty());
  EXPECT_EQ(pdf[0].rfind("%PDF-", 0), 0u);
  bool names_tool = false;
  for (const std::string& line : pdf) {
    names_tool |= line.find("/Creator <FEFF004F0050004C0020006F0070006C005F00730069006D0075006C006100740065") != std::string::npos;
  }
  EXPECT_TRUE(names_tool);
}

TEST(SimulateSweepCli, Errors) {
  testing_support::TempDir dir;
  const std::string out = " --out " + dir.File("s.csv") + " --plot " + dir.File("s.png");
  const std::string base = "sweep --design " + kDesign + " --iterations 5";
  RunResult r = Simulate(base + " --param angle --values 1,2" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, StartsWith("opl_simulate: --param: unknown sweep parameter 'angle'"));
  r = Simulate(base + " --param beams_per_side --values 5:2:x" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "opl_simulate: --values: value list '5:2:x': 'x' is not a finite number\n");
  r = Simulate(base + " --param beams_per_side --values 5,8" + out);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_simulate: beams_per_side = 8: must be an odd integer in [3, 201]\n");
  r = Simulate(base + " --param noise_mm --values 0.1 --out " + dir.File("s.csv") + " --plot " +
               dir.File("s.jpg"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "opl_simulate: --plot " + dir.File("s.jpg") +
                       ": a figure must be named .png, .svg or .pdf (got '.jpg')\n");
  // layout has named values: no log axis for them.
  r = Simulate(base + " --param layout --values side_by_side,staggered --log-x" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "opl_simulate: --log-x: --param layout has named values, not a numeric axis\n");
  r = Simulate(base + " --param noise_mm --values 0.1 --weighting best" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.out, "");
  EXPECT_TRUE(dir.Entries().empty());  // nothing written by any failed run
}

TEST(SimulateSweepCli, HelpTeaches) {
  const RunResult r = Simulate("sweep --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* word : {"noise_mm", "full_angle_deg", "beams_per_side", "separation_mm",
                           "distance_mm", "stagger_deg", "side_by_side", "--plot", "Cramer-Rao"}) {
    EXPECT_THAT(r.out, HasSubstr(word));
  }
}

}  // namespace
}  // namespace opl
