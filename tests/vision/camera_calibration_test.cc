// Camera calibration: (1) rendered tag-board views with a known camera, and a
// Monte Carlo check of the reported standard deviations; (2) OpenCV's sample
// chessboard photographs against cv::calibrateCamera on the same corners;
// (3) errors.
#include "opl/vision/camera_calibration.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "opl/core/format.h"
#include "opl/lab/planar_target_image.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

Camera TruthCamera() {
  Camera camera;
  camera.name = "truth";
  CameraIntrinsics& k = camera.intrinsics;
  k.width_px = 1024;
  k.height_px = 768;
  k.fx_px = 1100.0;
  k.fy_px = 1096.0;
  k.cx_px = 517.4;
  k.cy_px = 379.2;
  k.k1 = -0.18;
  k.k2 = 0.07;
  k.p1 = 8e-4;
  k.p2 = -5e-4;
  return camera;
}

TagBoard TestBoard() {
  TagBoard board;
  board.columns = 6;
  board.rows = 4;
  board.tag_size = 30.0;  // mm; cell 3.75 mm
  board.tag_gap = 7.5;    // 2 cells
  board.first_id = 100;
  return board;
}

// 12 board poses (cam_from_board): the board's centre at different places of
// the field, tilted by up to ~40 degrees about varied axes.
std::vector<Rigid3d> BoardPoses(const TagBoard& board) {
  const Eigen::Vector3d centre_in_board(0.5 * (board.columns * (board.tag_size + board.tag_gap) - board.tag_gap),
                                        0.5 * (board.rows * (board.tag_size + board.tag_gap) - board.tag_gap), 0.0);
  std::vector<Rigid3d> poses;
  std::mt19937_64 rng(7);
  const double offsets[12][2] = {{0, 0},     {-0.15, -0.1}, {0.15, -0.1}, {-0.15, 0.1}, {0.15, 0.1}, {0, -0.12},
                                 {0, 0.12},  {-0.18, 0},    {0.18, 0},    {-0.1, 0.06}, {0.1, -0.06}, {0.03, 0.03}};
  for (int v = 0; v < 12; ++v) {
    const double tilt = (15.0 + 25.0 * Uniform01(rng)) * kPi / 180.0;
    const double axis = 2.0 * kPi * Uniform01(rng);
    const double roll = (Uniform01(rng) - 0.5) * 0.6;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis), std::sin(axis), 0.0)) *
                               Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                                  .toRotationMatrix();
    const double depth = 470.0 + 60.0 * Uniform01(rng);  // mm
    const Eigen::Vector3d centre_in_cam(offsets[v][0] * depth, offsets[v][1] * depth, depth);
    poses.emplace_back(R, centre_in_cam - R * centre_in_board);
  }
  return poses;
}

struct RenderedViews {
  std::vector<cv::Mat> images;
  std::vector<Rigid3d> cam_from_board;
};

const RenderedViews& Views() {
  static const RenderedViews views = [] {
    RenderedViews out;
    Camera camera = TruthCamera();  // camera frame = scene frame
    Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(camera, 1);
    EXPECT_TRUE(renderer.ok());
    const TagBoard board = TestBoard();
    int v = 0;
    for (const Rigid3d& pose : BoardPoses(board)) {
      Result<PlanarTarget> target = MakeTagBoardTarget(board, pose, 2);
      EXPECT_TRUE(target.ok()) << target.status().ToString();
      TargetRenderOptions o;
      o.blur_sigma_px = 0.7;
      o.noise_sigma = 0.01;
      o.seed = static_cast<uint64_t>(1000 + v++);
      Result<RenderedTargetImage> r = renderer->Render({*target}, o);
      EXPECT_TRUE(r.ok()) << r.status().ToString();
      for (const RenderedTag& t : r->tags) EXPECT_TRUE(t.in_image) << "view " << v << " tag " << t.id;
      out.images.push_back(r->image);
      out.cam_from_board.push_back(pose);
    }
    return out;
  }();
  return views;
}

