// Runs opl_measure and opl_simulate as a user would and checks exit codes,
// messages on stderr, stdout and that nothing is written on any error.
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "io/temp_dir.h"
#include "support/provenance_strip.h"
#include "opl/core/version.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/points_csv.h"
#include "opl/io/spots_csv.h"
#include "pipeline/synthetic_module.h"

namespace opl {
namespace {

using cli_test::Measure;
using cli_test::RunResult;
using cli_test::Simulate;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }
using testing_support::SyntheticCalibration;
using testing_support::SyntheticSpots;
using testing_support::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

std::string SpotsText(const std::vector<Spot>& spots) {
  Result<std::string> text = FormatSpotsCsv(spots);
  EXPECT_TRUE(text.ok());
  return text.ok() ? *text : std::string();
}

// A directory with a good calibration (cal.json), good spots (spots.csv, true
// scale 2 mm per scene unit) and a points file (scene.csv).
class MeasureCli : public ::testing::Test {
 protected:
  void SetUp() override {
    calibration_ = SyntheticCalibration(2);
    ASSERT_TRUE(WriteModuleCalibrationJson(calibration_, dir_.File("cal.json")).ok());
    spots_ = SyntheticSpots(calibration_, testing_support::SceneTransform(), 1000.0,
                            dir_.File("spots.csv"));
    dir_.Write("spots.csv", SpotsText(spots_));
    dir_.Write("scene.csv", "name,x,y,z\nT1,1.5,-2.25,1e3\nT2,0.1,0.2,0.3\n");
  }
  // Runs opl_measure with the calibration, `spots_file` and --apply/--out, and
  // checks that on failure nothing was written.
  RunResult MeasureWith(const std::string& spots_file, const std::string& extra = "") {
    RunResult r = Measure("--calibration " + dir_.File("cal.json") + " --spots " +
                          dir_.File(spots_file) + " --apply " + dir_.File("scene.csv") +
                          " --out " + dir_.File("scaled.csv") + " " + extra);
    if (r.exit_code != 0) {
      EXPECT_EQ(r.out, "");
      EXPECT_EQ(dir_.Entries().size(), entries_before_);  // nothing written, no temp file
    }
    return r;
  }
  void WriteSpots(const std::string& name, const std::string& text) {
    dir_.Write(name, text);
    entries_before_ = dir_.Entries().size();
  }

