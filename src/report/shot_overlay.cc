#include "opl/report/shot_overlay.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace opl {
namespace {

const cv::Scalar kTagColour(255, 255, 0);        // cyan (BGR)
const cv::Scalar kIdentifiedColour(0, 220, 0);   // green
const cv::Scalar kMatchedColour(0, 230, 255);    // yellow
const cv::Scalar kDetectedColour(0, 140, 255);   // orange
const cv::Scalar kRejectedColour(40, 40, 255);   // red

cv::Point ToPoint(const Eigen::Vector2d& p) {
  return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
}

// Text with a dark outline, readable on any background.
void Label(cv::Mat* image, const std::string& text, cv::Point at, double scale,
           const cv::Scalar& colour, int thickness) {
  cv::putText(*image, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0),
              thickness + 2, cv::LINE_AA);
  cv::putText(*image, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv::LINE_AA);
}

}  // namespace

Result<cv::Mat> DrawShotOverlay(const cv::Mat& image, const ShotOverlay& overlay) {
  if (image.empty()) return Status::InvalidArgument("DrawShotOverlay: empty image");
  if ((image.depth() != CV_8U && image.depth() != CV_16U) ||
      (image.channels() != 1 && image.channels() != 3)) {
    return Status::InvalidArgument("DrawShotOverlay: the image must be 8 or 16 bit, 1 or 3 channels");
  }
  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  // Dimmed to 60% so that the markers stand out.
  cv::Mat grey8;
  grey.convertTo(grey8, CV_8U, (image.depth() == CV_8U ? 1.0 : 1.0 / 257.0) * 0.6);
  cv::Mat out;
  cv::cvtColor(grey8, out, cv::COLOR_GRAY2BGR);

  const double size = std::max(out.cols, out.rows);
  const int radius = std::max(6, static_cast<int>(std::lround(size / 250.0)));
  const int thickness = std::max(1, radius / 6);
  const double font = std::max(0.4, size / 2500.0);

  for (const Eigen::Vector2d& p : overlay.rejected_px) {
    cv::drawMarker(out, ToPoint(p), kRejectedColour, cv::MARKER_CROSS, radius, thickness,
                   cv::LINE_AA);
  }
  int counts[3] = {0, 0, 0};
  for (const ShotOverlay::Spot& s : overlay.spots) {
    const cv::Scalar& colour = s.state == ShotOverlay::SpotState::kIdentified ? kIdentifiedColour
                               : s.state == ShotOverlay::SpotState::kMatched  ? kMatchedColour
                                                                              : kDetectedColour;
    ++counts[static_cast<int>(s.state)];
    cv::circle(out, ToPoint(s.center_px), radius, colour, thickness, cv::LINE_AA);
    if (!s.label.empty()) {
      Label(&out, s.label, ToPoint(s.center_px) + cv::Point(radius + 2, -radius - 2), 0.6 * font,
            colour, thickness);
    }
  }
  for (const ShotOverlay::Tag& t : overlay.tags) {
    std::vector<cv::Point> quad;
    for (const Eigen::Vector2d& c : t.corners_px) quad.push_back(ToPoint(c));
    cv::polylines(out, quad, true, kTagColour, thickness + 1, cv::LINE_AA);
    cv::circle(out, quad[0], radius / 2 + 1, kTagColour, cv::FILLED, cv::LINE_AA);
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& c : t.corners_px) centre += c / 4.0;
    Label(&out, std::to_string(t.id), ToPoint(centre), font, kTagColour, thickness + 1);
  }

  // Caption: what was found, and the legend.
  const std::string caption =
      overlay.title + ": " + std::to_string(overlay.tags.size()) + " tags (cyan), " +
      std::to_string(counts[2]) + " identified (green), " + std::to_string(counts[1]) +
      " matched (yellow), " + std::to_string(counts[0]) + " unmatched (orange), " +
      std::to_string(overlay.rejected_px.size()) + " rejected blobs (red x)";
  int baseline = 0;
  const cv::Size text = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, font, thickness, &baseline);
  cv::rectangle(out, cv::Rect(0, 0, out.cols, text.height + baseline + 2 * radius),
                cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(out, caption, cv::Point(radius, text.height + radius), cv::FONT_HERSHEY_SIMPLEX, font,
              cv::Scalar(255, 255, 255), thickness, cv::LINE_AA);
  return out;
}

}  // namespace opl