TEST(CameraCalibration, RenderedTagBoardRecoversTheCamera) {
  const RenderedViews& views = Views();
  CameraCalibrationOptions options;
  Result<CameraCalibration> cal = CalibrateCameraFromTagBoard(views.images, TestBoard(), options);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  std::printf("%s", cal->Report().c_str());
  EXPECT_EQ(cal->num_views, 12);
  EXPECT_EQ(cal->num_corners, 12 * 24 * 4);
  ASSERT_EQ(cal->view_rms_px.size(), 12u);
  // The RMS is the detector's corner accuracy (~0.02-0.03 px on these images).
  EXPECT_LT(cal->rms_px, 0.05);
  const CameraIntrinsics truth = TruthCamera().intrinsics;
  const auto est = cal->intrinsics.Packed();
  const auto tru = truth.Packed();
  const char* names[] = {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"};
  double sum_z2 = 0.0;
  for (int k = 0; k < 8; ++k) {
    const double z = (est[k] - tru[k]) / cal->intrinsics_std[k];
    std::printf("  %s: estimate %.6g truth %.6g error %.3g = %.2f sigma\n", names[k], est[k], tru[k], est[k] - tru[k], z);
    ASSERT_GT(cal->intrinsics_std[k], 0.0);
    EXPECT_LT(std::abs(z), 4.5) << names[k];
    if (k < 4) sum_z2 += z * z;
  }
  EXPECT_EQ(cal->intrinsics_std[8], 0.0);  // k3 fixed
  // The std devs are of the size of the actual errors: the RMS of the four
  // normalised errors of fx, fy, cx, cy is not tiny (std devs far too large)
  // nor large (far too small).
  const double z_rms = std::sqrt(sum_z2 / 4.0);
  std::printf("  RMS normalised error of fx, fy, cx, cy: %.2f\n", z_rms);
  EXPECT_LT(z_rms, 3.0);
  EXPECT_GT(z_rms, 0.05);
  // Absolute figures: the focal lengths to 0.05%, the principal point to 0.5 px.
  EXPECT_NEAR(cal->intrinsics.fx_px, truth.fx_px, 5e-4 * truth.fx_px);
  EXPECT_NEAR(cal->intrinsics.fy_px, truth.fy_px, 5e-4 * truth.fy_px);
  EXPECT_NEAR(cal->intrinsics.cx_px, truth.cx_px, 0.5);
  EXPECT_NEAR(cal->intrinsics.cy_px, truth.cy_px, 0.5);
  // The poses.
  for (int v = 0; v < 12; ++v) {
    const Rigid3d& est_pose = cal->cam_from_board[static_cast<size_t>(v)];
    const Rigid3d& true_pose = views.cam_from_board[static_cast<size_t>(v)];
    EXPECT_LT((est_pose.translation - true_pose.translation).norm(), 0.5) << "view " << v;  // mm at ~450 mm
    EXPECT_LT(est_pose.rotation.angularDistance(true_pose.rotation), 1e-3) << "view " << v;
  }
}

TEST(CameraCalibration, ReportedStdDevsMatchMonteCarlo) {
  // Exact projections of the board corners plus Gaussian noise of a known
  // sigma, calibrated many times: the spread of the estimates against the
  // reported standard deviations (an independent check of the covariance).
  const Camera camera = TruthCamera();
  const TagBoard board = TestBoard();
  std::vector<Rigid3d> poses = BoardPoses(board);
  poses.resize(4);
  const double sigma_px = 0.05;
  std::mt19937_64 rng(99);
  NormalGenerator normal;
  const int trials = 60;
  std::array<double, 4> sum{}, sum2{}, reported{};
  for (int t = 0; t < trials; ++t) {
    std::vector<BoardView> views;
    for (const Rigid3d& pose : poses) {
      BoardView view;
      for (int id = board.first_id; id < board.first_id + board.NumTags(); id += 3) {  // 8 tags
        const Result<std::array<Eigen::Vector3d, 4>> corners = board.TagCorners(id);
        ASSERT_TRUE(corners.ok());
        for (const Eigen::Vector3d& p : *corners) {
          Eigen::Vector2d px;
          ASSERT_TRUE(ProjectToPixel(camera.intrinsics, pose * p, &px));
          view.points_in_board.push_back(p);
          view.pixels.push_back(px + sigma_px * Eigen::Vector2d(normal(rng), normal(rng)));
        }
      }
      views.push_back(view);
    }
    Result<CameraCalibration> cal = CalibrateCamera(views, 1024, 768, CameraCalibrationOptions{});
    ASSERT_TRUE(cal.ok()) << cal.status().ToString();
    const auto est = cal->intrinsics.Packed();
    for (int k = 0; k < 4; ++k) {
      sum[k] += est[k];
      sum2[k] += est[k] * est[k];
      reported[k] += cal->intrinsics_std[k] / trials;
    }
  }
  const char* names[] = {"fx", "fy", "cx", "cy"};
  for (int k = 0; k < 4; ++k) {
    const double mean = sum[k] / trials;
    const double empirical = std::sqrt(std::max(0.0, (sum2[k] - trials * mean * mean) / (trials - 1)));
    std::printf("  %s: Monte Carlo std %.4f px, reported std %.4f px (mean of %d)\n", names[k], empirical,
                reported[k], trials);
    // 60 trials: the empirical std is known to about +-9% (1 sigma); an
    // error of sqrt(2) (OpenCV < 4.8's variance) is outside these bounds.
    EXPECT_GT(empirical, 0.78 * reported[k]) << names[k];
    EXPECT_LT(empirical, 1.25 * reported[k]) << names[k];
  }
}

TEST(CameraCalibration, PixelCovarianceBlocksGiveTheSandwich) {
  // As above, but each tag's 4 corners err together: a shift common to the
  // tag (variance rho sigma^2 per axis) plus independent noise ((1 - rho)
  // sigma^2), as the views' 8 x 8 blocks say. The residual-based figure
  // (blocks left out) misses the common part; the sandwich follows it.
  const Camera camera = TruthCamera();
  const TagBoard board = TestBoard();
  std::vector<Rigid3d> poses = BoardPoses(board);
  poses.resize(4);
  const double sigma_px = 0.05, rho = 0.6;
  Eigen::MatrixXd block = (1.0 - rho) * sigma_px * sigma_px * Eigen::MatrixXd::Identity(8, 8);
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      block.block<2, 2>(2 * a, 2 * b) += rho * sigma_px * sigma_px * Eigen::Matrix2d::Identity();
    }
  }
  std::mt19937_64 rng(7);
  NormalGenerator normal;
  const int trials = 60;
  std::array<double, 4> sum{}, sum2{}, reported{}, residual_based{};
  for (int t = 0; t < trials; ++t) {
    std::vector<BoardView> views;
    for (const Rigid3d& pose : poses) {
      BoardView view;
      for (int id = board.first_id; id < board.first_id + board.NumTags(); id += 3) {  // 8 tags
        const Result<std::array<Eigen::Vector3d, 4>> corners = board.TagCorners(id);
        ASSERT_TRUE(corners.ok());
        const Eigen::Vector2d common = std::sqrt(rho) * sigma_px * Eigen::Vector2d(normal(rng), normal(rng));
        for (const Eigen::Vector3d& p : *corners) {
          Eigen::Vector2d px;
          ASSERT_TRUE(ProjectToPixel(camera.intrinsics, pose * p, &px));
          view.points_in_board.push_back(p);
          view.pixels.push_back(px + common +
                                std::sqrt(1.0 - rho) * sigma_px * Eigen::Vector2d(normal(rng), normal(rng)));
        }
        view.pixel_covariance_blocks_px2.push_back(block);
      }
      views.push_back(view);
    }
    Result<CameraCalibration> cal = CalibrateCamera(views, 1024, 768, CameraCalibrationOptions{});
    ASSERT_TRUE(cal.ok()) << cal.status().ToString();
    ASSERT_TRUE(cal->std_from_pixel_covariances);
    for (BoardView& v : views) v.pixel_covariance_blocks_px2.clear();
    Result<CameraCalibration> plain = CalibrateCamera(views, 1024, 768, CameraCalibrationOptions{});
    ASSERT_TRUE(plain.ok()) << plain.status().ToString();
    ASSERT_FALSE(plain->std_from_pixel_covariances);
    const auto est = cal->intrinsics.Packed();
    for (int k = 0; k < 4; ++k) {
      sum[k] += est[k];
      sum2[k] += est[k] * est[k];
      reported[k] += cal->intrinsics_std[k] / trials;
      residual_based[k] += plain->intrinsics_std[k] / trials;
    }
  }
  const char* names[] = {"fx", "fy", "cx", "cy"};
  for (int k = 0; k < 4; ++k) {
    const double mean = sum[k] / trials;
    const double empirical = std::sqrt(std::max(0.0, (sum2[k] - trials * mean * mean) / (trials - 1)));
    std::printf("  %s: Monte Carlo std %.4f px, sandwich %.4f px, residual-based %.4f px (means of %d)\n",
                names[k], empirical, reported[k], residual_based[k], trials);
    EXPECT_GT(empirical, 0.78 * reported[k]) << names[k];
    EXPECT_LT(empirical, 1.25 * reported[k]) << names[k];
    // The residual-based figure is far too small here.
    EXPECT_LT(residual_based[k], 0.75 * empirical) << names[k];
  }
}

