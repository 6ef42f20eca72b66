// Fuzzing the tools (issue 19 item 10; docs/testing.md, "Fuzzing"): mutated
// input files given to opl_measure, opl_calibrate and opl_simulate as a user
// would. Every run must end with an exit code of the documented set
// (docs/cli.md: 0, 3 bad input, 4 no solution; never 1, a signal or a
// hang), and on failure with ONE line on stderr starting "<tool>: " (control
// characters escaped; with exit 3, naming the input file), nothing on stdout
// and no output file (nor a temporary one) left. A few dozen runs per case
// here; OPL_FUZZ_ITERATIONS raises them (tests/fuzz/run_long.sh).
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "fuzz/fuzz_harness.h"
#include "io/temp_dir.h"

namespace opl {
namespace fuzz {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;

// Mutated inputs per case in ctest: each is a process, about 0.15 s in
// Release and several times that under the sanitizers (whose run of the whole
// suite has a time budget).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_UNDEFINED__)
constexpr int kIterations = 6;
#else
constexpr int kIterations = 12;
#endif

struct ToolRun {
  int exit_code = -1;  // -1: killed by a signal (or by the timeout)
  std::string out, err;
};

// Runs `tool args` in `dir` with a time limit (a hang is a finding, not a
// stuck test: timeout kills it and the exit code is then 124 or 137).
ToolRun RunTool(const std::string& exe, const std::string& args, const TempDir& capture,
            double limit_seconds) {
  const std::string out = capture.File("stdout"), err = capture.File("stderr");
  const std::string command = "timeout -s KILL " + std::to_string(static_cast<int>(limit_seconds)) +
                              " '" + exe + "' " + args + " >'" + out + "' 2>'" + err + "'";
  const int status = std::system(command.c_str());
  ToolRun r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = ReadAll(out);
  r.err = ReadAll(err);
  return r;
}

// Lines libpng and libjpeg print on stderr by default (issue 19 item 7).
// The tools decode PNG and JPEG with OPL's own decoder (vision/
// image_decode.h), whose handlers collect them instead: one of them on
// stderr, whatever the exit code, is a finding of its own.
bool IsDecoderLine(const std::string& line) {
  return line.rfind("libpng ", 0) == 0 || line.rfind("Corrupt JPEG data", 0) == 0 ||
         line.rfind("Premature end of JPEG", 0) == 0 || line.rfind("Invalid SOS", 0) == 0 ||
         line.rfind("Warning: ", 0) == 0 || line.rfind("Inconsistent progression", 0) == 0;
}

class CliFuzz : public ::testing::Test {
 protected:
  void SetUp() override {
    settings_ = FuzzSettings::FromEnvironment(kIterations);
    settings_.run_seeds = false;
    // A tool run that accepts its input does the whole work (0.2 to 1.2 s
    // here, under the sanitizers too): five times the readers' bound, so that
    // a loaded CI machine is not a finding; a hang still is.
    if (std::getenv("OPL_FUZZ_SLOW_SECONDS") == nullptr) settings_.slow_seconds *= 5;
    ASSERT_FALSE(work_.path().empty());
  }

  // Copies a corpus file into the work folder.
  std::string Stage(const std::string& corpus_file, const std::string& name) const {
    std::filesystem::create_directories(std::filesystem::path(work_.File(name)).parent_path());
    return work_.Write(name, ReadAll(CorpusDir() + "/" + corpus_file));
  }

