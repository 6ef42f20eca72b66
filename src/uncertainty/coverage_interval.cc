#include "opl/uncertainty/coverage_interval.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace opl {

int CoverageIndexQ(int num_values, double probability) {
  const double pm = probability * static_cast<double>(num_values);
  const double rounded = std::round(pm);
  // p M is "an integer" when it is one to rounding (0.95 * 100 = 95.000000000000014).
  if (std::fabs(pm - rounded) <= 1e-9 * std::max(1.0, pm)) return static_cast<int>(rounded);
  return static_cast<int>(std::floor(pm + 0.5));
}

Result<CoverageInterval> CoverageIntervalOfSorted(const std::vector<double>& sorted,
                                                  double probability,
                                                  CoverageIntervalKind kind) {
  if (!(probability > 0.0 && probability < 1.0)) {
    return Status::InvalidArgument("coverage probability must be in (0, 1), got " +
                                   std::to_string(probability));
  }
  const int m = static_cast<int>(sorted.size());
  const int q = CoverageIndexQ(m, probability);
  if (m - q < 1) {
    return Status::InvalidArgument(
        "too few values for a " + std::to_string(probability * 100.0) + " % coverage interval: " +
        std::to_string(m) + " values give q = " + std::to_string(q) + ", need M - q >= 1");
  }
  int r = 0;
  if (kind == CoverageIntervalKind::kProbabilisticallySymmetric) {
    r = ((m - q) % 2 == 0) ? (m - q) / 2 : (m - q + 1) / 2;
  } else {
    r = 1;
    double best = sorted[static_cast<size_t>(r + q - 1)] - sorted[static_cast<size_t>(r - 1)];
    for (int k = 2; k <= m - q; ++k) {
      const double width = sorted[static_cast<size_t>(k + q - 1)] - sorted[static_cast<size_t>(k - 1)];
      if (width < best) {
        best = width;
        r = k;
      }
    }
  }
  CoverageInterval interval;
  interval.r = r;
  interval.q = q;
  interval.low = sorted[static_cast<size_t>(r - 1)];
  interval.high = sorted[static_cast<size_t>(r + q - 1)];
  return interval;
}

Result<CoverageInterval> ComputeCoverageInterval(const std::vector<double>& values,
                                                 double probability,
                                                 CoverageIntervalKind kind) {
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return Status::InvalidArgument("value " + std::to_string(i) + " is not finite");
    }
  }
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  return CoverageIntervalOfSorted(sorted, probability, kind);
}

}  // namespace opl
