// DetectTags on REAL photographs with tags composited into them (issue 17):
// recall against libapriltag's own (called directly here, quad_decimate 1, as
// the reference), no false tag on the tag-free photographs, corner accuracy.
//
// The composite set. OpenCV's sample photographs (package opencv-doc, read
// from /usr/share/doc/opencv-doc/examples/data like camera_calibration_test)
// get tag36h11 tags (cv::aruco::drawMarker, 32 px per cell, quiet zone 0.5 to
// 2 cells, black and white levels drawn at random) warped in by the
// homography of a tag plane tilted up to 70 degrees and seen by a pinhole
// camera, at 10 to 60 px side. Rendering: the tag is warped at 4 x 4
// supersampling and area-averaged (cv::INTER_AREA), alpha-blended by its
// exact coverage; then the whole image is blurred (Gaussian sigma 0.4 to 1.2
// px) and JPEG-compressed (quality 60 to 95, cv::imencode). The true corners
// are the homography's images of the black square's corners. Seeded: the same
// images every run.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

extern "C" {
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
}

#include "opl/core/format.h"
#include "opl/sim/random.h"
#include "opl/vision/tag_detection.h"

namespace opl {
namespace {

const char* const kDataDir = "/usr/share/doc/opencv-doc/examples/data/";

struct TrueTag {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px;  // OPL order and pixel convention
  double side_px = 0.0;                       // mean edge length
  double tilt_deg = 0.0;
  double quiet_zone_cells = 0.0;
};

struct Composite {
  std::string photo;
  cv::Mat image;  // CV_8UC1, after blur and JPEG
  std::vector<TrueTag> tags;
};

double MeanSide(const std::array<Eigen::Vector2d, 4>& c) {
  double s = 0.0;
  for (int k = 0; k < 4; ++k) s += 0.25 * (c[(k + 1) % 4] - c[k]).norm();
  return s;
}

Eigen::Vector2d Centre(const std::array<Eigen::Vector2d, 4>& c) { return 0.25 * (c[0] + c[1] + c[2] + c[3]); }

// 3x3 homography applied to a point.
Eigen::Vector2d Apply(const Eigen::Matrix3d& H, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = H * p.homogeneous();
  return q.hnormalized();
}

// Composites tags into `photo` (gray). Every tag gets a cell of a grid so that
// none overlaps another; ids are distinct within an image.
Composite MakeComposite(const std::string& name, const cv::Mat& photo, uint64_t seed) {
  Composite out;
  out.photo = name;
  std::mt19937_64 rng(seed);
  cv::Mat canvas;
  photo.convertTo(canvas, CV_32F);
  const cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  constexpr int kPpc = 32;     // template pixels per cell
  constexpr int kSuper = 4;    // supersampling of the warp
  constexpr double kCell = 96; // grid cell [px]
  const int cols = static_cast<int>(photo.cols / kCell), rows = static_cast<int>(photo.rows / kCell);
  const double f = 800.0;  // focal length of the pinhole camera [px]
  int next_id = static_cast<int>(seed % 300);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      TrueTag truth;
      truth.id = next_id;
      next_id = (next_id + 7) % 587;
      // Template: the marker with its quiet zone, levels at random.
      const double qz = std::array<double, 4>{0.5, 1.0, 1.0, 2.0}[rng() % 4];
      truth.quiet_zone_cells = qz;
      const int border = static_cast<int>(std::lround(qz * kPpc));
      cv::Mat marker;
      cv::aruco::drawMarker(dict, truth.id, 8 * kPpc, marker, 1);
      cv::Mat tmpl(8 * kPpc + 2 * border, 8 * kPpc + 2 * border, CV_8UC1, cv::Scalar(255));
      marker.copyTo(tmpl(cv::Rect(border, border, 8 * kPpc, 8 * kPpc)));
      const double black = 15.0 + 55.0 * Uniform01(rng), white = 150.0 + 90.0 * Uniform01(rng);
      cv::Mat tmplf;
      tmpl.convertTo(tmplf, CV_32F, (white - black) / 255.0, black);
      // Pose: tilt about an in-plane axis, roll; side drawn in [10, 60] px.
      const double side = 10.0 + 50.0 * Uniform01(rng);
      const double tilt = 70.0 * Uniform01(rng) * kPi / 180.0;
      truth.tilt_deg = tilt * 180.0 / kPi;
      const double axis = 2.0 * kPi * Uniform01(rng), roll = 2.0 * kPi * Uniform01(rng);
      const Eigen::Matrix3d R =
          (Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis), std::sin(axis), 0.0)) *
           Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
              .toRotationMatrix();
      const double u0 = (c + 0.5) * kCell + (Uniform01(rng) - 0.5) * 0.2 * kCell;
      const double v0 = (r + 0.5) * kCell + (Uniform01(rng) - 0.5) * 0.2 * kCell;
      const double cx = 0.5 * photo.cols, cy = 0.5 * photo.rows;
      const double depth = f / side;  // a tag of side 1 at this depth is `side` px wide
      const Eigen::Vector3d t(depth * (u0 - cx) / f, depth * (v0 - cy) / f, depth);
      Eigen::Matrix3d K;
      K << f, 0, cx, 0, f, cy, 0, 0, 1;
      // Template edge coordinates (pixel corners at integers) to the tag
      // plane (side 1, origin at the black square's centre).
      const double centre_t = 0.5 * tmpl.cols;
      Eigen::Matrix3d A;
      A << 1.0 / (8 * kPpc), 0, -centre_t / (8 * kPpc), 0, 1.0 / (8 * kPpc), -centre_t / (8 * kPpc), 0, 0, 1;
      Eigen::Matrix3d P;
      P.col(0) = R.col(0);
      P.col(1) = R.col(1);
      P.col(2) = t;
      // Template edge coordinates to image edge coordinates (pixel corners at
      // integers; the image's centre convention is 0.5 less).
      const Eigen::Matrix3d H = K * P * A;
      const double b0 = border, b1 = border + 8 * kPpc;
      const std::array<Eigen::Vector2d, 4> black_corners = {Eigen::Vector2d(b0, b0), Eigen::Vector2d(b1, b0),
                                                            Eigen::Vector2d(b1, b1), Eigen::Vector2d(b0, b1)};
      for (int k = 0; k < 4; ++k) truth.corners_px[k] = Apply(H, black_corners[k]) - Eigen::Vector2d(0.5, 0.5);
      truth.side_px = MeanSide(truth.corners_px);
      // Bounding box of the whole template in the image.
      double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
      for (const Eigen::Vector2d& e : {Eigen::Vector2d(0, 0), Eigen::Vector2d(tmpl.cols, 0),
                                       Eigen::Vector2d(tmpl.cols, tmpl.rows), Eigen::Vector2d(0, tmpl.rows)}) {
        const Eigen::Vector2d p = Apply(H, e);
        x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
      }
      const int bx0 = static_cast<int>(std::floor(x0)) - 2, by0 = static_cast<int>(std::floor(y0)) - 2;
      const int bx1 = static_cast<int>(std::ceil(x1)) + 2, by1 = static_cast<int>(std::ceil(y1)) + 2;
      if (bx0 < 0 || by0 < 0 || bx1 > photo.cols || by1 > photo.rows) continue;
      const int bw = bx1 - bx0, bh = by1 - by0;
      // Template edge coordinates to the supersampled box's, then to OpenCV's
      // pixel-centre convention for warpPerspective.
      Eigen::Matrix3d S;
      S << kSuper, 0, -kSuper * bx0, 0, kSuper, -kSuper * by0, 0, 0, 1;
      Eigen::Matrix3d Tm, Tp;
      Tm << 1, 0, -0.5, 0, 1, -0.5, 0, 0, 1;
      Tp << 1, 0, 0.5, 0, 1, 0.5, 0, 0, 1;
      const Eigen::Matrix3d M = Tm * S * H * Tp;
      cv::Mat Mcv(3, 3, CV_64F);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) Mcv.at<double>(i, j) = M(i, j);
      }
      cv::Mat warped, mask;
      const cv::Size big(bw * kSuper, bh * kSuper);
      cv::warpPerspective(tmplf, warped, Mcv, big, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
      cv::warpPerspective(cv::Mat(tmpl.size(), CV_32F, cv::Scalar(1.0)), mask, Mcv, big, cv::INTER_LINEAR,
                          cv::BORDER_CONSTANT, cv::Scalar(0));
      cv::Mat layer, coverage;
      cv::resize(warped, layer, cv::Size(bw, bh), 0, 0, cv::INTER_AREA);
      cv::resize(mask, coverage, cv::Size(bw, bh), 0, 0, cv::INTER_AREA);
      cv::Mat roi = canvas(cv::Rect(bx0, by0, bw, bh));
      // layer is the premultiplied template (zero outside): blend.
      cv::Mat one_minus;
      cv::subtract(cv::Scalar(1.0), coverage, one_minus);
      roi = roi.mul(one_minus) + layer;
      out.tags.push_back(truth);
    }
  }
  const double blur = 0.4 + 0.8 * Uniform01(rng);
  cv::GaussianBlur(canvas, canvas, cv::Size(0, 0), blur);
  cv::Mat canvas8;
  canvas.convertTo(canvas8, CV_8U);
  const int quality = 60 + static_cast<int>(rng() % 36);
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", canvas8, jpeg, {cv::IMWRITE_JPEG_QUALITY, quality});
  out.image = cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE);
  return out;
}

