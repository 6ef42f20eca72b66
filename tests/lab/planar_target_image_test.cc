// The planar target renderer against closed forms: the area a frontal tag
// covers, the projected corners, supersampling convergence, the board layout,
// and bad input.
#include "opl/lab/planar_target_image.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "opl/core/format.h"

namespace opl {
namespace {

Camera PinholeCamera(int width, int height, double f) {
  Camera camera;
  camera.name = "pinhole";
  camera.intrinsics.width_px = width;
  camera.intrinsics.height_px = height;
  camera.intrinsics.fx_px = f;
  camera.intrinsics.fy_px = f;
  camera.intrinsics.cx_px = 0.5 * (width - 1) + 0.37;
  camera.intrinsics.cy_px = 0.5 * (height - 1) - 0.21;
  return camera;
}

Camera SmallDistortedCamera() {
  Camera camera = PinholeCamera(160, 120, 170.0);
  camera.intrinsics.k1 = -0.25;
  camera.intrinsics.k2 = 0.1;
  camera.intrinsics.p1 = 1e-3;
  camera.intrinsics.p2 = -5e-4;
  return camera;
}

Camera DistortedCamera() {
  Camera camera = PinholeCamera(400, 300, 420.0);
  camera.intrinsics.k1 = -0.25;
  camera.intrinsics.k2 = 0.1;
  camera.intrinsics.p1 = 1e-3;
  camera.intrinsics.p2 = -5e-4;
  return camera;
}

// Sum over the image of (white - I) / (white - black): the black area [px^2].
double BlackArea(const cv::Mat& image16, const TargetRenderOptions& o) {
  double sum = 0.0;
  for (int i = 0; i < image16.rows; ++i) {
    for (int j = 0; j < image16.cols; ++j) {
      const double level = image16.at<uint16_t>(i, j) / 65535.0;
      sum += (o.white_level - level) / (o.white_level - o.black_level);
    }
  }
  return sum;
}

TEST(PlanarTargetImage, FrontalTagCoversExactlyItsBlackArea) {
  const Camera camera = PinholeCamera(320, 240, 500.0);
  Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(camera, 1);
  ASSERT_TRUE(renderer.ok()) << renderer.status().ToString();
  TargetRenderOptions o;
  // Levels exactly representable in 16 bits, so that quantisation is exact
  // where a pixel is all black or all white.
  o.white_level = 52428.0 / 65535.0;
  o.black_level = 6553.0 / 65535.0;
  o.background_level = o.white_level;  // only the black cells darken the image
  o.bit_depth = 16;
  const double depth = 1.3, tag_size = 0.2;
  // Rolled about the optical axis and off-centre, so that edges cross pixels
  // at every phase.
  for (double roll_deg : {0.0, 17.0, 45.0}) {
    const Eigen::Matrix3d R(Eigen::AngleAxisd(roll_deg * kPi / 180.0, Eigen::Vector3d::UnitZ()));
    Result<PlanarTarget> tag = MakeTagTarget(7, tag_size, Rigid3d(R, Eigen::Vector3d(0.0123, -0.0071, depth)));
    ASSERT_TRUE(tag.ok());
    int black_cells = 0;
    for (int i = 0; i < tag->texture.rows; ++i) {
      for (int j = 0; j < tag->texture.cols; ++j) black_cells += tag->texture.at<uchar>(i, j) == 0 ? 1 : 0;
    }
    const double cell_px = 500.0 * tag_size / 8.0 / depth;  // fronto-parallel: uniform scale
    const double expected = black_cells * cell_px * cell_px;
    Result<RenderedTargetImage> r = renderer->Render({*tag}, o);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const double area = BlackArea(r->image, o);
    std::printf("roll %4.1f deg: black area %.3f px^2, closed form %.3f px^2\n", roll_deg, area, expected);
    // Exact up to rounding of mixed pixels to 16 bits (unbiased, ~1e-5 px^2 each).
    EXPECT_NEAR(area, expected, 0.01) << "roll " << roll_deg;
  }
}

TEST(PlanarTargetImage, CornersAreTheProjectedTagCornersInDocumentedOrder) {
  const Camera camera = DistortedCamera();
  const double s = 0.1;
  const Eigen::Matrix3d R(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1.0, 0.5, 0.0).normalized()));
  const Rigid3d scene_from_tag(R, Eigen::Vector3d(0.03, -0.02, 0.7));
  Result<PlanarTarget> tag = MakeTagTarget(3, s, scene_from_tag, 2);
  ASSERT_TRUE(tag.ok());
  Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(camera, 1);
  ASSERT_TRUE(renderer.ok());
  Result<RenderedTargetImage> r = renderer->Render({*tag}, TargetRenderOptions{});
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->tags.size(), 1u);
  EXPECT_EQ(r->tags[0].id, 3);
  EXPECT_TRUE(r->tags[0].in_image);
  // Tag frame corners: (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2).
  const Eigen::Vector3d corners_in_tag[4] = {{-s / 2, -s / 2, 0.0}, {s / 2, -s / 2, 0.0}, {s / 2, s / 2, 0.0},
                                             {-s / 2, s / 2, 0.0}};
  for (int c = 0; c < 4; ++c) {
    Eigen::Vector2d px;
    ASSERT_TRUE(camera.Project(scene_from_tag * corners_in_tag[c], &px));
    EXPECT_LT((r->tags[0].corners_px[c] - px).norm(), 1e-9) << "corner " << c;
  }
  // The corner of the black square is where the image turns black: the
  // pixel just inside corner 0 (towards the tag centre) is dark, just outside
  // (in the quiet zone) is bright.
  const Eigen::Vector2d centre = 0.25 * (r->tags[0].corners_px[0] + r->tags[0].corners_px[1] +
                                         r->tags[0].corners_px[2] + r->tags[0].corners_px[3]);
  const Eigen::Vector2d dir = (centre - r->tags[0].corners_px[0]).normalized();
  const Eigen::Vector2d inside = r->tags[0].corners_px[0] + 3.0 * dir;
  const Eigen::Vector2d outside = r->tags[0].corners_px[0] - 3.0 * dir;
  const auto at = [&](const Eigen::Vector2d& p) {
    return r->image.at<uchar>(static_cast<int>(std::lround(p.y())), static_cast<int>(std::lround(p.x())));
  };
  EXPECT_LT(at(inside), 40);
  EXPECT_GT(at(outside), 200);

  // An upright frontal tag: corner 0 top-left, 1 top-right, 2 bottom-right
  // (clockwise in the image).
  Result<PlanarTarget> upright = MakeTagTarget(3, s, Rigid3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.7)));
  Result<RenderedTargetImage> u = renderer->Render({*upright}, TargetRenderOptions{});
  ASSERT_TRUE(u.ok());
  const auto& k = u->tags[0].corners_px;
  EXPECT_LT(k[0].x(), k[1].x());
  EXPECT_NEAR(k[0].y(), k[1].y(), 1.0);
  EXPECT_LT(k[1].y(), k[2].y());
  EXPECT_NEAR(k[1].x(), k[2].x(), 1.0);
  EXPECT_GT(k[2].x(), k[3].x());
}