std::vector<std::string> SampleChessboardFiles() {
  std::vector<std::string> files;
  for (int i = 1; i <= 14; ++i) {
    char name[128];
    std::snprintf(name, sizeof(name), "/usr/share/doc/opencv-doc/examples/data/left%02d.jpg", i);
    if (std::ifstream(name).good()) files.push_back(name);
  }
  return files;
}

TEST(CameraCalibration, OpenCvSampleChessboardsAgreeWithOpenCv) {
  const std::vector<std::string> files = SampleChessboardFiles();
  if (files.size() < 3) {
    GTEST_SKIP() << "OpenCV's sample images left01.jpg .. left14.jpg not found in "
                    "/usr/share/doc/opencv-doc/examples/data (package opencv-doc)";
  }
  std::vector<cv::Mat> images;
  for (const std::string& f : files) images.push_back(cv::imread(f, cv::IMREAD_GRAYSCALE));
  const Chessboard board{9, 6, 1.0};
  CameraCalibrationOptions options;
  Result<CameraCalibration> ours = CalibrateCameraFromChessboard(images, board, options, files);
  ASSERT_TRUE(ours.ok()) << ours.status().ToString();
  std::printf("ours (%zu images):\n%s", files.size(), ours->Report().c_str());

  // OpenCV directly, on the same corners (detected through our API).
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  for (const cv::Mat& image : images) {
    Result<BoardView> view = DetectChessboardView(image, board, options);
    ASSERT_TRUE(view.ok());
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    for (size_t k = 0; k < view->pixels.size(); ++k) {
      obj.emplace_back(static_cast<float>(view->points_in_board[k].x()),
                       static_cast<float>(view->points_in_board[k].y()), 0.f);
      img.emplace_back(static_cast<float>(view->pixels[k].x()), static_cast<float>(view->pixels[k].y()));
    }
    object_points.push_back(obj);
    image_points.push_back(img);
  }
  cv::Mat K, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  const double rms = cv::calibrateCamera(object_points, image_points, images[0].size(), K, dist, rvecs, tvecs,
                                         cv::CALIB_FIX_K3);
  std::printf("OpenCV: RMS %.6f px fx %.4f fy %.4f cx %.4f cy %.4f k1 %.6f k2 %.6f\n", rms, K.at<double>(0, 0),
              K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2), dist.at<double>(0), dist.at<double>(1));
  EXPECT_NEAR(ours->rms_px, rms, 1e-4);
  EXPECT_NEAR(ours->intrinsics.fx_px, K.at<double>(0, 0), 0.05);
  EXPECT_NEAR(ours->intrinsics.fy_px, K.at<double>(1, 1), 0.05);
  EXPECT_NEAR(ours->intrinsics.cx_px, K.at<double>(0, 2), 0.05);
  EXPECT_NEAR(ours->intrinsics.cy_px, K.at<double>(1, 2), 0.05);
  EXPECT_NEAR(ours->intrinsics.k1, dist.at<double>(0), 1e-4);
  EXPECT_NEAR(ours->intrinsics.k2, dist.at<double>(1), 1e-3);
  // The sample set's known figures: RMS below 0.5 px, fx ~ 536 px.
  EXPECT_LT(ours->rms_px, 0.5);
  EXPECT_NEAR(ours->intrinsics.fx_px, 536.0, 10.0);
}

