// opl_calibrate --images as a user runs it: opl_simulate images renders the
// bundled calibration session (examples/calibration_session_small.json, 18
// images with light speckle and sensor noise), opl_calibrate --images
// calibrates the module from them against its nominal design (exit 0, a
// module calibration JSON whose separation is the design's 55 mm within its
// uncertainty, the per-image report, the heat maps, the overlays, all of them
// or none); the same on the harder lab (support/harder_session.h), its
// overlays ringing the true spots and no distractor; and the usage errors
// of --images and --overlays.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "apps/cli_test_util.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/scene_look.h"
#include "support/harder_session.h"

namespace opl {
namespace {

using cli_test::Calibrate;
using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;
using testing_support::ReadAll;

const std::string kExamples = OPL_EXAMPLES_DIR;
const std::string kScene = kExamples + "/calibration_session_small.json";
const std::string kDesign = kExamples + "/calibration_session_small_module.json";

// How many of a shot's true spots (and of its distractors) are ringed in
// green on its overlay (`overlays`/<stem>_overlay.jpg): the ring (radius
// 6 px, 1 px wide, softened by the JPEG) gives 10 or more green pixels
// (green above 110 and 60 above red and blue: the dimmed image is grey)
// within 8 px of the true centre, and none within 1 px of it (a ring, not a
// disc or one moved by its radius). Nothing drawn, or drawn a few pixels
// off, fails; the grid steps are 19 to 28 px.
struct RingCount {
  int visible = 0, ringed = 0;
  int encircled = 0;  // of the true spots, by the distractors' test below
  // Distractors inside the image and 12 px or more from every true spot,
  // and of those the ones encircled in green.
  int distractors = 0, distractors_ringed = 0;
};

RingCount RingedTrueSpots(const SceneRenderer& truth, const std::string& overlays,
                          const std::string& file) {
  RingCount c;
  int index = -1;
  for (size_t i = 0; i < truth.scene().shots.size(); ++i) {
    if (truth.scene().shots[i].file == file) index = static_cast<int>(i);
  }
  EXPECT_GE(index, 0) << file;
  if (index < 0) return c;
  Result<RenderedShot> shot = truth.RenderShot(index);
  EXPECT_TRUE(shot.ok()) << shot.status().ToString();
  const cv::Mat overlay =
      cv::imread(overlays + "/" + file.substr(0, file.rfind('.')) + "_overlay.jpg", cv::IMREAD_COLOR);
  EXPECT_FALSE(overlay.empty()) << file;
  if (!shot.ok() || overlay.empty()) return c;
  cv::Mat bgr[3], red_or_blue;
  cv::split(overlay, bgr);
  cv::max(bgr[0], bgr[2], red_or_blue);
  const cv::Mat green = (bgr[1] >= 110) & (bgr[1] - red_or_blue >= 60);
  const cv::Rect image_rect(0, 0, green.cols, green.rows);
  const auto ringed = [&](const Eigen::Vector2d& px) {
    const int col = static_cast<int>(std::lround(px.x()));
    const int row = static_cast<int>(std::lround(px.y()));
    const cv::Rect near = cv::Rect(col - 8, row - 8, 17, 17) & image_rect;
    const cv::Rect centre = cv::Rect(col - 1, row - 1, 3, 3) & image_rect;
    return cv::countNonZero(green(near)) >= 10 && cv::countNonZero(green(centre)) == 0;
  };
  // A ring around a distractor: green at 4.5-7.5 px from its centre in 6
  // or more of 8 directions (a label beside a near spot's ring, which
  // `ringed` would count, covers one side only).
  const auto encircled = [&](const Eigen::Vector2d& px) {
    bool sector[8] = {};
    for (int dv = -8; dv <= 8; ++dv) {
      for (int du = -8; du <= 8; ++du) {
        const cv::Point p(static_cast<int>(std::lround(px.x())) + du,
                          static_cast<int>(std::lround(px.y())) + dv);
        const double r = std::hypot(du, dv);
        if (r < 4.5 || r > 7.5 || !image_rect.contains(p) || green.at<uint8_t>(p) == 0) continue;
        const int k = static_cast<int>(std::floor((std::atan2(dv, du) + M_PI) / (M_PI / 4.0)));
        sector[std::clamp(k, 0, 7)] = true;
      }
    }
    return std::count(sector, sector + 8, true) >= 6;
  };
  for (const SpotView& v : shot->spots) {
    if (!v.visible) continue;
    ++c.visible;
    c.ringed += ringed(v.center_px) ? 1 : 0;
    c.encircled += encircled(v.center_px) ? 1 : 0;
  }
  for (const Distractor& d : shot->distractors) {
    if (!image_rect.contains(cv::Point(static_cast<int>(d.center_px.x()),
                                       static_cast<int>(d.center_px.y())))) {
      continue;
    }
    bool near_spot = false;  // a true spot's ring would count
    for (const SpotView& v : shot->spots) {
      near_spot = near_spot || (v.center_px.allFinite() && (v.center_px - d.center_px).norm() < 12.0);
    }
    if (near_spot) continue;
    ++c.distractors;
    c.distractors_ringed += encircled(d.center_px) ? 1 : 0;
  }
  return c;
}

TEST(CalibrateImagesCli, SimulateThenCalibrate) {
  testing_support::TempDir dir;
  const std::string shots = dir.File("shots");
  RunResult r = Simulate("images --scene " + kScene + " --out " + shots + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string out = dir.File("cal.json");
  const std::string report = dir.File("rep");
  const std::string overlays = dir.File("overlays");
  // An output that fails after the work (the report folder's name is taken
  // by a file): exit 5, and neither the calibration nor the overlays (staged
  // before the report) nor their folder stays.
  const std::string taken = dir.File("taken");
  std::ofstream(taken) << "a file\n";
  r = Calibrate("--images " + shots + " --scene " + kScene + " --design " + kDesign + " --out " +
                out + " --overlays " + overlays + " --report " + taken + " --threads 2");
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_THAT(r.err, HasSubstr("taken"));
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_FALSE(std::filesystem::exists(overlays));

  r = Calibrate("--images " + shots + " --scene " + kScene + " --design " + kDesign +
                " --out " + out + " --report " + report + " --overlays " + overlays +
                " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The per-image report names every image, then the artifact's scale.
  for (const char* file : {"s0_A_cam0.png", "s1_B_cam1.png", "s2_A_cam2.png"}) {
    EXPECT_THAT(r.out, HasSubstr(file));
  }
  EXPECT_THAT(r.out, HasSubstr("artifact: tags tag 8 - tag 9"));
  EXPECT_THAT(r.out, HasSubstr("A-B"));

  const nlohmann::json json = nlohmann::json::parse(ReadAll(out));
  EXPECT_EQ(json["format"], "opl.module_calibration");
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(out);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->sources.size(), 2u);
  EXPECT_EQ(cal->sources[0].pattern.beams().size(), 121u);
  EXPECT_EQ(cal->sources[1].pattern.beams().size(), 121u);
  ASSERT_EQ(cal->separations.size(), 1u);
  const double length = cal->separations[0].length_mm;
  const double u = cal->separations[0].u_length_mm;
  std::printf("separation %.4f mm +- %.4f mm\n", length, u);
  // Not a vacuous interval: speckled 1024 x 768 images give u of a few
  // hundredths of a mm.
  EXPECT_GT(u, 0.002);
  EXPECT_LT(u, 0.1);
  EXPECT_NEAR(length, 55.0, 3.0 * u);
  ASSERT_TRUE(cal->scaling.has_value());
  EXPECT_NEAR(cal->scaling->artifact_length_mm, 800.0, 1e-12);
  EXPECT_NEAR(cal->scaling->scale, 1.0, 3.0 * cal->scaling->u_scale_relative + 1e-12);

  std::set<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(report)) {
    files.insert(e.path().filename().string());
  }
  EXPECT_EQ(files,
            (std::set<std::string>{"beams.csv", "heatmap_A.png", "heatmap_B.png", "samples.csv"}));
  EXPECT_EQ(ReadAll(report + "/heatmap_B.png").substr(0, 8), "\x89PNG\r\n\x1a\n");

  // One overlay per image, a JPEG of the image's size.
  Result<Scene> scene = ReadSceneJson(kScene);
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  files.clear();
  for (const auto& e : std::filesystem::directory_iterator(overlays)) {
    files.insert(e.path().filename().string());
  }
  EXPECT_EQ(files.size(), scene->shots.size());
  for (const SceneShot& shot : scene->shots) {
    const std::string name = shot.file.substr(0, shot.file.rfind('.')) + "_overlay.jpg";
    EXPECT_EQ(files.count(name), 1u) << name;
    const cv::Mat overlay = cv::imread(overlays + "/" + name, cv::IMREAD_COLOR);
    ASSERT_FALSE(overlay.empty()) << name;
    EXPECT_EQ(overlay.cols, 1024) << name;
    EXPECT_EQ(overlay.rows, 768) << name;
  }
  // Every spot of a slice's grid is identified and ringed in green where the
  // truth puts it, in an image of each source on different slices
  // (RingedTrueSpots).
  Result<SceneRenderer> truth = SceneRenderer::Create(*scene);
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();
  for (const std::string file : {"s0_A_cam0.png", "s1_B_cam1.png"}) {
    const RingCount c = RingedTrueSpots(*truth, overlays, file);
    std::printf("%s: %d of %d true spots ringed in green\n", file.c_str(), c.ringed, c.visible);
    EXPECT_EQ(c.visible, 121) << file;
    EXPECT_GE(c.ringed, c.visible - 2) << file;
  }
}

// The harder lab (tests/support/harder_session.h: colour JPEG 90 on a
// photograph of fruit, ramp, vignetting, defocus, 40 distractors per
// camera, speckle and sensor noise, a laser-off shot per camera and slice):
// opl_simulate renders it, opl_calibrate --overlays calibrates from it
// (exit 0, the separation within 3 u of 55 mm) and writes one overlay per
// shot, laser-off shots included; on lit shots of both sources and two
// slices the identified spots are ringed in green on the true spot pixels,
// and no distractor is: a ring drawn on a distractor's centre would be one
// of its green pixels within 8 px and none within 1 px.
TEST(CalibrateImagesCli, HarderSessionOverlaysRingTheTrueSpots) {
  testing_support::TempDir dir;
  const std::string source_dir = kExamples + "/..";
  const std::string scene_file = dir.File("harder_session.json");
  std::ofstream(scene_file) << test::HarderSessionJson(/*noisy=*/true, source_dir).dump(1);
  const std::string shots = dir.File("shots");
  RunResult r = Simulate("images --scene " + scene_file + " --out " + shots + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string out = dir.File("cal.json");
  const std::string overlays = dir.File("overlays");
  r = Calibrate("--images " + shots + " --scene " + scene_file + " --design " + kDesign +
                " --out " + out + " --overlays " + overlays + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("s1_B_cam1.jpg (cam1)"));
  EXPECT_THAT(r.out, HasSubstr("minus s1_off_cam1.jpg"));
  Result<ModuleCalibration> cal = ReadModuleCalibrationJson(out);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  ASSERT_EQ(cal->separations.size(), 1u);
  const Separation& sep = cal->separations[0];
  std::printf("harder session: separation %.4f mm +- %.4f mm\n", sep.length_mm, sep.u_length_mm);
  EXPECT_GT(sep.u_length_mm, 0.02);
  EXPECT_LT(sep.u_length_mm, 0.2);
  EXPECT_NEAR(sep.length_mm, 55.0, 3.0 * sep.u_length_mm);

  Result<Scene> scene = ReadSceneJson(scene_file);
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  ASSERT_EQ(scene->shots.size(), 27u);
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(overlays)) files += e.is_regular_file();
  EXPECT_EQ(files, 27);
  Result<SceneRenderer> truth = SceneRenderer::Create(*scene);
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();
  for (const std::string file : {"s1_A_cam0.jpg", "s2_B_cam2.jpg"}) {
    const RingCount c = RingedTrueSpots(*truth, overlays, file);
    std::printf("%s: %d of %d true spots ringed in green (%d encircled); %d of %d distractors "
                "encircled\n",
                file.c_str(), c.ringed, c.visible, c.encircled, c.distractors_ringed, c.distractors);
    EXPECT_GE(c.visible, 110) << file;
    EXPECT_GE(c.ringed, c.visible - 6) << file;
    EXPECT_GE(c.encircled, c.visible - 6) << file;  // the distractors' test sees rings
    EXPECT_GE(c.distractors, 10) << file;
    EXPECT_EQ(c.distractors_ringed, 0) << file;
  }
}

// --overlays is refused before any work (exit 2, nothing written) when its
// folder cannot be written or an overlay would replace an input or another
// output; the images are not even read (there are none here).
TEST(CalibrateImagesCli, OverlaysRefusedBeforeAnyWork) {
  testing_support::TempDir dir;
  const std::string shots = dir.File("shots");
  const std::string out = dir.File("cal.json");
  const std::string file = dir.File("file");
  std::ofstream(file) << "a file\n";
  const auto calibrate = [&](const std::string& scene, const std::string& overlays,
                             const std::string& extra = "") {
    return Calibrate("--images " + shots + " --scene " + scene + " --design " + kDesign +
                     " --out " + out + " --overlays " + overlays + extra);
  };
  RunResult r = calibrate(kScene, file);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--overlays '" + file + "': not a folder"));
  r = calibrate(kScene, file + "/overlays");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("cannot be created ('" + file + "' is not a writable folder)"));
  // An overlay over another output.
  r = Calibrate("--images " + shots + " --scene " + kScene + " --design " + kDesign + " --out " +
                dir.File("s0_A_cam0_overlay.jpg") + " --overlays " + dir.path());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("the overlay of shot 's0_A_cam0.png') is the same file as --out"));

