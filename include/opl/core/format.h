// Number formatting for messages and reports, and the constants the modules
// share.
#pragma once

#include <string>

#include <Eigen/Core>

namespace opl {

inline constexpr double kPi = 3.14159265358979323846;

// printf("%.<significant_digits>g"): 17 digits round-trip a double exactly;
// 10 read well in messages.
std::string FormatNumber(double value, int significant_digits = 10);

// The shortest decimal text that reads back as exactly `value` (std::to_chars):
// "0.1", "55.154328932550705", "1e-05".
std::string FormatRoundTrip(double value);

// "(x, y, z)", each printf(fmt, .) as FormatPrintf, e.g. FormatTriple("%.4f", v).
std::string FormatTriple(const char* fmt, const Eigen::Vector3d& v);

// printf(fmt, value) for one double, e.g. FormatPrintf("%.4f", x), for reports.
std::string FormatPrintf(const char* fmt, double value);

}  // namespace opl
