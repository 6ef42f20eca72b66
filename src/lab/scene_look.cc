#include "opl/lab/scene_look.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "opl/lab/spot_image.h"
#include "opl/sim/random.h"
#include "opl/vision/image_decode.h"
#include "opl/vision/spot_detection.h"

namespace opl {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Adds a Gaussian blob of peak `amplitude` per channel (size channels) to
// `image` (CV_32FC1 or CV_32FC3 BGR; rgb is red, green, blue) within 4 sigma.
void AddBlob(const Distractor& d, const std::array<double, 3>& amplitude, cv::Mat* image) {
  const Eigen::Matrix2d info = d.shape_covariance_px2.inverse();
  const double hu = 4.0 * std::sqrt(d.shape_covariance_px2(0, 0));
  const double hv = 4.0 * std::sqrt(d.shape_covariance_px2(1, 1));
  const int x0 = std::max(0, static_cast<int>(std::floor(d.center_px.x() - hu)));
  const int x1 = std::min(image->cols - 1, static_cast<int>(std::ceil(d.center_px.x() + hu)));
  const int y0 = std::max(0, static_cast<int>(std::floor(d.center_px.y() - hv)));
  const int y1 = std::min(image->rows - 1, static_cast<int>(std::ceil(d.center_px.y() + hv)));
  const int channels = image->channels();
  for (int y = y0; y <= y1; ++y) {
    float* row = image->ptr<float>(y);
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d r(x - d.center_px.x(), y - d.center_px.y());
      const double g = std::exp(-0.5 * r.dot(info * r));
      if (channels == 1) {
        row[x] += static_cast<float>(amplitude[0] * g);
      } else {
        // BGR in memory.
        for (int c = 0; c < 3; ++c) row[3 * x + c] += static_cast<float>(amplitude[2 - c] * g);
      }
    }
  }
}

Eigen::Matrix2d EllipseCovariance(double sigma_major, double sigma_minor, double angle_rad) {
  Eigen::Matrix2d R;
  R << std::cos(angle_rad), -std::sin(angle_rad), std::sin(angle_rad), std::cos(angle_rad);
  return R * Eigen::Vector2d(sigma_major * sigma_major, sigma_minor * sigma_minor).asDiagonal() *
         R.transpose();
}

double Luma(const std::array<double, 3>& rgb) {
  return 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2];
}

// The texture scaled to cover width x height (aspect kept, centred crop).
cv::Mat CoverImage(const cv::Mat& texture, int width, int height) {
  const double scale = std::max(static_cast<double>(width) / texture.cols,
                                static_cast<double>(height) / texture.rows);
  const int w = std::max(width, static_cast<int>(std::ceil(texture.cols * scale)));
  const int h = std::max(height, static_cast<int>(std::ceil(texture.rows * scale)));
  cv::Mat scaled;
  cv::resize(texture, scaled, cv::Size(w, h), 0, 0, cv::INTER_LINEAR);
  return scaled(cv::Rect((w - width) / 2, (h - height) / 2, width, height)).clone();
}

// Shot and read noise, rounding and clipping of one channel (DN, CV_32FC1),
// as RenderSpotImage applies them (no spots: the image is the background).
Result<SpotImage> ApplySensor(const cv::Mat& expected_dn, const ImageLook& look, uint64_t seed) {
  SpotImageOptions o;
  o.width_px = expected_dn.cols;
  o.height_px = expected_dn.rows;
  o.bit_depth = look.bit_depth;
  o.background_image_dn = expected_dn;
  o.gain_e_per_dn = look.gain_e_per_dn;
  o.read_noise_dn = look.read_noise * SpotImageFullScale(o);
  o.seed = seed;
  return RenderSpotImage({}, o);
}

}  // namespace

const char* DistractorKindName(Distractor::Kind kind) {
  switch (kind) {
    case Distractor::Kind::kSpecularHighlight:
      return "specular_highlight";
    case Distractor::Kind::kLamp:
      return "lamp";
    case Distractor::Kind::kRetroreflector:
      return "retroreflector";
  }
  return "unknown";
}

