// The harder virtual lab (lab/scene_look.h, lab/shot_file.h) against
// independent measurements: tags and spots stay where the truth says under
// texture, colour, ambient ramp, vignetting, defocus and a Bayer mosaic
// (DetectTags, DetectSpots); the laser is seen through the documented
// response; the corner fall-off is the documented one; distractors are the
// same in lit and dark shots of a camera and where the truth says; the JPEG
// carries the EXIF orientation OpenCV honours; the scene JSON reads the new
// fields and refuses bad ones naming them.
#include "opl/lab/scene_look.h"

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/shot_file.h"
#include "opl/vision/spot_detection.h"
#include "opl/vision/tag_detection.h"
#include "support/scene_images.h"
#include "support/wall_scene.h"

namespace opl {
namespace {

std::string Texture(const std::string& name) {
  return test::SourceDir() + "/tests/data/textures/" + name;
}

using test::WallScene;

cv::Mat Channel(const cv::Mat& bgr, int c) {
  cv::Mat out;
  cv::extractChannel(bgr, out, c);
  return out;
}

// Largest distance from a truth spot to its nearest detection; -1 when a
// truth spot has none within 1 px.
double WorstSpotError(const RenderedShot& shot, const std::vector<DetectedSpot>& found) {
  double worst = 0.0;
  for (const SpotView& v : shot.spots) {
    if (!v.visible) continue;
    double best = 1e9;
    for (const DetectedSpot& d : found) {
      best = std::min(best, (Eigen::Vector2d(d.u_px, d.v_px) - v.center_px).norm());
    }
    if (best > 1.0) return -1.0;
    worst = std::max(worst, best);
  }
  return worst;
}

double WorstTagCornerError(const RenderedShot& shot, const std::vector<TagDetection>& found) {
  double worst = 0.0;
  for (const TagDetection& d : found) {
    for (const TagView& v : shot.tags) {
      if (v.id != d.id) continue;
      for (int c = 0; c < 4; ++c) worst = std::max(worst, (d.corners_px[c] - v.corners_px[c]).norm());
    }
  }
  return worst;
}

TEST(SceneLook, TagsAndSpotsStayAtTheTruthInAHarderLook) {
  Scene scene = WallScene();
  scene.image.color = true;
  scene.image.wall_texture = Texture("fruits.jpg");
  scene.image.wall_texture_contrast = 0.3;
  scene.image.ambient_gradient = 0.15;
  scene.image.ambient_angle_deg = 30.0;
  scene.image.vignetting = 0.35;
  scene.image.defocus_sigma_px = 0.7;
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().message();
  Result<RenderedShot> shot = renderer->RenderShot(0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  ASSERT_EQ(shot->image.type(), CV_16UC3);

  cv::Mat grey;
  cv::cvtColor(shot->image, grey, cv::COLOR_BGR2GRAY);
  Result<std::vector<TagDetection>> tags = DetectTags(grey);
  ASSERT_TRUE(tags.ok()) << tags.status().message();
  EXPECT_EQ(tags->size(), 4u);
  const double tag_error = WorstTagCornerError(*shot, *tags);
  // The spots' light is exact: in the red channel of lit minus dark (the
  // same camera, lasers off) the texture, ramp and vignetting cancel.
  scene.shots.push_back({"cam0", "dark.png", {}, 0});
  Result<SceneRenderer> with_dark = SceneRenderer::Create(scene);
  ASSERT_TRUE(with_dark.ok());
  Result<RenderedShot> dark = with_dark->RenderShot(1);
  ASSERT_TRUE(dark.ok());
  cv::Mat difference;
  cv::subtract(Channel(shot->image, 2), Channel(dark->image, 2), difference);
  Result<SpotDetectionResult> spots = DetectSpots(difference);
  ASSERT_TRUE(spots.ok()) << spots.status().message();
  const double spot_error = WorstSpotError(*shot, spots->spots);
  // On the red channel alone the texture under a spot pulls its centre.
  Result<SpotDetectionResult> red_spots = DetectSpots(Channel(shot->image, 2));
  ASSERT_TRUE(red_spots.ok());
  std::printf("harder look: %zu tags, worst corner %.4f px; lit - dark: %zu blobs, worst spot "
              "%.4f px; red alone: %zu blobs, worst spot %.4f px\n",
              tags->size(), tag_error, spots->spots.size(), spot_error, red_spots->spots.size(),
              WorstSpotError(*shot, red_spots->spots));
  EXPECT_LT(tag_error, 0.1);
  EXPECT_EQ(spots->spots.size(), 25u);
  EXPECT_GE(spot_error, 0.0) << "a spot was not found";
  EXPECT_LT(spot_error, 0.05);
  // The defocused spots are wider by the defocus: the central spot's sigma
  // 1.2 px (render_scene_test) becomes sqrt(1.2^2 + 0.7^2).
  EXPECT_NEAR(std::sqrt(shot->spots[12].shape_covariance_px2(0, 0)), std::hypot(1.2, 0.7), 0.02);
}

TEST(SceneLook, TheLaserIsSeenThroughTheCameraResponse) {
  Scene scene = WallScene();
  scene.tags.tags.clear();
  scene.image.color = true;
  scene.image.laser_response_rgb = {0.9, 0.12, 0.0};
  Result<RenderedShot> shot = RenderShot(scene, 0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  const SpotView& centre = shot->spots[12];
  const int u = static_cast<int>(std::lround(centre.center_px.x()));
  const int v = static_cast<int>(std::lround(centre.center_px.y()));
  const double background = scene.image.background_level * 65535.0;
  const cv::Vec3w px = shot->image.at<cv::Vec3w>(v, u);
  const double red = px[2] - background, green = px[1] - background, blue = px[0] - background;
  EXPECT_GT(red, 0.3 * 65535.0);
  EXPECT_NEAR(green / red, 0.12 / 0.9, 2e-3);
  EXPECT_NEAR(blue, 0.0, 1.0);
  // Away from the spots the wall is grey.
  const cv::Vec3w wall = shot->image.at<cv::Vec3w>(5, 5);
  EXPECT_EQ(wall[0], wall[2]);
  EXPECT_NEAR(wall[1], background, 1.0);
}

TEST(SceneLook, VignettingDarkensTheCornersAsDocumented) {
  Scene scene = WallScene(321, 241);
  scene.tags.tags.clear();
  scene.shots[0].lasers.clear();
  scene.image.background_level = 0.5;
  scene.image.vignetting = 0.4;
  Result<RenderedShot> shot = RenderShot(scene, 0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  const CameraIntrinsics& in = scene.cameras[0].intrinsics;
  // The principal point is right of and above the centre: the bottom-left
  // corner is the farthest, where the light is 1 - 0.4.
  EXPECT_NEAR(shot->image.at<uint16_t>(240, 0), 0.5 * 0.6 * 65535.0, 1.0);
  const double r2 = std::pow(320 - in.cx_px, 2) + std::pow(in.cy_px, 2);
  const double r2_corner = std::pow(in.cx_px, 2) + std::pow(240 - in.cy_px, 2);
  EXPECT_NEAR(shot->image.at<uint16_t>(0, 320), 0.5 * (1.0 - 0.4 * r2 / r2_corner) * 65535.0, 1.0);
  const int cu = static_cast<int>(std::lround(in.cx_px)), cv_ = static_cast<int>(std::lround(in.cy_px));
  EXPECT_NEAR(shot->image.at<uint16_t>(cv_, cu), 0.5 * 65535.0, 2.0);
}

// A shot's exposure scales all its light before the sensor: a laser-off
// shot at exposure 0.5 of a vignetted wall with distractors is half the
// same shot at exposure 1, pixel for pixel (noise-free, 16 bit: to the
// rounding). The plain lab refuses an exposure, naming the shot's field,
// and the field is read, range-checked and written back.
TEST(SceneLook, ExposureScalesTheShotsLight) {
  Scene scene = WallScene(321, 241);
  scene.image.vignetting = 0.3;
  scene.image.distractors = 6;
  scene.shots[0].lasers.clear();
  scene.shots.push_back(scene.shots[0]);
  scene.shots[1].file = "half.png";
  scene.shots[1].exposure = 0.5;
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().message();
  Result<RenderedShot> full = renderer->RenderShot(0);
  Result<RenderedShot> half = renderer->RenderShot(1);
  ASSERT_TRUE(full.ok() && half.ok());
  ASSERT_EQ(full->image.type(), CV_16UC1);
  double worst = 0.0, brightest = 0.0;
  for (int y = 0; y < full->image.rows; ++y) {
    for (int x = 0; x < full->image.cols; ++x) {
      const double a = full->image.at<uint16_t>(y, x), b = half->image.at<uint16_t>(y, x);
      if (a >= 65535.0) continue;  // clipped at exposure 1
      worst = std::max(worst, std::abs(b - 0.5 * a));
      brightest = std::max(brightest, a);
    }
  }
  EXPECT_GT(brightest, 0.5 * 65535.0);  // a distractor, not only the wall
  EXPECT_LE(worst, 1.0);

  Scene plain = WallScene(321, 241);
  plain.shots[0].exposure = 0.9;
  const Status refused = plain.ValidateForRendering();
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("shots[0].exposure: 0.9: the plain lab"), std::string::npos)
      << refused.message();
  scene.shots[1].exposure = 0.0;
  const Status zero = scene.Validate();
  ASSERT_FALSE(zero.ok());
  EXPECT_NE(zero.message().find("shots[1].exposure: 0: must be in (0, 10]"), std::string::npos)
      << zero.message();

  scene.shots[1].exposure = 0.5;
  Result<Scene> back = ParseSceneJson(FormatMeasurementSceneJson(scene, ""), "s.json", "", SceneUse::kMeasure);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->shots[0].exposure, 1.0);
  EXPECT_EQ(back->shots[1].exposure, 0.5);
}

TEST(SceneLook, DistractorsBelongToTheCameraLitOrDark) {
  Scene scene = WallScene();
  scene.image.bit_depth = 8;
  scene.image.distractors = 12;
  scene.shots.push_back({"cam0", "dark.png", {}, 0});
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().message();
  Result<RenderedShot> lit = renderer->RenderShot(0);
  Result<RenderedShot> dark = renderer->RenderShot(1);
  ASSERT_TRUE(lit.ok() && dark.ok());
  ASSERT_EQ(lit->distractors.size(), 12u);
  ASSERT_EQ(dark->distractors.size(), 12u);
  int kinds[3] = {0, 0, 0};
  for (size_t k = 0; k < 12; ++k) {
    EXPECT_EQ(lit->distractors[k].center_px, dark->distractors[k].center_px);
    ++kinds[static_cast<int>(lit->distractors[k].kind)];
  }
  std::printf("distractors: %d highlights, %d lamps, %d dots\n", kinds[0], kinds[1], kinds[2]);
  // Noise-free: lit minus dark is the laser light alone; each distractor's
  // centre is bright in both (at least 0.3 of full scale above the wall).
  cv::Mat diff;
  cv::absdiff(lit->image, dark->image, diff);
  for (const Distractor& d : lit->distractors) {
    const int u = static_cast<int>(std::lround(d.center_px.x()));
    const int v = static_cast<int>(std::lround(d.center_px.y()));
    bool near_spot = false;
    for (const SpotView& s : lit->spots) near_spot |= (s.center_px - d.center_px).norm() < 10.0;
    if (!near_spot) {
      EXPECT_EQ(diff.at<uint8_t>(v, u), 0);
    }
    EXPECT_GT(dark->image.at<uint8_t>(v, u), (scene.image.background_level + 0.25) * 255.0)
        << DistractorKindName(d.kind) << " at " << u << ", " << v;
  }
  int lit_pixels = cv::countNonZero(diff);
  EXPECT_GT(lit_pixels, 25 * 5);  // the 25 spots
  // The grey wall between is untouched.
  EXPECT_EQ(dark->image.at<uint8_t>(200, 320) > 0, true);
}

TEST(SceneLook, BayerMosaicKeepsTheRedSpot) {
  Scene scene = WallScene();
  scene.tags.tags.clear();
  scene.image.color = true;
  scene.image.bayer = true;
  scene.image.bit_depth = 8;
  scene.image.read_noise = 0.003;
  Result<RenderedShot> shot = RenderShot(scene, 0);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  ASSERT_EQ(shot->image.type(), CV_8UC3);
  // The demosaiced spot is red (the mosaic's pattern and OpenCV's name for
  // it agree), not blue: its light per channel over a window, against the
  // same scene without the mosaic.
  Scene plain = scene;
  plain.image.bayer = false;
  Result<RenderedShot> reference = RenderShot(plain, 0);
  ASSERT_TRUE(reference.ok());
  const SpotView& centre = shot->spots[12];
  const cv::Rect window(static_cast<int>(std::lround(centre.center_px.x())) - 5,
                        static_cast<int>(std::lround(centre.center_px.y())) - 5, 11, 11);
  const double background = 11 * 11 * scene.image.background_level * 255.0;
  const cv::Scalar bayer_flux = cv::sum(shot->image(window)) - cv::Scalar::all(background);
  const cv::Scalar plain_flux = cv::sum(reference->image(window)) - cv::Scalar::all(background);
  std::printf("spot light B G R: Bayer %.0f %.0f %.0f, plain %.0f %.0f %.0f DN\n", bayer_flux[0],
              bayer_flux[1], bayer_flux[2], plain_flux[0], plain_flux[1], plain_flux[2]);
  EXPECT_NEAR(bayer_flux[2] / plain_flux[2], 1.0, 0.1);
  EXPECT_LT(bayer_flux[0], 0.1 * bayer_flux[2]);
  Result<SpotDetectionResult> spots = DetectSpots(Channel(shot->image, 2));
  ASSERT_TRUE(spots.ok());
  const double error = WorstSpotError(*shot, spots->spots);
  std::printf("Bayer: worst spot %.4f px\n", error);
  EXPECT_GE(error, 0.0);
  EXPECT_LT(error, 0.15);
}

TEST(ShotFile, JpegCarriesTheExifOrientationOpenCvHonours) {
  cv::Mat image(48, 96, CV_8UC3, cv::Scalar(30, 90, 200));
  cv::line(image, {0, 0}, {95, 47}, cv::Scalar(255, 255, 255), 3);
  ImageLook look;
  look.bit_depth = 8;
  look.format = "jpeg";
  look.jpeg_quality = 80;
  look.exif_orientation = 6;
  Result<std::string> bytes = EncodeShotImage(image, look);
  ASSERT_TRUE(bytes.ok()) << bytes.status().message();
  const std::vector<uchar> data(bytes->begin(), bytes->end());
  const cv::Mat rotated = cv::imdecode(data, cv::IMREAD_COLOR);
  ASSERT_EQ(rotated.cols, 48);  // OpenCV applies the tag: 90 deg clockwise
  const cv::Mat sensor = cv::imdecode(data, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  ASSERT_EQ(sensor.cols, 96);
  cv::Mat turned;
  cv::rotate(sensor, turned, cv::ROTATE_90_CLOCKWISE);
  EXPECT_EQ(cv::norm(turned, rotated, cv::NORM_INF), 0.0);
  EXPECT_LT(cv::norm(sensor, image, cv::NORM_L2) / std::sqrt(96.0 * 48 * 3), 12.0);
  // A JPEG of lower quality is smaller; PNG is lossless.
  look.jpeg_quality = 30;
  look.exif_orientation = 0;
  EXPECT_LT(EncodeShotImage(image, look)->size(), bytes->size());
  look.format = "png";
  const std::string png = *EncodeShotImage(image, look);
  EXPECT_EQ(cv::norm(cv::imdecode(std::vector<uchar>(png.begin(), png.end()), cv::IMREAD_COLOR),
                     image, cv::NORM_INF),
            0.0);
  EXPECT_FALSE(InsertExifOrientation("not a jpeg", 6).ok());
  EXPECT_FALSE(InsertExifOrientation(*bytes, 9).ok());
}

std::string SceneJsonWithImage(const std::string& image) {
  return R"({"format": "opl.scene", "version": 1,
    "cameras": [{"name": "cam0", "width_px": 640, "height_px": 480,
                 "intrinsics": {"fx": 600, "fy": 600, "cx": 320, "cy": 240}}],
    "tags": {"size_mm": 100, "placements": [{"id": 1, "center_mm": [2000, 0, 0],
             "normal": [-1, 0, 0], "up": [0, 0, 1]}]},
    "image": )" + image + R"(,
    "shots": [{"camera": "cam0", "file": "a.png", "lasers": []}]})";
}

TEST(SceneLookJson, FieldsAreReadAndBadOnesNamed) {
  Result<Scene> scene = ParseSceneJson(
      SceneJsonWithImage(R"({"color": true, "bayer": true, "laser_response_rgb": [1, 0.2, 0.05],
        "wall_texture": "walls/brick.jpg", "wall_texture_contrast": 0.5, "ambient_gradient": 0.1,
        "ambient_angle_deg": 45, "vignetting": 0.3, "defocus_sigma_px": 1.5, "distractors": 20,
        "format": "jpeg", "jpeg_quality": 90, "exif_orientation": 6, "bit_depth": 8})"),
      "s.json", "/data/scenes");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  const ImageLook& l = scene->image;
  EXPECT_TRUE(l.color && l.bayer && l.HasSceneLook());
  EXPECT_EQ(l.laser_response_rgb[1], 0.2);
  EXPECT_EQ(std::filesystem::path(l.wall_texture), std::filesystem::path("/data/scenes/walls/brick.jpg"));
  EXPECT_EQ(l.distractors, 20);
  EXPECT_EQ(l.format, "jpeg");
  EXPECT_EQ(l.jpeg_quality, 90);
  EXPECT_EQ(l.exif_orientation, 6);
  EXPECT_FALSE(ImageLook().HasSceneLook());