const std::vector<std::string>& CompositePhotos() {
  static const std::vector<std::string> photos = {"building.jpg", "home.jpg",    "fruits.jpg",       "baboon.jpg",
                                                  "aero1.jpg",    "aero3.jpg",   "messi5.jpg",       "leuvenA.jpg",
                                                  "stuff.jpg",    "starry_night.jpg"};
  return photos;
}

// The composite set: each photograph with 3 seeds.
const std::vector<Composite>& CompositeSet() {
  static const std::vector<Composite> set = [] {
    std::vector<Composite> s;
    uint64_t seed = 17;
    for (const std::string& name : CompositePhotos()) {
      const cv::Mat photo = cv::imread(kDataDir + name, cv::IMREAD_GRAYSCALE);
      if (photo.empty()) continue;
      for (int k = 0; k < 3; ++k) s.push_back(MakeComposite(name, photo, seed++));
    }
    return s;
  }();
  return set;
}

struct Found {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px;
  bool has_corners = true;  // false: the centre only is compared (libapriltag reference)
  bool edge_fitted = true;
};

// Recall by band, false tags, corner errors.
struct Score {
  std::map<std::string, std::pair<int, int>> bands;  // band -> (found, total)
  int found = 0, total = 0, false_tags = 0;
  double sum2 = 0.0, sum2_unrefined = 0.0;
  int corners = 0, corners_unrefined = 0;
  double max_px = 0.0;
  std::map<std::string, std::pair<double, int>> band_sum2;  // size band -> (sum of squared errors, corners), edge fit
  Eigen::Vector2d sum_offset = Eigen::Vector2d::Zero();     // edge-fit corners: detected - true
  double Recall() const { return total > 0 ? static_cast<double>(found) / total : 0.0; }
  double Rms() const { return std::sqrt(sum2 / std::max(1, corners)); }
  double RmsUnrefined() const { return std::sqrt(sum2_unrefined / std::max(1, corners_unrefined)); }
};

