// Test support for the rendered figures: an RGB colour that prints itself in
// failures, and the colour of a pixel of a decoded (BGR) image.
#pragma once

#include <ostream>

#include <opencv2/core.hpp>

namespace opl::test {

struct Rgb {
  int r, g, b;
  bool operator==(const Rgb& o) const { return r == o.r && g == o.g && b == o.b; }
  bool operator!=(const Rgb& o) const { return !(*this == o); }
};

inline std::ostream& operator<<(std::ostream& os, const Rgb& c) {
  return os << "RGB(" << c.r << "," << c.g << "," << c.b << ")";
}

inline Rgb PixelAt(const cv::Mat& img, int x, int y) {
  const cv::Vec3b bgr = img.at<cv::Vec3b>(y, x);
  return Rgb{bgr[2], bgr[1], bgr[0]};
}

}  // namespace opl::test
