// opl_scene init end to end, as a user runs it: a virtual-lab session is
// rendered (opl_simulate images: 4 cameras x the sequencer's four frames,
// grid_a, grid_b, both, dark, each camera's images in its own folder), its
// per-frame metadata is written by the sequencer itself (opl::sequencer::
// Sequencer on the simulated chip, after a manual test trigger, so that the
// session is run 2), opl_scene init makes the scene, and opl_measure gives
// the same s on it as on the hand-written scene (which, copied without its
// module file, is measured too: measuring does not need the module). Then
// the refusals: a missing image (exit 3, nothing written), usage errors.
#include <filesystem>
#include <memory>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "opl/io/atomic_file.h"
#include "opl/io/cameras_json.h"
#include "opl/io/scene_json.h"
#include "opl/sequencer/sequencer.h"
#include "opl/sequencer/sim_chip.h"

namespace opl {
namespace {

using cli_test::Measure;
using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;

const std::string kExamples = OPL_EXAMPLES_DIR;

RunResult Scene(const std::string& args) { return cli_test::Run(OPL_SCENE_EXE, args); }

// The sequencer's metadata of a manual trigger (run 1) and one measurement
// (run 2), written by the sequencer on its simulated chip.
void WriteMetadata(const std::string& path) {
  using namespace opl::sequencer;
  SequencerConfig c;
  c.backend = "sim";
  c.line(LineRole::kLaserA).offset = 1;
  c.line(LineRole::kLaserB).offset = 2;
  c.line(LineRole::kBlocker).offset = 3;
  c.line(LineRole::kTrigger) = {4, true};
  c.timings.laser_warmup_ms = 30;
  c.timings.blocker_settle_ms = 50;
  c.timings.trigger_pulse_ms = 10;
  c.timings.exposure_ms = 30;
  c.timings.max_laser_on_ms = 500;
  c.metadata_path = path;
  auto clock = std::make_shared<ManualClock>(1000000000);
  auto chip = SimChip::Open(SimChipOptions{}, clock);
  ASSERT_TRUE(chip.ok());
  Sequencer seq(c, std::move(chip).value(), clock);
  ASSERT_TRUE(seq.Init().ok());
  ASSERT_TRUE(seq.Trigger("").ok());
  auto run_to_end = [&] {
    for (int i = 0; i < 1000; ++i) {
      const std::int64_t d = seq.NextDeadlineNs();
      if (d == Sequencer::kNoDeadline) return;
      clock->SetNs(std::max(d, clock->NowNs()));
      seq.OnTime();
    }
  };
  run_to_end();
  ASSERT_TRUE(seq.Start({SequenceKind::kMeasurement, 1, ""}).ok());
  run_to_end();
}

double ScaleOf(const RunResult& r, double* u) {
  const nlohmann::json report = nlohmann::json::parse(r.out);
  *u = report["measure"]["u_scale_factor"].get<double>();
  return report["measure"]["scale_factor"].get<double>();
}

TEST(SceneCli, InitFromASessionMeasuresAsTheHandWrittenScene) {
  testing_support::TempDir dir;
  // The session: scene_small's cameras, tags and module; per camera the four
  // frames of a measurement, files named as a camera numbers them.
  Result<std::string> example = ReadFileToString(kExamples + "/scene_small.json");
  ASSERT_TRUE(example.ok());
  nlohmann::ordered_json scene = nlohmann::ordered_json::parse(*example);
  scene["module"] = kExamples + "/scene_small_module.json";
  scene["shots"] = nlohmann::ordered_json::array();
  const std::vector<std::vector<std::string>> lasers = {{"A"}, {"B"}, {"A", "B"}, {}};
  for (int frame = 0; frame < 4; ++frame) {
    for (int cam = 0; cam < 4; ++cam) {
      const std::string name = "cam" + std::to_string(cam);
      scene["shots"].push_back({{"camera", name},
                                {"file", name + "/IMG_01" + std::to_string(17 + frame) + ".png"},
                                {"lasers", lasers[static_cast<size_t>(frame)]},
                                {"slice", 0}});
    }
  }
  const std::string render_scene = dir.Write("render.json", scene.dump(1));
  const std::string images = dir.File("session");
  RunResult r = Simulate("images --scene " + render_scene + " --out " + images);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string calibration = dir.File("cal.json");
  r = Simulate("calibration --design " + kExamples + "/scene_small_module.json --out " + calibration);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The hand-written scene, copied alone: its module file is not beside it.
  std::filesystem::create_directories(dir.File("hand"));
  scene["module"] = "scene_small_module.json";
  const std::string hand = dir.Write("hand/scene.json", scene.dump(1));
  ASSERT_FALSE(std::filesystem::exists(dir.File("hand/scene_small_module.json")));
  // The cameras file, as opl_camera calibrate writes it.
  Result<opl::Scene> read = ReadSceneJson(kExamples + "/scene_small.json");
  ASSERT_TRUE(read.ok());
  const std::string cameras = dir.Write("cameras.json", FormatCamerasJson(read->cameras));
  const std::string metadata = dir.File("frames.jsonl");
  WriteMetadata(metadata);
  ASSERT_FALSE(HasFailure());

  // Every line: 5 frames (the manual trigger too) for 4 images a camera.
  const std::string common = "init --images " + images + " --cameras " + cameras + " --metadata " + metadata +
                             " --tag-size-mm 140 --frame 0,1,2 --calibration " + calibration;
  const std::string generated = dir.File("scene.json");
  r = Scene(common + " --out " + generated);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("opl_scene: " + images + "/cam0: 4 image(s) of camera 'cam0' for 5 frame(s) in " +
                               metadata + " (every run): each frame needs exactly one image per camera"));
  EXPECT_FALSE(std::filesystem::exists(generated));
  // Run 2: the dry run prints the scene on stdout and the matching on stderr.
  r = Scene(common + " --run 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json dry = nlohmann::json::parse(r.out);
  EXPECT_EQ(dry["format"], "opl.scene");
  EXPECT_EQ(dry["shots"].size(), 16u);
  EXPECT_THAT(r.err, HasSubstr("4 frame(s) x 4 camera(s) = 16 shots; runs 2"));
  EXPECT_THAT(r.err, HasSubstr("dark"));
  r = Scene(common + " --run 2 --out " + generated);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("wrote " + generated));
  const nlohmann::ordered_json made = nlohmann::ordered_json::parse(testing_support::ReadAll(generated));
  // The shots are the hand-written ones, in the same order.
  ASSERT_EQ(made["shots"].size(), 16u);
  for (size_t k = 0; k < 16; ++k) {
    EXPECT_EQ(made["shots"][k]["camera"], scene["shots"][k]["camera"]) << k;
    EXPECT_EQ(made["shots"][k]["file"], scene["shots"][k]["file"]) << k;
    EXPECT_EQ(made["shots"][k]["lasers"], scene["shots"][k]["lasers"]) << k;
  }
  EXPECT_EQ(made["provenance"]["tool"], "opl_scene");
  EXPECT_EQ(made["provenance"]["inputs"].size(), 3u);
  EXPECT_FALSE(made.contains("module"));