std::string SizeBand(double side) {
  if (side < 16) return "side 10-16 px";
  if (side < 24) return "side 16-24 px";
  if (side < 36) return "side 24-36 px";
  return "side 36-60 px";
}
std::string TiltBand(double tilt) {
  if (tilt < 40) return "tilt  0-40 deg";
  if (tilt < 60) return "tilt 40-60 deg";
  return "tilt 60-70 deg";
}

void ScoreImage(const Composite& composite, const std::vector<Found>& found, Score* score) {
  std::vector<bool> used(found.size(), false);
  for (const TrueTag& truth : composite.tags) {
    ++score->total;
    ++score->bands[SizeBand(truth.side_px)].second;
    ++score->bands[TiltBand(truth.tilt_deg)].second;
    if (truth.quiet_zone_cells < 1.0) ++score->bands["quiet zone 0.5 cell"].second;
    for (size_t k = 0; k < found.size(); ++k) {
      if (used[k] || found[k].id != truth.id) continue;
      if ((Centre(found[k].corners_px) - Centre(truth.corners_px)).norm() > 0.25 * truth.side_px) continue;
      used[k] = true;
      ++score->found;
      ++score->bands[SizeBand(truth.side_px)].first;
      ++score->bands[TiltBand(truth.tilt_deg)].first;
      if (truth.quiet_zone_cells < 1.0) ++score->bands["quiet zone 0.5 cell"].first;
      if (!found[k].has_corners) break;
      for (int c = 0; c < 4; ++c) {
        const double e2 = (found[k].corners_px[c] - truth.corners_px[c]).squaredNorm();
        if (found[k].edge_fitted) {
          score->sum2 += e2;
          ++score->corners;
          score->max_px = std::max(score->max_px, std::sqrt(e2));
          score->band_sum2[SizeBand(truth.side_px)].first += e2;
          ++score->band_sum2[SizeBand(truth.side_px)].second;
          if (truth.quiet_zone_cells < 1.0) {
            score->band_sum2["quiet zone 0.5 cell"].first += e2;
            ++score->band_sum2["quiet zone 0.5 cell"].second;
          }
          score->band_sum2[TiltBand(truth.tilt_deg)].first += e2;
          ++score->band_sum2[TiltBand(truth.tilt_deg)].second;
          score->sum_offset += found[k].corners_px[c] - truth.corners_px[c];
        } else {
          score->sum2_unrefined += e2;
          ++score->corners_unrefined;
        }
      }
      break;
    }
  }
  for (size_t k = 0; k < found.size(); ++k) {
    if (!used[k]) ++score->false_tags;
  }
}

