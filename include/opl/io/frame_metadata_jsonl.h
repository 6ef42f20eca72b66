// The sequencer's per-frame metadata (docs/sequencer.md, "Per-frame metadata";
// written by opl::sequencer::Sequencer, one JSON object a line, one line per
// camera trigger):
//
//   {"t_ns":591826816602,"time":"2026-11-22T00:36:12.486753Z","sequence":"measurement",
//    "run":1,"slice":0,"step":"grid_a","step_index":0,"frame":0,
//    "lasers":{"a":true,"b":false},"blocker":"closed"}
//
// Read here without the sequencer library (which needs libgpiod), so that
// `opl_scene init` can turn a session's frames into a scene's shots.
//
// Rules: blank lines are skipped; every other line is one JSON object with
// `sequence` ("measurement", "calibration" or "manual"), `run` (integer >= 1),
// `frame` (integer >= 0), `lasers` (an object: laser name -> true/false, at
// least one laser) required; `slice` (integer >= 0 or null; null only for a
// manual trigger), `step` (string), `step_index` (integer 0..3 or null),
// `t_ns` (integer), `time` (string), `blocker` ("open" or "closed") optional
// and checked when present. Unknown fields are allowed (a newer sequencer may
// add some; the schema docs/schemas/sequencer_frame.schema.json says the
// same). Errors are ParseErrors of one line naming the file, the line and the
// field: "frames.jsonl:3: lasers.a: expected true or false, got 1".
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "opl/core/status.h"

namespace opl {

struct FrameMetadata {
  int line = 0;                     // 1-based line of the file
  std::string sequence;             // "measurement", "calibration" or "manual"
  int run = 0;                      // the daemon's run counter, >= 1
  std::optional<int> slice;         // calibration slice (0 in a measurement); none when manual
  std::string step;                 // "grid_a", "grid_b", "both", "dark", "manual" (may be empty)
  std::optional<int> step_index;    // 0..3 in a sequence
  int frame = 0;                    // frame number within the run
  std::optional<int64_t> t_ns;      // CLOCK_MONOTONIC at the trigger
  std::string time;                 // UTC wall time (may be empty)
  std::map<std::string, bool> lasers;  // laser name ("a", "b") -> on

  // The names of the lasers that were on, sorted.
  std::vector<std::string> LasersOn() const;
};

// Reads every line of a metadata file (at least one frame).
Result<std::vector<FrameMetadata>> ReadFrameMetadataJsonl(const std::string& path);
// The same from text; `name_for_messages` starts every message.
Result<std::vector<FrameMetadata>> ParseFrameMetadataJsonl(const std::string& text,
                                                           const std::string& name_for_messages);

}  // namespace opl
