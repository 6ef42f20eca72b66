// Fuzzing the sequencer daemon's configuration reader (issue 19: "the
// sequencer configuration is not fuzzed"; docs/testing.md, "Fuzzing"). The
// seeds are the example configurations (tests/fuzz/corpus/sequencer_config/,
// copies of examples/sequencer/); each seed and a few hundred seeded mutations
// go through LoadConfig as a file. It must come back with a valid
// configuration (IsValid) or a one-line, bounded message naming the file;
// nothing may throw, crash or hang.
#include <string>

#include <gtest/gtest.h>

#include "fuzz/fuzz_harness.h"
#include "io/temp_dir.h"
#include "opl/sequencer/config.h"

namespace opl {
namespace fuzz {
namespace {

constexpr int kIterations = 300;

TEST(SequencerConfigFuzz, LoadConfig) {
  const testing_support::TempDir dir;
  const FuzzStats stats = RunFuzz(
      "sequencer_config", InputKind::kText, FuzzSettings::FromEnvironment(kIterations),
      [&](const std::string& in, const std::string&) {
        const std::string path = dir.Write("sequencer.json", in);
        const sequencer::Result<sequencer::SequencerConfig> read = sequencer::LoadConfig(path);
        TargetResult r;
        if (!read.ok()) {
          r.problem = CheckErrorMessage(read.status().message(), path);
          return r;
        }
        r.accepted = true;
        std::string why;
        if (!read.value().IsValid(&why)) r.problem = "accepted an invalid configuration: " + why;
        return r;
      });
  EXPECT_GT(stats.accepted, 2);  // the seeds and some mutations
  EXPECT_LT(stats.accepted, stats.inputs);
}

}  // namespace
}  // namespace fuzz
}  // namespace opl
