#include "opl/report/coverage_image.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"

namespace opl {
namespace {

// Distinct colours: hue stepped by the golden angle.
cv::Scalar ViewColour(size_t v) {
  const double hue = std::fmod(static_cast<double>(v) * 137.508, 360.0);
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(hue / 2.0, 220, 210));
  cv::Mat bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

}  // namespace

std::string SensorCoverage::Summary() const {
  const int cells = cells_across * cells_down;
  int covered = 0;
  for (int n : corners_per_cell) covered += n > 0 ? 1 : 0;
  std::string out = "corners in " + std::to_string(covered) + " of " + std::to_string(cells) + " cells (" +
                    FormatPrintf("%.0f", 100.0 * fraction_covered) + "%) of a " + std::to_string(cells_across) +
                    " x " + std::to_string(cells_down) + " grid over the image";
  // Which regions (thirds of the image) hold empty cells.
  const char* names[3][3] = {{"top-left", "top", "top-right"},
                             {"left", "centre", "right"},
                             {"bottom-left", "bottom", "bottom-right"}};
  bool empty_region[3][3] = {};
  for (int r = 0; r < cells_down; ++r) {
    for (int c = 0; c < cells_across; ++c) {
      if (corners_per_cell[static_cast<size_t>(r * cells_across + c)] > 0) continue;
      empty_region[std::min(2, 3 * r / cells_down)][std::min(2, 3 * c / cells_across)] = true;
    }
  }
  std::string empty;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (empty_region[i][j]) empty += std::string(empty.empty() ? "" : ", ") + names[i][j];
    }
  }
  if (!empty.empty()) out += "; empty cells: " + empty;
  return out;
}

Result<SensorCoverage> ComputeSensorCoverage(int width_px, int height_px, const std::vector<BoardView>& views,
                                             int cells_across) {
  if (width_px < 1 || height_px < 1) {
    return Status::InvalidArgument("ComputeSensorCoverage: image size " + std::to_string(width_px) + " x " +
                                   std::to_string(height_px) + " must be positive");
  }
  if (cells_across < 1 || cells_across > 100) {
    return Status::InvalidArgument("ComputeSensorCoverage: cells_across = " + std::to_string(cells_across) +
                                   ": must be in [1, 100]");
  }
  SensorCoverage cov;
  cov.cells_across = cells_across;
  cov.cells_down = std::max(1, static_cast<int>(std::lround(cells_across * static_cast<double>(height_px) / width_px)));
  cov.corners_per_cell.assign(static_cast<size_t>(cov.cells_across * cov.cells_down), 0);
  for (const BoardView& view : views) {
    for (const Eigen::Vector2d& p : view.pixels) {
      // Pixel (u, v) covers [u - 0.5, u + 0.5): the image spans [-0.5, W - 0.5).
      const double x = (p.x() + 0.5) / width_px, y = (p.y() + 0.5) / height_px;
      if (!(x >= 0.0 && x < 1.0 && y >= 0.0 && y < 1.0)) continue;
      const int c = std::min(cov.cells_across - 1, static_cast<int>(x * cov.cells_across));
      const int r = std::min(cov.cells_down - 1, static_cast<int>(y * cov.cells_down));
      ++cov.corners_per_cell[static_cast<size_t>(r * cov.cells_across + c)];
      ++cov.num_corners;
    }
  }
  int covered = 0;
  for (int n : cov.corners_per_cell) covered += n > 0 ? 1 : 0;
  cov.fraction_covered = static_cast<double>(covered) / static_cast<double>(cov.corners_per_cell.size());
  return cov;
}

Status CoverageImageOptions::Validate() const {
  if (max_side_px < 200 || max_side_px > 4000) {
    return Status::InvalidArgument("CoverageImageOptions.max_side_px = " + std::to_string(max_side_px) +
                                   ": must be in [200, 4000]");
  }
  return Status::Ok();
}

