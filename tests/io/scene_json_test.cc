// The scene JSON reader: the example scene read back against the numbers in
// the file (camera centres, tag frames from centre/normal/up in closed form),
// and each kind of bad input with its exact one-line message.
#include "opl/io/scene_json.h"

#include <cstdlib>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io/temp_dir.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

std::string ExamplePath(const std::string& name) {
  const char* root = std::getenv("OPL_SOURCE_DIR");
  return std::string(root == nullptr ? "." : root) + "/examples/" + name;
}

const std::string kCamera =
    R"({"name": "cam0", "width_px": 320, "height_px": 240,
        "intrinsics": {"fx": 300, "fy": 300, "cx": 159.5, "cy": 119.5, "k1": -0.05},
        "pose": {"center_mm": [0, 0, 0], "look_at_mm": [1000, 0, 0]}})";
const std::string kTags =
    R"({"size_mm": 100, "placements": [
        {"id": 3, "center_mm": [1000, 200, 100], "normal": [-1, 0, 0], "up": [0, 0, 1]},
        {"id": 4, "center_mm": [1000, -200, 100], "normal": [-1, 0, 0], "up": [0, 0.2, 1]},
        {"id": 5}]})";
const std::string kModule =
    R"({"sources": [{"name": "A", "pattern": "equal_angle", "beams_per_side": 5,
                     "full_angle_deg": 10, "origin_mm": [0, 0, 0], "rotation_xyz_rad": [0, 0, 0]}],
        "surface": {"type": "plane", "point_mm": [1000, 0, 0], "normal": [-1, 0, 0]},
        "spot_noise_mm": [0, 0, 0]})";
const std::string kShots = R"([{"camera": "cam0", "file": "a.png", "lasers": ["A"]}])";

// A valid scene whose parts can be replaced.
std::string Doc(const std::string& cameras = "[" + kCamera + "]", const std::string& tags = kTags,
                const std::string& shots = kShots, const std::string& extra = "",
                const std::string& module = kModule) {
  return R"({"format": "opl.scene", "version": 1, "cameras": )" + cameras + R"(, "tags": )" + tags +
         R"(, "module": )" + module + R"(, "shots": )" + shots + extra + "}";
}

std::string Message(const std::string& text) {
  Result<Scene> r = ParseSceneJson(text, "s.json");
  return r.ok() ? std::string("OK") : r.status().message();
}

TEST(SceneJson, NestingIsCappedAt64Levels) {
  // Issue 19: an 80 KB file of '[' took 2.4 GB.
  EXPECT_EQ(Message(std::string(80000, '[')), "s.json:1:65: invalid JSON: nested deeper than 64 levels");
  EXPECT_EQ(Message(R"({"format": "opl.scene", "a": )" + std::string(70, '{')),
            "s.json:1:93: invalid JSON: nested deeper than 64 levels");
}

TEST(SceneJson, CameraSizesWithinTheImageLimit) {
  // Issue 19 (as finding 4): a camera of 100000 x 100000 pixels was accepted
  // and rendering allocated 10^10 pixels a frame.
  Result<Scene> example = ReadSceneJson(ExamplePath("scene_small.json"));
  ASSERT_TRUE(example.ok());
  nlohmann::json scene = nlohmann::json::parse(testing_support::ReadAll(ExamplePath("scene_small.json")));
  scene["module"] = ExamplePath("scene_small_module.json");
  scene["cameras"][1]["width_px"] = 100000;
  EXPECT_EQ(Message(scene.dump()), "s.json: cameras[1].width_px: must be in [1, 32768], got 100000");
  scene["cameras"][1]["width_px"] = 20000;
  scene["cameras"][1]["height_px"] = 20000;
  EXPECT_EQ(Message(scene.dump()),
            "s.json: cameras[1]: 20000 x 20000 pixels is beyond the limit of 160 megapixels");
}