TEST(PlanarTargetImage, SupersamplingConverges) {
  // A tilted tag through a distorted camera: the straight-quad approximation
  // of a sub-pixel's footprint converges as the sub-pixels shrink.
  const Camera camera = SmallDistortedCamera();
  const Eigen::Matrix3d R(Eigen::AngleAxisd(0.8, Eigen::Vector3d(0.3, 1.0, 0.0).normalized()));
  // Near the image corner, where the distortion gradient is largest.
  Result<PlanarTarget> tag = MakeTagTarget(11, 0.12, Rigid3d(R, Eigen::Vector3d(0.2, 0.13, 0.6)));
  ASSERT_TRUE(tag.ok());
  TargetRenderOptions o;
  o.bit_depth = 16;
  std::vector<cv::Mat> images;
  for (int n : {1, 2, 4, 8}) {
    Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(camera, n);
    ASSERT_TRUE(renderer.ok());
    Result<RenderedTargetImage> r = renderer->Render({*tag}, o);
    ASSERT_TRUE(r.ok());
    ASSERT_TRUE(r->tags[0].in_image);
    cv::Mat d;
    r->image.convertTo(d, CV_64F, 1.0 / 65535.0);
    images.push_back(d);
  }
  const double d1 = cv::norm(images[0], images[3], cv::NORM_INF);
  const double d2 = cv::norm(images[1], images[3], cv::NORM_INF);
  const double d4 = cv::norm(images[2], images[3], cv::NORM_INF);
  std::printf("max |I_n - I_8| (fraction of full scale): n=1 %.2e, n=2 %.2e, n=4 %.2e\n", d1, d2, d4);
  // Exact area coverage already at n = 1: differences are second order, far
  // below a grey level of an 8-bit image (3.9e-3).
  EXPECT_LT(d1, 2e-3);
  EXPECT_LE(d2, d1 + 2e-5);
  EXPECT_LE(d4, d2 + 2e-5);
  EXPECT_LT(d4, 3e-4);
}