Result<cv::Mat> DrawCoverageImage(int width_px, int height_px, const std::vector<BoardView>& views,
                                  const SensorCoverage& coverage, const CoverageImageOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (width_px < 1 || height_px < 1 || coverage.cells_across < 1 || coverage.cells_down < 1 ||
      coverage.corners_per_cell.size() != static_cast<size_t>(coverage.cells_across * coverage.cells_down)) {
    return Status::InvalidArgument("DrawCoverageImage: the image size or the coverage grid is invalid");
  }
  const double scale = static_cast<double>(options.max_side_px) / std::max(width_px, height_px);
  const int sw = std::max(1, static_cast<int>(std::lround(width_px * scale)));
  const int sh = std::max(1, static_cast<int>(std::lround(height_px * scale)));
  const int margin = 30, caption_h = 70, legend_w = 260;
  const int W = margin + sw + margin + legend_w, H = caption_h + sh + 2 * margin;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Point origin(margin, caption_h + margin);
  auto to_canvas = [&](double u, double v) {
    return cv::Point2d(origin.x + (u + 0.5) * scale, origin.y + (v + 0.5) * scale);
  };
  const int shift = 4;  // sub-pixel drawing
  const double f = 1 << shift;
  auto fixed = [&](const cv::Point2d& p) { return cv::Point(static_cast<int>(std::lround(p.x * f)), static_cast<int>(std::lround(p.y * f))); };

  // Sensor: light grey, empty cells tinted red, the grid, the outline.
  cv::rectangle(img, cv::Rect(origin.x, origin.y, sw, sh), cv::Scalar(245, 245, 245), cv::FILLED);
  for (int r = 0; r < coverage.cells_down; ++r) {
    for (int c = 0; c < coverage.cells_across; ++c) {
      const int x0 = origin.x + sw * c / coverage.cells_across, x1 = origin.x + sw * (c + 1) / coverage.cells_across;
      const int y0 = origin.y + sh * r / coverage.cells_down, y1 = origin.y + sh * (r + 1) / coverage.cells_down;
      if (coverage.corners_per_cell[static_cast<size_t>(r * coverage.cells_across + c)] == 0) {
        cv::rectangle(img, cv::Rect(x0, y0, x1 - x0, y1 - y0), cv::Scalar(215, 215, 255), cv::FILLED);
      }
      cv::rectangle(img, cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1), cv::Scalar(210, 210, 210), 1);
    }
  }
  cv::rectangle(img, cv::Rect(origin.x - 1, origin.y - 1, sw + 2, sh + 2), cv::Scalar(40, 40, 40), 2);

  // Views: hull outline and corners.
  for (size_t v = 0; v < views.size(); ++v) {
    const cv::Scalar colour = ViewColour(v);
    std::vector<cv::Point2f> pts;
    for (const Eigen::Vector2d& p : views[v].pixels) {
      const cv::Point2d q = to_canvas(p.x(), p.y());
      pts.emplace_back(static_cast<float>(q.x), static_cast<float>(q.y));
    }
    if (pts.size() >= 3) {
      std::vector<cv::Point2f> hull;
      cv::convexHull(pts, hull);
      std::vector<cv::Point> poly;
      for (const cv::Point2f& h : hull) poly.push_back(fixed(h));
      cv::polylines(img, poly, true, colour, 1, cv::LINE_AA, shift);
    }
    for (const cv::Point2f& q : pts) cv::circle(img, fixed(q), static_cast<int>(2.5 * f), colour, cv::FILLED, cv::LINE_AA, shift);
  }

  // Caption.
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  const std::string line1 = (options.title.empty() ? std::string("Sensor coverage") : options.title) + ": " +
                            std::to_string(views.size()) + " views, " + std::to_string(coverage.num_corners) +
                            " corners, image " + std::to_string(width_px) + " x " + std::to_string(height_px) + " px";
  const std::string line2 = "corners in " + FormatPrintf("%.0f", 100.0 * coverage.fraction_covered) + "% of the " +
                            std::to_string(coverage.cells_across) + " x " + std::to_string(coverage.cells_down) +
                            " cells; empty cells tinted red; dots: corners, lines: each view's outline";
  cv::putText(img, line1, cv::Point(margin, 28), font, 0.6, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, line2, cv::Point(margin, 54), font, 0.45, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);

  // Legend: as many views as fit, then "... and N more".
  const int lx = origin.x + sw + margin, line_h = 18;
  const int max_lines = std::max(1, (sh + margin) / line_h);
  for (size_t v = 0; v < views.size(); ++v) {
    const int y = origin.y + static_cast<int>(v) * line_h;
    if (static_cast<int>(v) == max_lines - 1 && views.size() > static_cast<size_t>(max_lines)) {
      cv::putText(img, "... and " + std::to_string(views.size() - v) + " more", cv::Point(lx, y + 12), font, 0.4,
                  cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      break;
    }
    cv::circle(img, cv::Point(lx + 6, y + 8), 5, ViewColour(v), cv::FILLED, cv::LINE_AA);
    std::string name = views[v].name;
    if (const size_t slash = name.find_last_of('/'); slash != std::string::npos) name = name.substr(slash + 1);
    if (name.size() > 30) name = name.substr(0, 27) + "...";
    cv::putText(img, name + " (" + std::to_string(views[v].pixels.size()) + ")", cv::Point(lx + 16, y + 12), font,
                0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return img;
}

}  // namespace opl
