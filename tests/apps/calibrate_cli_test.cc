// Runs `opl_calibrate` as a user would: simulate a calibration session with
// opl_simulate slices, calibrate it, read the calibration back, use it with
// opl_measure; and every documented refusal of bad input.
#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "support/provenance_strip.h"
#include "apps/cli_test_util.h"
#include <nlohmann/json.hpp>

#include "opl/io/module_calibration_json.h"

namespace opl {
namespace {

using cli_test::Calibrate;
using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }

class CalibrateCli : public ::testing::Test {
 protected:
  const std::string design_ = std::string(OPL_EXAMPLES_DIR) + "/prototype_design.json";
  testing_support::TempDir dir_;

  // A session of the example design into slices.csv.
  std::string Session(const std::string& extra = "") {
    const std::string path = dir_.File("slices.csv");
    const RunResult r = Simulate("slices --design " + design_ + " --depths 750:65:1335 --out " +
                                 path + " --seed 7 " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return path;
  }

  void ExpectRefused(const RunResult& r, int code, const std::string& message) {
    EXPECT_EQ(r.exit_code, code) << r.err;
    EXPECT_THAT(r.err, HasSubstr(message));
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;  // one line
    EXPECT_FALSE(std::filesystem::exists(dir_.File("module.json")));
    EXPECT_FALSE(std::filesystem::exists(dir_.File("report")));
  }
};

TEST_F(CalibrateCli, HelpTeachesTheSessionAndTheOutputs) {
  const RunResult r = Calibrate("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("A slice is one grid on"));
  EXPECT_THAT(r.out, HasSubstr("--artifact-length-mm"));
  EXPECT_THAT(r.out, HasSubstr("heatmap_<source>.png"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
}

TEST_F(CalibrateCli, CalibratesASimulatedSessionAndTheResultMeasures) {
  const std::string slices = Session("--missing 0.05 --outliers 0.01");
  const RunResult r = Calibrate("--spots " + slices + " --out " + dir_.File("module.json") +
                                " --report " + dir_.File("report"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, HasSubstr("source A (11 x 11, 10 slices)"));
  EXPECT_THAT(r.out, HasSubstr("flagged as wrong"));
  EXPECT_THAT(r.out, HasSubstr("A-B  5"));
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(dir_.File("module.json"));
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->separations.size(), 1u);
  // 0.02 mm is about one standard uncertainty of this separation.
  EXPECT_NEAR(cal->separations[0].length_mm, 55.0, 0.08);
  EXPECT_GT(cal->separations[0].u_length_mm, 0.01);
  EXPECT_LT(cal->separations[0].u_length_mm, 0.03);
  ASSERT_TRUE(cal->sources[0].quality.has_value());
  // 1% of the ~230 spots of each screen were made wrong: 2 a screen, 20 in all,
  // shared by the two grids; every one is flagged.
  EXPECT_EQ(cal->sources[0].quality->samples_flagged + cal->sources[1].quality->samples_flagged, 20);
  EXPECT_EQ(cal->sources[0].pattern.beams().size(), 121u);
  std::set<std::string> report_files;
  for (const auto& e : std::filesystem::directory_iterator(dir_.File("report"))) {
    report_files.insert(e.path().filename().string());
  }
  EXPECT_EQ(report_files,
            (std::set<std::string>{"beams.csv", "heatmap_A.png", "heatmap_B.png", "samples.csv"}));
  const std::string png = ReadAll(dir_.File("report/heatmap_A.png"));
  EXPECT_EQ(png.substr(0, 8), "\x89PNG\r\n\x1a\n");
  const std::string beams = ReadAll(dir_.File("report/beams.csv"));
  EXPECT_EQ(std::count(beams.begin(), beams.end(), '\n'), 1 + 242);
  EXPECT_THAT(beams, HasSubstr("\nA,61,5,5,0,0,"));  // the gauge: central beam at az = el = 0

  // The new calibration measures a scene of the same module (noise-free spots:
  // s = 1 up to the calibration's own error; u(s) comes from the residuals that
  // the calibrated directions leave, about 0.1%).
  ASSERT_EQ(Simulate("spots --design " + design_ + " --out " + dir_.File("scene.csv") +
                     " --seed 3 --noise-scale 0")
                .exit_code,
            0);
  const RunResult m =
      cli_test::Measure("--calibration " + dir_.File("module.json") + " --spots " +
                        dir_.File("scene.csv") + " --json");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  const nlohmann::json report = nlohmann::json::parse(m.out);
  const double s = report["scale_factor"].get<double>();
  const double u = report["u_scale_factor"].get<double>();
  EXPECT_LT(std::abs(s - 1.0), 2.0 * u);
  EXPECT_LT(u, 3e-3);
}

// The same session exported as a point table (no source, no beam, shuffled
// rows): identified against the design (--design) and calibrated to the same
// separation as the labelled session, to 1e-6 mm (the identification leaves
// out only the moved samples, which the labelled calibration flags).
TEST_F(CalibrateCli, UnlabelledSessionIsIdentifiedWithTheDesign) {
  const std::string slices = Session("--missing 0.05 --outliers 0.01");
  const std::string csv = ReadAll(slices);
  std::vector<std::string> rows;
  size_t start = csv.find('\n') + 1;
  for (size_t at; (at = csv.find('\n', start)) != std::string::npos; start = at + 1) {
    const std::string line = csv.substr(start, at - start);
    std::vector<std::string> f;
    size_t from = 0;
    for (size_t c; (c = line.find(',', from)) != std::string::npos; from = c + 1) {
      f.push_back(line.substr(from, c - from));
    }
    f.push_back(line.substr(from));
    // source,beam,x,y,z,sx,sy,sz,slice,... -> "P<k> x y z sx sy sz slice"
    std::string row = "P" + std::to_string(rows.size());
    for (int k = 2; k <= 8; ++k) row += " " + f[static_cast<size_t>(k)];
    rows.push_back(row);
  }
  std::reverse(rows.begin(), rows.end());
  std::string table = "Name X Y Z SX SY SZ Slice\n";
  for (const std::string& row : rows) table += row + "\n";
  const std::string points = dir_.Write("session.txt", table);

  const RunResult labelled = Calibrate("--spots " + slices + " --out " + dir_.File("ref.json"));
  ASSERT_EQ(labelled.exit_code, 0) << labelled.err;
  const RunResult r = Calibrate("--spots " + points + " --columns id,x,y,z,sx,sy,sz,slice --skip-rows 1" +
                                " --design " + design_ + " --out " + dir_.File("module.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("Identification: "));
  EXPECT_THAT(r.out, HasSubstr(" spots assigned in 20 slices"));
  Result<ModuleCalibration> ref = ReadModuleCalibrationJson(dir_.File("ref.json"));
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(dir_.File("module.json"));
  ASSERT_TRUE(ref.ok() && cal.ok());
  EXPECT_NEAR(cal->separations[0].length_mm, ref->separations[0].length_mm, 1e-6);
  EXPECT_EQ(cal->sources[0].pattern.beams().size(), 121u);

  // Without --design the unassigned spots are refused.
  std::filesystem::remove(dir_.File("module.json"));
  ExpectRefused(Calibrate("--spots " + points + " --columns id,x,y,z,sx,sy,sz,slice --skip-rows 1 --out " +
                          dir_.File("module.json")),
                3, "spots have no source or beam: give --design");
}

TEST_F(CalibrateCli, ArtifactScalesTheSession) {
  const std::string slices = Session("--noise-scale 0");
  // The session's frame is the design's (mm); the artifact says it is 1% short.
  dir_.Write("targets.csv", "id,x,y,z\nT1,0,0,0\nT2,1661.0495049504951,0,0\nX9,5,5,5\n");
  const RunResult r = Calibrate("--spots " + slices + " --out " + dir_.File("module.json") +
                                " --targets " + dir_.File("targets.csv") +
                                " --artifact T1,T2 --artifact-length-mm 1677.66 --artifact-u-mm 0.0167766");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("scaling         artifact T1-T2 1677.66 mm"));
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(dir_.File("module.json"));
  ASSERT_TRUE(cal.ok());
  EXPECT_NEAR(cal->separations[0].length_mm, 55.0 * 1.01, 1e-6);
  EXPECT_NEAR(cal->separations[0].u_length_mm, 55.0 * 1.01 * 1e-5, 1e-8);
  ASSERT_TRUE(cal->scaling.has_value());
  EXPECT_NEAR(cal->scaling->scale, 1.01, 1e-12);

  std::filesystem::remove(dir_.File("module.json"));
  ExpectRefused(Calibrate("--spots " + slices + " --out " + dir_.File("module.json") + " --targets " +
                          dir_.File("targets.csv") + " --artifact T1,T7 --artifact-length-mm 1677.66"),
                3, "no target 'T7' (--artifact)");
  ExpectRefused(Calibrate("--spots " + slices + " --out " + dir_.File("module.json") +
                          " --artifact T1,T2 --artifact-length-mm 1677.66"),
                2, "--artifact requires --targets");
}

// Pixels of exactly `rgb` in a PNG file.
int CountColour(const std::string& path, int r, int g, int b) {
  const cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
  int count = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
      count += c[2] == r && c[1] == g && c[0] == b;
    }
  }
  return count;
}

// The heat maps of a run share one colour scale: only the source with the
// run's largest mean point-to-ray distance has a cell in the top colour;
// --heatmap-max-mm sets the scale; --heatmap-format picks the format.
TEST_F(CalibrateCli, HeatMapsShareOneColourScale) {
  const std::string slices = Session();
  const auto run = [&](const std::string& extra) {
    std::filesystem::remove_all(dir_.File("report"));
    return Calibrate("--spots " + slices + " --out " + dir_.File("module.json") + " --report " +
                     dir_.File("report") + extra);
  };
  ASSERT_EQ(run("").exit_code, 0);
  // viridis(1) = RGB 253,231,37 fills the top cell (a 64 px cell, minus its
  // text) and the colour bar's top rows (about 3 rows of 22 px).
  const int top_a = CountColour(dir_.File("report/heatmap_A.png"), 253, 231, 37);
  const int top_b = CountColour(dir_.File("report/heatmap_B.png"), 253, 231, 37);
  EXPECT_GT(std::max(top_a, top_b), 2500) << top_a << " " << top_b;
  EXPECT_LT(std::min(top_a, top_b), 300) << top_a << " " << top_b;

  // The noise-level line (bold, RGB 0,110,70): only when every beam is at or
  // below --heatmap-noise-mm, by default the level derived from the session
  // (report/calibration_report.h): this session of pure noise has B's beams
  // all under it, and A's beam 53 (0.143 mm) above it (one of the ~5 % of
  // pure-noise maps that miss the line).
  EXPECT_EQ(CountColour(dir_.File("report/heatmap_A.png"), 0, 110, 70), 0);
  EXPECT_GT(CountColour(dir_.File("report/heatmap_B.png"), 0, 110, 70), 100);
  ASSERT_EQ(run(" --heatmap-noise-mm 10").exit_code, 0);
  EXPECT_GT(CountColour(dir_.File("report/heatmap_A.png"), 0, 110, 70), 100);
  ASSERT_EQ(run(" --heatmap-noise-mm 0.001").exit_code, 0);
  EXPECT_EQ(CountColour(dir_.File("report/heatmap_A.png"), 0, 110, 70), 0);

  // A fixed scale far above the data: every cell near viridis(0) = 68,1,84.
  ASSERT_EQ(run(" --heatmap-max-mm 1000").exit_code, 0);
  EXPECT_GT(CountColour(dir_.File("report/heatmap_A.png"), 68, 1, 84), 121 * 3000);
  EXPECT_LT(CountColour(dir_.File("report/heatmap_A.png"), 253, 231, 37), 300);

  // SVG and PDF, each with the run's provenance.
  ASSERT_EQ(run(" --heatmap-format svg").exit_code, 0);
  const std::string svg = testing_support::ReadAll(dir_.File("report/heatmap_B.svg"));
  EXPECT_THAT(svg, HasSubstr("<title>Source B: mean point-to-ray distance per beam</title>"));
  EXPECT_THAT(svg, HasSubstr("<metadata id=\"opl-provenance\">{\"tool\":\"opl_calibrate\""));
  ASSERT_EQ(run(" --heatmap-format pdf").exit_code, 0);
  const std::string pdf = testing_support::ReadAll(dir_.File("report/heatmap_A.pdf"));
  EXPECT_EQ(pdf.substr(0, 5), "%PDF-");
  EXPECT_THAT(pdf, HasSubstr("/Title (Source A: mean point-to-ray distance per beam)"));
  // "OPL opl_calibrate " in UTF-16 (cairo's encoding when the text has
  // parentheses: "(commit ...)").
  EXPECT_THAT(pdf, HasSubstr("/Creator <FEFF004F0050004C0020006F0070006C005F00630061006C0069006200"
                             "72006100740065"));
  EXPECT_THAT(pdf, HasSubstr("/Subject <FEFF007B00220074006F006F006C0022"));  // {"tool"
  EXPECT_FALSE(std::filesystem::exists(dir_.File("report/heatmap_A.png")));

  std::filesystem::remove(dir_.File("module.json"));
  ExpectRefused(run(" --heatmap-max-mm 0"), 2, "--heatmap-max-mm must be finite and > 0, got 0");
  ExpectRefused(run(" --heatmap-format jpg"), 2, "--heatmap-format");
  ExpectRefused(run(" --heatmap-noise-mm -1"), 2, "--heatmap-noise-mm must be finite and >= 0, got -1");
}

TEST_F(CalibrateCli, BadSessionsAreRefusedAndNothingIsWritten) {
  const std::string out = " --out " + dir_.File("module.json") + " --report " + dir_.File("report");
  // One depth only.
  ASSERT_EQ(Simulate("slices --design " + design_ + " --depths 900 --out " + dir_.File("one.csv")).exit_code, 0);
  ExpectRefused(Calibrate("--spots " + dir_.File("one.csv") + out), 4,
                "opl_calibrate: source 'A': all samples come from one slice (0): a calibration "
                "needs the screen at two depths or more");
  // A source with fewer than three usable beams.
  dir_.Write("few.csv",
             "source,beam,x,y,z,slice\n"
             "A,61,800,0,0,0\nA,61,900,0,0,1\nA,60,800,5,0,0\nA,60,900,5.6,0,1\n");
  ExpectRefused(Calibrate("--spots " + dir_.File("few.csv") + out + " --beams-per-side 11"), 4,
                "only 2 beam(s) have 2 or more usable samples: a calibration needs at least three");
  // Without --beams-per-side the grid is inferred from the largest id (61: 9 x 9),
  // and the message says so.
  ExpectRefused(Calibrate("--spots " + dir_.File("few.csv") + out), 4,
                "the central beam 41 has fewer than 2 usable samples: the gauge (central beam az "
                "= el = 0) cannot be fixed (grid of 9 x 9 inferred from the largest beam id, 61: "
                "give the beams per side if wrong)");
  // A slice that mixes two sources.
  dir_.Write("mixed.csv",
             "source,beam,x,y,z,slice\n"
             "A,61,800,0,0,0\nB,61,800,-55,0,0\n");
  ExpectRefused(Calibrate("--spots " + dir_.File("mixed.csv") + out), 3,
                "mixed.csv:3: slice 0 holds spots of source 'B' and of source 'A' (" +
                    dir_.File("mixed.csv") + ":2): a slice is one grid at one screen position");
  // Unknown columns (refused unless allowed), a missing slice column.
  const std::string slices = Session();
  std::string text = ReadAll(slices);
  text.replace(0, text.find('\n'), text.substr(0, text.find('\n')) + ",sigma_x");
  for (size_t at = text.find('\n', 0); (at = text.find('\n', at + 1)) != std::string::npos;) {
    text.insert(at, ",1");
    at += 2;
  }
  dir_.Write("extra.csv", text);
  ExpectRefused(Calibrate("--spots " + dir_.File("extra.csv") + out), 3,
                "extra.csv:1: unknown column 'sigma_x' (expected source,beam,x,y,z,sx,sy,sz,slice; "
                "--allow-extra-columns ignores it)");
  dir_.Write("noslice.csv", "source,beam,x,y,z\nA,61,800,0,0\n");
  ExpectRefused(Calibrate("--spots " + dir_.File("noslice.csv") + out), 3,
                "noslice.csv:1: missing column 'slice'");
  // Malformed CSV: file and line.
  dir_.Write("bad.csv", "source,beam,x,y,z,slice\nA,61,800,0,zero,0\n");
  ExpectRefused(Calibrate("--spots " + dir_.File("bad.csv") + out), 3, "bad.csv:2: field 'z'");
  // Unknown --loss: usage.
  ExpectRefused(Calibrate("--spots " + slices + out + " --loss bisquare"), 2, "--loss");
  // A --out that cannot be written (issue 19 item 2): exit 5, and the report
  // folder is neither filled nor left behind (it is created only after --out
  // is staged, and removed again when the run writes nothing).
  ExpectRefused(Calibrate("--spots " + slices + " --report " + dir_.File("report") + " --out " +
                          dir_.File("missing/module.json")),
                5, "missing/module.json: cannot write");
  // A disk that fills under --report (issue 19 item 2): every file is limited
  // to 16 KB, which the calibration JSON and the heat maps each exceed. The
  // run fails with exit 5 naming what it could not write, and leaves neither
  // the calibration nor the report folder (ExpectRefused checks both).
  {
    const auto entries = [&] {
      std::vector<std::string> names;
      for (const auto& e : std::filesystem::directory_iterator(dir_.path())) {
        names.push_back(e.path().filename().string());
      }
      std::sort(names.begin(), names.end());
      return names;
    };
    const std::vector<std::string> before = entries();
    const RunResult full = cli_test::RunWithFileSizeLimit(
        OPL_CALIBRATE_EXE, "--spots " + slices + out, 16 * 1024);
    ExpectRefused(full, 5, "cannot write");
    EXPECT_THAT(full.err, HasSubstr("File too large")) << full.err;
    EXPECT_EQ(entries(), before);  // no staged temporary left behind either
  }
  // With --allow-extra-columns the same file calibrates.
  const RunResult ok = Calibrate("--spots " + dir_.File("extra.csv") + out + " --allow-extra-columns");
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

}  // namespace
}  // namespace opl