  TempDir dir_;
  ModuleCalibration calibration_;
  std::vector<Spot> spots_;
  size_t entries_before_ = 3;
};

TEST(MeasureCliUsage, HelpTeachesTheTool) {
  RunResult r = Measure("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, HasSubstr("Measures the scale factor of a photogrammetry scene"));
  EXPECT_THAT(r.out, HasSubstr("opl_measure --calibration cal.json --spots spots.csv\n"));
  EXPECT_THAT(r.out, HasSubstr("--apply"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  EXPECT_THAT(r.out, HasSubstr("  4  no solution"));
  EXPECT_THAT(r.out, HasSubstr("docs/formats.md"));
}

// Is `line` "opl_<name> <x>.<y>.<z> (commit <7+ hex digits>[-dirty] or
// unknown)\n"? (std::regex would do, at the price of GCC 12's
// -Wmaybe-uninitialized inside <regex> in the sanitizer build.)
bool IsVersionLine(const std::string& line) {
  size_t k = 0;
  auto run = [&](auto is) {
    const size_t start = k;
    while (k < line.size() && is(line[k])) ++k;
    return k - start;
  };
  auto literal = [&](const std::string& text) {
    if (line.compare(k, text.size(), text) != 0) return false;
    k += text.size();
    return true;
  };
  auto digit = [](char c) { return c >= '0' && c <= '9'; };
  auto lower = [](char c) { return c >= 'a' && c <= 'z'; };
  auto hex = [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); };
  if (!literal("opl_") || run(lower) == 0 || !literal(" ")) return false;
  for (int part = 0; part < 3; ++part) {
    if (run(digit) == 0 || (part < 2 && !literal("."))) return false;
  }
  if (!literal(" (commit ")) return false;
  if (!literal("unknown")) {
    if (run(hex) < 7) return false;
    literal("-dirty");
  }
  return literal(")\n") && k == line.size();
}

TEST(CliVersion, VersionLineShape) {
  EXPECT_TRUE(IsVersionLine("opl_measure 0.9.0 (commit 5928886)\n"));
  EXPECT_TRUE(IsVersionLine("opl_verify 10.2.33 (commit 5928886ab-dirty)\n"));
  EXPECT_TRUE(IsVersionLine("opl_scene 1.0.0 (commit unknown)\n"));
  EXPECT_FALSE(IsVersionLine("opl_measure 0.9 (commit 5928886)\n"));
  EXPECT_FALSE(IsVersionLine("opl_measure 0.9.0 (commit 59288)\n"));
  EXPECT_FALSE(IsVersionLine("opl_measure 0.9.0 (commit 5928886)"));
  EXPECT_FALSE(IsVersionLine("opl_Measure 0.9.0 (commit 5928886)\n"));
  EXPECT_FALSE(IsVersionLine("opl_measure 0.9.0 (commit 5928886-dirty-x)\n"));
}

// --version on every tool: "<tool> <x.y.z> (commit <git describe>)" on
// stdout, exit 0, the library's VersionString() (core/version.h), which
// names the commit of this checkout.
TEST(CliVersion, EveryToolPrintsItsVersionAndCommit) {
  const std::pair<const char*, const char*> tools[] = {
      {"opl_measure", OPL_MEASURE_EXE}, {"opl_simulate", OPL_SIMULATE_EXE}, {"opl_calibrate", OPL_CALIBRATE_EXE}};
  for (const auto& [name, exe] : tools) {
    const RunResult r = cli_test::Run(exe, "--version");
    EXPECT_EQ(r.exit_code, 0) << name;
    EXPECT_EQ(r.err, "") << name;
    EXPECT_EQ(r.out, std::string(name) + " " + VersionString() + "\n");
    EXPECT_TRUE(IsVersionLine(r.out)) << r.out;
  }
  EXPECT_EQ(VersionString(), VersionNumber() + " (commit " + GitDescribe() + ")");
}

TEST(MeasureCliUsage, UsageErrorsExitWith2) {
  RunResult r = Measure("--spots s.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "opl_measure: --calibration is required (see --help)\n");
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(Measure("--calibration c.json --spots s.csv --bogus").exit_code, 2);
  r = Measure("--calibration c.json --spots s.csv --apply p.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, StartsWith("opl_measure: --apply requires --out"));
}

TEST_F(MeasureCli, GoodInputPrintsTheSummaryAndScalesThePoints) {
  RunResult r = MeasureWith("spots.csv");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, HasSubstr("Source A: 121 spots, 121 used, 0 outliers"));
  EXPECT_THAT(r.out, HasSubstr("Scale factor s = 2.000000000 +- "));
  Result<PointsCsv> scaled = PointsCsv::Read(dir_.File("scaled.csv"));
  ASSERT_TRUE(scaled.ok()) << scaled.status().ToString();
  ASSERT_EQ(scaled->num_points(), 2);
  EXPECT_NEAR(scaled->points()[0].z(), 2000.0, 1e-6);
}

TEST_F(MeasureCli, JsonOutputAndApplyUseExactlyTheSameS) {
  RunResult r = MeasureWith("spots.csv", "--json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double s = j["scale_factor"].get<double>();
  EXPECT_NEAR(s, 2.0, 1e-9);
  EXPECT_GT(j["u_scale_factor"].get<double>(), 0.0);
  ASSERT_EQ(j["sources"].size(), 2u);
  EXPECT_EQ(j["sources"][1]["name"], "B");
  EXPECT_EQ(j["sources"][1]["n_spots"], 121);
  EXPECT_EQ(j["sources"][1]["origin_cov"].size(), 3u);
  EXPECT_EQ(j["lengths"][0]["cal"].get<double>(), calibration_.separations[0].length_mm);
  EXPECT_EQ(ReadAll(dir_.File("scaled.csv")).substr(0, 11), "name,x,y,z\n");
  Result<PointsCsv> scaled = PointsCsv::Read(dir_.File("scaled.csv"));
  ASSERT_TRUE(scaled.ok());
  EXPECT_EQ(scaled->points()[0], Eigen::Vector3d(s * 1.5, s * -2.25, s * 1e3));
  EXPECT_EQ(scaled->points()[1], Eigen::Vector3d(s * 0.1, s * 0.2, s * 0.3));
}

TEST_F(MeasureCli, MalformedCsvIsBadInputNamingFileAndLine) {
  WriteSpots("bad.csv", "source,beam,x,y,z\nA,1,1,2,3\nA,2,1,2\n");
  RunResult r = MeasureWith("bad.csv");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("bad.csv") +
                       ":3: expected 5 fields (as the header), found 4\n");
}

TEST_F(MeasureCli, NanOrInfiniteValueIsBadInput) {
  WriteSpots("nan.csv", "source,beam,x,y,z\nA,1,1,2,3\nA,2,1,NaN,3\n");
  RunResult r = MeasureWith("nan.csv");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("nan.csv") + ":3: field 'y': not finite: 'NaN'\n");
  WriteSpots("inf.csv", "z,y,x,beam,source\n1,2,inf,1,A\n");
  r = MeasureWith("inf.csv");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("inf.csv") + ":2: field 'x': not finite: 'inf'\n");
}

TEST_F(MeasureCli, UnknownSourceIsBadInput) {
  std::vector<Spot> spots = spots_;
  spots[7].source = "Q";
  WriteSpots("unknown.csv", SpotsText(spots));
  RunResult r = MeasureWith("unknown.csv");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("unknown.csv") +
                       ":9: unknown source 'Q' (the calibration has A, B)\n");
}

TEST_F(MeasureCli, DuplicateBeamIdIsBadInput) {
  std::vector<Spot> spots = spots_;
  spots[20].observation.beam_id = spots[2].observation.beam_id;
  WriteSpots("dup.csv", SpotsText(spots));
  RunResult r = MeasureWith("dup.csv");
  EXPECT_EQ(r.exit_code, 3);
  const std::string f = dir_.File("dup.csv");
  EXPECT_EQ(r.err, "opl_measure: " + f + ":22: duplicate spot of source 'A' beam 3 (also at " +
                       f + ":4)\n");
}

TEST_F(MeasureCli, TooFewSpotsIsNoSolution) {
  std::vector<Spot> spots;
  for (const Spot& s : spots_) {
    if (s.source == "A" || s.observation.beam_id <= 3) spots.push_back(s);
  }
  WriteSpots("few.csv", SpotsText(spots));
  RunResult r = MeasureWith("few.csv");
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_THAT(r.err, StartsWith("opl_measure: source 'B': "));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
}

TEST_F(MeasureCli, CollinearSpotsAreNoSolution) {
  std::vector<Spot> spots;
  for (const Spot& s : spots_) {
    // Source B: only its central column, a straight line on the wall.
    if (s.source == "A" || (s.observation.beam_id - 1) % 11 == 5) spots.push_back(s);
  }
  WriteSpots("line.csv", SpotsText(spots));
  RunResult r = MeasureWith("line.csv");
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_THAT(r.err, StartsWith("opl_measure: source 'B': "));
}

TEST_F(MeasureCli, UnreadableOrWrongFormatCalibrationIsBadInput) {
  RunResult r = Measure("--calibration " + dir_.File("none.json") + " --spots " +
                        dir_.File("spots.csv") + " --apply " + dir_.File("scene.csv") + " --out " +
                        dir_.File("scaled.csv"));
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("none.json") +
                       ": cannot open: No such file or directory\n");
  EXPECT_EQ(dir_.Entries().size(), 3u);