  // Writes `input` as `input_name`, runs `tool args`, checks the outcome and
  // removes `outputs` (files or folders, relative to the work folder).
  TargetResult Check(const std::string& tool, const std::string& exe, const std::string& args,
                     const std::string& input, const std::string& input_name,
                     const std::vector<std::string>& outputs) {
    work_.Write(input_name, input);
    const std::vector<std::string> before = work_.Entries();
    const ToolRun r = RunTool(exe, args, capture_, settings_.hang_seconds);
    TargetResult result;
    result.accepted = r.exit_code == 0;
    auto fail = [&](const std::string& what) {
      result.problem = what + " (exit " + std::to_string(r.exit_code) + ", stderr " +
                       std::to_string(r.err.size()) + " bytes: '" + r.err.substr(0, 300) + "')";
    };
    std::vector<std::string> lines;
    size_t from = 0;
    for (size_t nl = r.err.find('\n'); nl != std::string::npos; nl = r.err.find('\n', from)) {
      lines.push_back(r.err.substr(from, nl - from));
      from = nl + 1;
    }
    const bool ends_with_newline = from == r.err.size();
    const auto decoder_line = std::find_if(lines.begin(), lines.end(), IsDecoderLine);
    if (r.exit_code != 0 && r.exit_code != 3 && r.exit_code != 4) {
      fail(r.exit_code == -1 || r.exit_code == 137 ? "killed (signal or timeout)"
                                                   : "exit code outside 0, 3, 4");
    } else if (decoder_line != lines.end()) {
      fail("the image decoder printed on stderr: '" + decoder_line->substr(0, 120) + "'");
    } else if (r.exit_code != 0) {
      // One line from the tool.
      const std::string& last = lines.empty() ? r.err : lines.back();
      if (!ends_with_newline || lines.size() != 1) {
        fail("stderr is not one line");
      } else if (last.rfind(tool + ": ", 0) != 0) {
        fail("stderr does not start with '" + tool + ": '");
      } else if (std::any_of(last.begin(), last.end(), [](char c) {
                   return static_cast<unsigned char>(c) < 0x20 || c == 0x7f;
                 })) {
        fail("stderr holds a control character");
      } else if (r.exit_code == 3 && last.find(work_.path() + "/") == std::string::npos &&
                 last.find(std::filesystem::path(input_name).filename().string() + ":") ==
                     std::string::npos) {
        // Bad input names the file (docs/cli.md): its path (every input is in
        // work_), or a shot by its name in the scene ("cam0_A.png: ...").
        fail("exit 3 without naming an input file");
      } else if (!r.out.empty()) {
        fail("stdout is not empty after a failure");
      } else if (work_.Entries() != before) {
        fail("the folder changed: an output (or a temporary file) was left");
      }
    } else {
      for (const std::string& o : outputs) {
        if (!std::filesystem::exists(work_.File(o))) fail("exit 0 without " + o);
      }
    }
    for (const std::string& o : outputs) std::filesystem::remove_all(work_.File(o));
    return result;
  }

  std::string F(const std::string& name) const { return "'" + work_.File(name) + "'"; }

