// The sequencer's per-frame metadata read back: the lines of docs/sequencer.md
// (and the sequencer's own writer in tests/apps/scene_cli_test.cc), blank
// lines, manual triggers, and each kind of bad line with its one-line message.
#include "opl/io/frame_metadata_jsonl.h"

#include <string>

#include <gtest/gtest.h>

namespace opl {
namespace {

const std::string kGridA =
    R"({"t_ns":591826816602,"time":"2026-11-22T00:36:12.486753Z","sequence":"measurement",)"
    R"("run":1,"slice":0,"step":"grid_a","step_index":0,"frame":0,"lasers":{"a":true,"b":false},"blocker":"closed"})";

std::string Message(const std::string& text) {
  Result<std::vector<FrameMetadata>> r = ParseFrameMetadataJsonl(text, "f.jsonl");
  return r.ok() ? std::string("OK") : r.status().message();
}

TEST(FrameMetadataJsonl, ReadsTheSequencersLines) {
  const std::string manual =
      R"({"t_ns":7,"time":"x","sequence":"manual","run":2,"slice":null,"step":"manual","step_index":null,)"
      R"("frame":0,"lasers":{"a":false,"b":false},"blocker":"open","future_field":[1,2]})";
  Result<std::vector<FrameMetadata>> r = ParseFrameMetadataJsonl(kGridA + "\n\n  \r\n" + manual + "\r\n", "f.jsonl");
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r->size(), 2u);
  const FrameMetadata& a = (*r)[0];
  EXPECT_EQ(a.line, 1);
  EXPECT_EQ(a.sequence, "measurement");
  EXPECT_EQ(a.run, 1);
  EXPECT_EQ(a.slice, 0);
  EXPECT_EQ(a.step, "grid_a");
  EXPECT_EQ(a.step_index, 0);
  EXPECT_EQ(a.frame, 0);
  EXPECT_EQ(a.t_ns, 591826816602LL);
  EXPECT_EQ(a.time, "2026-11-22T00:36:12.486753Z");
  EXPECT_EQ(a.LasersOn(), std::vector<std::string>{"a"});
  const FrameMetadata& m = (*r)[1];
  EXPECT_EQ(m.line, 4);  // blank lines count
  EXPECT_EQ(m.sequence, "manual");
  EXPECT_FALSE(m.slice.has_value());
  EXPECT_FALSE(m.step_index.has_value());
  EXPECT_TRUE(m.LasersOn().empty());
}

TEST(FrameMetadataJsonl, BadLinesAreNamed) {
  EXPECT_EQ(Message(""), "f.jsonl: no frame (the file holds no metadata line)");
  EXPECT_EQ(Message("\n \n"), "f.jsonl: no frame (the file holds no metadata line)");
  EXPECT_EQ(Message(kGridA + "\n{\"run\":1"), "f.jsonl:2:9: invalid JSON: syntax error while parsing object - "
                                              "unexpected end of input; expected '}'");
  EXPECT_EQ(Message("{\"run\": 1e999}"),
            "f.jsonl:1: invalid JSON: number overflow parsing '1e999'");
  EXPECT_EQ(Message("[1]"), "f.jsonl:1: expected a JSON object, got [1]");
  EXPECT_EQ(Message(R"({"run":1,"frame":0,"slice":0,"lasers":{"a":true}})"), "f.jsonl:1: sequence: missing field");
  EXPECT_EQ(Message(R"({"sequence":"measure","run":1,"frame":0,"slice":0,"lasers":{"a":true}})"),
            "f.jsonl:1: sequence: expected \"measurement\", \"calibration\" or \"manual\", got \"measure\"");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":0,"frame":0,"slice":0,"lasers":{"a":true}})"),
            "f.jsonl:1: run: must be >= 1, got 0");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":"0","slice":0,"lasers":{"a":true}})"),
            "f.jsonl:1: frame: expected an integer, got \"0\"");
  EXPECT_EQ(Message(R"({"sequence":"calibration","run":1,"frame":0,"slice":null,"lasers":{"a":true}})"),
            "f.jsonl:1: slice: missing or null in a calibration frame (only manual triggers have none)");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":0,"slice":-1,"lasers":{"a":true}})"),
            "f.jsonl:1: slice: must be >= 0 or null, got -1");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":0,"slice":0,"lasers":{"a":1}})"),
            "f.jsonl:1: lasers.a: expected true or false, got 1");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":0,"slice":0,"lasers":{}})"),
            "f.jsonl:1: lasers: expected an object of laser name: true/false (at least one), got {}");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":0,"slice":0})"), "f.jsonl:1: lasers: missing field");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":0,"slice":0,"step_index":4,"lasers":{"a":true}})"),
            "f.jsonl:1: step_index: must be 0..3 or null, got 4");
  EXPECT_EQ(Message(R"({"sequence":"measurement","run":1,"frame":0,"slice":0,"blocker":"half","lasers":{"a":true}})"),
            "f.jsonl:1: blocker: expected \"open\" or \"closed\", got \"half\"");
}

}  // namespace
}  // namespace opl
