#include "opl/lab/planar_target_image.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "opl/sim/random.h"

namespace opl {
namespace {

constexpr int kTagCells = 8;  // tag36h11: 6 data cells + 1 border cell each side
constexpr int kTag36h11Count = 587;

// Signed area of a polygon (shoelace).
double PolygonArea(const double* xs, const double* ys, int n) {
  double a = 0.0;
  for (int i = 0, j = n - 1; i < n; j = i++) a += xs[j] * ys[i] - xs[i] * ys[j];
  return 0.5 * a;
}

// Sutherland-Hodgman clipping of a polygon against the half plane
// sign * (coord - bound) >= 0 on axis `axis` (0: x, 1: y).
int ClipHalfPlane(const double* xs, const double* ys, int n, int axis, double bound, double sign,
                  double* out_x, double* out_y) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    const double ci = axis == 0 ? xs[i] : ys[i];
    const double cj = axis == 0 ? xs[j] : ys[j];
    const bool in_i = sign * (ci - bound) >= 0.0;
    const bool in_j = sign * (cj - bound) >= 0.0;
    if (in_i) {
      out_x[m] = xs[i];
      out_y[m] = ys[i];
      ++m;
    }
    if (in_i != in_j) {
      const double t = (bound - ci) / (cj - ci);
      out_x[m] = xs[i] + t * (xs[j] - xs[i]);
      out_y[m] = ys[i] + t * (ys[j] - ys[i]);
      ++m;
    }
  }
  return m;
}

// Area of the convex-or-not quad (xs, ys) inside the box [x0, x1] x [y0, y1].
double ClippedArea(const double* xs, const double* ys, double x0, double x1, double y0,
                   double y1) {
  // A quad clipped by 4 half planes has at most 8 vertices.
  double ax[16], ay[16], bx[16], by[16];
  int n = ClipHalfPlane(xs, ys, 4, 0, x0, 1.0, ax, ay);
  if (n < 3) return 0.0;
  n = ClipHalfPlane(ax, ay, n, 0, x1, -1.0, bx, by);
  if (n < 3) return 0.0;
  n = ClipHalfPlane(bx, by, n, 1, y0, 1.0, ax, ay);
  if (n < 3) return 0.0;
  n = ClipHalfPlane(ax, ay, n, 1, y1, -1.0, bx, by);
  if (n < 3) return 0.0;
  return PolygonArea(bx, by, n);
}

// Reflectance texture as doubles in [0, 1].
Result<cv::Mat> TextureAsDouble(const cv::Mat& texture, int index) {
  const std::string where = "targets[" + std::to_string(index) + "].texture";
  if (texture.empty()) return Status::InvalidArgument(where + ": empty");
  if (texture.channels() != 1) {
    return Status::InvalidArgument(where + ": " + std::to_string(texture.channels()) +
                                   " channels, expected 1");
  }
  cv::Mat out;
  if (texture.depth() == CV_8U) {
    texture.convertTo(out, CV_64F, 1.0 / 255.0);
  } else if (texture.depth() == CV_32F || texture.depth() == CV_64F) {
    texture.convertTo(out, CV_64F);
  } else {
    return Status::InvalidArgument(where + ": depth " + std::to_string(texture.depth()) +
                                   ", expected CV_8U, CV_32F or CV_64F");
  }
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(out, &lo, &hi);
  if (!(lo >= 0.0 && hi <= 1.0)) {
    return Status::InvalidArgument(where + ": reflectance in [" + FormatNumber(lo) + ", " +
                                   FormatNumber(hi) + "], expected within [0, 1]");
  }
  return out;
}

// Sub-pixel values kept only in square tiles of kTilePx x kTilePx pixels
// (kTilePx n sub-pixels a side), allocated, at the background level, the
// first time a target touches them.
class SubpixelTiles {
 public:
  static constexpr int kTilePx = 64;

  SubpixelTiles(int width, int height, int n, double background)
      : width_(width), height_(height), n_(n), background_(background),
        tiles_x_((width + kTilePx - 1) / kTilePx), tiles_y_((height + kTilePx - 1) / kTilePx),
        tiles_(static_cast<size_t>(tiles_x_) * static_cast<size_t>(tiles_y_)) {}

