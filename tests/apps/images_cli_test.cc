// The image front end as a user runs it: opl_simulate images renders the
// bundled small scene (examples/scene_small.json), opl_measure --images
// measures it (exit 0, a per-image report, s near the truth's, --spots-out
// written), and the command-line errors of --images in opl_measure and
// opl_calibrate (usage: 2; bad input: 3; no solution: 4), with no output
// file left behind on failure.
#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli_test_util.h"
#include "opl/core/format.h"

namespace opl {
namespace {

using cli_test::Calibrate;
using cli_test::Measure;
using cli_test::RunResult;
using cli_test::Simulate;
using ::testing::HasSubstr;

const std::string kExamples = OPL_EXAMPLES_DIR;
const std::string kScene = kExamples + "/scene_small.json";

TEST(ImagesCli, SimulateThenMeasure) {
  testing_support::TempDir dir;
  const std::string shots = dir.File("shots");
  const std::string calibration = dir.File("cal.json");
  RunResult r = Simulate("calibration --design " + kExamples + "/scene_small_module.json --out " +
                         calibration);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = Simulate("images --scene " + kScene + " --out " + shots);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string spots_out = dir.File("spots3d.csv");
  const std::string overlays = dir.File("overlays");
  // An overlays folder that cannot be written: refused before any work.
  const std::string file = dir.File("a_file");
  std::ofstream(file) << "a file\n";
  r = Measure("--calibration " + calibration + " --images " + shots + " --scene " + kScene +
              " --overlays " + file);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("--overlays '" + file + "': not a folder"));
  // An output that cannot be written: exit 5, and none of the others stays
  // (the overlays were staged first), nor the overlays' folder.
  r = Measure("--calibration " + calibration + " --images " + shots + " --scene " + kScene +
              " --overlays " + overlays + " --spots-out " + dir.File("missing/spots3d.csv"));
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_FALSE(std::filesystem::exists(overlays));
  r = Measure("--calibration " + calibration + " --images " + shots + " --scene " + kScene +
              " --spots-out " + spots_out + " --overlays " + overlays + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // One overlay per shot, the image's size, with the identified spots drawn
  // in green (pure green pixels do not occur in the dimmed grey image).
  for (const std::string name : {"cam0_A", "cam1_A", "cam2_A", "cam3_A", "cam0_B", "cam1_B",
                                 "cam2_B", "cam3_B"}) {
    const cv::Mat overlay = cv::imread(overlays + "/" + name + "_overlay.jpg", cv::IMREAD_COLOR);
    ASSERT_FALSE(overlay.empty()) << name;
    EXPECT_EQ(overlay.cols, 1024);
    EXPECT_EQ(overlay.rows, 768);
    cv::Mat green;
    cv::inRange(overlay, cv::Scalar(0, 170, 0), cv::Scalar(90, 255, 90), green);
    EXPECT_GT(cv::countNonZero(green), 100 * 5) << name;  // ~100 rings, ~11 px each seen
  }
  const nlohmann::json report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["format"], "opl.image_measure_report");
  EXPECT_EQ(report["images"].size(), 8u);
  for (const auto& image : report["images"]) {
    EXPECT_TRUE(image["placed"].get<bool>()) << image["file"];
    EXPECT_GT(image["spots_matched"].get<int>(), 60) << image["file"];
  }
  // The scene's unit is the nominal tag size's, which is the true size: s is
  // 1 within its uncertainty. The two-step s (speckled spots: about 1% for
  // this small scene) is in "measure"; the reported s is, by default, the
  // scale inside the adjustment: within 3 of its u of the truth (1), and at
  // least 5 times more precise than the two-step s on this scene (measured:
  // 0.00037 against 0.0135).
  const double s = report["measure"]["scale_factor"].get<double>();
  const double u = report["measure"]["u_scale_factor"].get<double>();
  EXPECT_GT(u, 1e-4);
  EXPECT_LT(u, 0.02);
  EXPECT_NEAR(s, 1.0, 3.0 * u);
  EXPECT_EQ(report["scale_method"], "adjustment");
  EXPECT_EQ(report["scale_method_note"], "");
  ASSERT_TRUE(report.contains("projector")) << r.out;
  const double sp = report["scale_factor"].get<double>();
  const double up = report["u_scale_factor"].get<double>();
  EXPECT_EQ(sp, report["projector"]["scale_factor"].get<double>());
  EXPECT_EQ(up, report["projector"]["u_scale_factor"].get<double>());
  EXPECT_GT(up, 0.0);
  EXPECT_NEAR(sp, 1.0, 3.0 * up);
  EXPECT_LT(5.0 * up, u);
  std::ifstream in(spots_out);
  std::string header;
  while (std::getline(in, header) && header.rfind("# opl ", 0) == 0) {
  }  // the provenance lines first
  EXPECT_EQ(header.rfind("source,beam,x,y,z", 0), 0u) << header;

