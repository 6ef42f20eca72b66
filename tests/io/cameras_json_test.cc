// Cameras JSON and the cameras block of a scene (io/cameras_json.h), and the
// board JSON (io/board_json.h).
#include "opl/io/cameras_json.h"

#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io/temp_dir.h"
#include "opl/io/board_json.h"
#include "opl/io/scene_json.h"

namespace opl {
namespace {

SceneCamera Calibrated(const std::string& name) {
  SceneCamera c;
  c.name = name;
  CameraIntrinsics& k = c.intrinsics;
  k.width_px = 1024;
  k.height_px = 768;
  k.fx_px = 1001.25;
  k.fy_px = 999.5;
  k.cx_px = 510.125;
  k.cy_px = 380.0625;
  k.k1 = -0.0625;
  k.k2 = 0.015625;
  k.p1 = 1e-4;
  k.p2 = -2e-4;
  SceneCameraCalibration cal;
  cal.intrinsics_std = {0.5, 0.25, 0.75, 0.5, 1e-3, 2e-3, 1e-5, 2e-5, 0.0};
  cal.rms_px = 0.125;
  cal.num_views = 12;
  cal.num_corners = 1152;
  cal.board = "tag36h11 grid 6 x 4 tags";
  c.calibration = cal;
  return c;
}

TEST(CamerasJson, RoundTripsExactly) {
  const std::string text = FormatCamerasJson({Calibrated("cam0"), Calibrated("cam1")});
  Result<std::vector<SceneCamera>> read = ParseCamerasJson(text, "c.json");
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 2u);
  const SceneCamera& c = (*read)[1];
  EXPECT_EQ(c.name, "cam1");
  EXPECT_EQ(c.intrinsics.Packed(), Calibrated("x").intrinsics.Packed());
  ASSERT_TRUE(c.calibration.has_value());
  EXPECT_EQ(c.calibration->intrinsics_std, Calibrated("x").calibration->intrinsics_std);
  EXPECT_EQ(c.calibration->num_corners, 1152);
  EXPECT_EQ(c.calibration->board, "tag36h11 grid 6 x 4 tags");
}

TEST(CamerasJson, ErrorsNameTheField) {
  auto message = [](const std::string& text) {
    Result<std::vector<SceneCamera>> r = ParseCamerasJson(text, "c.json");
    return r.ok() ? std::string("ok") : r.status().message();
  };
  std::string text = FormatCamerasJson({Calibrated("cam0")});
  EXPECT_EQ(message(R"({"format": "opl.cameras", "version": 1, "cameras": []})"),
            "c.json: cameras: must hold at least one camera");
  std::string negative = text;
  negative.replace(negative.find("\"fx\": 0.5"), 9, "\"fx\": -0.5");
  EXPECT_EQ(message(negative), "c.json: cameras[0].calibration.intrinsics_std.fx: a standard deviation must be >= 0, got -0.5");
  std::string twice = FormatCamerasJson({Calibrated("cam0"), Calibrated("cam0")});
  EXPECT_EQ(message(twice), "c.json: cameras[1].name: duplicate camera name 'cam0'");
  std::string implausible = text;
  implausible.replace(implausible.find("\"fx\": 1001.25"), 13, "\"fx\": 1e308");
  EXPECT_EQ(message(implausible).rfind("c.json: cameras[0].intrinsics.fx: ", 0), 0u) << message(implausible);
}

TEST(CamerasJson, UpdatesTheSceneKeepingEverythingElse) {
  const std::string examples = OPL_EXAMPLES_DIR;
  Result<std::string> original = [&]() -> Result<std::string> {
    std::ifstream in(examples + "/scene_small.json");
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }();
  ASSERT_FALSE(original->empty());
  // Replace cam1 (its pose kept) and add cam9.
  Result<CamerasBlockUpdate> replaced = UpdateCamerasBlock(*original, "scene_small.json", examples, Calibrated("cam1"));
  ASSERT_TRUE(replaced.ok()) << replaced.status().ToString();
  EXPECT_TRUE(replaced->replaced);
  Result<CamerasBlockUpdate> added = UpdateCamerasBlock(replaced->text, "scene_small.json", examples, Calibrated("cam9"));
  ASSERT_TRUE(added.ok()) << added.status().ToString();
  EXPECT_FALSE(added->replaced);
  Result<Scene> before = ParseSceneJson(*original, "before", examples);
  Result<Scene> after = ParseSceneJson(added->text, "after", examples);
  ASSERT_TRUE(before.ok() && after.ok()) << after.status().ToString();
  ASSERT_EQ(after->cameras.size(), before->cameras.size() + 1);
  const SceneCamera& cam1 = after->cameras[1];
  EXPECT_EQ(cam1.name, "cam1");
  EXPECT_EQ(cam1.intrinsics.Packed(), Calibrated("x").intrinsics.Packed());
  ASSERT_TRUE(cam1.cam_from_scene && before->cameras[1].cam_from_scene);
  EXPECT_TRUE(cam1.cam_from_scene->translation.isApprox(before->cameras[1].cam_from_scene->translation));
  EXPECT_EQ(after->cameras.back().name, "cam9");
  EXPECT_FALSE(after->cameras.back().cam_from_scene.has_value());
  // Every field but the cameras is as it was, in the same order.
  nlohmann::ordered_json a = nlohmann::ordered_json::parse(*original), b = nlohmann::ordered_json::parse(added->text);
  a.erase("cameras");
  b.erase("cameras");
  EXPECT_EQ(a.dump(), b.dump());
  // The other cameras untouched.
  const nlohmann::ordered_json ca = nlohmann::ordered_json::parse(*original)["cameras"];
  const nlohmann::ordered_json cb = nlohmann::ordered_json::parse(added->text)["cameras"];
  EXPECT_EQ(ca[0].dump(), cb[0].dump());
  EXPECT_EQ(ca[2].dump(), cb[2].dump());
  // A cameras JSON is updated the same way; anything else is refused.
  Result<CamerasBlockUpdate> in_cameras =
      UpdateCamerasBlock(FormatCamerasJson({Calibrated("cam0")}), "c.json", "", Calibrated("cam1"));
  ASSERT_TRUE(in_cameras.ok());
  EXPECT_EQ(ParseCamerasJson(in_cameras->text, "c.json")->size(), 2u);
  Result<CamerasBlockUpdate> other = UpdateCamerasBlock(R"({"format": "opl.board", "version": 1})", "b.json", "",
                                                        Calibrated("cam1"));
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.status().message(), "b.json: format: expected \"opl.scene\" or \"opl.cameras\" (a scene or a cameras JSON)");
  // An invalid scene is refused before any change.
  Result<CamerasBlockUpdate> invalid = UpdateCamerasBlock(R"({"format": "opl.scene", "version": 1, "cameras": []})",
                                                          "s.json", "", Calibrated("cam1"));
  ASSERT_FALSE(invalid.ok());
  EXPECT_EQ(invalid.status().message().rfind("s.json: ", 0), 0u);
}