  // A scene whose shot files collide with the overlays: one shot's image is
  // named as another's overlay; two shots have the same stem.
  nlohmann::json json = nlohmann::json::parse(ReadAll(kScene));
  json["module"] = kDesign;
  nlohmann::json over_input = json;
  over_input["shots"][1]["file"] = "s0_A_cam0_overlay.jpg";
  const std::string scene_over_input = dir.File("over_input.json");
  std::ofstream(scene_over_input) << over_input.dump();
  r = calibrate(scene_over_input, shots);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("is the same file as the image of shot 's0_A_cam0_overlay.jpg': "
                               "refusing to overwrite an input"));
  nlohmann::json same_stem = json;
  same_stem["shots"][1]["file"] = "s0_A_cam0.jpg";
  const std::string scene_same_stem = dir.File("same_stem.json");
  std::ofstream(scene_same_stem) << same_stem.dump();
  r = calibrate(scene_same_stem, dir.File("overlays"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("shots 's0_A_cam0.png' and 's0_A_cam0.jpg' would both have the "
                               "overlay 's0_A_cam0_overlay.jpg'"));
  // --overlays is for --images.
  r = Calibrate("--spots s.csv --overlays " + dir.File("overlays") + " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--overlays requires --images"));
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_FALSE(std::filesystem::exists(dir.File("overlays")));
  EXPECT_FALSE(std::filesystem::exists(shots));
}

TEST(CalibrateImagesCli, UsageErrors) {
  testing_support::TempDir dir;
  const std::string out = dir.File("cal.json");
  RunResult r = Calibrate("--images " + dir.File("shots") + " --scene " + kScene + " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--images needs --design"));
  r = Calibrate("--images " + dir.File("shots") + " --design " + kDesign + " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--images requires --scene"));
  r = Calibrate("--images " + dir.File("shots") + " --scene " + kScene + " --design " + kDesign +
                " --targets t.csv --artifact T1,T2 --artifact-length-mm 800 --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--targets/--artifact are for --spots"));
  r = Calibrate("--spots s.csv --one-pose-per-camera --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--one-pose-per-camera requires --images"));
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace opl
