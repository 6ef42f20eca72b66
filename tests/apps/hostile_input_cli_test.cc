// Issue 19 (security and robustness audit): hostile or corrupt inputs given to
// the tools as a user would. Every one must end at once (well under a second)
// with the documented exit code (3 for a bad file, 2 for an option out of
// range), ONE line on stderr naming the file (and line or field) or the
// option, nothing on stdout, and no output file (nor a temporary one) left.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "io/temp_dir.h"
#include "support/provenance_strip.h"

namespace opl {
namespace {

using cli_test::Calibrate;
using cli_test::Measure;
using cli_test::RunResult;
using cli_test::Simulate;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }
using testing_support::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kExamples = OPL_EXAMPLES_DIR;

// "At once": a refusal takes a few ms; the bound leaves room for a loaded
// machine and for the sanitizer build (.ci/test), while the quadratic or
// unbounded behaviours of issue 19 took seconds to forever.
#if defined(__SANITIZE_ADDRESS__)
constexpr double kAtOnceSeconds = 5.0;
#else
constexpr double kAtOnceSeconds = 1.0;
#endif

// `text` with its first `from` replaced by `to` (the test fails when absent).
std::string ReplaceFirst(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// The 1-based line of `path` (read as is) that starts with `prefix`; 0 if none.
int LineOf(const std::string& path, const std::string& prefix) {
  std::ifstream in(path);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.rfind(prefix, 0) == 0) return number;
  }
  ADD_FAILURE() << path << " has no line starting " << prefix;
  return 0;
}

// A folder with a calibration (cal.json), its spots (spots.csv), a
// calibration session (slices.csv) and a design (design.json), all from the
// prototype example.
class HostileInput : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    shared_ = new TempDir();
    const std::string design = kExamples + "/prototype_design.json";
    ASSERT_EQ(Simulate("calibration --design " + design + " --out " + shared_->File("cal.json"))
                  .exit_code,
              0);
    ASSERT_EQ(Simulate("spots --design " + design + " --out " + shared_->File("spots.csv"))
                  .exit_code,
              0);
    ASSERT_EQ(Simulate("slices --design " + design + " --depths 750:65:1335 --out " +
                       shared_->File("slices.csv"))
                  .exit_code,
              0);
  }
  static void TearDownTestSuite() {
    delete shared_;
    shared_ = nullptr;
  }
  void SetUp() override {
    for (const char* name : {"cal.json", "spots.csv", "slices.csv"}) {
      dir_.Write(name, ReadAll(shared_->File(name)));
    }
    dir_.Write("design.json", ReadAll(kExamples + "/prototype_design.json"));
  }

  // Runs `run` and checks what every refusal shares: `exit_code`, one line on
  // stderr starting "<tool>: " and containing every `parts`, nothing on
  // stdout, no new file in the folder, and done within a second.
  template <typename Runner>
  RunResult ExpectRefused(Runner run, const std::string& args, int exit_code,
                          const std::string& tool, const std::vector<std::string>& parts) {
    const size_t entries_before = dir_.Entries().size();
    const auto start = std::chrono::steady_clock::now();
    RunResult r = run(args);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(r.exit_code, exit_code) << args << "\n" << r.err;
    EXPECT_THAT(r.err, StartsWith(tool + ": ")) << args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    for (const std::string& part : parts) EXPECT_THAT(r.err, HasSubstr(part)) << args;
    EXPECT_EQ(r.out, "") << args;
    EXPECT_EQ(dir_.Entries().size(), entries_before) << args << ": an output was written";
    EXPECT_LT(seconds, kAtOnceSeconds) << args;
    return r;
  }
  RunResult MeasureRefused(const std::string& args, int code,
                           const std::vector<std::string>& parts) {
    return ExpectRefused(Measure, args, code, "opl_measure", parts);
  }
  RunResult CalibrateRefused(const std::string& args, int code,
                             const std::vector<std::string>& parts) {
    return ExpectRefused(Calibrate, args, code, "opl_calibrate", parts);
  }
  RunResult SimulateRefused(const std::string& args, int code,
                            const std::vector<std::string>& parts) {
    return ExpectRefused(Simulate, args, code, "opl_simulate", parts);
  }
  std::string F(const std::string& name) const { return dir_.File(name); }

  static TempDir* shared_;
  TempDir dir_;
};

