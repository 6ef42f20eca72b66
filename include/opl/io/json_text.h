// Text-level touches to JSON that a writer has already formatted.
#pragma once

#include <string>

namespace opl {

// nlohmann's indented dump puts every array element on its own line; a
// vector of numbers reads better on one. Every array whose elements are all
// numbers becomes "[0.0, 27.5, 0.0]" (its numbers' text kept as written);
// other arrays, objects and string literals (escapes included) are copied
// untouched. E.g. "[\n  [\n    1,\n    2\n  ],\n  \"a\"\n]" becomes
// "[\n  [1, 2],\n  \"a\"\n]". Linear in the text's length.
std::string CompactNumberArrays(const std::string& json_text);

}  // namespace opl
