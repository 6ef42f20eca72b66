// Issue 17, "the JPEG bias": where JPEG moves the laser spots and the tag
// corners, by file format, chroma subsampling and spot channel, against the
// renderer's truth; and what that does to s.
//
// The lab: examples/scene_clutter.json without speckle and sensor noise
// (colour, fruit wall, ambient ramp, vignetting, defocus 0.5 px, 40
// distractors per camera; tests/integration/harder_lab_scene.h), the module
// at seed k's placement (PlaceModuleForSeed). Every shot is rendered once and
// written as
//   - PNG (lossless),
//   - colour JPEG 90, 4:2:0 chroma (what cv::imwrite and most cameras write),
//   - colour JPEG 90, 4:4:4 chroma (libjpeg, every component at full
//     resolution),
//   - grey JPEG 90 of the red channel (a monochrome camera behind a red
//     filter: no chroma at all),
// then read by the front end's reader (ReadShotImage), the laser-off shot of
// the camera (written the same way) subtracted as the front end does
// (SubtractDarkFrame), and the spots detected (DetectSpots, the front end's
// options) in each channel: red, luma, red-minus-green. Each detection
// within 1 px of a visible true spot gives an offset d = detected - true
// [px]. Figures per (file, channel): mean dx, dy, RMS |d|, the 99th
// percentile, the radial scale about the image centre and about the grid's
// centre (the least-squares k of d . r_hat = k |r|: a grid that JPEG made
// larger or smaller), and the RMS for the smaller and larger half of the
// spots; the tag corners' offsets (luma, DetectTags) per file.
//
// The study part (OPL_STUDY_SCENES placements, default 0 in ctest; `ctest
// -L study` runs 16) measures each placement's noise-free images in each
// file kind with MeasureScaleFromImages and reports s/s_true - 1 and z.
// docs/images.md, "The JPEG bias", has the figures.
#include <cstddef>
#include <cstdio>

#include <jpeglib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "integration/harder_lab_scene.h"
#include "opl/io/atomic_file.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/shot_file.h"
#include "opl/pipeline/image_front_end.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "opl/vision/dark_frame.h"
#include "opl/vision/shot_image.h"
#include "opl/vision/spot_detection.h"
#include "opl/vision/tag_detection.h"
#include "support/lab_truth.h"
#include "support/scene_images.h"