// Issue 19 item 6: fx = 1e308 or k1 = 1e6 were read and the failure came
// later, blamed on the images ("no tag is seen in two images").
TEST(SceneJson, IntrinsicsArePlausible) {
  auto with = [](const std::string& from, const std::string& to) {
    std::string camera = kCamera;
    const size_t at = camera.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) camera.replace(at, from.size(), to);
    return Message(Doc("[" + camera + "]"));
  };
  EXPECT_EQ(Message(Doc()), "OK");
  const std::string f_range =
      "must be in [16, 32000] px (0.05 to 100 times the image's larger side, 320 px), got ";
  EXPECT_EQ(with("\"fx\": 300", "\"fx\": 1e308"),
            "s.json: cameras[0].intrinsics.fx: " + f_range + "1e+308");
  EXPECT_EQ(with("\"fy\": 300", "\"fy\": 10"), "s.json: cameras[0].intrinsics.fy: " + f_range + "10");
  EXPECT_EQ(with("\"cx\": 159.5", "\"cx\": 1e6"),
            "s.json: cameras[0].intrinsics.cx: the principal point must lie within the image "
            "widened by half its width on each side, [-160, 480] px, got 1000000");
  EXPECT_EQ(with("\"cy\": 119.5", "\"cy\": -200"),
            "s.json: cameras[0].intrinsics.cy: the principal point must lie within the image "
            "widened by half its height on each side, [-120, 360] px, got -200");
  // The corner is at r = 0.667 (normalized): r (1 - r^2) peaks at r = 0.577.
  EXPECT_EQ(with("\"k1\": -0.05", "\"k1\": -1"),
            "s.json: cameras[0].intrinsics.k1: the distortion folds back inside the image (r_d "
            "stops increasing at r = 0.578, r_d = 0.385; the image corner is at r_d = 0.667, "
            "normalized)");
  EXPECT_EQ(with("\"k1\": -0.05", "\"k1\": -0.05, \"k3\": -40"),
            "s.json: cameras[0].intrinsics.k3: the distortion folds back inside the image (r_d "
            "stops increasing at r = 0.39, r_d = 0.332; the image corner is at r_d = 0.667, "
            "normalized)");
  // Monotonic but absurd: the corner would be at r = 0.009.
  EXPECT_THAT(with("\"k1\": -0.05", "\"k1\": 1e6"),
              ::testing::StartsWith("s.json: cameras[0].intrinsics.k1: the radial distortion "
                                    "scales the image corner by "));
  EXPECT_THAT(with("\"k1\": -0.05", "\"p1\": 2"),
              ::testing::StartsWith("s.json: cameras[0].intrinsics.p1: tangential distortion"));
  // Strong but real lenses pass.
  EXPECT_EQ(with("\"k1\": -0.05", "\"k1\": -0.3, \"k2\": 0.1"), "OK");
  EXPECT_EQ(with("\"k1\": -0.05", "\"k1\": 0.4"), "OK");
  // Every bundled scene passes.
  for (const char* name : {"scene_small.json", "scene_clutter.json", "scene_18mp.json",
                           "calibration_session_small.json"}) {
    Result<Scene> scene = ReadSceneJson(ExamplePath(name));
    EXPECT_TRUE(scene.ok()) << name << ": " << scene.status().message();
  }
}

