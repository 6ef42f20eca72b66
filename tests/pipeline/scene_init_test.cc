// InitScene: the matching rules of `opl_scene init` on folders of (empty)
// image files: one folder per camera, one camera's flat folder, run
// selection, laser names, and every refusal with its message. The end-to-end
// check (rendered images, the sequencer's own metadata, opl_measure on the
// result) is tests/apps/scene_cli_test.cc.
#include "opl/pipeline/scene_init.h"

#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/temp_dir.h"

namespace opl {
namespace {

using ::testing::HasSubstr;

SceneCamera Camera(const std::string& name) {
  SceneCamera c;
  c.name = name;
  c.intrinsics.width_px = 640;
  c.intrinsics.height_px = 480;
  c.intrinsics.fx_px = c.intrinsics.fy_px = 600;
  c.intrinsics.cx_px = 319.5;
  c.intrinsics.cy_px = 239.5;
  return c;
}

// The four frames of one measurement run, as the sequencer writes them.
std::string MeasurementRun(int run) {
  std::string out;
  const char* steps[] = {"grid_a", "grid_b", "both", "dark"};
  const bool a[] = {true, false, true, false}, b[] = {false, true, true, false};
  for (int k = 0; k < 4; ++k) {
    out += R"({"sequence":"measurement","run":)" + std::to_string(run) + R"(,"slice":0,"step":")" + steps[k] +
           R"(","step_index":)" + std::to_string(k) + R"(,"frame":)" + std::to_string(k) + R"(,"lasers":{"a":)" +
           (a[k] ? "true" : "false") + R"(,"b":)" + (b[k] ? "true" : "false") + "}}\n";
  }
  return out;
}

void Touch(const testing_support::TempDir& dir, const std::string& name) {
  std::filesystem::create_directories(std::filesystem::path(dir.File(name)).parent_path());
  dir.Write(name, "");
}

SceneInitOptions Options(const testing_support::TempDir& dir, const std::string& metadata,
                         std::vector<std::string> cameras) {
  SceneInitOptions o;
  o.images_dir = dir.File("images");
  for (const std::string& c : cameras) o.cameras.push_back(Camera(c));
  Result<std::vector<FrameMetadata>> frames = ParseFrameMetadataJsonl(metadata, "frames.jsonl");
  EXPECT_TRUE(frames.ok()) << frames.status().message();
  if (frames.ok()) o.frames = *frames;
  o.metadata_name = "frames.jsonl";
  o.tag_size_mm = 140;
  return o;
}

TEST(SceneInit, OneFolderPerCameraFrameMajor) {
  testing_support::TempDir dir;
  // Names sort in shooting order; a non-image file is ignored.
  for (const char* cam : {"left", "right"}) {
    for (const char* f : {"IMG_0007.JPG", "IMG_0008.JPG", "IMG_0009.JPG", "IMG_0010.JPG"}) {
      Touch(dir, std::string("images/") + cam + "/" + f);
    }
    Touch(dir, std::string("images/") + cam + "/notes.txt");
  }
  SceneInitOptions o = Options(dir, MeasurementRun(1), {"right", "left"});
  o.frame = SceneFrameTags{0, 1, 2};
  Result<SceneInit> init = InitScene(o);
  ASSERT_TRUE(init.ok()) << init.status().message();
  EXPECT_TRUE(init->per_camera_folders);
  const std::vector<SceneShot>& shots = init->scene.shots;
  ASSERT_EQ(shots.size(), 8u);
  // Frame-major, cameras in the cameras file's order.
  EXPECT_EQ(shots[0].camera, "right");
  EXPECT_EQ(shots[0].file, "right/IMG_0007.JPG");
  EXPECT_EQ(shots[1].camera, "left");
  EXPECT_EQ(shots[1].file, "left/IMG_0007.JPG");
  EXPECT_EQ(shots[0].lasers, std::vector<std::string>{"A"});
  EXPECT_EQ(shots[2].file, "right/IMG_0008.JPG");
  EXPECT_EQ(shots[2].lasers, std::vector<std::string>{"B"});
  EXPECT_EQ(shots[4].lasers, (std::vector<std::string>{"A", "B"}));
  EXPECT_EQ(shots[7].file, "left/IMG_0010.JPG");
  EXPECT_TRUE(shots[7].lasers.empty());  // the dark frame
  EXPECT_EQ(init->scene.tags.size_mm, 140.0);
  EXPECT_EQ(init->scene.frame->plane_tag, 2);
  EXPECT_TRUE(init->scene.Validate().ok());
  const std::string text = init->ToText();
  EXPECT_THAT(text, HasSubstr("4 frame(s) x 2 camera(s) = 8 shots; runs 1"));
  EXPECT_THAT(text, HasSubstr("dark     off (dark) right/IMG_0010.JPG left/IMG_0010.JPG"));
}

TEST(SceneInit, OneCameraFlatFolderRunsAndLaserNames) {
  testing_support::TempDir dir;
  for (int k = 0; k < 4; ++k) Touch(dir, "images/shot_" + std::to_string(k) + ".png");
  // Runs 1 and 2 in one file: run 2 taken.
  SceneInitOptions o = Options(dir, MeasurementRun(1) + MeasurementRun(2), {"cam0"});
  o.images_dir += "/";  // "images/" is the folder "images": files stay relative to it
  o.runs = {2};
  o.laser_sources = {{"a", "Left"}};
  Result<SceneInit> init = InitScene(o);
  ASSERT_TRUE(init.ok()) << init.status().message();
  EXPECT_FALSE(init->per_camera_folders);
  EXPECT_EQ(init->runs, std::vector<int>{2});
  ASSERT_EQ(init->frames.size(), 4u);
  EXPECT_EQ(init->frames[0].line, 5);
  ASSERT_EQ(init->scene.shots.size(), 4u);
  EXPECT_EQ(init->scene.shots[0].file, "shot_0.png");
  EXPECT_EQ(init->scene.shots[0].lasers, std::vector<std::string>{"Left"});
  EXPECT_EQ(init->scene.shots[2].lasers, (std::vector<std::string>{"B", "Left"}));
  // Every line: 8 frames for 4 images.
  o.runs.clear();
  Result<SceneInit> all = InitScene(o);
  ASSERT_FALSE(all.ok());
  EXPECT_EQ(all.status().message(),
            dir.File("images") + "/: 4 image(s) of camera 'cam0' for 8 frame(s) in frames.jsonl (every run): each "
            "frame needs exactly one image per camera, matched in order (the k-th image by file name is the "
            "k-th frame)");
  o.runs = {3};
  EXPECT_EQ(InitScene(o).status().message(), "frames.jsonl: no frame of run 3 (the file has runs 1, 2)");
  o.runs = {2};
  o.laser_sources = {{"c", "C"}};
  EXPECT_EQ(InitScene(o).status().message(), "laser mapping 'c=C': no laser 'c' in frames.jsonl");
  o.laser_sources.clear();
  o.known_sources = {"A", "Q"};
  EXPECT_EQ(InitScene(o).status().message(),
            "frames.jsonl:6: laser 'b' maps to source 'B', not a source of the calibration (A, Q): map it with "
            "--laser b=SOURCE");
  o.known_sources.clear();
  o.laser_sources = {{"a", "X"}, {"b", "X"}};
  EXPECT_EQ(InitScene(o).status().message(), "frames.jsonl:7: two lasers on map to one source: check --laser");
}

TEST(SceneInit, Refusals) {
  testing_support::TempDir dir;
  for (int k = 0; k < 4; ++k) Touch(dir, "images/cam0/" + std::to_string(k) + ".png");
  // Two cameras, one folder.
  SceneInitOptions o = Options(dir, MeasurementRun(1), {"cam0", "cam1"});
  EXPECT_EQ(InitScene(o).status().message(),
            dir.File("images") + ": no folder for camera(s) cam1 (there is one for cam0): put each camera's "
            "images in a folder named as the camera");
  // Two cameras, no folder.
  SceneInitOptions flat = Options(dir, MeasurementRun(1), {"x", "y"});
  EXPECT_EQ(InitScene(flat).status().message(),
            dir.File("images") + ": the cameras file has 2 cameras (x, y): put each camera's images in a folder "
            "named as the camera (" + dir.File("images") + "/x/, ...)");
  // Images beside the camera folders.
  Touch(dir, "images/stray.jpg");
  SceneInitOptions one = Options(dir, MeasurementRun(1), {"cam0"});
  EXPECT_EQ(InitScene(one).status().message(),
            dir.File("images") + ": 1 image(s) beside the camera folders (e.g. 'stray.jpg'): to which camera do "
            "they belong? move them into its folder");
  std::filesystem::remove(dir.File("images/stray.jpg"));
  // A missing image.
  std::filesystem::remove(dir.File("images/cam0/3.png"));
  EXPECT_THAT(InitScene(one).status().message(),
              HasSubstr("images/cam0: 3 image(s) of camera 'cam0' for 4 frame(s) in frames.jsonl"));
  // Measurement and calibration frames mixed.
  const std::string calibration =
      R"({"sequence":"calibration","run":2,"slice":0,"step":"grid_a","frame":0,"lasers":{"a":true,"b":false}})";
  SceneInitOptions mixed = Options(dir, MeasurementRun(1) + calibration, {"cam0"});
  EXPECT_EQ(InitScene(mixed).status().message(),
            "frames.jsonl: measurement (run 1, line 1) and calibration (run 2, line 5) frames in one scene: "
            "choose the runs of one session (opl_scene init --run N)");
  // Options.
  SceneInitOptions bad = one;
  bad.tag_size_mm = 0;
  EXPECT_EQ(InitScene(bad).status().message(), "tag size: must be > 0 mm (and below 1e6), got 0");
  bad = one;
  bad.images_dir = dir.File("nope");
  EXPECT_EQ(InitScene(bad).status().message(), dir.File("nope") + ": not a folder");
}

TEST(SceneInit, AnImageOfAnotherSizeIsRefused) {
  testing_support::TempDir dir;
  std::filesystem::create_directories(dir.File("images"));
  for (int k = 0; k < 4; ++k) {
    // Frame 2 is 480 x 640 (another camera's, or turned): refused by its header.
    const cv::Mat image = k == 2 ? cv::Mat(640, 480, CV_8UC1, cv::Scalar(0)) : cv::Mat(480, 640, CV_8UC1, cv::Scalar(0));
    ASSERT_TRUE(cv::imwrite(dir.File("images/" + std::to_string(k) + ".png"), image));
  }
  SceneInitOptions o = Options(dir, MeasurementRun(1), {"cam0"});
  EXPECT_EQ(InitScene(o).status().message(),
            dir.File("images/2.png") + ": 480 x 640 pixels, but camera 'cam0' is 640 x 480: not this camera's image?");
  ASSERT_TRUE(cv::imwrite(dir.File("images/2.png"), cv::Mat(480, 640, CV_8UC1, cv::Scalar(0))));
  EXPECT_TRUE(InitScene(o).ok());
}

TEST(SceneInit, CalibrationSlicesAndManualTriggers) {
  testing_support::TempDir dir;
  for (int k = 0; k < 3; ++k) Touch(dir, "images/" + std::to_string(k) + ".png");
  const std::string lines =
      R"({"sequence":"calibration","run":1,"slice":0,"step":"grid_a","frame":0,"lasers":{"a":true,"b":false}})"
      "\n"
      R"({"sequence":"calibration","run":1,"slice":3,"step":"grid_b","frame":13,"lasers":{"a":false,"b":true}})"
      "\n"
      R"({"sequence":"manual","run":2,"slice":null,"step":"manual","frame":0,"lasers":{"a":true,"b":false}})"
      "\n";
  SceneInitOptions o = Options(dir, lines, {"cam0"});
  o.artifact = SceneArtifact{8, 9, 1677.66, 0.005};
  Result<SceneInit> init = InitScene(o);
  ASSERT_TRUE(init.ok()) << init.status().message();
  EXPECT_EQ(init->scene.shots[1].slice, 3);
  EXPECT_EQ(init->scene.shots[2].slice, 0);  // manual: no slice
  EXPECT_EQ(init->scene.artifact->length_mm, 1677.66);
}

}  // namespace
}  // namespace opl