TempDir* HostileInput::shared_ = nullptr;

// 1. beams_per_side beyond the limit: n^2 allocations and int overflow.
TEST_F(HostileInput, HugeGridsAreRefusedEverywhere) {
  for (const std::string n : {"203", "46341", "100001"}) {
    dir_.Write("big_cal.json", ReplaceFirst(ReadAll(F("cal.json")), "\"beams_per_side\": 11",
                                            "\"beams_per_side\": " + n));
    MeasureRefused("--calibration " + F("big_cal.json") + " --spots " + F("spots.csv") +
                       " --json",
                   3,
                   {F("big_cal.json") + ": sources[0].beams_per_side: must be odd and in [3, 201], "
                                        "got " + n});
    dir_.Write("big_design.json", ReplaceFirst(ReadAll(F("design.json")), "\"beams_per_side\": 11",
                                               "\"beams_per_side\": " + n));
    SimulateRefused("calibration --design " + F("big_design.json") + " --out " + F("out.json"), 3,
                    {F("big_design.json") +
                     ": sources[0].beams_per_side: must be odd and in [3, 201], got " + n});
    CalibrateRefused("--spots " + F("slices.csv") + " --out " + F("out.json") +
                         " --beams-per-side " + n,
                     2, {"--beams-per-side", "must be odd and in [3, 201], got " + n});
  }
  CalibrateRefused("--spots " + F("slices.csv") + " --out " + F("out.json") +
                       " --beams-per-side 11x",
                   2, {"--beams-per-side", "not an integer"});
  // A beam id beyond 201^2 in a session: no grid inferred from it.
  dir_.Write("big_id.csv",
             ReplaceFirst(ReadAll(F("slices.csv")), "\nA,1,", "\nA,2147483647,"));
  CalibrateRefused("--spots " + F("big_id.csv") + " --out " + F("out.json"), 3,
                   {F("big_id.csv") + ":" + std::to_string(LineOf(F("big_id.csv"), "A,2147483647,")) +
                        ": source 'A': beam id 2147483647 is beyond the largest grid (201 x 201 = "
                        "40401 beams)"});
  // A beam id beyond the grid given, and one beam twice in a slice: file:line.
  CalibrateRefused("--spots " + F("big_id.csv") + " --out " + F("out.json") +
                       " --beams-per-side 11",
                   3,
                   {F("big_id.csv") + ":" + std::to_string(LineOf(F("big_id.csv"), "A,2147483647,")) +
                        ": beam id 2147483647 of source 'A' is outside 1..121 (a grid of 11 x 11 "
                        "beams)"});
  // The first spot of source A written twice, on consecutive lines.
  {
    std::string text = ReadAll(F("slices.csv"));
    const size_t begin = text.find("\nA,") + 1;
    const size_t end = text.find('\n', begin) + 1;
    const std::string row = text.substr(begin, end - begin);
    text.insert(end, row);
    dir_.Write("twice.csv", text);
  }
  const int first = LineOf(F("twice.csv"), "A,");
  CalibrateRefused("--spots " + F("twice.csv") + " --out " + F("out.json"), 3,
                   {F("twice.csv") + ":" + std::to_string(first + 1) + ": a second spot of beam ",
                    " of source 'A' in slice ",
                    "(the first is " + F("twice.csv") + ":" + std::to_string(first) +
                        "): a slice holds each beam's spot once"});
}


