// The background and noise model of DetectSpots: BlockGrid, per-block values
// interpolated bilinearly between the block centres, and Median.
#include <algorithm>
#include <cstddef>
#include <vector>

#include "vision/spot_detection_internal.h"

namespace opl {
namespace spot_internal {

double BlockGrid::At(double u, double v) const {
  double bx, by;
  int x0, y0, x1, y1;
  Coordinate(u, width_, values_.cols, &x0, &x1, &bx);
  Coordinate(v, height_, values_.rows, &y0, &y1, &by);
  const double a = values_.at<float>(y0, x0), b = values_.at<float>(y0, x1);
  const double c = values_.at<float>(y1, x0), d = values_.at<float>(y1, x1);
  return (1 - by) * ((1 - bx) * a + bx * b) + by * ((1 - bx) * c + bx * d);
}

void BlockGrid::PrepareRow(int v) {
  if (col_t_.empty()) {
    col_i0_.resize(static_cast<size_t>(width_));
    col_i1_.resize(static_cast<size_t>(width_));
    col_t_.resize(static_cast<size_t>(width_));
    for (int u = 0; u < width_; ++u) {
      const size_t k = static_cast<size_t>(u);
      Coordinate(u, width_, values_.cols, &col_i0_[k], &col_i1_[k], &col_t_[k]);
    }
  }
  if (v == row_v_) return;
  double by;
  int y0, y1;
  Coordinate(v, height_, values_.rows, &y0, &y1, &by);
  row_.resize(static_cast<size_t>(values_.cols));
  for (int x = 0; x < values_.cols; ++x) {
    row_[static_cast<size_t>(x)] =
        (1 - by) * values_.at<float>(y0, x) + by * values_.at<float>(y1, x);
  }
  row_v_ = v;
}

void BlockGrid::Row(int v, std::vector<float>* out) {
  PrepareRow(v);
  out->resize(static_cast<size_t>(width_));
  for (int u = 0; u < width_; ++u) (*out)[static_cast<size_t>(u)] = ValueInRow(u);
}

void BlockGrid::RowSpan(int v, int u0, int u1, float* out) {
  PrepareRow(v);
  for (int u = u0; u < u1; ++u) out[u - u0] = ValueInRow(u);
}

double BlockGrid::Centre(int b, int size) const {
  const int lo = b * block_;
  const int hi = std::min((b + 1) * block_, size);
  return 0.5 * (lo + hi - 1);
}

void BlockGrid::Coordinate(double p, int size, int n, int* i0, int* i1, double* t) const {
  if (n == 1 || p <= Centre(0, size)) {
    *i0 = *i1 = 0;
    *t = 0;
    return;
  }
  if (p >= Centre(n - 1, size)) {
    *i0 = *i1 = n - 1;
    *t = 0;
    return;
  }
  int b = std::min(n - 2, static_cast<int>(p / block_));
  if (p < Centre(b, size)) --b;
  b = std::clamp(b, 0, n - 2);
  *i0 = b;
  *i1 = b + 1;
  const double c0 = Centre(b, size), c1 = Centre(b + 1, size);
  *t = std::clamp((p - c0) / (c1 - c0), 0.0, 1.0);
}

double Median(std::vector<float>* v) {
  if (v->empty()) return 0.0;
  const size_t mid = v->size() / 2;
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(mid), v->end());
  return (*v)[mid];
}

}  // namespace spot_internal
}  // namespace opl