  const std::pair<const char*, const char*> bad[] = {
      {R"({"bayer": true})", "image.bayer"},
      {R"({"format": "tiff"})", "image.format"},
      {R"({"format": "jpeg", "bit_depth": 16})", "image.format"},
      {R"({"vignetting": 0.95})", "image.vignetting"},
      {R"({"distractors": -1})", "image.distractors"},
      {R"({"color": "yes"})", "image.color"},
      {R"({"laser_response_rgb": [1, 2, 0]})", "image.laser_response_rgb[1]"},
      {R"({"exif_orientation": 6})", "image.exif_orientation"},
      {R"({"format": "jpeg", "bit_depth": 8, "jpeg_quality": 0})", "image.jpeg_quality"},
  };
  for (const auto& [image, field] : bad) {
    Result<Scene> s = ParseSceneJson(SceneJsonWithImage(image), "s.json", "");
    ASSERT_FALSE(s.ok()) << image;
    EXPECT_NE(s.status().message().find(field), std::string::npos) << s.status().message();
  }
}

TEST(SceneLook, AMissingWallTextureIsNamed) {
  Scene scene = WallScene();
  scene.image.wall_texture = "/nonexistent/wall.jpg";
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  ASSERT_FALSE(renderer.ok());
  EXPECT_NE(renderer.status().message().find("image.wall_texture: /nonexistent/wall.jpg"),
            std::string::npos)
      << renderer.status().message();
}

// The texture is decoded as the shots are (vision/image_decode.h): the
// photograph's pixels / 255, and a damaged file refused with the decoder's
// word, nothing printed on stderr.
TEST(SceneLook, WallTextureIsDecodedAsShotsAreAndADamagedOneRefused) {
  const std::string fruits = Texture("fruits.jpg");
  Result<cv::Mat> texture = ReadWallTexture(fruits);
  ASSERT_TRUE(texture.ok()) << texture.status().message();
  const cv::Mat bgr = cv::imread(fruits, cv::IMREAD_COLOR);
  ASSERT_EQ(texture->size(), bgr.size());
  ASSERT_EQ(texture->type(), CV_32FC3);
  cv::Mat expected;
  bgr.convertTo(expected, CV_32FC3, 1.0 / 255.0);
  EXPECT_EQ(cv::norm(*texture, expected, cv::NORM_INF), 0.0);

  testing_support::TempDir dir;
  const std::string bytes = testing_support::ReadAll(fruits);
  const std::string cut = dir.Write("cut.jpg", bytes.substr(0, bytes.size() / 2));
  ::testing::internal::CaptureStderr();
  Result<cv::Mat> damaged = ReadWallTexture(cut);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  ASSERT_FALSE(damaged.ok());
  EXPECT_EQ(damaged.status().code(), StatusCode::kIoError);
  EXPECT_EQ(damaged.status().message(),
            cut + ": the wall texture is damaged (Premature end of JPEG file)");
}

}  // namespace
}  // namespace opl
