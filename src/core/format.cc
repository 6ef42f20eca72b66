#include "opl/core/format.h"

#include <cstdio>

namespace opl {

std::string FormatNumber(double value, int significant_digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", significant_digits, value);
  return buf;
}

std::string FormatPrintf(const char* fmt, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), fmt, value);
  return buffer;
}

}  // namespace opl
