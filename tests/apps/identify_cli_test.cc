// Runs opl_measure as a user would on an unsorted point export
// (examples/unsorted_points.txt: the spots of examples/fabricated_design.json
// shuffled, without source or beam, 15 % missing, 1 % moved 5 mm, and 10 %
// spurious points, half of them 0.5-3 mm from a real spot), and checks every
// assignment against the truth of the simulation
// (tests/apps/unsorted_points_truth.csv). Then the refusals and the errors.
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"

namespace opl {
namespace {

using cli_test::Measure;
using cli_test::RunResult;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kExamples = OPL_EXAMPLES_DIR;
const std::string kExport = " --spots " + kExamples +
                            "/unsorted_points.txt --columns id,x,y,z,sx,sy,sz --skip-rows 2";
const std::string kCalibration = " --calibration " + kExamples + "/fabricated_calibration.json";

std::vector<std::vector<std::string>> ReadCsv(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind('#', 0) == 0) continue;  // OPL's provenance lines
    std::vector<std::string> fields;
    std::stringstream s(line);
    for (std::string f; std::getline(s, f, ',');) fields.push_back(f);
    if (!line.empty() && line.back() == ',') fields.push_back("");
    rows.push_back(fields);
  }
  return rows;
}

TEST(IdentifyCli, UnsortedExportIsIdentifiedAndMeasured) {
  testing_support::TempDir dir;
  const RunResult r =
      Measure(kCalibration + kExport + " --json --identified " + dir.File("sorted.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.contains("identification"));
  EXPECT_EQ(j["identification"]["points"], 226);
  for (const nlohmann::json& s : j["identification"]["sources"]) {
    EXPECT_EQ(s["outcome"], "found") << s.dump();
  }
  // s = 1 within 3 u(s) (the scene is in mm).
  EXPECT_NEAR(j["scale_factor"].get<double>(), 1.0, 3.0 * j["u_scale_factor"].get<double>());

  // Every assignment against the truth.
  std::map<std::string, std::vector<std::string>> truth;  // id -> source, beam, kind
  for (const auto& row : ReadCsv(std::string(OPL_SOURCE_DIR) + "/tests/apps/unsorted_points_truth.csv")) {
    ASSERT_EQ(row.size(), 4u);
    truth[row[0]] = {row[1], row[2], row[3]};
  }
  const auto sorted = ReadCsv(dir.File("sorted.csv"));
  ASSERT_EQ(sorted.size(), 227u);
  ASSERT_EQ(sorted[0].back(), "id");
  int right = 0, wrong = 0, real = 0, spurious_assigned = 0;
  for (size_t i = 1; i < sorted.size(); ++i) {
    const std::vector<std::string>& row = sorted[i];
    const std::vector<std::string>& t = truth.at(row.back());
    const bool assigned = row[0] != "\"\"" && !row[0].empty();
    if (t[2] == "spot") ++real;
    if (!assigned) continue;
    if (t[2] == "spurious") {
      ++spurious_assigned;
    } else if (row[0] == t[0] && row[1] == t[1]) {
      ++right;
    } else {
      ++wrong;
    }
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(spurious_assigned, 0);
  EXPECT_GE(right, 0.99 * real) << right << " of " << real << " real spots";
}

TEST(IdentifyCli, TextReportSaysWhatWasIdentified) {
  const RunResult r = Measure(kCalibration + kExport);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, StartsWith("Identification: "));
  EXPECT_THAT(r.out, HasSubstr("  A: found, "));
  EXPECT_THAT(r.out, HasSubstr("  B: found, "));
}

// The ideal prototype pattern is symmetric under a 90 deg roll: its spots,
// unlabelled, cannot be identified for sure, and the tool refuses (exit 4)
// rather than guess, writing nothing.
TEST(IdentifyCli, SymmetricPatternIsRefused) {
  testing_support::TempDir dir;
  std::ifstream in(kExamples + "/prototype_spots.csv");
  std::string header, line, unlabelled;
  std::getline(in, header);
  unlabelled = header + "\n";
  while (std::getline(in, line)) {  // source and beam emptied, the rest kept
    const size_t second_comma = line.find(',', line.find(',') + 1);
    unlabelled += "," + line.substr(second_comma) + "\n";
  }
  const std::string spots = dir.Write("unlabelled.csv", unlabelled);
  const RunResult r = Measure(" --calibration " + kExamples + "/prototype_calibration.json --spots " +
                              spots + " --identified " + dir.File("sorted.csv"));
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_THAT(r.err, StartsWith("opl_measure: "));
  EXPECT_THAT(r.err, HasSubstr("ambiguous"));
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(dir.Entries().size(), 1u);  // only the input
}

TEST(IdentifyCli, PointTableErrors) {
  testing_support::TempDir dir;
  RunResult r = Measure(kCalibration + " --spots " + kExamples +
                        "/unsorted_points.txt --columns id,x,y,q");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, StartsWith("opl_measure: --columns: unknown column name 'q'"));
  r = Measure(kCalibration + " --spots " + kExamples + "/prototype_spots.csv --skip-rows 1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("need --columns"));
  const std::string bad = dir.Write("bad.txt", "P1 1000 2 3\nP2 1000 x 3\n");
  r = Measure(kCalibration + " --spots " + bad + " --columns id,x,y,z");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("bad.txt:2: field 'y': not a number: 'x'"));
}

}  // namespace
}  // namespace opl