TEST(SceneJson, ReadsTheSmallExample) {
  Result<Scene> scene = ReadSceneJson(ExamplePath("scene_small.json"));
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  EXPECT_TRUE(scene->ValidateForRendering().ok());
  ASSERT_EQ(scene->cameras.size(), 4u);
  EXPECT_EQ(scene->cameras[0].intrinsics.width_px, 1024);
  EXPECT_EQ(scene->cameras[0].intrinsics.k1, -0.05);
  const Camera cam{"", scene->cameras[0].intrinsics, *scene->cameras[0].cam_from_scene};
  EXPECT_LT((cam.CenterInScene() - Eigen::Vector3d(-300, 700, 500)).norm(), 1e-9);
  // The optical axis passes through look_at (2000, 0, 0).
  Eigen::Vector3d look = *scene->cameras[0].cam_from_scene * Eigen::Vector3d(2000, 0, 0);
  EXPECT_NEAR(look.x(), 0.0, 1e-9);
  EXPECT_NEAR(look.y(), 0.0, 1e-9);
  ASSERT_EQ(scene->tags.tags.size(), 10u);
  EXPECT_EQ(scene->tags.size_mm, 140.0);
  // Tag 0 at (2000, -750, -650) on the wall x = 2000 facing -X, up +Z: tag x =
  // -Y (right for a viewer looking along +X), y = -Z, z = +X.
  const Rigid3d& t0 = scene->FindTag(0)->scene_from_tag;
  EXPECT_LT((t0.translation - Eigen::Vector3d(2000, -750, -650)).norm(), 1e-12);
  Eigen::Matrix3d expected;
  expected << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  EXPECT_LT((t0.RotationMatrix() - expected).norm(), 1e-12);
  ASSERT_TRUE(scene->frame.has_value());
  EXPECT_EQ(scene->frame->axis_tag, 1);
  ASSERT_TRUE(scene->artifact.has_value());
  EXPECT_EQ(scene->artifact->length_mm, 800.0);
  ASSERT_TRUE(scene->module.has_value());
  EXPECT_EQ(scene->module->sources.size(), 2u);
  EXPECT_EQ(scene->shots.size(), 8u);
  EXPECT_EQ(scene->shots[5].file, "cam1_B.png");
  EXPECT_EQ(scene->shots[5].lasers, std::vector<std::string>{"B"});
  EXPECT_EQ(scene->image.blur_sigma_px, 0.6);
  EXPECT_EQ(scene->spots.diameter_mm, 16.0);
}

TEST(SceneJson, ParsesTagFramesAndDirectPoses) {
  const std::string direct =
      R"([{"name": "c", "width_px": 10, "height_px": 10,
           "intrinsics": {"fx": 10, "fy": 10, "cx": 5, "cy": 5},
           "cam_from_scene": {"quaternion_wxyz": [0, 1, 0, 0], "translation_mm": [1, 2, 3]}}])";
  Result<Scene> scene = ParseSceneJson(
      Doc(direct, kTags, R"([{"camera": "c", "file": "a.png"}])"), "s.json");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  const Rigid3d& pose = *scene->cameras[0].cam_from_scene;
  EXPECT_EQ(pose.rotation.x(), 1.0);  // 180 deg about x
  EXPECT_EQ(pose.translation, Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(scene->FindCamera("c")->cam_from_scene->rotation.w() != 0.0);
  // "up" (0, 0.2, 1) is projected on the wall: y = -(0, 0.2, 1) / |.|.
  const Eigen::Matrix3d R = scene->FindTag(4)->scene_from_tag.RotationMatrix();
  EXPECT_LT((R.col(1) - -Eigen::Vector3d(0, 0.2, 1).normalized()).norm(), 1e-12);
  EXPECT_LT((R.col(2) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  // A placement without a pose: identity.
  EXPECT_EQ(scene->FindTag(5)->scene_from_tag.translation, Eigen::Vector3d::Zero());
}

TEST(SceneJson, MessagesNameTheFieldExactly) {
  EXPECT_EQ(Message(Doc()), "OK");
  // Missing field.
  EXPECT_EQ(Message(R"({"format": "opl.scene", "version": 1, "cameras": [], "tags": )" + kTags + "}"),
            "s.json: shots: missing field");
  EXPECT_EQ(Message(Doc("[" + std::string(R"({"name": "c", "width_px": 10, "height_px": 10,
                                               "intrinsics": {"fy": 1, "cx": 0, "cy": 0}})") + "]")),
            "s.json: cameras[0].intrinsics.fx: missing field");
  // Unknown field.
  EXPECT_EQ(Message(Doc("[" + kCamera.substr(0, kCamera.size() - 1) + R"(, "focal": 3})" + "]")),
            "s.json: cameras[0].focal: unknown field (allowed here: calibration, cam_from_scene, height_px, "
            "intrinsics, name, pose, width_px)");
  EXPECT_EQ(Message(Doc() .substr(0, Doc().size() - 1) + R"(, "images": 1})"),
            "s.json: images: unknown field (allowed here: artifact, cameras, check_lengths, "
            "description, format, frame, image, module, module_placements, provenance, seed, shots, "
            "spots, tags, version)");
  // Wrong type.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", R"({"size_mm": "abc", "placements": []})")),
            "s.json: tags.size_mm: expected a number, got \"abc\"");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, R"([{"camera": "cam0", "file": 7}])")),
            "s.json: shots[0].file: expected a string, got 7");
  // A camera unknown in a shot.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags,
                        R"([{"camera": "cam0", "file": "a.png"}, {"camera": "cam9", "file": "b.png"}])")),
            "s.json: shots[1].camera: no camera named 'cam9'");
  // Duplicate tag id.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", R"({"size_mm": 100, "placements": [{"id": 3}, {"id": 3}]})")),
            "s.json: tags.placements[1].id: duplicate tag id 3 (also tags.placements[0])");
  // A frame tag that is not in the scene.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots,
                        R"(, "frame": {"origin_tag": 3, "axis_tag": 7, "plane_tag": 5})")),
            "s.json: frame.axis_tag: tag 7 is not among the scene's tags");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots,
                        R"(, "artifact": {"tag_1": 3, "tag_2": 3, "length_mm": 500})")),
            "s.json: artifact.tag_2: must differ from tag_1 (3)");
  // A laser the module does not have.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, R"([{"camera": "cam0", "file": "a.png", "lasers": ["C"]}])")),
            "s.json: shots[0].lasers[0]: no source named 'C' in the module (it has A)");
  // Errors inside an inline module name its path in the scene.
  std::string bad_module = kModule;
  bad_module.replace(bad_module.find("\"full_angle_deg\": 10"), 20, "\"full_angle_deg\": -1");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots, "", bad_module)),
            "s.json: module.sources[0].full_angle_deg: must be > 0 and < 180, got -1");
  // Geometry of a placement.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]",
                        R"({"size_mm": 100, "placements": [{"id": 1, "center_mm": [0, 0, 0],
                            "normal": [1, 0, 0], "up": [2, 0, 0]}]})")),
            "s.json: tags.placements[0].up: must not be parallel to the normal");
  EXPECT_EQ(Message(R"({"format": "opl.scene", "version": 2})"),
            "s.json: version: unsupported version 2 (this reader reads version 1)");
  EXPECT_EQ(Message("{\"format\": \"opl.scene\",\n \"version\": 1,}"),
            "s.json:2:15: invalid JSON: syntax error while parsing object key - unexpected '}'; "
            "expected string literal");
}