namespace opl {
namespace {

enum class FileKind { kPng, kJpeg420, kJpeg444, kGreyJpegOfRed };

const char* KindName(FileKind k) {
  switch (k) {
    case FileKind::kPng: return "PNG";
    case FileKind::kJpeg420: return "JPEG 90 4:2:0";
    case FileKind::kJpeg444: return "JPEG 90 4:4:4";
    case FileKind::kGreyJpegOfRed: return "grey JPEG 90 (red)";
  }
  return "?";
}

// libjpeg (the library OpenCV writes with), quality 90, BGR or grey input;
// `full_chroma`: every component sampled 1 x 1 (4:4:4), else luma 2 x 2
// (4:2:0, libjpeg's and OpenCV's default).
std::string EncodeJpeg(const cv::Mat& image, int quality, bool full_chroma) {
  jpeg_compress_struct cinfo;
  jpeg_error_mgr jerr;
  cinfo.err = jpeg_std_error(&jerr);
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = static_cast<JDIMENSION>(image.cols);
  cinfo.image_height = static_cast<JDIMENSION>(image.rows);
  cinfo.input_components = image.channels();
  cinfo.in_color_space = image.channels() == 3 ? JCS_EXT_BGR : JCS_GRAYSCALE;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  if (image.channels() == 3) {
    const int f = full_chroma ? 1 : 2;
    cinfo.comp_info[0].h_samp_factor = f;
    cinfo.comp_info[0].v_samp_factor = f;
  }
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = const_cast<JSAMPROW>(image.ptr<unsigned char>(static_cast<int>(cinfo.next_scanline)));
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  std::string out(reinterpret_cast<const char*>(buffer), size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return out;
}

std::string Encode(const cv::Mat& bgr, FileKind kind) {
  switch (kind) {
    case FileKind::kPng: {
      Result<std::string> png = EncodeShotImage(bgr, ImageLook());
      EXPECT_TRUE(png.ok());
      return png.ok() ? *png : std::string();
    }
    case FileKind::kJpeg420: return EncodeJpeg(bgr, 90, false);
    case FileKind::kJpeg444: return EncodeJpeg(bgr, 90, true);
    case FileKind::kGreyJpegOfRed: {
      cv::Mat red;
      cv::extractChannel(bgr, red, 2);
      return EncodeJpeg(red, 90, false);
    }
  }
  return {};
}

struct Offsets {
  std::vector<Eigen::Vector2d> d;          // detected - true [px]
  std::vector<Eigen::Vector2d> from_image; // true - image centre
  std::vector<Eigen::Vector2d> from_grid;  // true - the grid's centre in the image
  std::vector<double> size_px;             // the drawn spot's sigma, sqrt(tr C / 2)
  int visible = 0;
};

struct Summary {
  int n = 0, visible = 0;
  double mean_dx = 0, mean_dy = 0, rms = 0, p99 = 0;
  double k_image = 0, k_grid = 0;  // radial scale (dimensionless)
  double rms_small = 0, rms_large = 0;
};

Summary Summarise(const Offsets& o) {
  Summary s;
  s.n = static_cast<int>(o.d.size());
  s.visible = o.visible;
  if (s.n == 0) return s;
  std::vector<double> norms;
  double num_i = 0, den_i = 0, num_g = 0, den_g = 0;
  for (size_t i = 0; i < o.d.size(); ++i) {
    s.mean_dx += o.d[i].x() / s.n;
    s.mean_dy += o.d[i].y() / s.n;
    s.rms += o.d[i].squaredNorm() / s.n;
    norms.push_back(o.d[i].norm());
    // d . r_hat = k |r|  =>  k = sum (d . r) / sum |r|^2
    num_i += o.d[i].dot(o.from_image[i]);
    den_i += o.from_image[i].squaredNorm();
    num_g += o.d[i].dot(o.from_grid[i]);
    den_g += o.from_grid[i].squaredNorm();
  }
  s.rms = std::sqrt(s.rms);
  std::sort(norms.begin(), norms.end());
  s.p99 = norms[std::min(norms.size() - 1, static_cast<size_t>(0.99 * norms.size()))];
  s.k_image = num_i / den_i;
  s.k_grid = num_g / den_g;
  std::vector<double> sizes = o.size_px;
  std::nth_element(sizes.begin(), sizes.begin() + static_cast<long>(sizes.size() / 2), sizes.end());
  const double median_size = sizes[sizes.size() / 2];
  double small = 0, large = 0;
  int n_small = 0, n_large = 0;
  for (size_t i = 0; i < o.d.size(); ++i) {
    if (o.size_px[i] < median_size) {
      small += o.d[i].squaredNorm();
      ++n_small;
    } else {
      large += o.d[i].squaredNorm();
      ++n_large;
    }
  }
  s.rms_small = n_small > 0 ? std::sqrt(small / n_small) : 0.0;
  s.rms_large = n_large > 0 ? std::sqrt(large / n_large) : 0.0;
  return s;
}

struct TagOffsets {
  int corners = 0;
  double mean_dx = 0, mean_dy = 0, rms = 0;
  double k_tag = 0;  // each tag's corners radially about its centre: size scale
};

const std::vector<SpotChannel> kChannels = {SpotChannel::kRed, SpotChannel::kLuma,
                                            SpotChannel::kRedMinusGreen};

// Per (file kind, channel): the spot offsets of every lit shot of `scene`;
// per file kind: the tag corners'.
struct StudyResult {
  std::map<std::pair<FileKind, SpotChannel>, Offsets> spots;
  std::map<FileKind, TagOffsets> tags;
};

void MeasureOffsets(const Scene& scene, const std::vector<FileKind>& kinds, StudyResult* out) {
  StudyResult& result = *out;
  Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
  EXPECT_TRUE(renderer.ok()) << renderer.status().ToString();
  if (!renderer.ok()) return;
  const std::filesystem::path dir = test::FreshTempDir("jpeg_offsets");
  std::vector<Result<RenderedShot>> shots;
  for (size_t i = 0; i < scene.shots.size(); ++i) {
    shots.push_back(renderer->RenderShot(static_cast<int>(i)));
    EXPECT_TRUE(shots.back().ok());
    if (!shots.back().ok()) return;
  }
  const FrontEndOptions front_end;
  for (FileKind kind : kinds) {
    // Written and read back as the front end reads it, per channel.
    std::vector<std::string> paths;
    for (size_t i = 0; i < scene.shots.size(); ++i) {
      paths.push_back((dir / ("shot" + std::to_string(i) + ".img")).string());
      EXPECT_TRUE(WriteFileAtomically(paths.back(), Encode(shots[i]->image, kind)).ok());
    }
    TagOffsets& tags = result.tags[kind];
    double tag_num = 0, tag_den = 0;
    for (SpotChannel channel : kChannels) {
      if (kind == FileKind::kGreyJpegOfRed && channel != SpotChannel::kRed) continue;
      Offsets& o = result.spots[{kind, channel}];
      for (size_t i = 0; i < scene.shots.size(); ++i) {
        const SceneShot& shot = scene.shots[i];
        if (shot.lasers.empty()) continue;
        size_t dark = scene.shots.size();
        for (size_t j = 0; j < scene.shots.size(); ++j) {
          if (scene.shots[j].lasers.empty() && scene.shots[j].camera == shot.camera) dark = j;
        }
        Result<ShotImage> lit = ReadShotImage(paths[i], channel);
        ASSERT_TRUE(lit.ok()) << lit.status().ToString();
        cv::Mat for_spots = lit->for_spots;
        SpotDetectionOptions options = front_end.spots;
        if (dark < scene.shots.size()) {
          Result<ShotImage> off = ReadShotImage(paths[dark], channel);
          ASSERT_TRUE(off.ok());
          Result<cv::Mat> difference = SubtractDarkFrame(lit->for_spots, off->for_spots);
          ASSERT_TRUE(difference.ok());
          for_spots = *difference;
        }
        Result<SpotDetectionResult> detected = DetectSpots(for_spots, options);
        ASSERT_TRUE(detected.ok());
        Eigen::Vector2d grid_centre = Eigen::Vector2d::Zero();
        int grid_n = 0;
        for (const SpotView& v : shots[i]->spots) {
          if (!v.visible) continue;
          grid_centre += v.center_px;
          ++grid_n;
        }
        grid_centre /= std::max(1, grid_n);
        const Eigen::Vector2d image_centre((lit->for_spots.cols - 1) / 2.0,
                                           (lit->for_spots.rows - 1) / 2.0);
        for (const SpotView& v : shots[i]->spots) {
          if (!v.visible) continue;
          ++o.visible;
          const DetectedSpot* best = nullptr;
          double best_d = 1.0;
          for (const DetectedSpot& d : detected->spots) {
            const double dist = (Eigen::Vector2d(d.u_px, d.v_px) - v.center_px).norm();
            if (dist < best_d) {
              best_d = dist;
              best = &d;
            }
          }
          if (best == nullptr) continue;
          o.d.push_back(Eigen::Vector2d(best->u_px, best->v_px) - v.center_px);
          o.from_image.push_back(v.center_px - image_centre);
          o.from_grid.push_back(v.center_px - grid_centre);
          o.size_px.push_back(std::sqrt(v.shape_covariance_px2.trace() / 2.0));
        }
        if (channel != SpotChannel::kRed) continue;
        // Tags (luma), once per shot.
        Result<std::vector<TagDetection>> found = DetectTags(lit->for_tags, front_end.tags);
        ASSERT_TRUE(found.ok());
        for (const TagDetection& t : *found) {
          for (const TagView& truth : shots[i]->tags) {
            if (truth.id != t.id || !truth.in_image) continue;
            Eigen::Vector2d c_true = Eigen::Vector2d::Zero();
            for (int k = 0; k < 4; ++k) c_true += truth.corners_px[static_cast<size_t>(k)] / 4.0;
            for (int k = 0; k < 4; ++k) {
              const Eigen::Vector2d d =
                  t.corners_px[static_cast<size_t>(k)] - truth.corners_px[static_cast<size_t>(k)];
              const Eigen::Vector2d r = truth.corners_px[static_cast<size_t>(k)] - c_true;
              ++tags.corners;
              tags.mean_dx += d.x();
              tags.mean_dy += d.y();
              tags.rms += d.squaredNorm();
              tag_num += d.dot(r);
              tag_den += r.squaredNorm();
            }
          }
        }
      }
    }
    if (tags.corners > 0) {
      tags.mean_dx /= tags.corners;
      tags.mean_dy /= tags.corners;
      tags.rms = std::sqrt(tags.rms / tags.corners);
      tags.k_tag = tag_num / tag_den;
    }
  }
  std::filesystem::remove_all(dir);
  return;
}

void Print(const StudyResult& r) {
  std::printf("%-20s %-16s %9s %8s %8s %7s %7s %9s %9s %7s %7s\n", "file", "channel", "found",
              "mean dx", "mean dy", "RMS", "p99", "k image", "k grid", "small", "large");
  for (const auto& [key, offsets] : r.spots) {
    const Summary s = Summarise(offsets);
    std::printf("%-20s %-16s %4d/%4d %+8.4f %+8.4f %7.4f %7.4f %+9.2e %+9.2e %7.4f %7.4f\n",
                KindName(key.first), SpotChannelName(key.second), s.n, s.visible, s.mean_dx,
                s.mean_dy, s.rms, s.p99, s.k_image, s.k_grid, s.rms_small, s.rms_large);
  }
  for (const auto& [kind, t] : r.tags) {
    std::printf("tags, %-20s %5d corners: mean (%+.4f, %+.4f) px, RMS %.4f px, tag size scale %+.2e\n",
                KindName(kind), t.corners, t.mean_dx, t.mean_dy, t.rms, t.k_tag);
  }
}

// The seeded CI part: seed 1's placement, every file kind and channel.
TEST(JpegSpotOffsets, ChromaSubsamplingNotAShiftMovesRedSpots) {
  Scene scene = test::NoiseFree(test::ClutterScene());
  ASSERT_FALSE(scene.shots.empty());
  scene.seed = 1;
  test::PlaceModuleForSeed(scene, 1);
  StudyResult r;
  MeasureOffsets(
      scene, {FileKind::kPng, FileKind::kJpeg420, FileKind::kJpeg444, FileKind::kGreyJpegOfRed}, &r);
  ASSERT_FALSE(HasFatalFailure());
  Print(r);
  const auto at = [&](FileKind k, SpotChannel c) { return Summarise(r.spots.at({k, c})); };
  const Summary png = at(FileKind::kPng, SpotChannel::kRed);
  const Summary j420 = at(FileKind::kJpeg420, SpotChannel::kRed);
  const Summary j444 = at(FileKind::kJpeg444, SpotChannel::kRed);
  const Summary grey = at(FileKind::kGreyJpegOfRed, SpotChannel::kRed);
  const Summary luma420 = at(FileKind::kJpeg420, SpotChannel::kLuma);
  const Summary rmg420 = at(FileKind::kJpeg420, SpotChannel::kRedMinusGreen);
  // Measured (docs/images.md, "The JPEG bias"): RMS 0.018 px lossless,
  // 0.144 px in red with 4:2:0 chroma, 0.046 px in luma, 0.325 px in red
  // minus green, 0.076 px in red with 4:4:4 chroma, 0.027 px as a grey JPEG.
  EXPECT_LT(png.rms, 0.03);
  EXPECT_GT(j420.rms, 0.12);
  EXPECT_LT(j420.rms, 0.17);
  EXPECT_LT(luma420.rms, 0.06);
  EXPECT_LT(luma420.rms, 0.4 * j420.rms);
  EXPECT_GT(rmg420.rms, 2.0 * j420.rms);
  EXPECT_GT(j444.rms, 0.06);
  EXPECT_LT(j444.rms, 0.09);
  EXPECT_LT(grey.rms, 0.035);
  EXPECT_GE(j420.n, 960);
  // Not a shift and not a scale, in any file or channel: mean offsets
  // below 0.006 px, radial scales below 1.5e-5 (s/s_true - 1 of +2.8e-3
  // would need 2.8e-3).
  for (const auto& [key, offsets] : r.spots) {
    const Summary s = Summarise(offsets);
    EXPECT_LT(std::abs(s.mean_dx), 0.01) << KindName(key.first) << ", " << SpotChannelName(key.second);
    EXPECT_LT(std::abs(s.mean_dy), 0.01) << KindName(key.first) << ", " << SpotChannelName(key.second);
    EXPECT_LT(std::abs(s.k_image), 2e-5) << KindName(key.first) << ", " << SpotChannelName(key.second);
    EXPECT_LT(std::abs(s.k_grid), 2e-5) << KindName(key.first) << ", " << SpotChannelName(key.second);
  }
  // The tags (luma, full resolution in every JPEG) do not move: RMS within
  // 0.01 px of the lossless file's (0.074 against 0.068 px), no size change.
  for (const auto& [kind, t] : r.tags) {
    EXPECT_EQ(t.corners, r.tags.at(FileKind::kPng).corners) << KindName(kind);
    EXPECT_LT(t.rms, r.tags.at(FileKind::kPng).rms + 0.01) << KindName(kind);
    EXPECT_LT(std::abs(t.k_tag), 1e-5) << KindName(kind);
  }
}

// The study: OPL_STUDY_SCENES noise-free placements (seeds 1..N), each
// rendered once and measured from each file kind (and, for 4:2:0, each spot
// channel) with the exact calibration: s/s_true - 1 and z of the reported s
// (the scale inside the adjustment) and of the two-step s.
TEST(JpegSpotOffsets, StudyScaleByFileKindOverPlacements) {
  const char* env = std::getenv("OPL_STUDY_SCENES");
  const int n = env != nullptr ? std::atoi(env) : 0;
  if (n <= 0) GTEST_SKIP() << "OPL_STUDY_SCENES=<N> (ctest -L study: 16)";
  struct Variant {
    FileKind kind;
    SpotChannel channel;
  };
  const std::vector<Variant> variants = {
      {FileKind::kPng, SpotChannel::kRed},          {FileKind::kJpeg420, SpotChannel::kRed},
      {FileKind::kJpeg420, SpotChannel::kLuma},     {FileKind::kJpeg420, SpotChannel::kRedMinusGreen},
      {FileKind::kJpeg444, SpotChannel::kRed},      {FileKind::kGreyJpegOfRed, SpotChannel::kRed}};
  struct Sums {
    int n = 0;
    double e = 0, e2 = 0, z = 0, z2 = 0, zt = 0, zt2 = 0;
  };
  std::vector<Sums> sums(variants.size());
  // Placements refused, by variant: the scene's (seed 14: distractors over
  // frame tag 2 in all but one camera, docs/images.md), so the same for
  // every file kind and channel.
  std::vector<std::vector<int>> refused(variants.size());
  for (int k = 1; k <= n; ++k) {
    Scene scene = test::NoiseFree(test::ClutterScene());
    ASSERT_FALSE(scene.shots.empty());
    scene.seed = static_cast<uint64_t>(k);
    test::PlaceModuleForSeed(scene, static_cast<uint64_t>(k));
    Result<SceneRenderer> renderer = SceneRenderer::Create(scene);
    ASSERT_TRUE(renderer.ok());
    std::vector<cv::Mat> images;
    for (size_t i = 0; i < scene.shots.size(); ++i) {
      Result<RenderedShot> shot = renderer->RenderShot(static_cast<int>(i));
      ASSERT_TRUE(shot.ok());
      images.push_back(shot->image);
    }
    Result<ModuleCalibration> calibration = ExactCalibration(*scene.module);
    ASSERT_TRUE(calibration.ok());
    for (size_t v = 0; v < variants.size(); ++v) {
      const std::filesystem::path dir = test::FreshTempDir("jpeg_study");
      for (size_t i = 0; i < scene.shots.size(); ++i) {
        ASSERT_TRUE(WriteFileAtomically((dir / scene.shots[i].file).string(),
                                        Encode(images[i], variants[v].kind))
                        .ok());
      }
      ImageMeasureOptions options;
      options.front_end.num_threads = 2;
      options.front_end.spot_channel = variants[v].channel;
      Result<ImageMeasureReport> report =
          MeasureScaleFromImages(scene, dir.string(), *calibration, options);
      std::filesystem::remove_all(dir);
      if (!report.ok()) {
        std::printf("placement %d, %s, %s: not measured: %s\n", k, KindName(variants[v].kind),
                    SpotChannelName(variants[v].channel), report.status().ToString().c_str());
        refused[v].push_back(k);
        continue;
      }
      const test::TruthFit fit = test::FitToTruth(*report, *renderer);
      if (fit.points < 4) continue;
      const double e = report->scale_factor / fit.scale - 1.0;
      const double z = (report->scale_factor - fit.scale) / report->u_scale_factor;
      const double zt = (report->measure.scale.scale_factor - fit.scale) /
                        report->measure.scale.u_scale_factor;
      std::printf("placement %d, %-20s %-16s s/s_true - 1 = %+.2e (u %.1e), z %+.2f; two-step "
                  "%+.2e, z %+.2f\n",
                  k, KindName(variants[v].kind), SpotChannelName(variants[v].channel), e,
                  report->u_scale_factor / fit.scale, z,
                  report->measure.scale.scale_factor / fit.scale - 1.0, zt);
      Sums& s = sums[v];
      ++s.n;
      s.e += e;
      s.e2 += e * e;
      s.z += z;
      s.z2 += z * z;
      s.zt += zt;
      s.zt2 += zt * zt;
    }
  }
  for (size_t v = 0; v < variants.size(); ++v) {
    const Sums& s = sums[v];
    if (s.n == 0) continue;
    const double mean = s.e / s.n, sd = std::sqrt(std::max(0.0, s.e2 / s.n - mean * mean));
    std::printf("%-20s %-16s %d placements: s/s_true - 1 mean %+.2e +- %.1e (sd %.2e, RMS %.2e); "
                "z mean %+.2f RMS %.2f; two-step z mean %+.2f RMS %.2f\n",
                KindName(variants[v].kind), SpotChannelName(variants[v].channel), s.n, mean,
                sd / std::sqrt(s.n), sd, std::sqrt(s.e2 / s.n), s.z / s.n, std::sqrt(s.z2 / s.n),
                s.zt / s.n, std::sqrt(s.zt2 / s.n));
    EXPECT_EQ(s.n + static_cast<int>(refused[v].size()), n);
    EXPECT_EQ(refused[v], refused[0]) << KindName(variants[v].kind) << " " << SpotChannelName(variants[v].channel);
  }
  // At most one placement in 16 refused (seed 14 is, for its tags).
  EXPECT_LE(static_cast<int>(refused[0].size()), (n + 15) / 16);
}

}  // namespace
}  // namespace opl