Score ScoreOpl(const TagDetectionOptions& options) {
  Score score;
  for (const Composite& composite : CompositeSet()) {
    Result<std::vector<TagDetection>> dets = DetectTags(composite.image, options);
    EXPECT_TRUE(dets.ok()) << dets.status().ToString();
    if (!dets.ok()) continue;
    std::vector<Found> found;
    for (const TagDetection& d : *dets) found.push_back({d.id, d.corners_px, true, d.edge_fitted});
    ScoreImage(composite, found, &score);
  }
  return score;
}

// libapriltag called directly, as its own demo does: tag36h11 with 2 bits
// corrected, quad_decimate 1, everything else at libapriltag's defaults. Only
// its id and centre are compared (its corner conventions are DetectTags'
// business).
Score ScoreAprilTagReference() {
  Score score;
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family_bits(detector, family, 2);
  detector->quad_decimate = 1.0f;
  for (const Composite& composite : CompositeSet()) {
    const cv::Mat& im = composite.image;
    image_u8_t image{im.cols, im.rows, static_cast<int32_t>(im.step[0]), const_cast<uint8_t*>(im.ptr<uint8_t>(0))};
    zarray_t* detections = apriltag_detector_detect(detector, &image);
    std::vector<Found> found;
    for (int i = 0; i < zarray_size(detections); ++i) {
      apriltag_detection_t* det = nullptr;
      zarray_get(detections, i, &det);
      Found f;
      f.id = det->id;
      f.has_corners = false;
      // Its centre, in its own convention (pixel corners at integers): within
      // the matching tolerance either way.
      for (int c = 0; c < 4; ++c) f.corners_px[c] = Eigen::Vector2d(det->c[0] - 0.5, det->c[1] - 0.5);
      found.push_back(f);
    }
    apriltag_detections_destroy(detections);
    ScoreImage(composite, found, &score);
  }
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
  return score;
}

void Print(const char* name, const Score& s) {
  std::printf("%-28s recall %3d/%3d = %.3f  false %d", name, s.found, s.total, s.Recall(), s.false_tags);
  if (s.corners > 0) std::printf("  edge-fit corner RMS %.3f px (max %.3f, %d)", s.Rms(), s.max_px, s.corners);
  if (s.corners_unrefined > 0) std::printf("  unrefined RMS %.3f px (%d)", s.RmsUnrefined(), s.corners_unrefined);
  std::printf("\n");
  if (s.corners > 0) {
    std::printf("    mean offset of edge-fit corners (%.3f, %.3f) px\n", s.sum_offset.x() / s.corners,
                s.sum_offset.y() / s.corners);
  }
  for (const auto& [band, e] : s.band_sum2) {
    std::printf("    %-22s edge-fit corner RMS %.3f px (%d)\n", band.c_str(), std::sqrt(e.first / e.second), e.second);
  }
  for (const auto& [band, ft] : s.bands) std::printf("    %-22s %3d/%3d = %.3f\n", band.c_str(), ft.first, ft.second,
                                                     ft.second ? static_cast<double>(ft.first) / ft.second : 0.0);
}

bool HavePhotos() { return std::ifstream(std::string(kDataDir) + "building.jpg").good(); }

