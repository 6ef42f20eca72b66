// Runs `opl_simulate slices` as a user would: a simulated calibration session
// (a screen at several depths) written as a spots CSV with a slice column.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "io/temp_dir.h"
#include "support/provenance_strip.h"
#include "opl/io/spots_csv.h"

namespace opl {
namespace {

using cli_test::RunResult;
using cli_test::Simulate;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }
using testing_support::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const char kHeader[] = "source,beam,x,y,z,sx,sy,sz,slice,screen,outlier,true_x,true_y,true_z";
const char kHeaderNoSigmas[] = "source,beam,x,y,z,slice,screen,outlier,true_x,true_y,true_z";

// The data lines of a CSV, split at commas (after checking the header).
std::vector<std::vector<std::string>> Rows(const std::string& text, const std::string& header) {
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, header);
  std::vector<std::vector<std::string>> rows;
  while (std::getline(lines, line)) {
    std::vector<std::string> f;
    std::istringstream fields(line);
    for (std::string v; std::getline(fields, v, ',');) f.push_back(v);
    rows.push_back(f);
  }
  return rows;
}

class SimulateSlicesCli : public ::testing::Test {
 protected:
  // Runs `slices` with the prototype design and `extra`, output in out.csv.
  RunResult Slices(const std::string& extra, const std::string& design = "") {
    return Simulate("slices --design " + (design.empty() ? design_ : design) + " --out " +
                    dir_.File("out.csv") + " " + extra);
  }
  // A failed run: one line on stderr, nothing on stdout, no file written.
  void ExpectFailure(const RunResult& r, int exit_code, const std::string& err_prefix) {
    EXPECT_EQ(r.exit_code, exit_code) << r.err;
    EXPECT_THAT(r.err, StartsWith(err_prefix));
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.out, "");
    EXPECT_EQ(dir_.Entries(), entries_before_);
  }

  std::string design_ = std::string(OPL_EXAMPLES_DIR) + "/prototype_design.json";
  TempDir dir_;
  std::vector<std::string> entries_before_;
};

