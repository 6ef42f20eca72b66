#include "opl/vision/dark_frame.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

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

namespace {

Status CheckFramePair(const cv::Mat& lit, const cv::Mat& dark) {
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
  return Status::Ok();
}

double FullScale(int depth) { return depth == CV_8U ? 255.0 : 65535.0; }

double Saturation(int depth, double saturation_dn) {
  return saturation_dn > 0.0 ? saturation_dn : FullScale(depth);
}

int PixelAt(const cv::Mat& m, int y, int x) {
  return m.depth() == CV_8U ? m.ptr<uint8_t>(y)[x] : m.ptr<uint16_t>(y)[x];
}

double MedianOf(std::vector<double>* v) {
  const size_t mid = v->size() / 2;
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(mid), v->end());
  return (*v)[mid];
}

}  // namespace

Result<DarkFrameGain> EstimateDarkFrameGain(const cv::Mat& lit, const cv::Mat& dark,
                                            double saturation_dn) {
  OPL_RETURN_IF_ERROR(CheckFramePair(lit, dark));
  const double near_saturation = 0.9 * Saturation(lit.depth(), saturation_dn);
  const double pixels = static_cast<double>(lit.rows) * lit.cols;
  const int stride = std::max(1, static_cast<int>(std::sqrt(pixels / 5e5)));
  std::vector<double> l, d;
  for (int y = stride / 2; y < lit.rows; y += stride) {
    for (int x = stride / 2; x < lit.cols; x += stride) {
      const int a = PixelAt(lit, y, x), b = PixelAt(dark, y, x);
      if (a >= near_saturation || b >= near_saturation) continue;
      l.push_back(a);
      d.push_back(b);
    }
  }
  constexpr int kMinSamples = 1000;
  const auto too_few = [&](size_t n) {
    return Status::NoSolution("dark frame exposure: " + std::to_string(n) +
                              " usable pixels sampled, at least " + std::to_string(kMinSamples) +
                              " needed (saturated or black frames)");
  };
  if (l.size() < static_cast<size_t>(kMinSamples)) return too_few(l.size());
  DarkFrameGain out;
  double sum_l = 0.0, sum_d = 0.0;
  for (size_t i = 0; i < l.size(); ++i) {
    sum_l += l[i];
    sum_d += d[i];
  }
  if (!(sum_d > 0.0)) {
    return Status::NoSolution("dark frame exposure: the laser-off frame is black where sampled");
  }
  out.gain = sum_l / sum_d;
  out.samples = static_cast<int>(l.size());
  std::vector<double> residual(l.size());
  for (int round = 0; round < 2; ++round) {
    for (size_t i = 0; i < l.size(); ++i) residual[i] = std::abs(l[i] - out.gain * d[i]);
    std::vector<double> scratch = residual;
    out.residual_sigma_dn = 1.4826 * MedianOf(&scratch);
    const double keep = std::max(5.0 * out.residual_sigma_dn, 1.0);
    sum_l = sum_d = 0.0;
    int kept = 0;
    for (size_t i = 0; i < l.size(); ++i) {
      if (residual[i] > keep) continue;
      sum_l += l[i];
      sum_d += d[i];
      ++kept;
    }
    if (kept < kMinSamples) return too_few(static_cast<size_t>(kept));
    if (!(sum_d > 0.0)) {
      return Status::NoSolution("dark frame exposure: the laser-off frame is black where sampled");
    }
    out.gain = sum_l / sum_d;
    out.samples = kept;
  }
  const size_t p95 = static_cast<size_t>(0.95 * static_cast<double>(d.size() - 1));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(p95), d.end());
  out.mismatch_dn = std::abs(out.gain - 1.0) * d[p95];
  return out;
}

bool DarkFrameGainMatters(const DarkFrameGain& g, int image_depth) {
  const double step = 0.25 * FullScale(image_depth) / 255.0;
  return g.mismatch_dn >= std::max(0.3 * g.residual_sigma_dn, step);
}

Result<cv::Mat> SubtractDarkFrame(const cv::Mat& lit, const cv::Mat& dark, double saturation_dn,
                                  double gain) {
  OPL_RETURN_IF_ERROR(CheckFramePair(lit, dark));
  if (!(gain > 0.0 && gain <= 16.0)) {
    return Status::InvalidArgument("dark frame gain must be in (0, 16], got " + std::to_string(gain));
  }
  const bool eight = lit.depth() == CV_8U;
  const double saturation = Saturation(lit.depth(), saturation_dn);
  const int offset = eight ? 256 * std::max(1, static_cast<int>(std::ceil(gain))) : 4096;
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
        o[x] = gain * d >= near_saturation ? static_cast<uint16_t>(offset) : 65535;
      } else if (gain == 1.0) {
        o[x] = static_cast<uint16_t>(std::clamp(l - d + offset, 0, 65534));
      } else {
        const long v = std::lround(l - gain * d) + offset;
        o[x] = static_cast<uint16_t>(std::clamp(v, 0L, 65534L));
      }
    }
  }
  return out;
}

}  // namespace opl