std::vector<Distractor> MakeDistractors(int count, int width_px, int height_px, uint64_t seed) {
  std::mt19937_64 rng(SplitMix64(seed).Next());
  auto uniform = [&rng](double a, double b) { return a + (b - a) * Uniform01(rng); };
  std::vector<Distractor> out;
  out.reserve(static_cast<size_t>(std::max(0, count)));
  const double margin = std::min(10.0, 0.1 * std::min(width_px, height_px));
  for (int k = 0; k < count; ++k) {
    Distractor d;
    const double kind = Uniform01(rng);
    d.center_px = Eigen::Vector2d(uniform(margin, width_px - 1 - margin),
                                  uniform(margin, height_px - 1 - margin));
    if (kind < 0.4) {
      d.kind = Distractor::Kind::kSpecularHighlight;
      d.shape_covariance_px2 = EllipseCovariance(uniform(3.0, 12.0), uniform(0.8, 2.0),
                                                 uniform(0.0, kPi));
      d.peak_fraction = uniform(1.0, 3.0);
    } else if (kind < 0.7) {
      d.kind = Distractor::Kind::kLamp;
      const double s = uniform(1.5, 5.0);
      d.shape_covariance_px2 = EllipseCovariance(s, s, 0.0);
      d.peak_fraction = uniform(1.5, 4.0);
      d.rgb = {1.0, 0.8, 0.55};
    } else {
      d.kind = Distractor::Kind::kRetroreflector;
      const double s = uniform(1.0, 2.5);
      d.shape_covariance_px2 = EllipseCovariance(s, s, 0.0);
      d.peak_fraction = uniform(0.3, 0.9);
    }
    out.push_back(d);
  }
  return out;
}

Result<cv::Mat> ReadWallTexture(const std::string& path) {
  // Decoded as the shots are (vision/image_decode.h: sensor pixels, nothing
  // printed on stderr). A damaged file is refused rather than rendered with
  // the decoder's fill.
  Result<DecodedImage> image = ReadImageFile(path);
  if (!image.ok()) return image.status();
  if (!image->warnings.empty()) {
    return Status::IoError(path + ": the wall texture is damaged (" + image->warnings.front() +
                           ")");
  }
  const cv::Mat& pixels = image->pixels;
  if (pixels.depth() != CV_8U && pixels.depth() != CV_16U) {
    return Status::IoError(path + ": image type " + OpenCvTypeName(pixels.type()) +
                           " is not supported for a wall texture (8 or 16 bit)");
  }
  cv::Mat bgr = pixels;
  if (pixels.channels() == 1) cv::cvtColor(pixels, bgr, cv::COLOR_GRAY2BGR);
  if (bgr.channels() != 3) {
    return Status::IoError(path + ": image type " + OpenCvTypeName(pixels.type()) +
                           " is not supported for a wall texture (grey or colour)");
  }
  cv::Mat texture;
  bgr.convertTo(texture, CV_32FC3, pixels.depth() == CV_8U ? 1.0 / 255.0 : 1.0 / 65535.0);
  return texture;
}