TEST(BoardJson, ReadsBothKindsAndNamesBadFields) {
  Result<CalibrationBoard> tags = ParseBoardJson(
      R"({"format": "opl.board", "version": 1, "type": "tag_grid", "cols": 6, "rows": 4,
          "tag_size_mm": 30, "pitch_mm": 37.5, "first_id": 10})", "b.json");
  ASSERT_TRUE(tags.ok()) << tags.status().ToString();
  EXPECT_EQ(tags->kind, CalibrationBoard::Kind::kTagGrid);
  EXPECT_DOUBLE_EQ(tags->tag_grid.tag_gap, 7.5);
  EXPECT_EQ(tags->tag_grid.first_id, 10);
  // Round trip through FormatBoardJson.
  Result<CalibrationBoard> again = ParseBoardJson(FormatBoardJson(*tags), "b2.json");
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->Describe(), tags->Describe());
  Result<CalibrationBoard> chess = ParseBoardJson(
      R"({"format": "opl.board", "version": 1, "type": "chessboard", "inner_cols": 9, "inner_rows": 6, "square_mm": 25})",
      "c.json");
  ASSERT_TRUE(chess.ok());
  EXPECT_EQ(chess->Describe(), "chessboard 9 x 6 inner corners, square 25 mm");
  auto message = [](const std::string& body) {
    Result<CalibrationBoard> r = ParseBoardJson(R"({"format": "opl.board", "version": 1, )" + body + "}", "b.json");
    return r.ok() ? std::string("ok") : r.status().message();
  };
  EXPECT_EQ(message(R"("type": "tag_grid", "cols": 6, "rows": 4, "tag_size_mm": 30, "gap_mm": 7.5, "pitch_mm": 37.5)"),
            "b.json: pitch_mm: give either \"gap_mm\" or \"pitch_mm\" (= tag_size_mm + gap_mm), not both nor neither");
  EXPECT_EQ(message(R"("type": "tag_grid", "cols": 0, "rows": 4, "tag_size_mm": 30, "gap_mm": 7.5)"),
            "b.json: cols: must be in [1, 100], got 0");
  EXPECT_EQ(message(R"("type": "tag_grid", "cols": 30, "rows": 20, "tag_size_mm": 30, "gap_mm": 7.5)"),
            "b.json: first_id: the ids first_id .. first_id + cols * rows - 1 = 0 .. 599 must lie in [0, 586] (tag36h11)");
  EXPECT_EQ(message(R"("type": "circles")"), "b.json: type: expected \"tag_grid\" or \"chessboard\", got \"circles\"");
  EXPECT_EQ(message(R"("type": "chessboard", "inner_cols": 9, "inner_rows": 6, "square": 25)").rfind("b.json: square: unknown field", 0), 0u);
  EXPECT_EQ(message(R"("type": "chessboard", "inner_cols": 9, "inner_rows": 6, "square_mm": -1)"),
            "b.json: square_mm: must be > 0, got -1");
  testing_support::TempDir dir;
  Result<CalibrationBoard> missing = ReadBoardJson(dir.File("none.json"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().message().rfind(dir.File("none.json") + ": cannot open", 0), 0u) << missing.status().message();
}

