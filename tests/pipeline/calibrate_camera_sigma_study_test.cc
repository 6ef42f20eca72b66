// Seeded study of the standard deviations of a tag-grid camera calibration
// (OPL issue 18 item 1): sets of ten rendered views of the 6 x 4 tag grid
// (tests/support/board_views.h), each set with its own poses and noise, are
// calibrated as `opl_camera calibrate` does (DetectCalibrationBoard, then
// CalibrateCamera), and the normalised errors z = (estimate - truth) / sigma
// of fx .. p2 are pooled over the sets: their RMS is 1 for honest sigmas.
//
// Each set is calibrated twice from the same corners: with their covariances
// (the tag grid's way, the sandwich of vision/camera_calibration.h) and
// without (the residual-based figure that assumes independent corners of
// one variance, the chessboard's way); the estimates are the same, the
// sigmas differ.
//
// The short version (4 sets) runs in the default suite; the full one is the
// ctest entry pipeline/calibrate_camera_sigma_study_40 (label "study";
// OPL_STUDY_SETS=40). Environment, for studies by hand:
//   OPL_STUDY_SETS   number of sets (default 4)
//   OPL_STUDY_NOISE  noise sigma [fraction of full scale] (default 0.01)
//   OPL_STUDY_DUMP   a file to write every corner (detected, truth, the edge
//                    fit's covariance) and every set's estimate to, as CSV
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "opl/lab/planar_target_image.h"
#include "opl/vision/board_detection.h"
#include "opl/vision/camera_calibration.h"
#include "opl/vision/tag_detection.h"
#include "support/board_views.h"