  std::string text = ReadAll(dir_.File("cal.json"));
  text.replace(text.find("opl.module_calibration"), 22, "opl.module_design");
  dir_.Write("wrong.json", text);
  r = Measure("--calibration " + dir_.File("wrong.json") + " --spots " + dir_.File("spots.csv") +
              " --apply " + dir_.File("scene.csv") + " --out " + dir_.File("scaled.csv"));
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("wrong.json") +
                       ": format: expected \"opl.module_calibration\", got \"opl.module_design\"\n");
  dir_.Write("syntax.json", "{\"format\": ");
  r = Measure("--calibration " + dir_.File("syntax.json") + " --spots " + dir_.File("spots.csv"));
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, StartsWith("opl_measure: " + dir_.File("syntax.json") +
                                ":1:12: JSON syntax error: "));
  EXPECT_FALSE(std::filesystem::exists(dir_.File("scaled.csv")));
}

TEST_F(MeasureCli, MalformedPointsFileIsBadInput) {
  dir_.Write("scene.csv", "name,x,y\nT1,1,2\n");
  RunResult r = MeasureWith("spots.csv");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("scene.csv") +
                       ":1: missing column 'z' (a points CSV needs x, y and z columns)\n");
}

TEST_F(MeasureCli, UnwritableOutputExitsWith5) {
  RunResult r = Measure("--calibration " + dir_.File("cal.json") + " --spots " +
                        dir_.File("spots.csv") + " --apply " + dir_.File("scene.csv") + " --out " +
                        dir_.File("missing_dir/scaled.csv"));
  EXPECT_EQ(r.exit_code, 5);
  EXPECT_THAT(r.err, StartsWith("opl_measure: " + dir_.File("missing_dir/scaled.csv") +
                                ": cannot write: "));
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(dir_.Entries().size(), 3u);
}