Result<SceneImage> ComposeSceneImage(const SceneImageLayers& layers, const ImageLook& look,
                                     const CameraIntrinsics& camera, uint64_t noise_seed) {
  const int W = camera.width_px;
  const int H = camera.height_px;
  const cv::Size size(W, H);
  if (layers.tag_levels.size() != size || layers.tag_levels.type() != CV_32FC1) {
    return Status::InvalidArgument("ComposeSceneImage: tag_levels must be CV_32FC1 of the image size");
  }
  if (!layers.spot_light.empty() &&
      (layers.spot_light.size() != size || layers.spot_light.type() != CV_32FC1)) {
    return Status::InvalidArgument("ComposeSceneImage: spot_light must be CV_32FC1 of the image size");
  }
  if (!layers.wall_texture.empty() && layers.wall_texture.type() != CV_32FC3) {
    return Status::InvalidArgument("ComposeSceneImage: wall_texture must be CV_32FC3");
  }
  if (!(layers.exposure > 0.0 && std::isfinite(layers.exposure))) {
    return Status::InvalidArgument("ComposeSceneImage: exposure must be finite and > 0");
  }
  const int channels = look.color ? 3 : 1;
  const double bg = look.background_level;

  // 1. Wall, and the tags over it.
  cv::Mat scene;  // CV_32FC(channels), fractions of full scale
  if (!layers.wall_texture.empty()) {
    cv::Mat texture = CoverImage(layers.wall_texture, W, H);
    if (channels == 1) cv::cvtColor(texture, texture, cv::COLOR_BGR2GRAY);
    cv::Mat luma;
    if (channels == 3) {
      cv::cvtColor(texture, luma, cv::COLOR_BGR2GRAY);
    } else {
      luma = texture;
    }
    const double mean = std::max(1e-3, cv::mean(luma)[0]);
    const double k = look.wall_texture_contrast;
    texture.convertTo(scene, texture.type(), bg * k / mean, bg * (1.0 - k));
    // The tags cover the wall wherever their image departs from the plain
    // wall level, and a blur's reach beyond (their quiet zone's outer edge
    // blends into the texture; the black square is 2 cells further in).
    cv::Mat departs;
    cv::absdiff(layers.tag_levels, cv::Scalar(bg), departs);
    cv::Mat mask;
    cv::threshold(departs, mask, 1e-4, 1.0, cv::THRESH_BINARY);
    const int reach = 1 + static_cast<int>(std::ceil(2.0 * look.blur_sigma_px));
    cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_RECT,
                                                     cv::Size(2 * reach + 1, 2 * reach + 1)));
    cv::GaussianBlur(mask, mask, cv::Size(0, 0), std::max(0.7, look.blur_sigma_px));
    cv::Mat tags = layers.tag_levels;
    cv::Mat one_minus;
    cv::subtract(cv::Scalar(1.0), mask, one_minus);
    if (channels == 3) {
      cv::cvtColor(mask, mask, cv::COLOR_GRAY2BGR);
      cv::cvtColor(one_minus, one_minus, cv::COLOR_GRAY2BGR);
      cv::cvtColor(tags, tags, cv::COLOR_GRAY2BGR);
    }
    scene = tags.mul(mask) + scene.mul(one_minus);
  } else if (channels == 3) {
    cv::cvtColor(layers.tag_levels, scene, cv::COLOR_GRAY2BGR);
  } else {
    scene = layers.tag_levels.clone();
  }

  // 2. Ambient light ramp.
  if (look.ambient_gradient > 0.0) {
    const double a = look.ambient_angle_deg * kPi / 180.0;
    const double cu = std::cos(a), sv = std::sin(a);
    const double extent = std::abs(cu) * (W - 1) + std::abs(sv) * (H - 1);
    const double per_px = extent > 0.0 ? look.ambient_gradient / extent : 0.0;
    const double u0 = 0.5 * (W - 1), v0 = 0.5 * (H - 1);
    for (int y = 0; y < H; ++y) {
      float* row = scene.ptr<float>(y);
      for (int x = 0; x < W; ++x) {
        const float add = static_cast<float>(per_px * ((x - u0) * cu + (y - v0) * sv));
        for (int c = 0; c < channels; ++c) row[channels * x + c] += add;
      }
    }
  }

  // 3. Distractors.
  for (const Distractor& d : layers.distractors) {
    std::array<double, 3> amplitude;
    if (channels == 1) {
      amplitude = {d.peak_fraction * Luma(d.rgb), 0.0, 0.0};
    } else {
      for (int c = 0; c < 3; ++c) amplitude[c] = d.peak_fraction * d.rgb[c];
    }
    AddBlob(d, amplitude, &scene);
  }

  // 4. Defocus.
  if (look.defocus_sigma_px > 0.0) {
    cv::GaussianBlur(scene, scene, cv::Size(0, 0), look.defocus_sigma_px, 0.0,
                     cv::BORDER_REFLECT);
  }

  // 5. Spots through the camera's response.
  if (!layers.spot_light.empty()) {
    if (channels == 1) {
      scene += layers.spot_light;
    } else {
      std::vector<cv::Mat> planes;
      cv::split(scene, planes);  // B, G, R
      for (int c = 0; c < 3; ++c) {
        cv::scaleAdd(layers.spot_light, look.laser_response_rgb[static_cast<size_t>(2 - c)],
                     planes[static_cast<size_t>(c)], planes[static_cast<size_t>(c)]);
      }
      cv::merge(planes, scene);
    }
  }

  // 6. Vignetting, 7. to DN.
  SpotImageOptions scale;
  scale.bit_depth = look.bit_depth;
  const double full_scale = SpotImageFullScale(scale);
  const double r2_corner = std::max(
      {std::pow(camera.cx_px, 2) + std::pow(camera.cy_px, 2),
       std::pow(W - 1 - camera.cx_px, 2) + std::pow(camera.cy_px, 2),
       std::pow(camera.cx_px, 2) + std::pow(H - 1 - camera.cy_px, 2),
       std::pow(W - 1 - camera.cx_px, 2) + std::pow(H - 1 - camera.cy_px, 2), 1.0});
  for (int y = 0; y < H; ++y) {
    float* row = scene.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      const double r2 = std::pow(x - camera.cx_px, 2) + std::pow(y - camera.cy_px, 2);
      const double v = layers.exposure * full_scale * (1.0 - look.vignetting * r2 / r2_corner);
      for (int c = 0; c < channels; ++c) {
        row[channels * x + c] = static_cast<float>(std::max(0.0, row[channels * x + c] * v));
      }
    }
  }

  // 7. Sensor.
  SceneImage out;
  if (channels == 1) {
    Result<SpotImage> s = ApplySensor(scene, look, noise_seed);
    if (!s.ok()) return s.status();
    out.image = std::move(s->image);
    out.saturated_mask = std::move(s->saturated_mask);
    return out;
  }
  if (look.bayer) {
    // RGGB: red at (even row, even column), blue at (odd, odd).
    cv::Mat mosaic(H, W, CV_32FC1);
    for (int y = 0; y < H; ++y) {
      const float* row = scene.ptr<float>(y);
      float* m = mosaic.ptr<float>(y);
      for (int x = 0; x < W; ++x) {
        const int c = (y % 2 == 0) ? (x % 2 == 0 ? 2 : 1) : (x % 2 == 0 ? 1 : 0);  // BGR index
        m[x] = row[3 * x + c];
      }
    }
    Result<SpotImage> s = ApplySensor(mosaic, look, noise_seed);
    if (!s.ok()) return s.status();
    // OpenCV names a Bayer pattern by its second row's second and third
    // pixels: RGGB (R at the origin) is its BayerBG.
    cv::cvtColor(s->image, out.image, cv::COLOR_BayerBG2BGR);
    cv::Mat red = cv::Mat::zeros(H, W, CV_8U);
    const double full = full_scale;
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        const double value = look.bit_depth == 8 ? out.image.at<cv::Vec3b>(y, x)[2]
                                                 : out.image.at<cv::Vec3w>(y, x)[2];
        if (value >= full) red.at<uint8_t>(y, x) = 255;
      }
    }
    out.saturated_mask = red;
    return out;
  }
  std::vector<cv::Mat> planes;
  cv::split(scene, planes);
  std::vector<cv::Mat> written(3);
  SplitMix64 seeds(noise_seed);
  for (int c = 0; c < 3; ++c) {
    Result<SpotImage> s = ApplySensor(planes[static_cast<size_t>(c)], look, seeds.Next());
    if (!s.ok()) return s.status();
    written[static_cast<size_t>(c)] = std::move(s->image);
    if (c == 2) out.saturated_mask = std::move(s->saturated_mask);
  }
  cv::merge(written, out.image);
  return out;
}

}  // namespace opl
