#include "opl/io/colmap_model.h"

#include <cmath>
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "opl/core/format.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;
using ::testing::HasSubstr;

// A tiny model written by hand in COLMAP's text format: two cameras, two
// images (the second without 2D points: its POINTS2D line is blank), two
// points. Image 1 is turned 90 deg about the camera's z axis:
// qvec = (cos 45, 0, 0, sin 45).
const char* kCamerasTxt =
    "# Camera list with one line of data per camera:\n"
    "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    "# Number of cameras: 2\n"
    "1 PINHOLE 640 480 500 510 320.5 240.25\n"
    "7 SIMPLE_RADIAL 100 80 90 50 40 -0.125\n";
const char* kImagesTxt =
    "# Image list with two lines of data per image:\n"
    "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
    "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
    "1 0.70710678118654757 0 0 0.70710678118654757 1 2 3 1 shot 01.png\n"
    "10.5 20.25 -1 30 40 12\n"
    "4 1 0 0 0 -1 0 0.5 7 b.png\n"
    "\n";
const char* kPoints3DTxt =
    "# 3D point list with one line of data per point:\n"
    "12 1.5 -2 3.25 255 0 17 0.75 1 1\n"
    "13 0 0 1 1 2 3 -1\n";

std::string WriteTextModel(const TempDir& dir, const std::string& cameras = kCamerasTxt,
                           const std::string& images = kImagesTxt,
                           const std::string& points = kPoints3DTxt) {
  dir.Write("cameras.txt", cameras);
  dir.Write("images.txt", images);
  dir.Write("points3D.txt", points);
  return dir.path();
}