TEST_F(MeasureCli, UnwritableStdoutExitsWith5) {
  const std::string command = std::string("'") + OPL_MEASURE_EXE + "' --calibration " +
                              dir_.File("cal.json") + " --spots " + dir_.File("spots.csv") +
                              " >/dev/full 2>/dev/null";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 5);
}

TEST(SimulateCliUsage, HelpAndUsageErrors) {
  RunResult r = Simulate("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("Simulates the data of an optically projected length scale"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  r = Simulate("spots --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("--noise-scale"));
  EXPECT_THAT(r.out, HasSubstr("--seed"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  r = Simulate("");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, StartsWith("opl_simulate: "));
  EXPECT_EQ(Simulate("spots --out x.csv").exit_code, 2);
  EXPECT_EQ(Simulate("spots --design d.json --out x.csv --seed abc").exit_code, 2);
}

class SimulateCli : public ::testing::Test {
 protected:
  std::string design_ = std::string(OPL_EXAMPLES_DIR) + "/prototype_design.json";
  TempDir dir_;
};

TEST_F(SimulateCli, BadInputsExitWith3AndWriteNothing) {
  RunResult r = Simulate("spots --design " + dir_.File("none.json") + " --out " + dir_.File("s.csv"));
  EXPECT_EQ(r.exit_code, 3);
  // (The design reader is the simulation module's; its message names the file.)
  EXPECT_THAT(r.err, StartsWith("opl_simulate: " + dir_.File("none.json") + ": "));
  EXPECT_THAT(r.err, HasSubstr("No such file or directory"));
  r = Simulate("spots --design " + design_ + " --out " + dir_.File("s.csv") + " --missing 1.5");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, StartsWith("opl_simulate: invalid option: "));
  EXPECT_THAT(r.err, HasSubstr("1.5"));
  r = Simulate("spots --design " + design_ + " --out " + dir_.File("s.csv") + " --noise-scale -1");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, StartsWith("opl_simulate: --noise-scale must be finite and >= 0"));
  dir_.Write("cal.json", ReadAll(design_).substr(0, 40));  // truncated JSON
  r = Simulate("calibration --design " + dir_.File("cal.json") + " --out " + dir_.File("c.json"));
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, StartsWith("opl_simulate: " + dir_.File("cal.json")));
  EXPECT_EQ(dir_.Entries(), std::vector<std::string>{"cal.json"});
}

TEST_F(SimulateCli, UnwritableOutputExitsWith5) {
  RunResult r = Simulate("calibration --design " + design_ + " --out " + dir_.File("no/c.json"));
  EXPECT_EQ(r.exit_code, 5);
  EXPECT_THAT(r.err, StartsWith("opl_simulate: " + dir_.File("no/c.json") + ": cannot write: "));
  EXPECT_TRUE(dir_.Entries().empty());
}

TEST_F(SimulateCli, SameSeedSameSpots) {
  const std::string common = "spots --design " + design_ + " --missing 0.1 --outliers 0.05 ";
  ASSERT_EQ(Simulate(common + "--seed 9 --out " + dir_.File("a.csv")).exit_code, 0);
  ASSERT_EQ(Simulate(common + "--seed 9 --out " + dir_.File("b.csv")).exit_code, 0);
  ASSERT_EQ(Simulate(common + "--seed 10 --out " + dir_.File("c.csv")).exit_code, 0);
  EXPECT_EQ(ReadAll(dir_.File("a.csv")), ReadAll(dir_.File("b.csv")));
  EXPECT_NE(ReadAll(dir_.File("a.csv")), ReadAll(dir_.File("c.csv")));
  Result<SpotsCsvData> spots = ReadSpotsCsv(dir_.File("a.csv"));
  ASSERT_TRUE(spots.ok()) << spots.status().ToString();
  EXPECT_TRUE(spots->has_sigmas);
  // Two 11 x 11 grids, 10% missing: round(0.1 * 242) = 24 dropped.
  EXPECT_EQ(spots->spots.size(), 218u);
  ASSERT_TRUE(spots->spots[0].observation.cov_in_scene.has_value());
  EXPECT_NEAR(std::sqrt((*spots->spots[0].observation.cov_in_scene)(0, 0)), 0.110, 1e-15);
}

