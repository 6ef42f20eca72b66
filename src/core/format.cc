#include "opl/core/format.h"

#include <cstdio>

namespace opl {

std::string FormatNumber(double value, int significant_digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", significant_digits, value);
  return buf;
}

}  // namespace opl
