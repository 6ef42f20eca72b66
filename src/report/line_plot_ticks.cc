// Tick values and labels of the line plots' axes.
#include "opl/report/line_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "opl/core/format.h"

namespace opl {
namespace {

// m * 10^e, correctly rounded when m is an exact integer (|m| < 2^53) and
// |e| <= 22 (the powers of ten that are exact doubles): 3 * 10^-1 is the
// double nearest 0.3, not 0.30000000000000004.
double Scaled(double m, int e) {
  static const std::array<double, 23> kPow = [] {
    std::array<double, 23> p{};
    p[0] = 1;
    for (size_t i = 1; i < p.size(); ++i) p[i] = p[i - 1] * 10;
    return p;
  }();
  if (e >= 0) return e <= 22 ? m * kPow[static_cast<size_t>(e)] : m * std::pow(10.0, e);
  return -e <= 22 ? m / kPow[static_cast<size_t>(-e)] : m * std::pow(10.0, e);
}

// lo <= v <= hi up to a relative 1e-12 (0 < lo < hi; for log ticks).
bool InRange(double v, double lo, double hi) {
  return v >= lo * (1 - 1e-12) && v <= hi * (1 + 1e-12);
}

}  // namespace

std::vector<double> NiceTicks(double lo, double hi, int max_ticks) {
  std::vector<double> ticks;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi) || max_ticks < 1) return ticks;
  const double span = hi - lo;
  if (!std::isfinite(span)) return ticks;
  int e = static_cast<int>(std::floor(std::log10(span / max_ticks))) - 1;
  static const int kMantissas[] = {1, 2, 5};
  for (int iter = 0; iter < 40; ++iter, ++e) {
    for (int m : kMantissas) {
      const double step = Scaled(m, e);
      const double k_lo = std::ceil(lo / step - 1e-9);
      const double k_hi = std::floor(hi / step + 1e-9);
      if (k_hi - k_lo + 1 > max_ticks) continue;
      const int count = static_cast<int>(k_hi - k_lo + 1);  // a counter: k += 1 can stall
      for (int i = 0; i < count; ++i) {                     // beyond 2^53
        const double k = k_lo + i;
        // Exact integer k * m when small enough, then one rounding.
        ticks.push_back(std::fabs(k) < 1e15 ? Scaled(k * m, e) : k * step);
      }
      return ticks;
    }
  }
  return ticks;
}

LogTicks NiceLogTicks(double lo, double hi, int max_ticks) {
  LogTicks out;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo > 0) || !(lo < hi) || max_ticks < 1) {
    return out;
  }
  const double a = std::log10(lo);
  const double b = std::log10(hi);
  const int k0 = static_cast<int>(std::floor(a)) - 1;
  const int k1 = static_cast<int>(std::ceil(b)) + 1;
  struct Candidate {
    double value;
    int mantissa;
    int exponent;
  };
  std::vector<Candidate> all;
  for (int k = k0; k <= k1; ++k) {
    for (int m = 1; m <= 9; ++m) {
      const double v = Scaled(m, k);
      if (InRange(v, lo, hi)) all.push_back({v, m, k});
    }
  }
  std::vector<double> decades, one_two_five, every;
  for (const Candidate& c : all) {
    every.push_back(c.value);
    if (c.mantissa == 1) decades.push_back(c.value);
    if (c.mantissa == 1 || c.mantissa == 2 || c.mantissa == 5) one_two_five.push_back(c.value);
  }
  const auto n = [](const std::vector<double>& v) { return static_cast<int>(v.size()); };
  const double span = b - a;
  if (span >= 2 - 1e-9) {
    for (int every_m = 1;; ++every_m) {
      std::vector<double> major;
      for (const Candidate& c : all) {
        if (c.mantissa == 1 && c.exponent % every_m == 0) major.push_back(c.value);
      }
      if (n(major) <= max_ticks || every_m > 400) {
        out.major = std::move(major);
        break;
      }
    }
    for (const Candidate& c : all) {
      const bool is_major =
          std::find(out.major.begin(), out.major.end(), c.value) != out.major.end();
      if (is_major) continue;
      if (c.mantissa == 1 || span <= 8 + 1e-9) out.minor.push_back(c.value);
    }
    return out;
  }
  // Enough labels to read the axis: three or more when they fit (10..45
  // gets 10, 20, 30, 40, not just 10 and 20), else two.
  const auto fits = [&](const std::vector<double>& v, int at_least) {
    return n(v) >= at_least && n(v) <= max_ticks;
  };
  if (fits(one_two_five, 3)) {
    out.major = one_two_five;
  } else if (fits(every, 3)) {
    out.major = every;
  } else if (fits(one_two_five, 2)) {
    out.major = one_two_five;
  } else if (fits(decades, 2)) {
    out.major = decades;
  } else if (fits(every, 2)) {
    out.major = every;
  } else {
    out.major = NiceTicks(lo, hi, max_ticks);
  }
  for (double v : every) {
    if (std::find(out.major.begin(), out.major.end(), v) == out.major.end()) {
      out.minor.push_back(v);
    }
  }
  return out;
}

namespace {

// "2.5e-05" -> "2.5e-5", "1e+06" -> "1e6".
std::string CleanExponent(std::string s) {
  const size_t e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mantissa = s.substr(0, e);
  std::string exponent = s.substr(e + 1);
  std::string sign;
  if (!exponent.empty() && (exponent[0] == '+' || exponent[0] == '-')) {
    if (exponent[0] == '-') sign = "-";
    exponent = exponent.substr(1);
  }
  while (exponent.size() > 1 && exponent[0] == '0') exponent = exponent.substr(1);
  return mantissa + "e" + sign + exponent;
}

}  // namespace

std::string FormatTickLabel(double value, double step) {
  if (value == 0) return "0";
  if (!std::isfinite(value)) return FormatNumber(value);
  char buf[64];
  if (step > 0 && std::isfinite(step)) {
    const int e = static_cast<int>(std::floor(std::log10(step) + 1e-9));
    const int decimals = std::max(0, -e);
    if (std::fabs(value) < 1e6 && decimals <= 4) {
      std::snprintf(buf, sizeof(buf), "%.*f", decimals, value);
      return buf;
    }
    const int digits = static_cast<int>(std::floor(std::log10(std::fabs(value)) + 1e-9)) - e + 1;
    std::snprintf(buf, sizeof(buf), "%.*e", std::clamp(digits, 1, 15) - 1, value);
    return CleanExponent(buf);
  }
  std::snprintf(buf, sizeof(buf), "%.6g", value);
  return CleanExponent(buf);
}

}  // namespace opl