// 2. JSON nested deeper than 64 levels (memory quadratic in the depth).
TEST_F(HostileInput, DeeplyNestedJsonIsRefusedWithItsLine) {
  const std::string deep = "{\n\"a\": " + std::string(80000, '[');
  dir_.Write("deep.json", deep);
  const std::string where = F("deep.json") + ":2:69: invalid JSON: nested deeper than 64 levels";
  SimulateRefused("calibration --design " + F("deep.json") + " --out " + F("out.json"), 3,
                  {where});
  MeasureRefused("--calibration " + F("deep.json") + " --spots " + F("spots.csv"), 3, {where});
  SimulateRefused("images --scene " + F("deep.json") + " --out " + F("shots"), 3, {where});
}

// 3. A header of 100k columns (the duplicate check was quadratic).
TEST_F(HostileInput, WideCsvHeadersAreCheckedAtOnce) {
  std::string header = "source,beam,x,y,z";
  for (int i = 0; i < 100000; ++i) header += ",c" + std::to_string(i);
  dir_.Write("wide.csv", header + ",x\nA,1,1,2,3\n");
  MeasureRefused("--calibration " + F("cal.json") + " --spots " + F("wide.csv"), 3,
                 {F("wide.csv") + ":1: duplicate column 'x'"});
  CalibrateRefused("--spots " + F("wide.csv") + " --out " + F("out.json"), 3,
                   {F("wide.csv") + ":1: duplicate column 'x'"});
}

// 4. An image whose header claims 100000 x 100000 pixels (uncaught OpenCV
// exception, exit 1).
TEST_F(HostileInput, HugeImageHeadersAreRefusedBeforeDecoding) {
  std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + std::string("\0\0\0\x0dIHDR", 8) +
                    std::string("\0\x01\x86\xa0\0\x01\x86\xa0\x08\x02\0\0\0", 13);
  png += std::string(60 - png.size(), '\0');
  std::filesystem::create_directories(F("shots"));
  for (const char* cam : {"cam0", "cam1", "cam2", "cam3"}) {
    for (const char* laser : {"A", "B"}) {
      dir_.Write(std::string("shots/") + cam + "_" + laser + ".png", png);
    }
  }
  ASSERT_EQ(Simulate("calibration --design " + kExamples + "/scene_small_module.json --out " +
                     F("scene_cal.json"))
                .exit_code,
            0);
  MeasureRefused("--calibration " + F("scene_cal.json") + " --images " + F("shots") +
                     " --scene " + kExamples + "/scene_small.json --spots-out " + F("out.csv"),
                 3,
                 {"_A.png: 100000 x 100000 pixels is beyond the limit of 32768 pixels a side and "
                  "160 megapixels"});
}

// 5. Monte Carlo iterations beyond the limit (bad_alloc after reserving).
TEST_F(HostileInput, MonteCarloIterationsAreBounded) {
  const std::string design = " --design " + F("design.json");
  SimulateRefused("mc" + design + " --iterations 2000000000", 2,
                  {"--iterations: at most 10000000 iterations", "got 2000000000"});
  SimulateRefused("mc" + design + " --iterations 99999999999999999999", 2, {"--iterations"});
  SimulateRefused("mc" + design + " --calibration --iterations 10000001", 2,
                  {"--iterations: at most 10000000 iterations", "got 10000001"});
  SimulateRefused("sweep" + design + " --param noise_mm --values 0.1,0.2 --out " +
                      F("sweep.csv") + " --iterations 2000000000",
                  2, {"--iterations: at most 10000000 iterations"});
}