namespace opl {
namespace {

constexpr int kViews = 10;
constexpr int kStudied = 8;  // fx .. p2 (k3 held)
const char* const kNames[] = {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"};

int EnvInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::atoi(v) : fallback;
}

double EnvDouble(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::atof(v) : fallback;
}

struct SetResult {
  std::array<double, kStudied> z{};      // with the reported sigmas (the sandwich)
  std::array<double, kStudied> z_iid{};  // with the residual-based sigmas (independent, equal corners)
  std::array<double, kStudied> sigma{};
  std::array<double, kStudied> sigma_iid{};
  double rms_px = 0.0;
  bool from_pixel_covariances = false;
  bool same_estimate = false;  // both calibrations gave the same intrinsics
};

// One set: kViews views of the grid at poses of seed 1000 + set, noise seeds
// 7000 + 100 set + view.
SetResult RunSet(int set, double noise_sigma, std::FILE* dump) {
  const Camera camera = test::BoardTruthCamera();
  static const Result<PlanarTargetRenderer> renderer = PlanarTargetRenderer::Create(camera, 1);
  EXPECT_TRUE(renderer.ok());
  const TagBoard board = test::SixByFourTagBoard();
  const std::vector<Rigid3d> poses = test::BoardPoses(camera, Eigen::Vector2d(0, 0), test::TagBoardExtent(board),
                                                      kViews, 1000 + static_cast<uint64_t>(set));
  EXPECT_EQ(poses.size(), static_cast<size_t>(kViews));
  const CameraCalibrationOptions options;
  std::vector<BoardView> views;
  for (size_t v = 0; v < poses.size(); ++v) {
    Result<PlanarTarget> target = MakeTagBoardTarget(board, poses[v], 2);
    EXPECT_TRUE(target.ok());
    TargetRenderOptions o;
    o.blur_sigma_px = 0.7;
    o.noise_sigma = noise_sigma;
    o.seed = 7000 + 100 * static_cast<uint64_t>(set) + v;
    Result<RenderedTargetImage> r = renderer->Render({*target}, o);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    Result<BoardView> view = DetectCalibrationBoard(r->image, CalibrationBoard::TagGrid(board), options);
    EXPECT_TRUE(view.ok()) << view.status().ToString();
    views.push_back(*view);
    if (dump != nullptr) {
      Result<std::vector<TagDetection>> tags = DetectTags(r->image, options.detection);
      EXPECT_TRUE(tags.ok());
      for (const TagDetection& t : *tags) {
        if (!board.HasTag(t.id)) continue;
        for (const RenderedTag& truth : r->tags) {
          if (truth.id != t.id) continue;
          const std::array<Eigen::Vector3d, 4> in_board = *board.TagCorners(t.id);
          for (int c = 0; c < 4; ++c) {
            const Eigen::Matrix2d& cov = t.corner_covariance_px2[static_cast<size_t>(c)];
            std::fprintf(dump, "C,%d,%zu,%d,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6g,%.6g,%.6g,%d\n", set, v, t.id, c,
                         in_board[c].x(), in_board[c].y(), t.corners_px[c].x(), t.corners_px[c].y(),
                         truth.corners_px[c].x(), truth.corners_px[c].y(), cov(0, 0), cov(0, 1), cov(1, 1),
                         t.edge_fitted ? 1 : 0);
          }
        }
      }
      const Eigen::Quaterniond q(poses[v].rotation);
      const Eigen::AngleAxisd aa(q);
      const Eigen::Vector3d rvec = aa.angle() * aa.axis();
      std::fprintf(dump, "P,%d,%zu,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g\n", set, v, rvec.x(), rvec.y(), rvec.z(),
                   poses[v].translation.x(), poses[v].translation.y(), poses[v].translation.z());
    }
  }
  SetResult out;
  Result<CameraCalibration> cal = CalibrateCamera(views, camera.intrinsics.width_px, camera.intrinsics.height_px,
                                                  options);
  EXPECT_TRUE(cal.ok()) << cal.status().ToString();
  // The same views without their corners' covariances: the residual-based
  // figures (the chessboard's way).
  std::vector<BoardView> plain = views;
  for (BoardView& v : plain) v.pixel_covariance_blocks_px2.clear();
  Result<CameraCalibration> iid = CalibrateCamera(plain, camera.intrinsics.width_px, camera.intrinsics.height_px,
                                                  options);
  EXPECT_TRUE(iid.ok()) << iid.status().ToString();
  if (!cal.ok() || !iid.ok()) return out;
  const auto est = cal->intrinsics.Packed();
  const auto tru = camera.intrinsics.Packed();
  out.same_estimate = est == iid->intrinsics.Packed();
  for (int k = 0; k < kStudied; ++k) {
    out.sigma[k] = cal->intrinsics_std[static_cast<size_t>(k)];
    out.sigma_iid[k] = iid->intrinsics_std[static_cast<size_t>(k)];
    out.z[k] = (est[k] - tru[k]) / out.sigma[k];
    out.z_iid[k] = (est[k] - tru[k]) / out.sigma_iid[k];
  }
  out.rms_px = cal->rms_px;
  out.from_pixel_covariances = cal->std_from_pixel_covariances && !iid->std_from_pixel_covariances;
  if (dump != nullptr) {
    std::fprintf(dump, "K,%d", set);
    for (int k = 0; k < kStudied; ++k) std::fprintf(dump, ",%.12g,%.6g", est[k], out.sigma[k]);
    std::fprintf(dump, "\n");
  }
  return out;
}

// RMS over sets of z per parameter, and pooled over the parameters.
struct RmsZ {
  std::array<double, kStudied> per{};
  double pooled = 0.0;
};

RmsZ Summarise(const std::vector<std::array<double, kStudied>>& z, const char* label) {
  RmsZ out;
  double all = 0.0;
  for (int k = 0; k < kStudied; ++k) {
    double sum = 0.0;
    for (const auto& set : z) sum += set[k] * set[k];
    out.per[k] = std::sqrt(sum / z.size());
    all += sum;
  }
  out.pooled = std::sqrt(all / (kStudied * z.size()));
  std::printf("RMS z, %s:", label);
  for (int k = 0; k < kStudied; ++k) std::printf(" %s %.2f", kNames[k], out.per[k]);
  std::printf("; pooled %.2f\n", out.pooled);
  return out;
}

TEST(CalibrateCameraSigmaStudy, TagGridNormalisedErrors) {
  const int sets = EnvInt("OPL_STUDY_SETS", 4);
  const double noise = EnvDouble("OPL_STUDY_NOISE", 0.01);
  ASSERT_GE(sets, 1);
  const char* dump_path = std::getenv("OPL_STUDY_DUMP");
  std::FILE* dump = dump_path != nullptr && *dump_path != '\0' ? std::fopen(dump_path, "w") : nullptr;
  std::vector<std::array<double, kStudied>> z, z_iid;
  double rms_px = 0.0;
  for (int s = 0; s < sets; ++s) {
    const SetResult r = RunSet(s, noise, dump);
    std::printf("set %2d:", s);
    for (int k = 0; k < kStudied; ++k) std::printf(" %s %+.2f", kNames[k], r.z[k]);
    std::printf("  (RMS %.4f px; sigma / residual-based sigma: fx %.2f cy %.2f)\n", r.rms_px,
                r.sigma[0] / r.sigma_iid[0], r.sigma[3] / r.sigma_iid[3]);
    z.push_back(r.z);
    z_iid.push_back(r.z_iid);
    rms_px += r.rms_px / sets;
    // The tag grid's sigmas come from the corners' covariances; the estimate
    // is OpenCV's either way.
    EXPECT_TRUE(r.from_pixel_covariances) << "set " << s;
    EXPECT_TRUE(r.same_estimate) << "set " << s;
    // Neighbouring corners share an edge and err together, which the
    // residual-based figure misses: the focal lengths' sigmas grow (fx's by
    // 1.12-1.33 in the 40 sets of the study).
    for (int k = 0; k < 2; ++k) {
      EXPECT_GT(r.sigma[k] / r.sigma_iid[k], 1.03) << kNames[k] << ", set " << s;
      EXPECT_LT(r.sigma[k] / r.sigma_iid[k], 1.8) << kNames[k] << ", set " << s;
    }
  }
  if (dump != nullptr) std::fclose(dump);
  std::printf("%d sets of %d views, noise %.3g, mean RMS reprojection %.4f px\n", sets, kViews, noise, rms_px);
  const RmsZ now = Summarise(z, "reported sigmas (corner covariances, sandwich)");
  const RmsZ before = Summarise(z_iid, "residual-based sigmas");
  if (sets >= 30 && noise == 0.01) {
    // The study (docs/targets_and_calibration.md, "Measured"): every
    // parameter's RMS z within [0.8, 1.25] (the sampling error of one RMS
    // over 40 sets is ~0.11). At noise 0.03 cy's was 1.30.
    for (int k = 0; k < kStudied; ++k) {
      EXPECT_GT(now.per[k], 0.8) << kNames[k];
      EXPECT_LT(now.per[k], 1.25) << kNames[k];
    }
    EXPECT_GT(before.pooled, now.pooled);
  } else {
    // A few sets: the pooled RMS of the 8 x sets normalised errors (4 sets:
    // ~0.15 sampling error for honest sigmas).
    EXPECT_GT(now.pooled, 0.6);
    EXPECT_LT(now.pooled, 1.45);
  }
}

}  // namespace
}  // namespace opl
