#include "opl/vision/dark_frame.h"

#include <algorithm>
#include <limits>
#include <map>

namespace opl {

double TagShiftPx(const std::vector<TagDetection>& a, const std::vector<TagDetection>& b,
                  int* common_tags) {
  std::map<int, const TagDetection*> by_id;
  for (const TagDetection& t : b) by_id[t.id] = &t;
  std::vector<double> shifts;
  int common = 0;
  for (const TagDetection& t : a) {
    const auto it = by_id.find(t.id);
    if (it == by_id.end()) continue;
    ++common;
    for (int c = 0; c < 4; ++c) shifts.push_back((t.corners_px[c] - it->second->corners_px[c]).norm());
  }
  if (common_tags != nullptr) *common_tags = common;
  if (shifts.empty()) return std::numeric_limits<double>::infinity();
  const size_t mid = shifts.size() / 2;
  std::nth_element(shifts.begin(), shifts.begin() + static_cast<std::ptrdiff_t>(mid), shifts.end());
  return shifts[mid];
}

Result<cv::Mat> SubtractDarkFrame(const cv::Mat& lit, const cv::Mat& dark,
                                  double saturation_dn) {
  if (lit.type() != dark.type() || lit.size() != dark.size()) {
    return Status::InvalidArgument("the dark frame is " + std::to_string(dark.cols) + " x " +
                                   std::to_string(dark.rows) + " (type " +
                                   std::to_string(dark.type()) + "), the lit image " +
                                   std::to_string(lit.cols) + " x " + std::to_string(lit.rows) +
                                   " (type " + std::to_string(lit.type()) + ")");
  }
  if (lit.type() != CV_8UC1 && lit.type() != CV_16UC1) {
    return Status::InvalidArgument("dark frame subtraction needs CV_8UC1 or CV_16UC1 images");
  }
  const bool eight = lit.depth() == CV_8U;
  const double saturation = saturation_dn > 0.0 ? saturation_dn : (eight ? 255.0 : 65535.0);
  const int offset = eight ? 256 : 4096;
  const double near_saturation = 0.9 * saturation;
  cv::Mat out(lit.size(), CV_16UC1);
  for (int y = 0; y < lit.rows; ++y) {
    uint16_t* o = out.ptr<uint16_t>(y);
    for (int x = 0; x < lit.cols; ++x) {
      const int l = eight ? lit.ptr<uint8_t>(y)[x] : lit.ptr<uint16_t>(y)[x];
      const int d = eight ? dark.ptr<uint8_t>(y)[x] : dark.ptr<uint16_t>(y)[x];
      if (l >= saturation) {
        // Saturated with the lasers off too, or nearly (a lamp's rim, where
        // noise tips the pixel over in one frame and not the other):
        // whatever is there hides any laser.
        o[x] = d >= near_saturation ? static_cast<uint16_t>(offset) : 65535;
      } else {
        o[x] = static_cast<uint16_t>(std::clamp(l - d + offset, 0, 65534));
      }
    }
  }
  return out;
}

}  // namespace opl