TEST(ColmapModel, ReadsAHandWrittenTextModelFieldByField) {
  TempDir dir;
  Result<ColmapModel> model = ReadColmapModel(WriteTextModel(dir));
  ASSERT_TRUE(model.ok()) << model.status().ToString();
  EXPECT_EQ(model->format, ColmapFormat::kText);

  ASSERT_EQ(model->cameras.size(), 2u);
  const ColmapCamera& c1 = model->cameras.at(1);
  EXPECT_EQ(c1.camera_id, 1u);
  EXPECT_EQ(c1.model_id, kColmapPinhole);
  EXPECT_EQ(c1.width_px, 640u);
  EXPECT_EQ(c1.height_px, 480u);
  EXPECT_EQ(c1.params, (std::vector<double>{500, 510, 320.5, 240.25}));
  const ColmapCamera& c7 = model->cameras.at(7);
  EXPECT_EQ(c7.model_id, kColmapSimpleRadial);
  EXPECT_EQ(c7.params, (std::vector<double>{90, 50, 40, -0.125}));

  ASSERT_EQ(model->images.size(), 2u);
  const ColmapImage& i1 = model->images.at(1);
  EXPECT_EQ(i1.qvec_wxyz[0], 0.70710678118654757);
  EXPECT_EQ(i1.qvec_wxyz[3], 0.70710678118654757);
  EXPECT_EQ(i1.tvec, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(i1.camera_id, 1u);
  EXPECT_EQ(i1.name, "shot 01.png");  // NAME is the rest of the line
  ASSERT_EQ(i1.points2D.size(), 2u);
  EXPECT_EQ(i1.points2D[0].xy_px, Eigen::Vector2d(10.5, 20.25));
  EXPECT_EQ(i1.points2D[0].point3D_id, kColmapNoPoint3D);
  EXPECT_EQ(i1.points2D[1].xy_px, Eigen::Vector2d(30, 40));
  EXPECT_EQ(i1.points2D[1].point3D_id, 12u);
  const ColmapImage& i4 = model->images.at(4);
  EXPECT_EQ(i4.name, "b.png");
  EXPECT_EQ(i4.camera_id, 7u);
  EXPECT_TRUE(i4.points2D.empty());
  EXPECT_EQ(model->FindImageByName("b.png"), &i4);
  EXPECT_EQ(model->FindImageByName("c.png"), nullptr);

  ASSERT_EQ(model->points3D.size(), 2u);
  const ColmapPoint3D& p12 = model->points3D.at(12);
  EXPECT_EQ(p12.xyz_in_world, Eigen::Vector3d(1.5, -2, 3.25));
  EXPECT_EQ(p12.rgb, (std::array<uint8_t, 3>{255, 0, 17}));
  EXPECT_EQ(p12.error_px, 0.75);
  ASSERT_EQ(p12.track.size(), 1u);
  EXPECT_EQ(p12.track[0].image_id, 1u);
  EXPECT_EQ(p12.track[0].point2D_idx, 1u);
  EXPECT_EQ(model->points3D.at(13).error_px, -1.0);
  EXPECT_TRUE(model->points3D.at(13).track.empty());

  // cam_from_world: R = Rz(90 deg) maps x to y; X_cam = R X + t by hand.
  const Eigen::Vector3d x_cam = i1.CamFromWorld() * Eigen::Vector3d(1, 0, 0);
  EXPECT_NEAR(x_cam.x(), 0.0 + 1, 1e-15);
  EXPECT_NEAR(x_cam.y(), 1.0 + 2, 1e-15);
  EXPECT_NEAR(x_cam.z(), 0.0 + 3, 1e-15);
  // Centre -R^T t = -Rz(-90)(1, 2, 3) = -(2, -1, 3).
  EXPECT_TRUE(i1.CenterInWorld().isApprox(Eigen::Vector3d(-2, 1, -3), 1e-15));
}

TEST(ColmapModel, TextBinaryRoundTripIsExact) {
  TempDir dir;
  Result<ColmapModel> text = ReadColmapModel(WriteTextModel(dir));
  ASSERT_TRUE(text.ok()) << text.status().ToString();
  // Values that need all 17 digits.
  text->images.at(1).tvec = Eigen::Vector3d(1.0 / 3.0, -2.0 / 7.0, 1e-300);
  text->points3D.at(12).xyz_in_world = Eigen::Vector3d(kPi, std::exp(1.0), -1.0 / 9.0);
  text->cameras.at(1).params[0] = 500.0 + 1.0 / 3.0;

  const std::string bin_dir = dir.File("bin");
  ASSERT_TRUE(WriteColmapModel(*text, bin_dir, ColmapFormat::kBinary).ok());
  EXPECT_TRUE(IsColmapModelDir(bin_dir));
  Result<ColmapModel> binary = ReadColmapModel(bin_dir);
  ASSERT_TRUE(binary.ok()) << binary.status().ToString();
  EXPECT_EQ(binary->format, ColmapFormat::kBinary);

  const std::string txt_dir = dir.File("txt");
  ASSERT_TRUE(WriteColmapModel(*binary, txt_dir, ColmapFormat::kText).ok());
  Result<ColmapModel> again = ReadColmapModel(txt_dir);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(again->format, ColmapFormat::kText);

  // Binary written from the text read back is byte for byte the first binary.
  const std::string bin2_dir = dir.File("bin2");
  ASSERT_TRUE(WriteColmapModel(*again, bin2_dir, ColmapFormat::kBinary).ok());
  for (const char* name : {"cameras.bin", "images.bin", "points3D.bin"}) {
    EXPECT_EQ(ReadAll(bin_dir + "/" + name), ReadAll(bin2_dir + "/" + name)) << name;
  }
  EXPECT_EQ(again->images.at(1).tvec, Eigen::Vector3d(1.0 / 3.0, -2.0 / 7.0, 1e-300));
  EXPECT_EQ(again->points3D.at(12).xyz_in_world,
            Eigen::Vector3d(kPi, std::exp(1.0), -1.0 / 9.0));
  EXPECT_EQ(again->cameras.at(1).params[0], 500.0 + 1.0 / 3.0);
  EXPECT_EQ(again->images.at(1).points2D[0].point3D_id, kColmapNoPoint3D);
  EXPECT_EQ(again->images.at(1).name, "shot 01.png");
  EXPECT_TRUE(again->images.at(4).points2D.empty());

  // cameras.bin by hand: count 2, then camera 1 = 4 + 4 + 8 + 8 + 4 * 8 bytes,
  // camera 7 = 24 + 4 * 8 bytes.
  EXPECT_EQ(ReadAll(bin_dir + "/cameras.bin").size(), 8u + (24 + 32) + (24 + 32));
  // points3D.bin: count, point 12 = 8 + 24 + 3 + 8 + 8 + 1 * 8, point 13 without track.
  EXPECT_EQ(ReadAll(bin_dir + "/points3D.bin").size(), 8u + 59 + 51);
}

TEST(ColmapModel, ScaledModelMultipliesPointsAndCameraCentresAndKeepsPixels) {
  TempDir dir;
  Result<ColmapModel> model = ReadColmapModel(WriteTextModel(dir));
  ASSERT_TRUE(model.ok());
  const double s = 183.25;
  const ColmapModel scaled = ScaledColmapModel(*model, s);
  // Image 1: centre (-2, 1, -3) by hand (ReadsAHandWrittenTextModelFieldByField).
  EXPECT_TRUE(scaled.images.at(1).CenterInWorld().isApprox(s * Eigen::Vector3d(-2, 1, -3), 1e-15));
  EXPECT_EQ(scaled.images.at(1).tvec, s * Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(scaled.images.at(1).qvec_wxyz, model->images.at(1).qvec_wxyz);
  EXPECT_EQ(scaled.points3D.at(12).xyz_in_world, s * Eigen::Vector3d(1.5, -2, 3.25));
  EXPECT_EQ(scaled.cameras.at(1).params, model->cameras.at(1).params);
  EXPECT_EQ(scaled.images.at(1).points2D[1].xy_px, model->images.at(1).points2D[1].xy_px);
  EXPECT_EQ(scaled.points3D.at(12).error_px, 0.75);
  // Point 12 projects to the same pixel in image 1 before and after.
  Result<CameraIntrinsics> in = IntrinsicsFromColmap(model->cameras.at(1));
  ASSERT_TRUE(in.ok());
  Eigen::Vector2d before, after;
  ASSERT_TRUE(ProjectToPixel(*in, model->images.at(1).CamFromWorld() *
                                      model->points3D.at(12).xyz_in_world, &before));
  ASSERT_TRUE(ProjectToPixel(*in, scaled.images.at(1).CamFromWorld() *
                                      scaled.points3D.at(12).xyz_in_world, &after));
  EXPECT_NEAR((after - before).norm(), 0.0, 1e-9);
}

TEST(ColmapModel, BinaryIsPreferredWhenBothFormatsArePresent) {
  TempDir dir;
  Result<ColmapModel> text = ReadColmapModel(WriteTextModel(dir));
  ASSERT_TRUE(text.ok());
  const std::string both = dir.File("both");
  ASSERT_TRUE(WriteColmapModel(*text, both, ColmapFormat::kBinary).ok());
  std::filesystem::copy_file(dir.File("cameras.txt"), both + "/cameras.txt");
  std::filesystem::copy_file(dir.File("images.txt"), both + "/images.txt");
  std::filesystem::copy_file(dir.File("points3D.txt"), both + "/points3D.txt");
  Result<ColmapModel> read = ReadColmapModel(both);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->format, ColmapFormat::kBinary);
}

// COLMAP's pixel convention against a point projected by hand: a PINHOLE
// camera f = 100 px, principal point (50, 40) in COLMAP's convention. The
// point (0.1, 0.2, 1) in the camera frame is at COLMAP pixel
// (100 * 0.1 + 50, 100 * 0.2 + 40) = (60, 60), which is OPL (OpenCV) pixel
// (59.5, 59.5).
TEST(ColmapModel, PixelConventionAgainstAHandProjection) {
  ColmapCamera camera;
  camera.camera_id = 3;
  camera.model_id = kColmapPinhole;
  camera.width_px = 100;
  camera.height_px = 80;
  camera.params = {100, 100, 50, 40};
  Result<CameraIntrinsics> in = IntrinsicsFromColmap(camera);
  ASSERT_TRUE(in.ok()) << in.status().ToString();
  EXPECT_EQ(in->cx_px, 49.5);
  EXPECT_EQ(in->cy_px, 39.5);
  Eigen::Vector2d opl_px;
  ASSERT_TRUE(ProjectToPixel(*in, Eigen::Vector3d(0.1, 0.2, 1.0), &opl_px));
  EXPECT_NEAR(opl_px.x(), 59.5, 1e-12);
  EXPECT_NEAR(opl_px.y(), 59.5, 1e-12);
  const Eigen::Vector2d colmap_px = ColmapPixelFromOpl(opl_px);
  EXPECT_NEAR(colmap_px.x(), 60.0, 1e-12);
  EXPECT_NEAR(colmap_px.y(), 60.0, 1e-12);
  EXPECT_EQ(OplPixelFromColmap(Eigen::Vector2d(60, 60)), Eigen::Vector2d(59.5, 59.5));
  // The centre of the top-left pixel: COLMAP (0.5, 0.5), OPL (0, 0).
  EXPECT_EQ(OplPixelFromColmap(Eigen::Vector2d(0.5, 0.5)), Eigen::Vector2d(0, 0));

  // And back: the intrinsics written into the camera give COLMAP's parameters.
  ColmapCamera back = camera;
  back.params.clear();
  ASSERT_TRUE(SetColmapIntrinsics(*in, &back).ok());
  EXPECT_EQ(back.params, camera.params);
}

TEST(ColmapModel, CameraModelsMapToOplIntrinsics) {
  ColmapCamera camera;
  camera.camera_id = 2;
  camera.width_px = 640;
  camera.height_px = 480;
  const auto map = [&](int model, std::vector<double> params) {
    camera.model_id = model;
    camera.params = std::move(params);
    return IntrinsicsFromColmap(camera);
  };
  Result<CameraIntrinsics> in = map(kColmapSimplePinhole, {400, 320, 240});
  ASSERT_TRUE(in.ok());
  EXPECT_EQ(in->fx_px, 400);
  EXPECT_EQ(in->fy_px, 400);
  EXPECT_EQ(in->cx_px, 319.5);
  in = map(kColmapRadial, {400, 320, 240, 0.1, -0.02});
  ASSERT_TRUE(in.ok());
  EXPECT_EQ(in->k1, 0.1);
  EXPECT_EQ(in->k2, -0.02);
  EXPECT_EQ(in->p1, 0.0);
  in = map(kColmapOpenCv, {400, 410, 320, 240, 0.1, -0.02, 0.001, -0.002});
  ASSERT_TRUE(in.ok());
  EXPECT_EQ(in->fy_px, 410);
  EXPECT_EQ(in->cy_px, 239.5);
  EXPECT_EQ(in->p1, 0.001);
  EXPECT_EQ(in->p2, -0.002);
  EXPECT_EQ(in->k3, 0.0);
  in = map(kColmapFullOpenCv, {400, 410, 320, 240, 0.1, -0.02, 0.001, -0.002, 0.003, 0, 0, 0});
  ASSERT_TRUE(in.ok());
  EXPECT_EQ(in->k3, 0.003);
  // Every supported model writes back to the same parameters.
  for (int model : {kColmapSimplePinhole, kColmapPinhole, kColmapSimpleRadial, kColmapRadial,
                    kColmapOpenCv, kColmapFullOpenCv}) {
    std::vector<double> params(ColmapCameraModelNumParams(model), 0.0);
    params[0] = 400;
    for (size_t i = 1; i < params.size(); ++i) params[i] = i < 4 ? 300 + i : 0.01 * i;
    if (model == kColmapFullOpenCv) params[9] = params[10] = params[11] = 0.0;
    Result<CameraIntrinsics> mapped = map(model, params);
    ASSERT_TRUE(mapped.ok()) << ColmapCameraModelName(model) << ": " << mapped.status().ToString();
    ColmapCamera back = camera;
    ASSERT_TRUE(SetColmapIntrinsics(*mapped, &back).ok()) << ColmapCameraModelName(model);
    EXPECT_EQ(back.params, params) << ColmapCameraModelName(model);
  }

  in = map(kColmapFullOpenCv, {400, 410, 320, 240, 0.1, -0.02, 0.001, -0.002, 0.003, 0, 0.01, 0});
  ASSERT_FALSE(in.ok());
  EXPECT_EQ(in.status().message(),
            "COLMAP camera 2: FULL_OPENCV parameter k5 = 0.01 is not 0: OPL's camera model has "
            "no rational radial term (k4, k5, k6)");
  in = map(kColmapOpenCvFisheye, {400, 410, 320, 240, 0.1, 0, 0, 0});
  ASSERT_FALSE(in.ok());
  EXPECT_EQ(in.status().message(),
            "COLMAP camera 2: model OPENCV_FISHEYE is not supported (supported: SIMPLE_PINHOLE, "
            "PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV with k4 = k5 = k6 = 0)");
  for (int model : {kColmapFov, kColmapSimpleRadialFisheye, kColmapRadialFisheye,
                    kColmapThinPrismFisheye}) {
    std::vector<double> params(ColmapCameraModelNumParams(model), 1.0);
    EXPECT_THAT(map(model, params).status().message(),
                HasSubstr(std::string("model ") + ColmapCameraModelName(model) +
                          " is not supported"));
  }

  // Writing back refuses terms the camera's model cannot hold.
  camera.model_id = kColmapRadial;
  camera.params = {400, 320, 240, 0, 0};
  CameraIntrinsics with_p1 = *map(kColmapOpenCv, {400, 400, 320, 240, 0.1, 0, 0.001, 0});
  camera.model_id = kColmapRadial;
  EXPECT_EQ(SetColmapIntrinsics(with_p1, &camera).message(),
            "COLMAP camera 2: model RADIAL cannot hold p1 = 0.001");
  CameraIntrinsics two_f = *map(kColmapPinhole, {400, 401, 320, 240});
  camera.model_id = kColmapSimplePinhole;
  EXPECT_EQ(SetColmapIntrinsics(two_f, &camera).message(),
            "COLMAP camera 2: model SIMPLE_PINHOLE cannot hold fy = 401 != fx = 400 (one focal "
            "length)");
}

// Bad files: each refused with one line naming the file, the line or record,
// and the field.
TEST(ColmapModel, BadTextFilesNameFileLineAndField) {
  struct Case {
    std::string cameras, images, points, message;
  };
  const std::string c = kCamerasTxt, i = kImagesTxt, p = kPoints3DTxt;
  const std::vector<Case> cases = {
      {"1 PINHOLE 640 abc 500 510 320 240\n", i, p,
       "cameras.txt:1: field 'HEIGHT': not an integer in [0, 4294967295]: 'abc'"},
      {"# c\n1 PINHOL 640 480 500 510 320 240\n", i, p,
       "cameras.txt:2: field 'MODEL': unknown camera model: 'PINHOL'"},
      {"1 PINHOLE 640 480 500 510 320\n", i, p,
       "cameras.txt:1: model PINHOLE has 4 parameters, found 3"},
      {"1 PINHOLE 640 480 500 510 320 2,5\n", i, p,
       "cameras.txt:1: field 'PARAMS[3]': not a finite number: '2,5'"},
      {c + "1 PINHOLE 640 480 500 510 320 240\n", i, p, "cameras.txt:6: camera 1 appears twice"},
      {c, "1 1 0 0 0 0 0 0 1 a.png\n", p,
       "images.txt:1: image 1: missing its POINTS2D line (the line after the image's line)"},
      {c, "1 1 0 0 0 0 0 nan 1 a.png\n\n", p,
       "images.txt:1: field 'TZ': not a finite number: 'nan'"},
      {c, "1 1 0 0 0 0 0 0 1 a.png\n1 2 -1 3\n", p,
       "images.txt:2: POINTS2D of image 1: expected triples X, Y, POINT3D_ID, found 4 fields"},
      {c, "1 1 0 0 0 0 0 0 1 a.png\n1 2 -2\n", p,
       "images.txt:2: field 'POINT3D_ID[0]': not an integer in [0, 18446744073709551614]: '-2'"},
      {c, "1 1 0 0 0 0 0 0 9 a.png\n\n", "",
       "images.txt: image 1: camera 9 does not exist"},
      {c, i, "12 1.5 -2 3.25 256 0 17 0.75 1 1\n13 0 0 1 1 2 3 -1\n",
       "points3D.txt:1: field 'R': not an integer in [0, 255]: '256'"},
      {c, i, "12 1.5 -2 3.25 255 0 17 0.75 1\n13 0 0 1 1 2 3 -1\n",
       "points3D.txt:1: expected POINT3D_ID, X, Y, Z, R, G, B, ERROR and pairs IMAGE_ID, "
       "POINT2D_IDX, found 9 fields"},
      {c, i, "12 1.5 -2 3.25 255 0 17 0.75 5 0\n13 0 0 1 1 2 3 -1\n",
       "points3D.txt: point 12: track element 1: image 5 does not exist"},
      {c, i, "12 1.5 -2 3.25 255 0 17 0.75 1 2\n13 0 0 1 1 2 3 -1\n",
       "points3D.txt: point 12: track element 1: POINT2D_IDX 2 is out of range (image 1 has 2 "
       "2D points)"},
      {c, i, "13 0 0 1 1 2 3 -1\n",
       "images.txt: image 1: 2D point 1: 3D point 12 does not exist"},
  };
  for (const Case& k : cases) {
    TempDir dir;
    Result<ColmapModel> model = ReadColmapModel(WriteTextModel(dir, k.cameras, k.images, k.points));
    ASSERT_FALSE(model.ok()) << k.message;
    EXPECT_EQ(model.status().code(), StatusCode::kParseError) << k.message;
    EXPECT_EQ(model.status().message(), dir.path() + "/" + k.message);
  }
}

TEST(ColmapModel, BadBinaryFilesNameFileRecordAndField) {
  TempDir dir;
  Result<ColmapModel> text = ReadColmapModel(WriteTextModel(dir));
  ASSERT_TRUE(text.ok());
  const std::string good = dir.File("good");
  ASSERT_TRUE(WriteColmapModel(*text, good, ColmapFormat::kBinary).ok());
  const std::string cameras = ReadAll(good + "/cameras.bin");
  const std::string images = ReadAll(good + "/images.bin");
  const std::string points = ReadAll(good + "/points3D.bin");

  const auto read_with = [&](const std::string& file, const std::string& contents) {
    TempDir bad;
    bad.Write("cameras.bin", file == "cameras.bin" ? contents : cameras);
    bad.Write("images.bin", file == "images.bin" ? contents : images);
    bad.Write("points3D.bin", file == "points3D.bin" ? contents : points);
    Result<ColmapModel> model = ReadColmapModel(bad.path());
    EXPECT_FALSE(model.ok());
    const std::string message = model.status().message();
    return message.substr(bad.path().size() + 1);
  };
  // Camera 7 (second record) cut 3 bytes short inside its last parameter:
  // the record starts at 8 + 56 = 64, its last parameter at 64 + 24 + 24 = 112.
  EXPECT_EQ(read_with("cameras.bin", cameras.substr(0, cameras.size() - 3)),
            "cameras.bin: record 2 (camera 7): field 'PARAMS': truncated file (needs 8 bytes "
            "at offset 112, file has 117)");
  EXPECT_EQ(read_with("cameras.bin", cameras + "x"),
            "cameras.bin: 1 bytes after the last record (corrupt file, or not a COLMAP model of "
            "this layout)");
  std::string bad_model = cameras;
  bad_model[8 + 4] = 42;  // camera 1's MODEL_ID
  EXPECT_EQ(read_with("cameras.bin", bad_model),
            "cameras.bin: record 1 (camera 1): field 'MODEL_ID': unknown camera model id 42");
  std::string huge = cameras;
  huge[7] = 0x10;  // a count of 2^60 + 2 cameras
  EXPECT_THAT(read_with("cameras.bin", huge),
              HasSubstr("cameras.bin: field 'number of cameras': 1152921504606846978 entries of "
                        "at least 24 bytes cannot fit in the 112 bytes left"));
  // images.bin ends in image 4's name, before its '\0'.
  const size_t name_end = images.rfind(std::string("b.png") + '\0');
  ASSERT_NE(name_end, std::string::npos);
  EXPECT_THAT(read_with("images.bin", images.substr(0, name_end + 3)),
              HasSubstr("images.bin: record 2 (image 4): field 'NAME': truncated file (no "
                        "terminating '\\0'"));
  // A count that cannot fit is caught before any record is read ...
  EXPECT_EQ(read_with("points3D.bin", points.substr(0, 8 + 10)),
            "points3D.bin: field 'number of points': 2 entries of at least 51 bytes cannot fit "
            "in the 10 bytes left (truncated or corrupt file)");
  // ... and a record cut short where it is: point 13 starts at 8 + 59 = 67,
  // its TRACK length at 67 + 8 + 24 + 3 + 8 = 110.
  EXPECT_EQ(read_with("points3D.bin", points.substr(0, points.size() - 1)),
            "points3D.bin: record 2 (point 13): field 'TRACK length': truncated file (needs 8 "
            "bytes at offset 110, file has 117)");
  EXPECT_EQ(read_with("points3D.bin", ""),
            "points3D.bin: field 'number of points': truncated file (needs 8 bytes at offset 0, "
            "file has 0)");
}

TEST(ColmapModel, FolderWithoutAModelIsRefused) {
  TempDir dir;
  dir.Write("cameras.txt", kCamerasTxt);
  dir.Write("images.bin", "");
  Result<ColmapModel> model = ReadColmapModel(dir.path());
  ASSERT_FALSE(model.ok());
  EXPECT_EQ(model.status().code(), StatusCode::kIoError);
  EXPECT_EQ(model.status().message(),
            dir.path() +
                ": not a COLMAP sparse model: needs cameras, images and points3D, all .bin or "
                "all .txt (found: cameras.txt, images.bin)");
  EXPECT_EQ(ReadColmapModel(dir.File("nowhere")).status().message(),
            dir.File("nowhere") + ": cannot read a COLMAP model: not a folder");
}

TEST(ColmapModel, WritingIsAllOrNothingAndRefusesAFolderWithFiles) {
  TempDir dir;
  Result<ColmapModel> model = ReadColmapModel(WriteTextModel(dir));
  ASSERT_TRUE(model.ok());
  // The folder holding the input has files: refused, nothing written.
  const Status refused = WriteColmapModel(*model, dir.path(), ColmapFormat::kBinary);
  EXPECT_EQ(refused.code(), StatusCode::kIoError);
  EXPECT_THAT(refused.message(), HasSubstr(": exists and is not empty: refusing to write"));
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"cameras.txt", "images.txt", "points3D.txt"}));

  // An empty folder is replaced by the model; no temporary folder is left.
  std::filesystem::create_directory(dir.File("out"));
  ASSERT_TRUE(WriteColmapModel(*model, dir.File("out") + "/", ColmapFormat::kText).ok());
  EXPECT_EQ(dir.Entries(),
            (std::vector<std::string>{"cameras.txt", "images.txt", "out", "points3D.txt"}));
  EXPECT_EQ(ReadAll(dir.File("out/cameras.txt")), ReadAll(dir.File("cameras.txt")));

  // A model that is not consistent is not written at all.
  ColmapModel broken = *model;
  broken.images.at(4).camera_id = 99;
  const Status invalid = WriteColmapModel(broken, dir.File("broken"), ColmapFormat::kText);
  EXPECT_EQ(invalid.message(), "images: image 4: camera 99 does not exist");
  EXPECT_FALSE(std::filesystem::exists(dir.File("broken")));

  // A parent that does not exist: an IoError, nothing left behind.
  const Status no_parent = WriteColmapModel(*model, dir.File("a/b"), ColmapFormat::kText);
  EXPECT_EQ(no_parent.code(), StatusCode::kIoError);
  EXPECT_THAT(no_parent.message(), HasSubstr("cannot create a temporary folder"));
}

}  // namespace
}  // namespace opl