  // The value of sub-pixel (row, col) of the sub-pixel grid (n H x n W).
  double& At(int row, int col) {
    const int side = kTilePx * n_;
    const int ty = row / side, tx = col / side;
    cv::Mat& tile = tiles_[static_cast<size_t>(ty) * static_cast<size_t>(tiles_x_) +
                           static_cast<size_t>(tx)];
    if (tile.empty()) tile = cv::Mat(TileRect(tx, ty).height * n_, TileRect(tx, ty).width * n_,
                                     CV_64FC1, cv::Scalar(background_));
    return tile.at<double>(row - ty * side, col - tx * side);
  }

  // The pixel image (width x height, CV_64F): the mean of every pixel's
  // sub-pixels (cv::resize INTER_AREA, which averages whole n x n blocks),
  // the background where no tile was allocated.
  cv::Mat Pixels() const {
    cv::Mat image(height_, width_, CV_64FC1, cv::Scalar(background_));
    for (int ty = 0; ty < tiles_y_; ++ty) {
      for (int tx = 0; tx < tiles_x_; ++tx) {
        const cv::Mat& tile = tiles_[static_cast<size_t>(ty) * static_cast<size_t>(tiles_x_) +
                                     static_cast<size_t>(tx)];
        if (tile.empty()) continue;
        const cv::Rect rect = TileRect(tx, ty);
        if (n_ == 1) {
          tile.copyTo(image(rect));
        } else {
          cv::Mat pixels;
          cv::resize(tile, pixels, rect.size(), 0.0, 0.0, cv::INTER_AREA);
          pixels.copyTo(image(rect));
        }
      }
    }
    return image;
  }

 private:
  cv::Rect TileRect(int tx, int ty) const {
    const int x0 = tx * kTilePx, y0 = ty * kTilePx;
    return cv::Rect(x0, y0, std::min(kTilePx, width_ - x0), std::min(kTilePx, height_ - y0));
  }
  int width_, height_, n_;
  double background_;
  int tiles_x_, tiles_y_;
  std::vector<cv::Mat> tiles_;
};

}  // namespace

Status TargetRenderOptions::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("TargetRenderOptions." + field + " = " +
                                   FormatNumber(value, 6) + ": " + rule);
  };
  auto level_ok = [](double v) { return v >= 0.0 && v <= 1.0; };
  if (!level_ok(background_level)) return bad("background_level", background_level, "must be in [0, 1]");
  if (!level_ok(black_level)) return bad("black_level", black_level, "must be in [0, 1]");
  if (!level_ok(white_level)) return bad("white_level", white_level, "must be in [0, 1]");
  if (!(blur_sigma_px >= 0.0 && blur_sigma_px <= 10.0)) {
    return bad("blur_sigma_px", blur_sigma_px, "must be in [0, 10]");
  }
  if (!(noise_sigma >= 0.0 && noise_sigma <= 1.0)) return bad("noise_sigma", noise_sigma, "must be in [0, 1]");
  if (bit_depth != 8 && bit_depth != 16) return bad("bit_depth", bit_depth, "must be 8 or 16");
  return Status::Ok();
}

Result<cv::Mat> MakeTag36h11Texture(int id, int quiet_zone_cells) {
  if (id < 0 || id >= kTag36h11Count) {
    return Status::InvalidArgument("tag36h11 id " + std::to_string(id) + ": must be in [0, " +
                                   std::to_string(kTag36h11Count - 1) + "]");
  }
  if (quiet_zone_cells < 0 || quiet_zone_cells > 100) {
    return Status::InvalidArgument("quiet_zone_cells = " + std::to_string(quiet_zone_cells) +
                                   ": must be in [0, 100]");
  }
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  cv::Mat marker;
  // One pixel per cell: sidePixels = 8 with a 1-cell border.
  dictionary->drawMarker(id, kTagCells, marker, 1);
  cv::Mat texture(kTagCells + 2 * quiet_zone_cells, kTagCells + 2 * quiet_zone_cells, CV_8UC1,
                  cv::Scalar(255));
  marker.copyTo(texture(cv::Rect(quiet_zone_cells, quiet_zone_cells, kTagCells, kTagCells)));
  return texture;
}