TEST(SceneJson, ModuleFileIsReadRelativeToTheScene) {
  testing_support::TempDir dir;
  dir.Write("module.json", R"({"format": "opl.module_design", "version": 1, )" + kModule.substr(1));
  const std::string scene_path = dir.Write("scene.json", Doc("[" + kCamera + "]", kTags, kShots, "", "\"module.json\""));
  Result<Scene> scene = ReadSceneJson(scene_path);
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  EXPECT_EQ(scene->module->sources[0].beams_per_side, 5);
  const std::string missing = dir.Write("missing.json", Doc("[" + kCamera + "]", kTags, kShots, "", "\"nope.json\""));
  Result<Scene> bad = ReadSceneJson(missing);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kIoError);
  EXPECT_EQ(bad.status().message(), missing + ": module: " + dir.File("nope.json") +
                                        ": cannot open: No such file or directory");
}

// Issue 18: a copied example failed to measure because its module file was
// missing, though measuring never uses the module. Read for measuring, the
// module is neither opened nor parsed; read for rendering it still is.
TEST(SceneJson, MeasuringDoesNotNeedTheModuleFile) {
  testing_support::TempDir dir;
  Result<std::string> example = ReadFileToString(ExamplePath("scene_small.json"));
  ASSERT_TRUE(example.ok());
  const std::string copy = dir.Write("scene.json", *example);  // without scene_small_module.json
  Result<Scene> render = ReadSceneJson(copy);
  ASSERT_FALSE(render.ok());
  EXPECT_EQ(render.status().message(), copy + ": module: " + dir.File("scene_small_module.json") +
                                           ": cannot open: No such file or directory");
  Result<Scene> measure = ReadSceneJson(copy, SceneUse::kMeasure);
  ASSERT_TRUE(measure.ok()) << measure.status().message();
  EXPECT_FALSE(measure->module.has_value());
  Result<Scene> full = ReadSceneJson(ExamplePath("scene_small.json"));
  ASSERT_TRUE(full.ok());
  // Everything the front end uses is the same as the full read's.
  ASSERT_EQ(measure->cameras.size(), full->cameras.size());
  for (size_t k = 0; k < full->cameras.size(); ++k) {
    EXPECT_EQ(measure->cameras[k].intrinsics.Packed(), full->cameras[k].intrinsics.Packed());
  }
  EXPECT_EQ(measure->tags.size_mm, 140.0);
  EXPECT_EQ(measure->tags.tags.size(), 10u);
  EXPECT_EQ(measure->shots.size(), 8u);
  EXPECT_EQ(measure->shots[7].file, "cam3_B.png");
  EXPECT_EQ(measure->shots[7].lasers, std::vector<std::string>{"B"});

  // An inline design is not parsed either (its pattern file is missing, and
  // a value out of range does not matter), but "module" must still be a path
  // or a design object.
  const std::string bad_module =
      R"({"sources": [{"name": "A", "pattern": "file", "pattern_file": "gone.csv", "beams_per_side": 4}]})";
  EXPECT_THAT(Message(Doc("[" + kCamera + "]", kTags, kShots, "", bad_module)), ::testing::HasSubstr("module."));
  EXPECT_TRUE(ParseSceneJson(Doc("[" + kCamera + "]", kTags, kShots, "", bad_module), "s.json", "",
                             SceneUse::kMeasure)
                  .ok());
  Result<Scene> number = ParseSceneJson(Doc("[" + kCamera + "]", kTags, kShots, "", "12"), "s.json", "",
                                        SceneUse::kMeasure);
  ASSERT_FALSE(number.ok());
  EXPECT_EQ(number.status().message(),
            "s.json: module: expected the path of a module design JSON or a design object, got 12");
  // Lasers are not checked against a module that was not read.
  EXPECT_TRUE(ParseSceneJson(Doc("[" + kCamera + "]", kTags, R"([{"camera": "cam0", "file": "a.png",
                                 "lasers": ["Q"]}])"),
                             "s.json", "", SceneUse::kMeasure)
                  .ok());
}