TEST(PlanarTargetImage, BoardTagsSitWhereTheBoardSaysAndLevelsAreApplied) {
  TagBoard board;
  board.columns = 3;
  board.rows = 2;
  board.tag_size = 40.0;
  board.tag_gap = 10.0;  // 2 cells of 5
  board.first_id = 20;
  const Rigid3d scene_from_board(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-70.0, -45.0, 400.0));
  Result<PlanarTarget> target = MakeTagBoardTarget(board, scene_from_board, 2);
  ASSERT_TRUE(target.ok()) << target.status().ToString();
  EXPECT_EQ(target->texture.cols, 2 * 2 + 3 * 8 + 2 * 2);
  EXPECT_EQ(target->texture.rows, 2 * 2 + 2 * 8 + 1 * 2);
  ASSERT_EQ(target->tags.size(), 6u);
  for (const TargetTag& tag : target->tags) {
    Result<std::array<Eigen::Vector3d, 4>> corners = board.TagCorners(tag.id);
    ASSERT_TRUE(corners.ok());
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector3d in_scene_from_target =
          target->scene_from_target * Eigen::Vector3d(tag.corners_in_target[c].x(), tag.corners_in_target[c].y(), 0.0);
      EXPECT_LT((in_scene_from_target - scene_from_board * (*corners)[c]).norm(), 1e-12);
    }
  }
  // The texel of the top-left corner of tag 20 is black, the one before it white.
  EXPECT_EQ(target->texture.at<uchar>(2, 2), 0);
  EXPECT_EQ(target->texture.at<uchar>(1, 1), 255);

  const Camera camera = PinholeCamera(320, 240, 500.0);
  Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(camera, 1);
  ASSERT_TRUE(renderer.ok());
  TargetRenderOptions o;
  o.background_level = 0.2;
  Result<RenderedTargetImage> r = renderer->Render({*target}, o);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->image.at<uchar>(0, 0), static_cast<uchar>(std::lround(0.2 * 255)));  // background
  EXPECT_EQ(r->tags.size(), 6u);
  // Noise: the standard deviation of a flat background region.
  o.noise_sigma = 0.02;
  o.bit_depth = 16;
  Result<RenderedTargetImage> noisy = renderer->Render({}, o);
  ASSERT_TRUE(noisy.ok());
  cv::Scalar mean, stddev;
  cv::meanStdDev(noisy->image, mean, stddev);
  EXPECT_NEAR(mean[0] / 65535.0, 0.2, 1e-3);
  EXPECT_NEAR(stddev[0] / 65535.0, 0.02, 5e-4);
}

TEST(PlanarTargetImage, BadInputGivesAClearStatus) {
  Camera bad_camera = PinholeCamera(320, 240, 500.0);
  bad_camera.intrinsics.fx_px = -1.0;
  EXPECT_FALSE(PlanarTargetRenderer::Create(bad_camera).ok());
  EXPECT_FALSE(PlanarTargetRenderer::Create(PinholeCamera(320, 240, 500.0), 0).ok());
  EXPECT_FALSE(MakeTag36h11Texture(587).ok());
  EXPECT_FALSE(MakeTagTarget(1, -0.1, Rigid3d()).ok());
  TagBoard board{2, 2, 40.0, 7.0, 0};  // gap not a whole number of 5-unit cells
  Result<PlanarTarget> b = MakeTagBoardTarget(board, Rigid3d());
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("tag_gap = 7"), std::string::npos) << b.status().message();

  Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(PinholeCamera(64, 48, 50.0), 1);
  ASSERT_TRUE(renderer.ok());
  TargetRenderOptions o;
  o.bit_depth = 12;
  Result<RenderedTargetImage> r = renderer->Render({}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("bit_depth = 12"), std::string::npos) << r.status().message();
  PlanarTarget empty;
  empty.texel_size = 1.0;
  Result<RenderedTargetImage> e = renderer->Render({empty}, TargetRenderOptions{});
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("targets[0].texture: empty"), std::string::npos) << e.status().message();
}

}  // namespace
}  // namespace opl