Result<PlanarTarget> MakeTagTarget(int id, double tag_size, const Rigid3d& scene_from_tag,
                                   int quiet_zone_cells) {
  if (!(tag_size > 0.0 && std::isfinite(tag_size))) {
    return Status::InvalidArgument("tag_size = " + FormatNumber(tag_size) + ": must be finite and > 0");
  }
  Result<cv::Mat> texture = MakeTag36h11Texture(id, quiet_zone_cells);
  if (!texture.ok()) return texture.status();
  PlanarTarget target;
  target.texture = *texture;
  target.texel_size = tag_size / kTagCells;
  const double half_width = 0.5 * target.Width();
  // target frame = tag frame shifted to the texture's top-left corner.
  target.scene_from_target =
      scene_from_tag * Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-half_width, -half_width, 0.0));
  const double q = quiet_zone_cells * target.texel_size;
  TargetTag tag;
  tag.id = id;
  tag.corners_in_target = {Eigen::Vector2d(q, q), Eigen::Vector2d(q + tag_size, q),
                           Eigen::Vector2d(q + tag_size, q + tag_size),
                           Eigen::Vector2d(q, q + tag_size)};
  target.tags.push_back(tag);
  return target;
}

Result<PlanarTarget> MakeTagBoardTarget(const TagBoard& board, const Rigid3d& scene_from_board,
                                        int margin_cells) {
  OPL_RETURN_IF_ERROR(board.Validate());
  if (margin_cells < 0 || margin_cells > 100) {
    return Status::InvalidArgument("margin_cells = " + std::to_string(margin_cells) +
                                   ": must be in [0, 100]");
  }
  const double cell = board.tag_size / kTagCells;
  const double gap_cells_real = board.tag_gap / cell;
  const int gap_cells = static_cast<int>(std::lround(gap_cells_real));
  if (std::abs(gap_cells_real - gap_cells) > 1e-9 * std::max(1.0, gap_cells_real)) {
    return Status::InvalidArgument("TagBoard.tag_gap = " + FormatNumber(board.tag_gap) +
                                   ": must be a whole number of tag cells (tag_size / 8 = " +
                                   FormatNumber(cell) + ") to be rendered");
  }
  const int pitch = kTagCells + gap_cells;
  const int cols = 2 * margin_cells + board.columns * kTagCells + (board.columns - 1) * gap_cells;
  const int rows = 2 * margin_cells + board.rows * kTagCells + (board.rows - 1) * gap_cells;
  PlanarTarget target;
  target.texture = cv::Mat(rows, cols, CV_8UC1, cv::Scalar(255));
  target.texel_size = cell;
  // Board frame origin = top-left corner of the first tag = texel (m, m).
  const Eigen::Vector3d origin_in_target(margin_cells * cell, margin_cells * cell, 0.0);
  target.scene_from_target =
      scene_from_board * Rigid3d(Eigen::Quaterniond::Identity(), -origin_in_target);
  for (int r = 0; r < board.rows; ++r) {
    for (int c = 0; c < board.columns; ++c) {
      const int id = board.first_id + r * board.columns + c;
      Result<cv::Mat> tag_texture = MakeTag36h11Texture(id, 0);
      if (!tag_texture.ok()) return tag_texture.status();
      tag_texture->copyTo(target.texture(
          cv::Rect(margin_cells + c * pitch, margin_cells + r * pitch, kTagCells, kTagCells)));
      Result<std::array<Eigen::Vector3d, 4>> corners = board.TagCorners(id);
      if (!corners.ok()) return corners.status();
      TargetTag tag;
      tag.id = id;
      for (int k = 0; k < 4; ++k) {
        tag.corners_in_target[k] = ((*corners)[k] + origin_in_target).head<2>();
      }
      target.tags.push_back(tag);
    }
  }
  return target;
}