TEST(SceneJson, MeasuringDoesNotNeedTagPlacements) {
  const std::string tags = R"({"size_mm": 100})";
  const std::string frame = R"(, "frame": {"origin_tag": 0, "axis_tag": 1, "plane_tag": 2})";
  // Rendering needs them.
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", tags, kShots, frame)), "s.json: tags.placements: missing field");
  Result<Scene> measure = ParseSceneJson(Doc("[" + kCamera + "]", tags, kShots, frame), "s.json", "",
                                         SceneUse::kMeasure);
  ASSERT_TRUE(measure.ok()) << measure.status().message();
  EXPECT_TRUE(measure->tags.tags.empty());
  EXPECT_EQ(measure->frame->plane_tag, 2);
  // Unlisted tags: ids are still held to tag36h11's range.
  Result<Scene> range = ParseSceneJson(
      Doc("[" + kCamera + "]", tags, kShots, R"(, "frame": {"origin_tag": 0, "axis_tag": 1, "plane_tag": 600})"),
      "s.json", "", SceneUse::kMeasure);
  ASSERT_FALSE(range.ok());
  EXPECT_EQ(range.status().message(), "s.json: frame.plane_tag: 600: must be in [0, 586] (tag36h11)");
  // Listed tags must hold the frame's.
  Result<Scene> listed = ParseSceneJson(Doc("[" + kCamera + "]", kTags, kShots, frame), "s.json", "",
                                        SceneUse::kMeasure);
  ASSERT_FALSE(listed.ok());
  EXPECT_EQ(listed.status().message(), "s.json: frame.origin_tag: tag 0 is not among the scene's tags");
  // Other fields present are still checked, and unknown fields refused.
  Result<Scene> typo = ParseSceneJson(Doc("[" + kCamera + "]", tags, kShots, R"(, "imgae": {})"), "s.json", "",
                                      SceneUse::kMeasure);
  ASSERT_FALSE(typo.ok());
  EXPECT_THAT(typo.status().message(), ::testing::HasSubstr("s.json: imgae: unknown field"));
}