  // The same s from both scenes (the same images and shots), near the truth.
  double u_hand = 0.0, u_made = 0.0;
  r = Measure("--calibration " + calibration + " --images " + images + " --scene " + hand + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double s_hand = ScaleOf(r, &u_hand);
  r = Measure("--calibration " + calibration + " --images " + images + " --scene " + generated + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double s_made = ScaleOf(r, &u_made);
  EXPECT_NEAR(s_made, s_hand, 1e-12 * s_hand);
  EXPECT_NEAR(u_made, u_hand, 1e-9 * u_hand);
  // The scene's unit is the true tag size's: s = 1 within its uncertainty.
  EXPECT_GT(u_made, 1e-4);
  EXPECT_NEAR(s_made, 1.0, 3.0 * u_made);
  std::cout << "s (hand-written) = " << s_hand << " +- " << u_hand << ", s (opl_scene init) = " << s_made
            << " +- " << u_made << "\n";

  // A missing image: refused, and the scene written before is untouched.
  const std::string before = testing_support::ReadAll(generated);
  std::filesystem::remove(images + "/cam2/IMG_0119.png");
  r = Scene(common + " --run 2 --out " + generated);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr(images + "/cam2: 3 image(s) of camera 'cam2' for 4 frame(s)"));
  EXPECT_EQ(testing_support::ReadAll(generated), before);
}

TEST(SceneCli, HelpAndUsage) {
  RunResult r = Scene("init --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("sorted by file name are its"));
  EXPECT_THAT(r.out, HasSubstr("EXIF time is not used"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  r = Scene("init --images x --cameras y --metadata z");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--tag-size-mm"));
  r = Scene("init --images x --cameras y --metadata z --tag-size-mm 100 --laser a");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--laser: expected LASER=SOURCE (e.g. a=A), got 'a'"));
  r = Scene("init --images x --cameras y --metadata y --tag-size-mm 100 --out y");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--out 'y' is the same file as --cameras"));
  r = Scene("--version");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_FALSE(r.out.empty());
}

}  // namespace
}  // namespace opl