Result<PlanarTargetRenderer> PlanarTargetRenderer::Create(const Camera& camera,
                                                          int subpixels_per_axis) {
  Result<PlanarTargetRenderer> made = CreateOnDemand(camera, subpixels_per_axis);
  if (!made.ok()) return made;
  PlanarTargetRenderer& r = *made;
  std::vector<Eigen::Vector2d> rays(static_cast<size_t>(r.grid_cols_) *
                                    static_cast<size_t>(r.grid_rows_));
  for (int i = 0; i < r.grid_rows_; ++i) {
    for (int j = 0; j < r.grid_cols_; ++j) {
      rays[static_cast<size_t>(i) * static_cast<size_t>(r.grid_cols_) + static_cast<size_t>(j)] =
          r.RayAt(i, j);
    }
  }
  r.rays_ = std::move(rays);
  return made;
}

Result<PlanarTargetRenderer> PlanarTargetRenderer::CreateOnDemand(const Camera& camera,
                                                                  int subpixels_per_axis) {
  {
    Status s = camera.intrinsics.Validate();
    if (!s.ok()) return Status::InvalidArgument("camera '" + camera.name + "': " + s.message());
  }
  if (subpixels_per_axis < 1 || subpixels_per_axis > 8) {
    return Status::InvalidArgument("subpixels_per_axis = " + std::to_string(subpixels_per_axis) +
                                   ": must be in [1, 8]");
  }
  PlanarTargetRenderer r;
  r.camera_ = camera;
  r.subpixels_ = subpixels_per_axis;
  r.grid_cols_ = subpixels_per_axis * camera.intrinsics.width_px + 1;
  r.grid_rows_ = subpixels_per_axis * camera.intrinsics.height_px + 1;
  return r;
}

Eigen::Vector2d PlanarTargetRenderer::RayAt(int grid_row, int grid_col) const {
  if (!rays_.empty()) {
    return rays_[static_cast<size_t>(grid_row) * static_cast<size_t>(grid_cols_) +
                 static_cast<size_t>(grid_col)];
  }
  const double u = -0.5 + static_cast<double>(grid_col) / subpixels_;
  const double v = -0.5 + static_cast<double>(grid_row) / subpixels_;
  Result<Eigen::Vector2d> xy = UndistortPixel(camera_.intrinsics, Eigen::Vector2d(u, v));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return xy.ok() ? *xy : Eigen::Vector2d(nan, nan);
}