TEST(CameraCalibration, ErrorsAreClearStatuses) {
  const RenderedViews& views = Views();
  CameraCalibrationOptions options;
  // Too few views.
  Result<CameraCalibration> few = CalibrateCameraFromTagBoard({views.images[0], views.images[1]}, TestBoard(), options);
  ASSERT_FALSE(few.ok());
  EXPECT_EQ(few.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(few.status().message().find("at least min_views = 3"), std::string::npos) << few.status().message();
  // An image without the board (the views are checked in order; the blank
  // one comes second, after a good one).
  const cv::Mat blank_image(768, 1024, CV_8UC1, cv::Scalar(128));
  std::vector<cv::Mat> images = {views.images[0], blank_image, views.images[2]};
  Result<CameraCalibration> blank = CalibrateCameraFromTagBoard(images, TestBoard(), options);
  ASSERT_FALSE(blank.ok());
  EXPECT_EQ(blank.status().code(), StatusCode::kNoSolution);
  EXPECT_NE(blank.status().message().find("image 1: no board found"), std::string::npos) << blank.status().message();
  images = {blank_image, blank_image, blank_image};
  // A board with other ids is not found either.
  TagBoard other = TestBoard();
  other.first_id = 300;
  Result<CameraCalibration> wrong = CalibrateCameraFromTagBoard({views.images[0], blank_image, blank_image}, other, options);
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().message().find("image 0: no board found"), std::string::npos) << wrong.status().message();
  // A chessboard that is not there.
  const cv::Mat small(240, 320, CV_8UC1, cv::Scalar(90));
  Result<CameraCalibration> chess = CalibrateCameraFromChessboard({small, small, small}, Chessboard{}, options);
  ASSERT_FALSE(chess.ok());
  EXPECT_NE(chess.status().message().find("image 0: no board found"), std::string::npos) << chess.status().message();
  // Empty image, bad options.
  images[0] = cv::Mat();
  Result<CameraCalibration> empty = CalibrateCameraFromTagBoard(images, TestBoard(), options);
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().message().find("image 0: image is empty"), std::string::npos) << empty.status().message();
  options.min_views = 2;
  Result<CameraCalibration> bad = CalibrateCameraFromTagBoard(views.images, TestBoard(), options);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("min_views = 2"), std::string::npos) << bad.status().message();
}

}  // namespace
}  // namespace opl
