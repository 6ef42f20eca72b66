// Every file the tools write says how it was made (issue 18, item 6;
// io/provenance_stamp.h), and a run's outputs appear all together or not at
// all (io/output_set.h). Digests are checked against coreutils' sha256sum.
#include <cstdio>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "io/temp_dir.h"
#include "opl/io/board_json.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/point_cloud_ply.h"
#include "opl/io/provenance_stamp.h"
#include "opl/io/spots_csv.h"

namespace opl {
namespace {

using cli_test::Measure;
using cli_test::RunResult;
using cli_test::Simulate;
using testing_support::ReadAll;
using testing_support::TempDir;

const std::string kExamples = OPL_EXAMPLES_DIR;

std::string Sha256sum(const std::string& path) {
  std::FILE* pipe = popen(("sha256sum '" + path + "'").c_str(), "r");
  if (pipe == nullptr) return "";
  char hex[65] = {0};
  const size_t n = std::fread(hex, 1, 64, pipe);
  pclose(pipe);
  return std::string(hex, n);
}

TEST(ProvenanceCli, MeasureStampsItsReportAndEveryFileWithTheInputsDigests) {
  TempDir dir;
  const std::string ply = dir.Write(
      "scan.ply",
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
      "property double z\nend_header\n1 2 3\n4 5 6\n");
  const std::string cal = kExamples + "/prototype_calibration.json";
  const std::string spots = kExamples + "/prototype_spots.csv";
  const RunResult r = Measure("--calibration " + cal + " --spots " + spots + " --json --apply " +
                              ply + " --out " + dir.File("scan_mm.ply") + " --identified " +
                              dir.File("sorted.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json report = nlohmann::json::parse(r.out);
  const nlohmann::json& p = report.at("provenance");
  EXPECT_EQ(p.at("tool"), "opl_measure");
  EXPECT_EQ(p.at("command_line").at(0), "opl_measure");
  EXPECT_EQ(p.at("command_line").at(2), cal);
  ASSERT_EQ(p.at("inputs").size(), 3u);
  for (const nlohmann::json& input : p.at("inputs")) {
    const std::string path = input.at("path");
    EXPECT_EQ(input.at("sha256"), Sha256sum(path)) << path;
    EXPECT_EQ(input.at("bytes").get<uint64_t>(), std::filesystem::file_size(path)) << path;
  }
  // The scaled PLY: the provenance as header comments, still a valid PLY.
  const std::string scaled = ReadAll(dir.File("scan_mm.ply"));
  EXPECT_NE(scaled.find("\ncomment opl tool: opl_measure\n"), std::string::npos) << scaled;
  EXPECT_NE(scaled.find("\ncomment opl input: " + ply + " "), std::string::npos);
  Result<PlyHeader> header = ParsePlyHeader(scaled, "scan_mm.ply");
  ASSERT_TRUE(header.ok()) << header.status().ToString();
  EXPECT_EQ(header->elements.at(0).count, 2);
  // The identified spots: "# opl" lines that the spots reader skips.
  const std::string sorted = ReadAll(dir.File("sorted.csv"));
  EXPECT_EQ(sorted.rfind("# opl tool: opl_measure\n# opl version: ", 0), 0u);
  EXPECT_NE(sorted.find("# opl input: " + spots + " " +
                        std::to_string(std::filesystem::file_size(spots)) + " bytes sha256 " +
                        Sha256sum(spots) + "\n"),
            std::string::npos);
  Result<SpotsCsvData> read = ReadSpotsCsv(dir.File("sorted.csv"));
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_GT(read->spots.size(), 200u);
}

// A calibration JSON written by one tool carries its provenance and is read
// by the next.
TEST(ProvenanceCli, SimulatedCalibrationCarriesItAndIsStillReadable) {
  TempDir dir;
  const RunResult r = Simulate("calibration --design " + kExamples + "/prototype_design.json --out " +
                               dir.File("cal.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(ReadAll(dir.File("cal.json")));
  EXPECT_EQ(j.at("provenance").at("tool"), "opl_simulate");
  EXPECT_EQ(j.at("provenance").at("inputs").at(0).at("sha256"),
            Sha256sum(kExamples + "/prototype_design.json"));
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(dir.File("cal.json"));
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  const RunResult m = Measure("--calibration " + dir.File("cal.json") + " --spots " + kExamples +
                              "/prototype_spots.csv");
  EXPECT_EQ(m.exit_code, 0) << m.err;
}

// A sweep's CSV and plot: both or neither. The plot's path is a folder, so
// the second output cannot be written: exit 5 and no CSV either.
TEST(ProvenanceCli, SweepWritesBothOutputsOrNeither) {
  TempDir dir;
  std::filesystem::create_directory(dir.File("plot.png"));
  const std::string args = "sweep --design " + kExamples +
                           "/staggered_design.json --param noise_mm --values 0.1,0.2 "
                           "--iterations 20 --seed 3 --threads 2 --out " + dir.File("s.csv") +
                           " --plot ";
  const RunResult bad = Simulate(args + dir.File("plot.png"));
  EXPECT_EQ(bad.exit_code, 5) << bad.err;
  EXPECT_NE(bad.err.find("plot.png: cannot write: is a directory"), std::string::npos) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(dir.File("s.csv")));
  const RunResult good = Simulate(args + dir.File("s.png"));
  ASSERT_EQ(good.exit_code, 0) << good.err;
  Result<std::vector<std::pair<std::string, std::string>>> text = PngTextChunks(ReadAll(dir.File("s.png")));
  ASSERT_TRUE(text.ok()) << text.status().ToString();
  ASSERT_EQ(text->size(), 3u);
  EXPECT_EQ(text->at(0).first, "Software");
  EXPECT_EQ(text->at(0).second.rfind("OPL opl_simulate ", 0), 0u);
  EXPECT_EQ(nlohmann::json::parse(text->at(2).second).at("command_line").at(1), "sweep");
  EXPECT_EQ(ReadAll(dir.File("s.csv")).rfind("# opl tool: opl_simulate\n", 0), 0u);
}

// opl_measure: --identified into a folder that does not exist fails (exit 5)
// and the --apply output, staged first, does not appear.
TEST(ProvenanceCli, MeasureWritesNoOutputWhenOneFails) {
  TempDir dir;
  const std::string xyz = dir.Write("cloud.xyz", "1 2 3\n");
  const RunResult r = Measure("--calibration " + kExamples + "/prototype_calibration.json --spots " +
                              kExamples + "/prototype_spots.csv --apply " + xyz + " --out " +
                              dir.File("cloud_mm.xyz") + " --identified " +
                              dir.File("missing/sorted.csv"));
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.File("cloud_mm.xyz")));
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"cloud.xyz"});
}

}  // namespace
}  // namespace opl
