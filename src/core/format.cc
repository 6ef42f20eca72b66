#include "opl/core/format.h"

#include <charconv>
#include <cstdio>

namespace opl {

std::string FormatNumber(double value, int significant_digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", significant_digits, value);
  return buf;
}

std::string FormatRoundTrip(double value) {
  char buffer[64];
  const std::to_chars_result r = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, r.ptr);
}

std::string FormatPrintf(const char* fmt, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), fmt, value);
  return buffer;
}

std::string FormatTriple(const char* fmt, const Eigen::Vector3d& v) {
  return "(" + FormatPrintf(fmt, v.x()) + ", " + FormatPrintf(fmt, v.y()) + ", " +
         FormatPrintf(fmt, v.z()) + ")";
}

}  // namespace opl