TEST(SceneJson, ProvenanceIsAcceptedAndMustBeAnObject) {
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots, R"(, "provenance": {"tool": "opl_scene"})")), "OK");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots, R"(, "provenance": "opl_scene")")),
            "s.json: provenance: expected an object, got \"opl_scene\"");
}

TEST(SceneJson, MeasurementSceneRoundTrips) {
  Result<Scene> full = ReadSceneJson(ExamplePath("scene_small.json"));
  ASSERT_TRUE(full.ok());
  const std::string text = FormatMeasurementSceneJson(
      *full, "round trip", R"({"tool": "opl_scene", "inputs": []})");
  const nlohmann::json doc = nlohmann::json::parse(text);
  EXPECT_EQ(doc["description"], "round trip");
  EXPECT_EQ(doc["provenance"]["tool"], "opl_scene");
  EXPECT_FALSE(doc.contains("module"));
  EXPECT_FALSE(doc["cameras"][0].contains("pose"));
  EXPECT_EQ(doc["tags"]["placements"][9], nlohmann::json({{"id", 9}}));
  Result<Scene> back = ParseSceneJson(text, "back.json", "", SceneUse::kMeasure);
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back->cameras.size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(back->cameras[k].name, full->cameras[k].name);
    EXPECT_EQ(back->cameras[k].intrinsics.Packed(), full->cameras[k].intrinsics.Packed());  // bit-exact
    EXPECT_FALSE(back->cameras[k].cam_from_scene.has_value());
  }
  EXPECT_EQ(back->tags.size_mm, full->tags.size_mm);
  EXPECT_EQ(back->frame->axis_tag, 1);
  EXPECT_EQ(back->artifact->length_mm, 800.0);
  EXPECT_EQ(back->artifact->length_sigma_mm, 0.01);
  ASSERT_EQ(back->shots.size(), full->shots.size());
  for (size_t k = 0; k < back->shots.size(); ++k) {
    EXPECT_EQ(back->shots[k].camera, full->shots[k].camera);
    EXPECT_EQ(back->shots[k].file, full->shots[k].file);
    EXPECT_EQ(back->shots[k].lasers, full->shots[k].lasers);
    EXPECT_EQ(back->shots[k].slice, full->shots[k].slice);
  }
}

// Module placements (issue 20): named motions of the designed module, each
// lit shot naming one; the motion rotates about the sources' centroid.
TEST(SceneJson, ModulePlacementsAreReadCheckedAndWrittenBack) {
  const std::string placements =
      R"(, "module_placements": [{"name": "P1"},
            {"name": "P2", "rotation_deg": [0, 0, 90], "translation_mm": [0, 300, -50]}])";
  const std::string shots = R"([{"camera": "cam0", "file": "a.png", "lasers": ["A"], "placement": "P1"},
                                {"camera": "cam0", "file": "b.png", "lasers": ["A"], "placement": "P2"},
                                {"camera": "cam0", "file": "c.png"}])";
  Result<Scene> scene = ParseSceneJson(Doc("[" + kCamera + "]", kTags, shots, placements), "s.json");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  ASSERT_EQ(scene->module_placements.size(), 2u);
  EXPECT_EQ(scene->shots[1].placement, "P2");
  EXPECT_EQ(scene->shots[2].placement, "");  // laser off: no placement needed
  EXPECT_EQ(scene->FindModulePlacement("P2"), 1);
  EXPECT_EQ(scene->FindModulePlacement("P3"), -1);
  // The one source sits at the origin, so the centroid is the origin: 90 deg
  // about z takes x to y, then the translation.
  const Rigid3d move = scene->module_placements[1].SceneFromDesign(*scene->module);
  EXPECT_LT((move * Eigen::Vector3d(10, 0, 0) - Eigen::Vector3d(0, 310, -50)).norm(), 1e-12);
  EXPECT_LT((scene->module_placements[0].SceneFromDesign(*scene->module) * Eigen::Vector3d(1, 2, 3) -
             Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  // Back through the measurement scene writer.
  Result<Scene> back = ParseSceneJson(FormatMeasurementSceneJson(*scene, "", ""), "back.json", "",
                                      SceneUse::kMeasure);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->module_placements.size(), 2u);
  EXPECT_EQ(back->module_placements[1].rotation_deg, scene->module_placements[1].rotation_deg);
  EXPECT_EQ(back->module_placements[1].translation_mm, scene->module_placements[1].translation_mm);
  EXPECT_EQ(back->shots[1].placement, "P2");
  EXPECT_EQ(back->shots[2].placement, "");

  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags,
                        R"([{"camera": "cam0", "file": "a.png", "lasers": ["A"], "placement": "P9"}])",
                        placements)),
            "s.json: shots[0].placement: no module placement named 'P9'");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots, placements)),
            "s.json: shots[0].placement: missing: the scene lists module_placements, so a shot with "
            "a laser on must name the placement it shows");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags,
                        R"([{"camera": "cam0", "file": "a.png", "lasers": ["A"], "placement": "P1"}])")),
            "s.json: shots[0].placement: 'P1': the scene lists no module_placements");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots,
                        R"(, "module_placements": [{"name": "P"}, {"name": "P"}])")),
            "s.json: module_placements[1].name: duplicate placement name 'P' (also "
            "module_placements[0])");
  EXPECT_EQ(Message(Doc("[" + kCamera + "]", kTags, kShots,
                        R"(, "module_placements": [{"name": "P", "rotation_deg": [0, 400, 0]}])")),
            "s.json: module_placements[0].rotation_deg: each angle must be finite and within "
            "[-360, 360] deg");
  EXPECT_THAT(Message(Doc("[" + kCamera + "]", kTags, kShots,
                          R"(, "module_placements": [{"name": "P", "translate_mm": [0, 0, 0]}])")),
              testing::StartsWith("s.json: module_placements[0].translate_mm: unknown field"));
}