TEST_F(SimulateSlicesCli, HelpTeachesSlicesDepthsAndTheirFrame) {
  RunResult r = Simulate("slices --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, HasSubstr("calibration session"));
  EXPECT_THAT(r.out, HasSubstr("slice i * K + k"));
  EXPECT_THAT(r.out, HasSubstr("first:step:last"));
  EXPECT_THAT(r.out, HasSubstr("750:65:1335"));
  EXPECT_THAT(r.out, HasSubstr("mean viewing direction"));
  EXPECT_THAT(r.out, HasSubstr("--tilt-deg"));
  EXPECT_THAT(r.out, HasSubstr("--curvature"));
  EXPECT_THAT(r.out, HasSubstr("--missing"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  EXPECT_THAT(Simulate("--help").out, HasSubstr("slices"));
}

TEST_F(SimulateSlicesCli, WritesTenSlicesWithMissingSpotsAndOutliers) {
  RunResult r = Slices("--depths 750:65:1335 --seed 3 --missing 0.1 --outliers 0.02 "
                       "--tilt-deg 2 --curvature 1e-5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(dir_.Entries(), std::vector<std::string>{"out.csv"});
  const std::string text = ReadAll(dir_.File("out.csv"));

  // The standard reader reads it (extra columns ignored), with sigmas.
  Result<SpotsCsvData> read = ReadSpotsCsv(dir_.File("out.csv"));
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_TRUE(read->has_sigmas);
  EXPECT_EQ(read->spots.size(), 10u * 218u);  // per slice: 242 hits, round(24.2) missing

  std::map<int, int> spots_per_slice, outliers_per_slice;
  std::map<int, std::set<std::string>> present;  // screen -> "source/beam"
  std::set<int> grid_slices;
  for (const std::vector<std::string>& f : Rows(text, kHeader)) {
    ASSERT_EQ(f.size(), 14u);
    const int slice = std::stoi(f[9]);  // the screen
    // One grid per slice: source A (index 0) on screen k is slice k, B is 10 + k.
    EXPECT_EQ(std::stoi(f[8]), (f[0] == "A" ? 0 : 10) + slice);
    grid_slices.insert(std::stoi(f[8]));
    ++spots_per_slice[slice];
    outliers_per_slice[slice] += f[10] == "1" ? 1 : 0;
    present[slice].insert(f[0] + "/" + f[1]);
    // Spots of screen k lie near depth 750 + 65 k (screens tilted by 2 deg,
    // slightly curved: within a few tens of mm).
    EXPECT_NEAR(std::stod(f[11]), 750.0 + 65.0 * slice, 30.0);
  }
  EXPECT_EQ(grid_slices.size(), 20u);
  ASSERT_EQ(spots_per_slice.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(spots_per_slice[k], 218) << "slice " << k;
    EXPECT_EQ(outliers_per_slice[k], 4) << "slice " << k;  // round(0.02 * 218)
  }
  EXPECT_NE(present[0], present[1]);  // different spots missing from each slice

  // Deterministic for a seed; another seed gives other spots.
  ASSERT_EQ(Simulate("slices --design " + design_ + " --out " + dir_.File("again.csv") +
                     " --depths 750:65:1335 --seed 3 --missing 0.1 --outliers 0.02 "
                     "--tilt-deg 2 --curvature 1e-5")
                .exit_code,
            0);
  EXPECT_EQ(ReadAll(dir_.File("again.csv")), text);
  ASSERT_EQ(Simulate("slices --design " + design_ + " --out " + dir_.File("other.csv") +
                     " --depths 750:65:1335 --seed 4 --missing 0.1 --outliers 0.02 "
                     "--tilt-deg 2 --curvature 1e-5")
                .exit_code,
            0);
  EXPECT_NE(ReadAll(dir_.File("other.csv")), text);
}

TEST_F(SimulateSlicesCli, NoiseFreeFlatScreensAreAtTheDepths) {
  RunResult r = Slices("--depths '800, 1000,1200' --noise-scale 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<std::vector<std::string>> rows =
      Rows(ReadAll(dir_.File("out.csv")), kHeaderNoSigmas);
  ASSERT_EQ(rows.size(), 3u * 242u);
  const double depth[3] = {800, 1000, 1200};
  for (const std::vector<std::string>& f : rows) {
    ASSERT_EQ(f.size(), 11u);
    const int slice = std::stoi(f[6]);  // the screen
    ASSERT_GE(slice, 0);
    ASSERT_LT(slice, 3);
    EXPECT_NEAR(std::stod(f[2]), depth[slice], 1e-9);  // x = depth: screens normal to +X
    EXPECT_EQ(f[2], f[8]);                             // noise free: x = true_x
    EXPECT_EQ(f[7], "0");
  }
}

TEST_F(SimulateSlicesCli, TheDesignsPlanesAreTheSlicesWithoutDepths) {
  nlohmann::json design = nlohmann::json::parse(ReadAll(design_));
  design["surface"] = {{"type", "planes"},
                       {"planes",
                        {{{"point_mm", {900.0, 0.0, 0.0}}, {"normal", {-1.0, 0.0, 0.0}}},
                         {{"point_mm", {1000.0, 0.0, 0.0}}, {"normal", {-1.0, 0.2, 0.0}}},
                         {{"point_mm", {1100.0, 0.0, 0.0}}, {"normal", {-1.0, 0.0, 0.1}}}}}};
  const std::string path = dir_.Write("planes.json", design.dump(2));
  RunResult r = Slices("--seed 2", path);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::set<std::string> slices;
  for (const auto& f : Rows(ReadAll(dir_.File("out.csv")), kHeader)) slices.insert(f[9]);
  EXPECT_EQ(slices, (std::set<std::string>{"0", "1", "2"}));
  // --depths replaces the design's planes.
  r = Slices("--depths 700,800", path);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  slices.clear();
  for (const auto& f : Rows(ReadAll(dir_.File("out.csv")), kHeader)) slices.insert(f[9]);
  EXPECT_EQ(slices, (std::set<std::string>{"0", "1"}));
}

TEST_F(SimulateSlicesCli, BadDepthsExitWithTheDocumentedCodeAndWriteNothing) {
  // Malformed --depths: a usage error (2).
  ExpectFailure(Slices("--depths 750:abc:1335"), 2,
                "opl_simulate: --depths: depth list '750:abc:1335': 'abc' is not a finite "
                "number (see --help)");
  ExpectFailure(Slices("--depths 1335:65:750"), 2,
                "opl_simulate: --depths: depth list '1335:65:750': first (1335) must be <= "
                "last (750)");
  ExpectFailure(Slices("--depths 750:0:1335"), 2, "opl_simulate: --depths: ");
  ExpectFailure(Slices("--depths ''"), 2, "opl_simulate: --depths: empty depth list");
  // Well-formed but invalid values: bad input (3).
  ExpectFailure(Slices("--depths=-5,100"), 3,
                "opl_simulate: invalid option: depths_mm[0] must be finite and > 0, got -5");
  ExpectFailure(Slices("--depths 0:100:1000"), 3,
                "opl_simulate: invalid option: depths_mm[0] must be finite and > 0, got 0");
  ExpectFailure(Slices("--depths 1000 --tilt-deg 95"), 3,
                "opl_simulate: invalid option: tilt_deg must be finite and in (-90, 90), got 95");
  ExpectFailure(Slices("--depths 1000 --missing 1.5"), 3,
                "opl_simulate: invalid option: missing_fraction must be in [0, 1], got 1.5");
  // No --depths and a design that is not a list of planes; --tilt-deg without --depths.
  ExpectFailure(Slices(""), 2,
                "opl_simulate: --depths is required: the design's surface is a plane, not a "
                "list of planes (see --help)");
  ExpectFailure(Slices("--tilt-deg 3"), 2, "opl_simulate: --tilt-deg requires --depths");
  // Unreadable design (3), unwritable output (5).
  ExpectFailure(Slices("--depths 1000", dir_.File("none.json")), 3,
                "opl_simulate: " + dir_.File("none.json") + ": cannot open");
  ExpectFailure(Simulate("slices --design " + design_ + " --depths 1000 --out " +
                         dir_.File("no/out.csv")),
                5, "opl_simulate: " + dir_.File("no/out.csv") + ": cannot write: ");
}

}  // namespace
}  // namespace opl