// 9. Seeds out of 0..2^64-1 were taken as 2^64 - 1.
TEST_F(HostileInput, SeedsOutOfRangeAreUsageErrors) {
  const std::string design = " --design " + F("design.json");
  for (const std::string seed : {"-1", "18446744073709551616", "99999999999999999999999", "1e3",
                                 "0x10", "+5", "' 7'"}) {
    SimulateRefused("spots" + design + " --out " + F("s.csv") + " --seed " + seed, 2,
                    {"--seed: not a seed in 0..18446744073709551615"});
    SimulateRefused("mc" + design + " --iterations 10 --seed " + seed, 2, {"--seed"});
    SimulateRefused("sweep" + design + " --param noise_mm --values 0.1 --out " + F("w.csv") +
                        " --seed " + seed,
                    2, {"--seed"});
    SimulateRefused("slices" + design + " --out " + F("s.csv") + " --seed " + seed, 2,
                    {"--seed"});
  }
  // The whole range is still accepted.
  for (const std::string seed : {"0", "18446744073709551615"}) {
    EXPECT_EQ(Simulate("spots" + design + " --out " + F("s" + seed + ".csv") + " --seed " + seed)
                  .exit_code,
              0);
  }
}

// 6. A design whose pattern_file is /dev/zero read forever; so did any input
// naming a device.
TEST_F(HostileInput, DevicesAreNotReadAsFiles) {
  std::string design = ReadAll(F("design.json"));
  design = ReplaceFirst(design, R"("pattern": "equal_angle",
      "beams_per_side": 11,
      "full_angle_deg": 29.0,)",
                        R"("pattern": "file", "pattern_file": "/dev/zero",)");
  dir_.Write("zero_design.json", design);
  SimulateRefused("calibration --design " + F("zero_design.json") + " --out " + F("out.json"), 3,
                  {F("zero_design.json") + ": sources[0].pattern_file: /dev/zero: cannot read "
                                           "pattern file: not a regular file"});
  const std::string not_regular = "/dev/zero: cannot read: not a regular file";
  SimulateRefused("spots --design /dev/zero --out " + F("out.csv"), 3, {not_regular});
  MeasureRefused("--calibration /dev/zero --spots " + F("spots.csv"), 3, {not_regular});
  MeasureRefused("--calibration " + F("cal.json") + " --spots /dev/zero", 3, {not_regular});
  MeasureRefused("--calibration " + F("cal.json") + " --spots " + F("spots.csv") +
                     " --apply /dev/zero --out " + F("out.csv"),
                 3, {not_regular});
  CalibrateRefused("--spots /dev/urandom --out " + F("out.json"), 3,
                   {"/dev/urandom: cannot read: not a regular file"});
  SimulateRefused("images --scene /dev/zero --out " + F("shots"), 3, {not_regular});
}

// 7. An output naming an input (opl_calibrate --spots s.csv --out s.csv
// overwrote its input and exited 0).
TEST_F(HostileInput, OutputsNamingAnInputAreUsageErrors) {
  const std::string slices_before = ReadAll(F("slices.csv"));
  // The same file by another name: "./", "..", a hard link, a symlink.
  std::filesystem::create_directories(F("sub"));
  std::filesystem::create_hard_link(F("slices.csv"), F("hard.csv"));
  std::filesystem::create_symlink(F("slices.csv"), F("sub/link.csv"));
  for (const std::string& out :
       {F("slices.csv"), dir_.path() + "/./slices.csv", F("sub") + "/../slices.csv",
        F("hard.csv"), F("sub/link.csv")}) {
    CalibrateRefused("--spots " + F("slices.csv") + " --out " + out, 2,
                     {"--out '" + out + "' is the same file as --spots: refusing to overwrite an "
                      "input"});
  }
  EXPECT_EQ(ReadAll(F("slices.csv")), slices_before);
  // --report DIR writes DIR/beams.csv and DIR/samples.csv.
  dir_.Write("sub/samples.csv", slices_before);
  CalibrateRefused("--spots " + F("sub/samples.csv") + " --out " + F("m.json") + " --report " +
                       F("sub"),
                   2, {"--report (samples.csv) '" + F("sub/samples.csv") +
                       "' is the same file as --spots"});
  CalibrateRefused("--spots " + F("slices.csv") + " --design " + F("design.json") + " --out " +
                       F("design.json"),
                   2, {"--out '" + F("design.json") + "' is the same file as --design"});
  const std::string cal = " --calibration " + F("cal.json");
  MeasureRefused(cal + " --spots " + F("spots.csv") + " --identified " + F("cal.json"), 2,
                 {"--identified '" + F("cal.json") + "' is the same file as --calibration"});
  MeasureRefused(cal + " --spots " + F("spots.csv") + " --apply " + F("pts.csv") + " --out " +
                     F("pts.csv"),
                 2, {"--out '" + F("pts.csv") + "' is the same file as --apply"});
  MeasureRefused(cal + " --spots " + F("spots.csv") + " --apply " + F("spots.csv") + " --out " +
                     F("o.csv") + " --identified " + F("o.csv"),
                 2, {"--identified '" + F("o.csv") + "' is the same file as --out"});
  SimulateRefused("spots --design " + F("design.json") + " --out " + F("design.json"), 2,
                  {"--out '" + F("design.json") + "' is the same file as --design"});
  SimulateRefused("sweep --design " + F("design.json") + " --param noise_mm --values 0.1 --out " +
                      F("w.csv") + " --plot " + F("design.json"),
                  2, {"--plot '" + F("design.json") + "' is the same file as --design"});
  SimulateRefused("images --scene " + F("design.json") + " --out " + F("design.json"), 2,
                  {"is the same file as --scene"});
}