// The end-to-end test: simulate an exact calibration and noise-free
// spots of the prototype design, measure: s = 1; --apply scales by exactly s.
TEST_F(SimulateCli, EndToEndNoiseFreeGivesScaleOne) {
  RunResult r = Simulate("calibration --design " + design_ + " --out " + dir_.File("cal.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  r = Simulate("spots --design " + design_ + " --out " + dir_.File("spots.csv") +
               " --noise-scale 0 --missing 0.2 --seed 4");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  dir_.Write("scene.csv", "id,x,y,z\np1,123.456,-7.5,0.001\np2,1,2,3\n");
  r = Measure("--calibration " + dir_.File("cal.json") + " --spots " + dir_.File("spots.csv") +
              " --json --apply " + dir_.File("scene.csv") + " --out " + dir_.File("scaled.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double s = j["scale_factor"].get<double>();
  EXPECT_NEAR(s, 1.0, 1e-6);
  EXPECT_NEAR(j["lengths"][0]["photo"].get<double>(), 55.0, 1e-6);
  EXPECT_TRUE(j["sources"][0]["outliers"].empty());
  Result<PointsCsv> scaled = PointsCsv::Read(dir_.File("scaled.csv"));
  ASSERT_TRUE(scaled.ok());
  EXPECT_EQ(scaled->points()[0], Eigen::Vector3d(s * 123.456, s * -7.5, s * 0.001));
  EXPECT_EQ(scaled->points()[1], Eigen::Vector3d(s * 1, s * 2, s * 3));
  EXPECT_EQ(ReadAll(dir_.File("scaled.csv")).substr(0, 11), "id,x,y,z\np1");
}

TEST_F(SimulateCli, EndToEndWithNoiseAndOutliers) {
  ASSERT_EQ(Simulate("calibration --design " + design_ + " --out " + dir_.File("cal.json")).exit_code, 0);
  ASSERT_EQ(Simulate("spots --design " + design_ + " --out " + dir_.File("spots.csv") +
                     " --seed 5 --outliers 0.03")
                .exit_code,
            0);
  RunResult r = Measure("--calibration " + dir_.File("cal.json") + " --spots " +
                        dir_.File("spots.csv") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double s = j["scale_factor"].get<double>(), u = j["u_scale_factor"].get<double>();
  EXPECT_GT(u, 0.0);
  EXPECT_LT(std::abs(s - 1.0), 4.0 * u);  // consistent with its own uncertainty
  // Every simulated outlier (ground-truth column outlier = 1) is reported, and
  // hardly anything else (a 5 mm offset at 1 m is ~50 sigma; a 5-sigma
  // threshold may flag a good spot now and then).
  std::set<std::pair<std::string, int>> simulated, reported;
  std::istringstream lines(ReadAll(dir_.File("spots.csv")));
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "source,beam,x,y,z,sx,sy,sz,slice,outlier,true_x,true_y,true_z");
  while (std::getline(lines, line)) {
    std::vector<std::string> f;
    std::istringstream fields(line);
    for (std::string v; std::getline(fields, v, ',');) f.push_back(v);
    ASSERT_EQ(f.size(), 13u) << line;
    if (f[9] == "1") simulated.insert({f[0], std::stoi(f[1])});
  }
  for (const nlohmann::json& src : j["sources"]) {
    for (int id : src["outliers"]) reported.insert({src["name"].get<std::string>(), id});
  }
  EXPECT_EQ(simulated.size(), 7u);  // round(0.03 * 242)
  for (const auto& o : simulated) {
    EXPECT_TRUE(reported.count(o)) << o.first << " beam " << o.second << " not reported";
  }
  EXPECT_LE(reported.size(), simulated.size() + 2);
}

}  // namespace
}  // namespace opl