Result<RenderedTargetImage> PlanarTargetRenderer::Render(const std::vector<PlanarTarget>& targets,
                                                         const TargetRenderOptions& options) const {
  OPL_RETURN_IF_ERROR(options.Validate());
  const int width = camera_.intrinsics.width_px;
  const int height = camera_.intrinsics.height_px;
  const int n = subpixels_;
  // Sub-pixel image, in fractions of full scale.
  SubpixelTiles sub(width, height, n, options.background_level);
  RenderedTargetImage out;

  for (size_t t = 0; t < targets.size(); ++t) {
    const PlanarTarget& target = targets[t];
    const int index = static_cast<int>(t);
    Result<cv::Mat> texture_or = TextureAsDouble(target.texture, index);
    if (!texture_or.ok()) return texture_or.status();
    const cv::Mat& texture = *texture_or;
    if (!(target.texel_size > 0.0 && std::isfinite(target.texel_size))) {
      return Status::InvalidArgument("targets[" + std::to_string(index) + "].texel_size = " +
                                     FormatNumber(target.texel_size) + ": must be finite and > 0");
    }
    // Rays in the target frame: origin o (camera centre), direction R d.
    const Rigid3d target_from_cam = (camera_.cam_from_scene * target.scene_from_target).Inverse();
    const Eigen::Matrix3d R = target_from_cam.RotationMatrix();
    const Eigen::Vector3d o = target_from_cam.translation;
    const double inv_texel = 1.0 / target.texel_size;

    // Pixel bounding box of the target: its outline sampled densely and
    // projected; the whole image when part of it is behind the camera.
    int j0 = 0, j1 = width - 1, i0 = 0, i1 = height - 1;
    {
      double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
      bool all_in_front = true;
      const Eigen::Vector2d corners[4] = {{0.0, 0.0}, {target.Width(), 0.0},
                                          {target.Width(), target.Height()}, {0.0, target.Height()}};
      constexpr int kSamples = 64;
      for (int e = 0; e < 4 && all_in_front; ++e) {
        for (int s = 0; s < kSamples; ++s) {
          const Eigen::Vector2d p2 = corners[e] + (corners[(e + 1) % 4] - corners[e]) * s / kSamples;
          Eigen::Vector2d px;
          if (!camera_.Project(target.scene_from_target * Eigen::Vector3d(p2.x(), p2.y(), 0.0), &px)) {
            all_in_front = false;
            break;
          }
          umin = std::min(umin, px.x());
          umax = std::max(umax, px.x());
          vmin = std::min(vmin, px.y());
          vmax = std::max(vmax, px.y());
        }
      }
      if (all_in_front) {
        constexpr double kPad = 3.0;
        j0 = std::max(0, static_cast<int>(std::floor(umin - kPad)));
        j1 = std::min(width - 1, static_cast<int>(std::ceil(umax + kPad)));
        i0 = std::max(0, static_cast<int>(std::floor(vmin - kPad)));
        i1 = std::min(height - 1, static_cast<int>(std::ceil(vmax + kPad)));
      }
    }
    if (j0 > j1 || i0 > i1) continue;
    // A target wholly behind the camera (its corners are, and depth is affine
    // over the plane) covers no pixel: skip the whole-image box.
    bool behind = true;
    for (const Eigen::Vector2d& c : {Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(target.Width(), 0.0),
                                     Eigen::Vector2d(target.Width(), target.Height()),
                                     Eigen::Vector2d(0.0, target.Height())}) {
      const Eigen::Vector3d in_cam =
          camera_.cam_from_scene * (target.scene_from_target * Eigen::Vector3d(c.x(), c.y(), 0.0));
      behind = behind && in_cam.z() <= 0.0;
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    if (!behind) {
      const int gc0 = j0 * n, gc1 = (j1 + 1) * n;  // inclusive grid column range
      const int gw = gc1 - gc0 + 1;
      // The box in bands of kBandRows pixel rows, so that the texture
      // coordinates held at once stay small whatever the box's size.
      constexpr int kBandRows = 64;
      for (int band = i0; band <= i1; band += kBandRows) {
        // Texture coordinates (texel units) of the grid corners in the band.
        const int gr0 = band * n, gr1 = (std::min(i1, band + kBandRows - 1) + 1) * n;
        const int gh = gr1 - gr0 + 1;
        std::vector<double> tx(static_cast<size_t>(gw) * static_cast<size_t>(gh));
        std::vector<double> ty(tx.size());
        for (int gi = 0; gi < gh; ++gi) {
          for (int gj = 0; gj < gw; ++gj) {
            const Eigen::Vector2d xy = RayAt(gr0 + gi, gc0 + gj);
            const size_t k = static_cast<size_t>(gi) * static_cast<size_t>(gw) + static_cast<size_t>(gj);
            const Eigen::Vector3d d = R * Eigen::Vector3d(xy.x(), xy.y(), 1.0);
            const double lambda = -o.z() / d.z();
            if (!(lambda > 0.0) || !std::isfinite(lambda)) {
              tx[k] = ty[k] = nan;
              continue;
            }
            tx[k] = (o.x() + lambda * d.x()) * inv_texel;
            ty[k] = (o.y() + lambda * d.y()) * inv_texel;
          }
        }

        // Coverage of every sub-pixel quad.
        const int tcols = texture.cols, trows = texture.rows;
        for (int gi = 0; gi + 1 < gh; ++gi) {
          for (int gj = 0; gj + 1 < gw; ++gj) {
            const size_t k00 = static_cast<size_t>(gi) * static_cast<size_t>(gw) + static_cast<size_t>(gj);
            const size_t k01 = k00 + 1;
            const size_t k10 = k00 + static_cast<size_t>(gw);
            const size_t k11 = k10 + 1;
            // Quad in order around the sub-pixel.
            const double qx[4] = {tx[k00], tx[k01], tx[k11], tx[k10]};
            const double qy[4] = {ty[k00], ty[k01], ty[k11], ty[k10]};
            if (!(std::isfinite(qx[0]) && std::isfinite(qx[1]) && std::isfinite(qx[2]) &&
                  std::isfinite(qx[3]))) {
              continue;  // (part of) the sub-pixel sees no point of the plane
            }
            const double xmin = std::min(std::min(qx[0], qx[1]), std::min(qx[2], qx[3]));
            const double xmax = std::max(std::max(qx[0], qx[1]), std::max(qx[2], qx[3]));
            const double ymin = std::min(std::min(qy[0], qy[1]), std::min(qy[2], qy[3]));
            const double ymax = std::max(std::max(qy[0], qy[1]), std::max(qy[2], qy[3]));
            if (xmax <= 0.0 || ymax <= 0.0 || xmin >= tcols || ymin >= trows) continue;  // off target
            const int c0 = static_cast<int>(std::floor(xmin));
            const int c1 = static_cast<int>(std::floor(xmax));
            const int r0 = static_cast<int>(std::floor(ymin));
            const int r1 = static_cast<int>(std::floor(ymax));
            double& value = sub.At(gr0 + gi, gc0 + gj);
            const double level_of = options.black_level;
            const double level_span = options.white_level - options.black_level;
            if (c0 == c1 && r0 == r1) {  // inside one texel (inside the texture: tested above)
              value = level_of + level_span * texture.at<double>(r0, c0);
              continue;
            }
            const double area = PolygonArea(qx, qy, 4);
            if (area == 0.0) continue;
            double covered = 0.0, weighted = 0.0;
            for (int r = std::max(r0, 0); r <= std::min(r1, trows - 1); ++r) {
              for (int c = std::max(c0, 0); c <= std::min(c1, tcols - 1); ++c) {
                const double a = ClippedArea(qx, qy, c, c + 1.0, r, r + 1.0);
                covered += a;
                weighted += a * (level_of + level_span * texture.at<double>(r, c));
              }
            }
            const double f = covered / area;  // fraction of the sub-pixel on the target
            value = value * (1.0 - f) + weighted / area;
          }
        }
      }
    }

    // Truth of the tags.
    for (const TargetTag& tag : target.tags) {
      RenderedTag truth;
      truth.id = tag.id;
      truth.target_index = index;
      truth.in_image = true;
      for (int c = 0; c < 4; ++c) {
        const Eigen::Vector3d p = target.scene_from_target *
                                  Eigen::Vector3d(tag.corners_in_target[c].x(), tag.corners_in_target[c].y(), 0.0);
        if (!camera_.Project(p, &truth.corners_px[c])) {
          truth.corners_px[c] = Eigen::Vector2d(nan, nan);
          truth.in_image = false;
        } else if (!camera_.InImage(truth.corners_px[c])) {
          truth.in_image = false;
        }
      }
      out.tags.push_back(truth);
    }
  }

  // Pixel = mean of its sub-pixels.
  cv::Mat image = sub.Pixels();
  if (options.blur_sigma_px > 0.0) {
    const int radius = static_cast<int>(std::ceil(4.0 * options.blur_sigma_px));
    cv::GaussianBlur(image, image, cv::Size(2 * radius + 1, 2 * radius + 1), options.blur_sigma_px,
                     options.blur_sigma_px, cv::BORDER_REFLECT);
  }
  if (options.keep_levels) image.convertTo(out.levels, CV_32FC1);
  if (options.noise_sigma > 0.0) {
    std::mt19937_64 rng(SplitMix64(options.seed).Next());
    NormalGenerator normal;
    for (int i = 0; i < height; ++i) {
      double* row = image.ptr<double>(i);
      for (int j = 0; j < width; ++j) row[j] += options.noise_sigma * normal(rng);
    }
  }
  const double full_scale = options.bit_depth == 8 ? 255.0 : 65535.0;
  // convertTo rounds to nearest and saturates.
  image.convertTo(out.image, options.bit_depth == 8 ? CV_8UC1 : CV_16UC1, full_scale);
  return out;
}

}  // namespace opl