// 8. A calibration with the separation A-B twice (55 and 66 mm) measured with
// one of them; a scene where no shot has a laser on measured nothing, exit 0.
TEST_F(HostileInput, ContradictorySeparationsAndScenesWithoutLasers) {
  std::string cal = ReadAll(F("cal.json"));
  const size_t open = cal.find("\"separations\": [");
  ASSERT_NE(open, std::string::npos);
  const size_t start = cal.find('{', open), end = cal.find('}', start);
  const std::string sep = cal.substr(start, end - start + 1);
  const std::string doubled = sep + ", " + ReplaceFirst(sep, "\"length_mm\": 55", "\"length_mm\": 66");
  dir_.Write("twice.json", ReplaceFirst(cal, sep, doubled));
  MeasureRefused("--calibration " + F("twice.json") + " --spots " + F("spots.csv"), 3,
                 {F("twice.json") + ": separations[1]: A-B 66", " mm contradicts separations[0], A-B 55",
                  "(each pair of sources may have one separation)"});

  nlohmann::json scene = nlohmann::json::parse(ReadAll(kExamples + "/scene_small.json"));
  scene["module"] = kExamples + "/scene_small_module.json";
  for (nlohmann::json& shot : scene["shots"]) shot["lasers"] = nlohmann::json::array();
  dir_.Write("dark.json", scene.dump(2));
  ASSERT_EQ(Simulate("calibration --design " + kExamples + "/scene_small_module.json --out " +
                     F("scene_cal.json"))
                .exit_code,
            0);
  std::filesystem::create_directories(F("shots"));
  const std::string no_lasers = F("dark.json") +
                                ": shots: no shot has a laser on (every shot's 'lasers' is empty or "
                                "absent): there are no spots to measure";
  MeasureRefused("--calibration " + F("scene_cal.json") + " --images " + F("shots") +
                     " --scene " + F("dark.json"),
                 3, {no_lasers});
  CalibrateRefused("--images " + F("shots") + " --scene " + F("dark.json") + " --design " +
                       kExamples + "/scene_small_module.json --out " + F("m.json"),
                   3, {no_lasers});
}

// `csv` with field `column` (0-based) of its line `line` (1-based) set to
// `value` (unquoted fields only; `value` is written as given).
std::string WithField(const std::string& csv, int line, int column, const std::string& value) {
  size_t start = 0;
  for (int i = 1; i < line; ++i) start = csv.find('\n', start) + 1;
  size_t end = csv.find('\n', start);
  std::string row = csv.substr(start, end - start);
  size_t from = 0;
  for (int i = 0; i < column; ++i) from = row.find(',', from) + 1;
  const size_t to = std::min(row.find(',', from), row.size());
  row.replace(from, to - from, value);
  return csv.substr(0, start) + row + csv.substr(end);
}