TEST(DetectTagsOnPhotos, RecallAtLeastLibAprilTagsOwnAndNoFalseTag) {
  if (!HavePhotos()) GTEST_SKIP() << "OpenCV's sample photographs not found in " << kDataDir << " (opencv-doc)";
  const std::vector<Composite>& set = CompositeSet();
  ASSERT_EQ(set.size(), 3 * CompositePhotos().size());
  const Score reference = ScoreAprilTagReference();
  TagDetectionOptions apriltag_only;
  apriltag_only.use_aruco = false;
  TagDetectionOptions aruco_only;
  aruco_only.use_apriltag = false;
  aruco_only.use_aruco = true;
  const Score opl = ScoreOpl(TagDetectionOptions());
  const Score opl_apriltag = ScoreOpl(apriltag_only);
  const Score opl_aruco = ScoreOpl(aruco_only);
  Print("libapriltag (reference)", reference);
  Print("DetectTags (default)", opl);
  Print("DetectTags, apriltag only", opl_apriltag);
  Print("DetectTags, aruco only (old)", opl_aruco);
  EXPECT_GE(opl.total, 400);
  EXPECT_GE(opl.found, reference.found);
  EXPECT_EQ(opl.false_tags, 0);
  EXPECT_EQ(opl_apriltag.false_tags, 0);
  EXPECT_EQ(opl_aruco.false_tags, 0);
  // aruco's candidates add tags libapriltag misses (why use_aruco is on).
  EXPECT_GT(opl.found, opl_apriltag.found);
  // The old detector (aruco's candidates alone) finds far fewer.
  EXPECT_LT(opl_aruco.found, opl.found - 100);
  // Corners on JPEG-compressed, blurred photographs (measured 0.24 px; the
  // half-cell quiet zones account for most of it).
  EXPECT_LT(opl.Rms(), 0.3);
  // Unrefined tags: libapriltag's corners, whose reported covariance
  // (fallback_corner_sigma_px per coordinate) describes their error within a
  // factor 2.
  const double sigma = TagDetectionOptions().fallback_corner_sigma_px;
  ASSERT_GT(opl.corners_unrefined, 0);
  EXPECT_LT(opl.RmsUnrefined(), 2.0 * std::sqrt(2.0) * sigma);
  EXPECT_GT(opl.RmsUnrefined(), 0.5 * std::sqrt(2.0) * sigma);
}

// Every photograph of opencv-doc's sample data (none shows a tag36h11 tag;
// chessboards, text, faces, buildings, foliage, paintings): no tag may be
// found. libapriltag's own count is printed for reference.
TEST(DetectTagsOnPhotos, NoFalseTagOnTagFreePhotographs) {
  if (!HavePhotos()) GTEST_SKIP() << "OpenCV's sample photographs not found in " << kDataDir << " (opencv-doc)";
  std::vector<std::string> files;
  for (const char* ext : {"jpg", "png"}) {
    std::vector<cv::String> found;
    cv::glob(std::string(kDataDir) + "*." + std::string(ext), found, false);
    files.insert(files.end(), found.begin(), found.end());
  }
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family_bits(detector, family, 2);
  int images = 0, opl_false = 0, apriltag_false = 0;
  for (const std::string& file : files) {
    const cv::Mat im = cv::imread(file, cv::IMREAD_GRAYSCALE);
    if (im.empty() || im.cols < 32 || im.rows < 32) continue;
    ++images;
    Result<std::vector<TagDetection>> dets = DetectTags(im);
    ASSERT_TRUE(dets.ok()) << file << ": " << dets.status().ToString();
    for (const TagDetection& d : *dets) {
      ADD_FAILURE() << file << ": false tag " << d.id << " at (" << d.corners_px[0].x() << ", "
                    << d.corners_px[0].y() << "), edge fitted " << d.edge_fitted << ", margin "
                    << d.decision_margin;
    }
    opl_false += static_cast<int>(dets->size());
    image_u8_t image{im.cols, im.rows, static_cast<int32_t>(im.step[0]), const_cast<uint8_t*>(im.ptr<uint8_t>(0))};
    zarray_t* detections = apriltag_detector_detect(detector, &image);
    apriltag_false += zarray_size(detections);
    apriltag_detections_destroy(detections);
  }
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
  std::printf("tag-free photographs: %d; false tags: DetectTags %d, libapriltag %d\n", images, opl_false,
              apriltag_false);
  EXPECT_GE(images, 60);
  EXPECT_EQ(opl_false, 0);
}

}  // namespace
}  // namespace opl