TEST(SceneJson, CheckLengthsAreReadCheckedAndWrittenBack) {
  const std::string lengths =
      R"(, "check_lengths": [{"name": "diagonal", "tag_1": 3, "tag_2": 4, "length_mm": 400.25,
                              "length_sigma_mm": 0.004}])";
  Result<Scene> scene = ParseSceneJson(Doc("[" + kCamera + "]", kTags, kShots, lengths), "s.json");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  ASSERT_EQ(scene->check_lengths.size(), 1u);
  EXPECT_EQ(scene->check_lengths[0].name, "diagonal");
  EXPECT_EQ(scene->check_lengths[0].tag_2, 4);
  EXPECT_EQ(scene->check_lengths[0].length_mm, 400.25);
  EXPECT_EQ(scene->check_lengths[0].length_sigma_mm, 0.004);
  Result<Scene> back = ParseSceneJson(FormatMeasurementSceneJson(*scene, "", ""), "back.json", "",
                                      SceneUse::kMeasure);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->check_lengths.size(), 1u);
  EXPECT_EQ(back->check_lengths[0].length_mm, 400.25);
  EXPECT_EQ(back->check_lengths[0].length_sigma_mm, 0.004);

  auto with = [&](const std::string& entry) {
    return Message(Doc("[" + kCamera + "]", kTags, kShots, R"(, "check_lengths": [)" + entry + "]"));
  };
  EXPECT_EQ(with(R"({"name": "a", "tag_1": 3, "tag_2": 9, "length_mm": 1})"),
            "s.json: check_lengths[0].tag_2: tag 9 is not among the scene's tags");
  EXPECT_EQ(with(R"({"name": "a", "tag_1": 3, "tag_2": 3, "length_mm": 1})"),
            "s.json: check_lengths[0].tag_2: must differ from tag_1 (3)");
  EXPECT_EQ(with(R"({"name": "a", "tag_1": 3, "tag_2": 4, "length_mm": 0})"),
            "s.json: check_lengths[0].length_mm: 0: must be finite and > 0");
  EXPECT_EQ(with(R"({"name": "a", "tag_1": 3, "tag_2": 4})"),
            "s.json: check_lengths[0].length_mm: missing field");
  EXPECT_EQ(with(R"({"name": "a", "tag_1": 3, "tag_2": 4, "length_mm": 1},
                   {"name": "a", "tag_1": 4, "tag_2": 5, "length_mm": 1})"),
            "s.json: check_lengths[1].name: duplicate check length name 'a' (also check_lengths[0])");
}

}  // namespace
}  // namespace opl