// 6. A spot at x = 1e308 gave exit 4 "all 121 spots lie on one line";
// coordinates and sigmas have a finite range (docs/formats.md, 'Limits').
TEST_F(HostileInput, NumbersBeyondTheirRangeAreBadInput) {
  const std::string spots = ReadAll(F("spots.csv"));
  const std::string cal = "--calibration " + F("cal.json") + " --spots ";
  for (const std::string x : {"1e308", "-1e308", "1.5e12"}) {
    dir_.Write("far.csv", WithField(spots, 2, 2, x));
    MeasureRefused(cal + F("far.csv"), 3,
                   {F("far.csv") + ":2: field 'x': beyond the limit of |value| <= 1e12 scene "
                                   "units, got " + x});
  }
  dir_.Write("far.csv", WithField(spots, 3, 4, "-2e15"));
  MeasureRefused(cal + F("far.csv"), 3, {F("far.csv") + ":3: field 'z': beyond the limit"});
  for (const std::string sigma : {"1e300", "1e-300", "2e12"}) {
    dir_.Write("sigma.csv", WithField(spots, 2, 5, sigma));
    MeasureRefused(cal + F("sigma.csv"), 3,
                   {F("sigma.csv") + ":2: field 'sx': standard deviation beyond the range 1e-12 "
                                     "to 1e12 scene units, got " + sigma});
  }
  // A calibration session and a points CSV (--apply) likewise.
  dir_.Write("far_slices.csv", WithField(ReadAll(F("slices.csv")), 5, 3, "1e300"));
  CalibrateRefused("--spots " + F("far_slices.csv") + " --out " + F("out.json"), 3,
                   {F("far_slices.csv") + ":5: field 'y': beyond the limit"});
  dir_.Write("pts.csv", "id,x,y,z\np1,1,2,3\np2,1,2,1e308\n");
  MeasureRefused(cal + F("spots.csv") + " --apply " + F("pts.csv") + " --out " + F("o.csv"), 3,
                 {F("pts.csv") + ":3: field 'z': beyond the limit of |value| <= 1e12"});
}

// 7. Control characters from a file (an ANSI escape in a source name, a line
// break in a quoted field) reached the terminal raw; a long field was echoed
// whole.
TEST_F(HostileInput, EchoedFieldsAreEscapedAndCut) {
  const std::string spots = ReadAll(F("spots.csv"));
  const std::string cal = "--calibration " + F("cal.json") + " --spots ";
  dir_.Write("esc.csv", WithField(spots, 2, 0, "\x1b[2J\x1b[31mA"));
  RunResult r = MeasureRefused(cal + F("esc.csv"), 3,
                               {F("esc.csv") + ":2: unknown source '\\x1b[2J\\x1b[31mA'"});
  EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << r.err;
  dir_.Write("newline.csv", WithField(spots, 2, 0, "\"A\nB\r\"") );
  MeasureRefused(cal + F("newline.csv"), 3, {"unknown source 'A\\nB\\r'"});
  dir_.Write("long.csv", WithField(spots, 2, 0, std::string(5000, 'Q')));
  r = MeasureRefused(cal + F("long.csv"), 3,
                     {"unknown source '" + std::string(200, 'Q') + "...'"});
  EXPECT_LT(r.err.size(), 600u);
  // A number field: shown quoted, escaped, cut at 40.
  dir_.Write("num.csv", WithField(spots, 2, 2, "1\x07" + std::string(100, '2')));
  MeasureRefused(cal + F("num.csv"), 3,
                 {F("num.csv") + ":2: field 'x': not a number: '1\\x07" + std::string(38, '2') +
                  "...'"});
}

}  // namespace
}  // namespace opl
