// `opl_simulate images` as a user runs it: a small scene gives one decodable
// PNG per shot and a truth.json whose spot pixels are where the images are
// bright; bad input gives the documented exit code and no output file.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "apps/cli_test_util.h"

namespace opl {
namespace {

using cli_test::Simulate;
namespace fs = std::filesystem;

// Two 320 x 240 cameras 1 m from a wall, two tags, a 5 x 5 grid.
std::string SmallScene(const std::string& shot_camera = "left") {
  return R"({"format": "opl.scene", "version": 1,
    "cameras": [
      {"name": "left", "width_px": 320, "height_px": 240,
       "intrinsics": {"fx": 300, "fy": 300, "cx": 159.5, "cy": 119.5, "k1": -0.05},
       "pose": {"center_mm": [0, 150, 0], "look_at_mm": [1000, 0, 0]}},
      {"name": "right", "width_px": 320, "height_px": 240,
       "intrinsics": {"fx": 300, "fy": 300, "cx": 159.5, "cy": 119.5, "k1": -0.05},
       "pose": {"center_mm": [0, -150, 0], "look_at_mm": [1000, 0, 0]}}],
    "tags": {"size_mm": 120, "placements": [
      {"id": 0, "center_mm": [1000, 300, 250], "normal": [-1, 0, 0], "up": [0, 0, 1]},
      {"id": 1, "center_mm": [1000, -300, -250], "normal": [-1, 0, 0], "up": [0, 0, 1]}]},
    "module": {"sources": [{"name": "A", "pattern": "equal_angle", "beams_per_side": 5,
                            "full_angle_deg": 16, "origin_mm": [0, 0, 0],
                            "rotation_xyz_rad": [0, 0, 0]}],
               "surface": {"type": "plane", "point_mm": [1000, 0, 0], "normal": [-1, 0, 0]},
               "spot_noise_mm": [0, 0, 0]},
    "spots": {"diameter_mm": 12},
    "image": {"bit_depth": 8, "read_noise": 0.004},
    "shots": [{"camera": ")" + shot_camera + R"(", "file": "left_A.png", "lasers": ["A"]},
              {"camera": "right", "file": "sub/right_A.png", "lasers": ["A"]}]})";
}

TEST(SimulateImagesCli, WritesImagesAndTruth) {
  testing_support::TempDir dir;
  const std::string scene = dir.Write("scene.json", SmallScene());
  const std::string out = dir.File("out");
  const cli_test::RunResult r =
      Simulate("images --scene '" + scene + "' --out '" + out + "' --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("left_A.png  camera left  lasers 1  tags in image 2/2  spots visible 25/25"),
            std::string::npos)
      << r.out;
  const cv::Mat left = cv::imread(out + "/left_A.png", cv::IMREAD_UNCHANGED);
  const cv::Mat right = cv::imread(out + "/sub/right_A.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(left.empty());
  ASSERT_FALSE(right.empty());
  EXPECT_EQ(left.type(), CV_8UC1);
  EXPECT_EQ(left.cols, 320);
  EXPECT_EQ(left.rows, 240);
  const nlohmann::json truth = nlohmann::json::parse(testing_support::ReadAll(out + "/truth.json"));
  EXPECT_EQ(truth["format"], "opl.scene_truth");
  EXPECT_EQ(truth["version"], 1);
  ASSERT_EQ(truth["tags"].size(), 2u);
  // Tag 1's centre is where the file put it; its corners are 120 mm apart.
  EXPECT_EQ(truth["tags"][1]["center_mm"], nlohmann::json::parse("[1000.0, -300.0, -250.0]"));
  ASSERT_EQ(truth["spots"].size(), 25u);
  EXPECT_DOUBLE_EQ(truth["spots"][12]["point_mm"][0].get<double>(), 1000.0);
  ASSERT_EQ(truth["shots"].size(), 2u);
  EXPECT_EQ(truth["shots"][1]["file"], "sub/right_A.png");
  // Every visible spot's pixel is bright in the image (background 0.25 of 255
  // = 64; a spot peaks at 0.6 of full scale above it).
  for (const auto& spot : truth["shots"][0]["spots"]) {
    ASSERT_TRUE(spot["visible"].get<bool>());
    const int u = static_cast<int>(std::lround(spot["center_px"][0].get<double>()));
    const int v = static_cast<int>(std::lround(spot["center_px"][1].get<double>()));
    EXPECT_GT(left.at<uint8_t>(v, u), 64 + 60) << u << ", " << v;
  }
  // The wall far from spots and tags reads the background level.
  EXPECT_NEAR(left.at<uint8_t>(5, 160), 64, 4);
}

TEST(SimulateImagesCli, BadSceneWritesNothing) {
  testing_support::TempDir dir;
  const std::string scene = dir.Write("scene.json", SmallScene("cam9"));
  const std::string out = dir.File("out");
  const cli_test::RunResult r = Simulate("images --scene '" + scene + "' --out '" + out + "'");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_simulate: " + scene + ": shots[0].camera: no camera named 'cam9'\n");
  EXPECT_FALSE(fs::exists(out));
  // A shot index out of range is a usage error.
  const std::string good = dir.Write("good.json", SmallScene());
  const cli_test::RunResult u =
      Simulate("images --scene '" + good + "' --out '" + out + "' --shots 0,2");
  EXPECT_EQ(u.exit_code, 2);
  EXPECT_EQ(u.err, "opl_simulate: --shots: 2: the scene has 2 shots, 0..1 (see --help)\n");
  EXPECT_FALSE(fs::exists(out));
  // An output folder that cannot be created: exit 5, nothing written.
  const std::string blocker = dir.Write("blocker", "x");
  const cli_test::RunResult w =
      Simulate("images --scene '" + good + "' --out '" + blocker + "/out'");
  EXPECT_EQ(w.exit_code, 5) << w.err;
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"blocker", "good.json", "scene.json"}));
}

TEST(SimulateImagesCli, HelpTeachesTheCommand) {
  const cli_test::RunResult r = Simulate("images --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text : {"truth.json", "--scene", "--out", "--shots", "--threads",
                           "opl_simulate images --scene examples/scene_small.json --out lab",
                           "Exit codes"}) {
    EXPECT_NE(r.out.find(text), std::string::npos) << text;
  }
}

}  // namespace
}  // namespace opl
