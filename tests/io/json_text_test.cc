// CompactNumberArrays (json_text.h): number arrays on one line, everything
// else (nested arrays, objects, strings with brackets and escapes) as written.
#include "opl/io/json_text.h"

#include <string>

#include <gtest/gtest.h>

namespace opl {
namespace {

TEST(CompactNumberArraysTest, NumberArraysOnOneLine) {
  EXPECT_EQ(CompactNumberArrays("[\n  [\n    1,\n    2\n  ],\n  \"a\"\n]"),
            "[\n  [1, 2],\n  \"a\"\n]");
  EXPECT_EQ(CompactNumberArrays("{\n  \"v\": [\n    -1.5e-07,\n    2E3,\n    0\n  ]\n}"),
            "{\n  \"v\": [-1.5e-07, 2E3, 0]\n}");
  // Arrays of objects, of strings, with null, and empty arrays stay.
  EXPECT_EQ(CompactNumberArrays("[\n  {\n    \"a\": 1\n  }\n]"), "[\n  {\n    \"a\": 1\n  }\n]");
  EXPECT_EQ(CompactNumberArrays("[\n  1,\n  null\n]"), "[\n  1,\n  null\n]");
  EXPECT_EQ(CompactNumberArrays("[]"), "[]");
  // Inside a string nothing changes, escaped quotes included.
  const std::string text = "{\n  \"s\": \"[\\n 1,\\n 2\\n] \\\" [\\n 3\\n]\",\n  \"t\": [\n    4\n  ]\n}";
  EXPECT_EQ(CompactNumberArrays(text),
            "{\n  \"s\": \"[\\n 1,\\n 2\\n] \\\" [\\n 3\\n]\",\n  \"t\": [4]\n}");
}

}  // namespace
}  // namespace opl
