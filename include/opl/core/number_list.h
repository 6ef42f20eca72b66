// Lists of numbers as the command lines take them (depths of calibration
// screens, values of a design sweep).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "opl/core/status.h"

namespace opl {

inline constexpr size_t kMaxValues = 10000;

// What the messages call the numbers, and the examples they give.
struct NumberListSyntax {
  std::string noun = "value";              // "value list '...'", "more than 10000 values"
  std::string range_example = "0.05:0.05:0.3";
  std::string list_example = "0.05,0.1,0.2";
};

// Parses
//   "first:step:last"  first, first + step, ... up to last (included when it is
//                      reached within 1e-9 relative; the last value is then
//                      exactly `last`); step > 0, first <= last;
//   "v1,v2,..."        the numbers as given (any order); one number is a list of one.
// Numbers are decimal (locale-independent) and finite; spaces around them are
// allowed. At most kMaxValues values. Errors: InvalidArgument, one line naming
// the text, e.g. "value list '1:x:3': 'x' is not a finite number".
Result<std::vector<double>> ParseNumberList(const std::string& text,
                                            const NumberListSyntax& syntax = NumberListSyntax());

}  // namespace opl