  FuzzSettings settings_;
  TempDir work_{std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp"};
  TempDir capture_;
};

TEST_F(CliFuzz, MeasureSpots) {
  Stage("calibration_json/tiny_exact.json", "cal.json");
  Stage("points_csv/targets.csv", "pts.csv");
  RunFuzz("spots_csv", InputKind::kText, settings_,
          [&](const std::string& in, const std::string&) {
            return Check("opl_measure", OPL_MEASURE_EXE,
                         "--calibration " + F("cal.json") + " --spots " + F("spots.csv") +
                             " --apply " + F("pts.csv") + " --out " + F("scaled.csv"),
                         in, "spots.csv", {"scaled.csv"});
          });
}

TEST_F(CliFuzz, MeasureCalibration) {
  Stage("spots_csv/tiny.csv", "spots.csv");
  Stage("points_csv/targets.csv", "pts.csv");
  RunFuzz("calibration_json", InputKind::kText, settings_,
          [&](const std::string& in, const std::string&) {
            return Check("opl_measure", OPL_MEASURE_EXE,
                         "--calibration " + F("cal.json") + " --spots " + F("spots.csv") +
                             " --json --identified " + F("identified.csv"),
                         in, "cal.json", {"identified.csv"});
          });
}

TEST_F(CliFuzz, MeasureApply) {
  Stage("calibration_json/tiny_exact.json", "cal.json");
  Stage("spots_csv/tiny.csv", "spots.csv");
  RunFuzz("points_csv", InputKind::kText, settings_,
          [&](const std::string& in, const std::string&) {
            return Check("opl_measure", OPL_MEASURE_EXE,
                         "--calibration " + F("cal.json") + " --spots " + F("spots.csv") +
                             " --apply " + F("pts.csv") + " --out " + F("scaled.csv"),
                         in, "pts.csv", {"scaled.csv"});
          });
}

TEST_F(CliFuzz, CalibrateSlices) {
  RunFuzz("slices_csv", InputKind::kText, settings_,
          [&](const std::string& in, const std::string&) {
            return Check("opl_calibrate", OPL_CALIBRATE_EXE,
                         "--spots " + F("slices.csv") + " --out " + F("module.json") +
                             " --report " + F("report"),
                         in, "slices.csv", {"module.json", "report"});
          });
}

TEST_F(CliFuzz, SimulateDesign) {
  Stage("design_json/aux/pattern3.csv", "aux/pattern3.csv");
  RunFuzz("design_json", InputKind::kText, settings_,
          [&](const std::string& in, const std::string&) {
            return Check("opl_simulate", OPL_SIMULATE_EXE,
                         "spots --design " + F("design.json") + " --out " + F("spots.csv") +
                             " --seed 3",
                         in, "design.json", {"spots.csv"});
          });
}

TEST_F(CliFuzz, SimulateImagesScene) {
  Stage("cli_scene_json/aux/module.json", "aux/module.json");
  RunFuzz("cli_scene_json", InputKind::kText, settings_,
          [&](const std::string& in, const std::string&) {
            return Check("opl_simulate", OPL_SIMULATE_EXE,
                         "images --scene " + F("scene.json") + " --out " + F("shots"), in,
                         "scene.json", {"shots"});
          });
}

// Shots of the tiny scene (one 320 x 240 camera, lasers A and B), rendered
// here, then one of them mutated (as PNG, or re-encoded as JPEG under the
// same name: the reader goes by the signature) and measured. Unharmed, the
// run ends with exit 4 (one camera cannot place the frame tags).
TEST_F(CliFuzz, MeasureImages) {
  const std::string scene = Stage("cli_scene_json/tiny_scene.json", "scene.json");
  Stage("cli_scene_json/aux/module.json", "aux/module.json");
  const TempDir rendered;
  ASSERT_EQ(RunTool(OPL_SIMULATE_EXE, "images --scene '" + scene + "' --out '" +
                                          rendered.File("shots") + "'",
                    capture_, 60)
                .exit_code,
            0);
  ASSERT_EQ(RunTool(OPL_SIMULATE_EXE, "calibration --design " + F("aux/module.json") +
                                          " --out " + F("cal.json"),
                    capture_, 60)
                .exit_code,
            0);
  std::filesystem::create_directories(work_.File("shots"));
  std::vector<CorpusEntry> corpus;
  for (const char* shot : {"cam0_A.png", "cam0_B.png"}) {
    const std::string png = ReadAll(rendered.File(std::string("shots/") + shot));
    work_.Write(std::string("shots/") + shot, png);
    corpus.push_back({shot, png});
    std::vector<uchar> jpeg;
    ASSERT_TRUE(cv::imencode(".jpg", cv::imread(rendered.File(std::string("shots/") + shot)),
                             jpeg, {cv::IMWRITE_JPEG_QUALITY, 85}));
    corpus.push_back({shot, std::string(jpeg.begin(), jpeg.end())});
  }
  RunFuzzOnCorpus("shot_images", corpus, InputKind::kImage, settings_,
                  [&](const std::string& in, const std::string& seed_name) {
                    TargetResult r = Check(
                        "opl_measure", OPL_MEASURE_EXE,
                        "--calibration " + F("cal.json") + " --images " + F("shots") +
                            " --scene " + F("scene.json") + " --spots-out " + F("spots.csv"),
                        in, "shots/" + seed_name, {"spots.csv"});
                    // The unharmed shot back for the next case.
                    for (const CorpusEntry& e : corpus) {
                      if (e.name != seed_name) continue;
                      work_.Write("shots/" + seed_name, e.bytes);  // the PNG
                      break;
                    }
                    return r;
                  });
}

}  // namespace
}  // namespace fuzz
}  // namespace opl