  // --no-scale-in-adjustment: the two-step s is the result, the same as
  // above (the same images, the same two-step path), and the text says so.
  r = Measure("--calibration " + calibration + " --images " + shots + " --scene " + kScene +
              " --no-scale-in-adjustment --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json two_step = nlohmann::json::parse(r.out);
  EXPECT_FALSE(two_step.contains("projector"));
  EXPECT_EQ(two_step["scale_method"], "two-step");
  EXPECT_THAT(two_step["scale_method_note"].get<std::string>(), HasSubstr("not asked for"));
  EXPECT_EQ(two_step["scale_factor"].get<double>(), two_step["measure"]["scale_factor"].get<double>());
  EXPECT_NEAR(two_step["scale_factor"].get<double>(), s, 1e-12);
  r = Measure("--calibration " + calibration + " --images " + shots + " --scene " + kScene);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("Result: s = " + FormatPrintf("%.9f", sp)));
  EXPECT_THAT(r.out, HasSubstr("the scale inside the adjustment (the two-step s above"));

  // A damaged shot that still decodes (a text chunk with a bad CRC after
  // IHDR: libpng used to print "libpng warning: tEXt: CRC error" on
  // stderr): measured as before, nothing on stderr from the decoder, and
  // the decoder's warning is the image's, in the report's warnings and its decode_warnings.
  const std::string shot = shots + "/cam0_A.png";
  std::string png = testing_support::ReadAll(shot);
  const std::string text("Comment\0hello", 13);
  png.insert(33, std::string("\0\0\0", 3) + static_cast<char>(text.size()) + "tEXt" + text +
                     "\xde\xad\xbe\xef");
  dir.Write("shots/cam0_A.png", png);
  // One run (the JSON holds the report's warnings as the text prints them).
  r = Measure("--calibration " + calibration + " --images " + shots + " --scene " + kScene +
              " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, ::testing::Not(HasSubstr("libpng")));
  const nlohmann::json damaged = nlohmann::json::parse(r.out);
  EXPECT_EQ(FormatPrintf("%.9f", damaged["scale_factor"].get<double>()), FormatPrintf("%.9f", sp));
  bool warned = false;
  for (const auto& warning : damaged["warnings"]) {
    warned |= warning.get<std::string>().rfind(
                  "cam0_A.png: damaged image file, decoded anyway (tEXt: CRC error)", 0) == 0;
  }
  EXPECT_TRUE(warned) << damaged["warnings"];
  for (const auto& image : damaged["images"]) {
    EXPECT_EQ(image["decode_warnings"],
              image["file"] == "cam0_A.png" ? nlohmann::json({"tEXt: CRC error"})
                                            : nlohmann::json::array())
        << image["file"];
  }
}

TEST(ImagesCli, UsageErrors) {
  RunResult r = Measure("--calibration c.json --spots s.csv --images d --scene " + kScene);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("give either --spots or --images"));
  r = Measure("--calibration c.json --images d");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--images requires --scene"));
  r = Measure("--calibration c.json --images d --scene " + kScene + " --identified x.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--identified is for --spots; with --images use --spots-out"));
  r = Calibrate("--images d --scene " + kScene + " --out m.json");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--images needs --design"));
  r = Measure("--calibration c.json --spots s.csv --one-pose-per-camera");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--one-pose-per-camera requires --images"));
}

TEST(ImagesCli, MissingImagesAndBadSceneAreInputErrors) {
  testing_support::TempDir dir;
  const std::string calibration = dir.File("cal.json");
  ASSERT_EQ(Simulate("calibration --design " + kExamples + "/scene_small_module.json --out " +
                     calibration)
                .exit_code,
            0);
  const std::string empty = dir.File("empty");
  std::filesystem::create_directories(empty);
  const std::string spots_out = dir.File("never.csv");
  RunResult r = Measure("--calibration " + calibration + " --images " + empty + " --scene " +
                        kScene + " --spots-out " + spots_out);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr(": no such image"));
  EXPECT_FALSE(std::filesystem::exists(spots_out));
  const std::string bad_scene = dir.File("bad_scene.json");
  std::ofstream(bad_scene) << "{\"format\": \"opl.scene\", \"version\": 1}";
  r = Measure("--calibration " + calibration + " --images " + empty + " --scene " + bad_scene);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("bad_scene.json"));
  // A camera without its calibration.
  nlohmann::json scene;
  std::ifstream(kScene) >> scene;
  scene["module"] = kExamples + "/scene_small_module.json";
  scene["cameras"][2].erase("intrinsics");
  const std::string uncalibrated = dir.File("uncalibrated.json");
  std::ofstream(uncalibrated) << scene.dump();
  r = Measure("--calibration " + calibration + " --images " + empty + " --scene " + uncalibrated);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("uncalibrated.json: cameras[2].intrinsics: missing field"));
}

}  // namespace
}  // namespace opl
