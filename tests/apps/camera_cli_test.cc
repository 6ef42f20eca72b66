// opl_camera as a user runs it: calibrate from OpenCV's sample photographs
// (a cameras JSON that the reader accepts; --into a scene keeping every other
// field; the report files), the errors (one line naming the input, the
// documented exit code, no output), and board (the PNG's size, the board
// JSON).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "support/provenance_strip.h"
#include "cli_test_util.h"
#include "opl/io/board_json.h"
#include "opl/io/cameras_json.h"
#include "opl/io/scene_json.h"
#include "opl/report/board_print.h"

namespace opl {
namespace {

using cli_test::RunResult;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }
using testing_support::TempDir;

RunResult Camera(const std::string& args) { return cli_test::Run(OPL_CAMERA_EXE, args); }

std::vector<std::string> Photos() {
  std::vector<std::string> files;
  for (int i = 1; i <= 14; ++i) {
    char name[128];
    std::snprintf(name, sizeof(name), "/usr/share/doc/opencv-doc/examples/data/left%02d.jpg", i);
    if (std::ifstream(name).good()) files.push_back(name);
  }
  return files;
}

std::string Join(const std::vector<std::string>& files) {
  std::string out;
  for (const std::string& f : files) out += "'" + f + "' ";
  return out;
}

// One line on stderr, "opl_camera: <message>".
void ExpectOneLineError(const RunResult& r, const std::string& starts_with) {
  EXPECT_EQ(r.err.rfind("opl_camera: " + starts_with, 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(CameraCli, CalibratesPhotosIntoACamerasJsonAndAReport) {
  const std::vector<std::string> photos = Photos();
  if (photos.size() < 10) GTEST_SKIP() << "opencv-doc's sample photographs not installed";
  TempDir dir;
  // A folder: the photographs and a picture without the board.
  const std::string shots = dir.File("shots");
  std::filesystem::create_directory(shots);
  for (const std::string& p : photos) {
    std::filesystem::copy_file(p, shots + "/" + std::filesystem::path(p).filename().string());
  }
  cv::imwrite(shots + "/zz_blank.png", cv::Mat(480, 640, CV_8UC1, cv::Scalar(100)));
  const RunResult r = Camera("calibrate --images '" + shots + "' --chessboard 9x6 --square-mm 25 --out '" +
                             dir.File("cams.json") + "' --camera left --report '" + dir.File("rep") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("13 of 14 images used"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("zz_blank.png: no board found"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fx = 536.4"), std::string::npos) << r.out;
  Result<std::vector<SceneCamera>> cams = ReadCamerasJson(dir.File("cams.json"));
  ASSERT_TRUE(cams.ok()) << cams.status().ToString();
  ASSERT_EQ(cams->size(), 1u);
  const SceneCamera& cam = (*cams)[0];
  EXPECT_EQ(cam.name, "left");
  EXPECT_EQ(cam.intrinsics.width_px, 640);
  EXPECT_NEAR(cam.intrinsics.fx_px, 536.46, 0.05);
  ASSERT_TRUE(cam.calibration.has_value());
  EXPECT_NEAR(cam.calibration->intrinsics_std[0], 0.88, 0.05);
  EXPECT_EQ(cam.calibration->num_views, 13);
  EXPECT_EQ(cam.calibration->num_corners, 13 * 54);
  // The report JSON and the coverage picture.
  const nlohmann::json report = nlohmann::json::parse(ReadAll(dir.File("rep/camera_report.json")));
  EXPECT_EQ(report["format"], "opl.camera_calibration_report");
  EXPECT_EQ(report["views"].size(), 13u);
  ASSERT_EQ(report["rejected"].size(), 1u);
  EXPECT_EQ(report["rejected"][0]["file"], shots + "/zz_blank.png");
  EXPECT_EQ(report["held_fixed"], nlohmann::json::array({"k3"}));
  const cv::Mat coverage = cv::imread(dir.File("rep/coverage.png"));
  EXPECT_FALSE(coverage.empty());
  EXPECT_NE(r.out.find("report: " + dir.File("rep/camera_report.json") + ", " + dir.File("rep/coverage.png")),
            std::string::npos)
      << r.out;
}

// --coverage-format svg|pdf: the picture in that format (and no PNG), with
// the run's provenance: the SVG's <metadata> element, the PDF's Creator.
TEST(CameraCli, CoverageAsSvgOrPdfCarriesTheProvenance) {
  const std::vector<std::string> photos = Photos();
  if (photos.size() < 10) GTEST_SKIP() << "opencv-doc's sample photographs not installed";
  TempDir dir;
  const std::string base = "calibrate --images " + Join(photos) + " --chessboard 9x6 --square-mm 25 --out '" +
                           dir.File("cams.json") + "' --report '" + dir.File("rep") + "' --coverage-format ";
  RunResult r = Camera(base + "svg");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // (Read raw: testing_support::ReadOutput strips the provenance.)
  std::ifstream svg_file(dir.File("rep/coverage.svg"), std::ios::binary);
  const std::string svg((std::istreambuf_iterator<char>(svg_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(svg.find("<title>Camera 'cam0': 13 views, 702 corners, image 640 x 480 px</title>"),
            std::string::npos);
  EXPECT_NE(svg.find("<metadata id=\"opl-provenance\">{\"tool\":\"opl_camera\""), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir.File("rep/coverage.png")));
  r = Camera(base + "pdf");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream pdf_file(dir.File("rep/coverage.pdf"), std::ios::binary);
  const std::string pdf((std::istreambuf_iterator<char>(pdf_file)), std::istreambuf_iterator<char>());
  EXPECT_EQ(pdf.rfind("%PDF-", 0), 0u);
  // "OPL opl_camera " in UTF-16 (cairo's encoding when the text has
  // parentheses: "(commit ...)").
  EXPECT_NE(pdf.find("/Creator <FEFF004F0050004C0020006F0070006C005F00630061006D006500720061"), std::string::npos);
  EXPECT_NE(pdf.find("/Subject <FEFF007B00220074006F006F006C0022"), std::string::npos);  // {"tool"
  EXPECT_NE(r.out.find(dir.File("rep/coverage.pdf")), std::string::npos) << r.out;
}

TEST(CameraCli, IntoASceneReplacesOneCameraAndKeepsTheRest) {
  const std::vector<std::string> photos = Photos();
  if (photos.size() < 10) GTEST_SKIP() << "opencv-doc's sample photographs not installed";
  TempDir dir;
  const std::string examples = OPL_EXAMPLES_DIR;
  std::filesystem::copy_file(examples + "/scene_small.json", dir.File("scene.json"));
  std::filesystem::copy_file(examples + "/scene_small_module.json", dir.File("scene_small_module.json"));
  const std::string before = ReadAll(dir.File("scene.json"));
  const RunResult r = Camera("calibrate --images " + Join(photos) + " --chessboard 9x6 --square-mm 25 --into '" +
                             dir.File("scene.json") + "' --camera cam2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("replaced camera 'cam2'"), std::string::npos) << r.out;
  Result<Scene> scene = ReadSceneJson(dir.File("scene.json"));
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  Result<Scene> original = ParseSceneJson(before, "before", dir.path());
  ASSERT_TRUE(original.ok());
  ASSERT_EQ(scene->cameras.size(), original->cameras.size());
  EXPECT_EQ(scene->cameras[2].intrinsics.width_px, 640);
  EXPECT_NEAR(scene->cameras[2].intrinsics.fx_px, 536.46, 0.05);
  ASSERT_TRUE(scene->cameras[2].cam_from_scene.has_value());  // the pose is kept
  EXPECT_TRUE(scene->cameras[2].cam_from_scene->translation.isApprox(original->cameras[2].cam_from_scene->translation));
  nlohmann::ordered_json a = nlohmann::ordered_json::parse(before), b = nlohmann::ordered_json::parse(ReadAll(dir.File("scene.json")));
  for (int k : {0, 1, 3}) EXPECT_EQ(a["cameras"][k].dump(), b["cameras"][k].dump()) << k;
  a.erase("cameras");
  b.erase("cameras");
  EXPECT_EQ(a.dump(), b.dump());
  // A new name is appended.
  const RunResult added = Camera("calibrate --images " + Join(photos) + " --chessboard 9x6 --square-mm 25 --into '" +
                                 dir.File("scene.json") + "' --camera cam4");
  ASSERT_EQ(added.exit_code, 0) << added.err;
  EXPECT_EQ(ReadSceneJson(dir.File("scene.json"))->cameras.back().name, "cam4");
}

TEST(CameraCli, ErrorsAreOneLineWithTheirExitCodeAndNoOutput) {
  const std::vector<std::string> photos = Photos();
  TempDir dir;
  std::vector<std::string> blanks;
  for (int k = 0; k < 3; ++k) {
    blanks.push_back(dir.File("blank" + std::to_string(k) + ".png"));
    cv::imwrite(blanks.back(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(100)));
  }
  const std::string out = " --out '" + dir.File("cams.json") + "' --report '" + dir.File("rep") + "'";
  // No board in any image: 4.
  RunResult r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9x6 --square-mm 25" + out);
  EXPECT_EQ(r.exit_code, 4);
  ExpectOneLineError(r, "no board found in any of the 3 images (chessboard 9 x 6 inner corners, square 25 mm): " +
                            blanks[0] + ": no board found");
  // A bad board JSON: 3, naming the file and the field.
  const std::string bad = dir.Write("bad.json", R"({"format": "opl.board", "version": 1, "type": "tag_grid",
    "cols": 0, "rows": 4, "tag_size_mm": 30, "gap_mm": 7.5})");
  r = Camera("calibrate --images " + Join(blanks) + " --board '" + bad + "'" + out);
  EXPECT_EQ(r.exit_code, 3);
  ExpectOneLineError(r, bad + ": cols: must be in [1, 100], got 0");
  // An unreadable image: 3, naming it.
  const std::string broken = dir.Write("broken.jpg", "not a JPEG at all");
  r = Camera("calibrate --images '" + broken + "' " + Join(blanks) + " --chessboard 9x6 --square-mm 25" + out);
  EXPECT_EQ(r.exit_code, 3);
  ExpectOneLineError(r, broken + ": ");
  if (photos.size() >= 2) {
    // Too few views: 4.
    r = Camera("calibrate --images '" + photos[0] + "' '" + photos[1] + "' '" + blanks[0] +
               "' --chessboard 9x6 --square-mm 25" + out);
    EXPECT_EQ(r.exit_code, 4);
    ExpectOneLineError(r, "the board was found in 2 of 3 images, at least 3 views are needed");
    // --into a scene that does not validate: 3, and the file unchanged.
    const std::string scene = dir.Write("scene.json", R"({"format": "opl.scene", "version": 1, "cameras": []})");
    r = Camera("calibrate --images " + Join(photos) + " --chessboard 9x6 --square-mm 25 --into '" + scene + "'");
    EXPECT_EQ(r.exit_code, 3);
    ExpectOneLineError(r, scene + ": ");
    EXPECT_EQ(ReadAll(scene), R"({"format": "opl.scene", "version": 1, "cameras": []})");
  }
  // --into is checked before the images are read: 3, not "no board found".
  const std::string not_a_scene = dir.Write("board_as_scene.json", R"({"format": "opl.board", "version": 1})");
  r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9x6 --square-mm 25 --into '" + not_a_scene + "'");
  EXPECT_EQ(r.exit_code, 3);
  ExpectOneLineError(r, not_a_scene + ": format: expected \"opl.scene\" or \"opl.cameras\"");
  // Usage errors: 2.
  r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9x6 --square-mm 25");
  EXPECT_EQ(r.exit_code, 2);
  ExpectOneLineError(r, "calibrate: give --out");
  r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9by6 --square-mm 25" + out);
  EXPECT_EQ(r.exit_code, 2);
  ExpectOneLineError(r, "--chessboard: expected inner corners as COLSxROWS");
  r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9x6 --square-mm 25 --out '" + blanks[0] + "'");
  EXPECT_EQ(r.exit_code, 2);
  r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9x6 --square-mm 25" + out +
             " --coverage-format jpg");
  EXPECT_EQ(r.exit_code, 2);
  ExpectOneLineError(r, "--coverage-format: jpg not in {png,svg,pdf}");
  r = Camera("calibrate --images " + Join(blanks) + " --chessboard 9x6 --square-mm 25 --out '" +
             dir.File("cams.json") + "' --coverage-format svg");
  EXPECT_EQ(r.exit_code, 2);
  ExpectOneLineError(r, "--coverage-format requires --report");
  // Nothing was written by any of these.
  EXPECT_FALSE(std::filesystem::exists(dir.File("cams.json")));
  EXPECT_FALSE(std::filesystem::exists(dir.File("rep")));
}

TEST(CameraCli, BoardWritesThePngAtItsDpiAndTheBoardJson) {
  TempDir dir;
  const RunResult r = Camera("board --out '" + dir.File("b.png") + "' --cols 4 --rows 3 --tag-mm 25 --gap-mm 5 --dpi 120 "
                             "--first-id 7 --board-json '" + dir.File("b.json") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  TagBoard board;
  board.columns = 4;
  board.rows = 3;
  board.tag_size = 25.0;
  board.tag_gap = 5.0;
  board.first_id = 7;
  BoardPrintOptions options;
  options.dpi = 120.0;
  Result<BoardPrintLayout> layout = LayOutBoardPrint(board, options);
  ASSERT_TRUE(layout.ok());
  const cv::Mat png = cv::imread(dir.File("b.png"), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, static_cast<int>(std::lround(layout->page_width_mm * 120.0 / 25.4)));
  EXPECT_EQ(png.rows, static_cast<int>(std::lround(layout->page_height_mm * 120.0 / 25.4)));
  Result<CalibrationBoard> read = ReadBoardJson(dir.File("b.json"));
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ(read->Describe(), CalibrationBoard::TagGrid(board).Describe());
  // The PDF too.
  const RunResult pdf = Camera("board --out '" + dir.File("b.pdf") + "' --cols 4 --rows 3 --tag-mm 25 --gap-mm 5");
  ASSERT_EQ(pdf.exit_code, 0) << pdf.err;
  EXPECT_EQ(ReadAll(dir.File("b.pdf")).rfind("%PDF-", 0), 0u);
  // A gap without a quiet zone, an unknown extension: usage errors, no file.
  RunResult bad = Camera("board --out '" + dir.File("c.png") + "' --cols 4 --rows 3 --tag-mm 25 --gap-mm 1");
  EXPECT_EQ(bad.exit_code, 2);
  ExpectOneLineError(bad, "invalid board: the gap between tags (1 mm) must be at least one tag cell");
  bad = Camera("board --out '" + dir.File("c.svg") + "' --cols 4 --rows 3 --tag-mm 25 --gap-mm 5");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir.File("c.png")));
  EXPECT_FALSE(std::filesystem::exists(dir.File("c.svg")));
  // --help documents the exit codes.
  const RunResult help = Camera("calibrate --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("Exit codes:"), std::string::npos);
  EXPECT_NE(help.out.find("--chessboard"), std::string::npos);
}

}  // namespace
}  // namespace opl
