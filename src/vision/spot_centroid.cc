// A spot's window and its intensity-weighted centroid over it (DetectSpots'
// first estimate of a spot, and its fallback when the Gaussian fit fails).
#include <algorithm>
#include <cmath>

#include "vision/spot_detection_internal.h"

namespace opl {
namespace spot_internal {

Window MakeWindow(double u, double v, int half, int width, int height) {
  const int cu = static_cast<int>(std::lround(u));
  const int cv_ = static_cast<int>(std::lround(v));
  Window w{cu - half, cv_ - half, cu + half, cv_ + half, false};
  if (w.x0 < 0 || w.y0 < 0 || w.x1 >= width || w.y1 >= height) w.clipped = true;
  w.x0 = std::max(w.x0, 0);
  w.y0 = std::max(w.y0, 0);
  w.x1 = std::min(w.x1, width - 1);
  w.y1 = std::min(w.y1, height - 1);
  return w;
}

// Intensity-weighted centroid of (image - background) over window w.
CentroidResult Centroid(const cv::Mat& img, const LocalBackground& bg, const Window& w, double noise,
                        double gain) {
  CentroidResult r;
  double s = 0, su = 0, sv = 0, suu = 0, suv = 0, svv = 0, peak = -1e300;
  for (int y = w.y0; y <= w.y1; ++y) {
    const PixRow row(img, y);
    for (int x = w.x0; x <= w.x1; ++x) {
      const double val = row[x] - bg.At(x, y);
      s += val;
      su += val * x;
      sv += val * y;
      suu += val * x * x;
      suv += val * x * y;
      svv += val * y * y;
      peak = std::max(peak, val);
    }
  }
  if (!(s > 0)) return r;
  r.u = su / s;
  r.v = sv / s;
  r.flux = s;
  r.peak = peak;
  r.shape << suu / s - r.u * r.u, suv / s - r.u * r.v, suv / s - r.u * r.v, svv / s - r.v * r.v;
  // Propagated noise: du/dI_i = (x_i - u) / F.
  double cuu = 0, cuv = 0, cvv = 0;
  for (int y = w.y0; y <= w.y1; ++y) {
    const PixRow row(img, y);
    for (int x = w.x0; x <= w.x1; ++x) {
      double var = noise * noise;
      if (gain > 0) var += std::max(0.0, row[x] - bg.At(x, y)) / gain;
      const double du = x - r.u, dv = y - r.v;
      cuu += du * du * var;
      cuv += du * dv * var;
      cvv += dv * dv * var;
    }
  }
  r.covariance << cuu, cuv, cuv, cvv;
  r.covariance /= s * s;
  r.ok = std::isfinite(r.u) && std::isfinite(r.v);
  return r;
}

}  // namespace spot_internal
}  // namespace opl