// Every JSON file OPL writes may carry a top-level "provenance" record
// (docs/formats.md, "Provenance"): the readers that refuse unknown fields
// accept it, and still refuse a misspelt one.
TEST(CamerasJson, ProvenanceIsAllowedAtTheTopLevel) {
  const std::string provenance = R"("provenance": {"tool": "opl_camera", "inputs": []})";
  const std::string camera =
      R"({"name": "c", "width_px": 640, "height_px": 480, "intrinsics": {"fx": 500, "fy": 500, "cx": 319.5, "cy": 239.5}})";
  Result<std::vector<SceneCamera>> cameras = ParseCamerasJson(
      R"({"format": "opl.cameras", "version": 1, "cameras": [)" + camera + "], " + provenance + "}", "c.json");
  ASSERT_TRUE(cameras.ok()) << cameras.status().message();
  EXPECT_EQ((*cameras)[0].intrinsics.fx_px, 500.0);
  Result<std::vector<SceneCamera>> typo = ParseCamerasJson(
      R"({"format": "opl.cameras", "version": 1, "cameras": [)" + camera + R"(], "provenence": {}})", "c.json");
  ASSERT_FALSE(typo.ok());
  EXPECT_NE(typo.status().message().find("c.json: provenence: unknown field"), std::string::npos);
  Result<CalibrationBoard> grid = ParseBoardJson(
      R"({"format": "opl.board", "version": 1, "type": "tag_grid", "cols": 2, "rows": 2, "tag_size_mm": 30,
          "gap_mm": 7.5, )" + provenance + "}", "b.json");
  EXPECT_TRUE(grid.ok()) << grid.status().message();
  Result<CalibrationBoard> chess = ParseBoardJson(
      R"({"format": "opl.board", "version": 1, "type": "chessboard", "inner_cols": 9, "inner_rows": 6,
          "square_mm": 25, )" + provenance + "}", "b.json");
  EXPECT_TRUE(chess.ok()) << chess.status().message();
}

}  // namespace
}  // namespace opl
