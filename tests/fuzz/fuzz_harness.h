// The fuzzing harness shared by tests/fuzz/reader_fuzz_test.cc (the
// library's readers) and tests/fuzz/cli_fuzz_test.cc (the tools): a seed
// corpus per format, seeded mutation (fuzz/mutator.h), a check per input,
// findings saved for replay, and a watchdog for inputs that hang
// (docs/testing.md, "Fuzzing").
//
// Settings come from the environment, so that ctest runs a short,
// deterministic run and tests/fuzz/run_long.sh a long one:
//   OPL_FUZZ_ITERATIONS  mutated inputs per format (default: the test's own,
//                        a few hundred for readers, a few dozen for tools)
//   OPL_FUZZ_SEED        the run's seed (default 1); case i of format f uses
//                        CaseSeed(seed, f, i), so any case replays alone
//   OPL_FUZZ_FINDINGS    a folder: every failing input is saved there as
//                        <format>/<seed>_<iteration>.bin, with a line in
//                        findings.txt (format, seed, iteration, operators,
//                        the problem)
//   OPL_FUZZ_REPLAY      a folder laid out like the corpus
//                        (<format>/<file>): its files are run as seeds too,
//                        e.g. a findings folder after a fix
//   OPL_FUZZ_SLOW_SECONDS  an input taking longer is a finding (default 2,
//                        10 under the sanitizers)
//   OPL_FUZZ_HANG_SECONDS  the watchdog saves the input and aborts the run
//                        after this long on one input (default 120)
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "fuzz/mutator.h"

namespace opl {
namespace fuzz {

struct FuzzSettings {
  uint64_t seed = 1;
  int iterations = 0;
  std::string findings_dir;  // empty: findings are only reported
  std::string replay_dir;    // empty: the corpus only
  double slow_seconds = 2.0;
  double hang_seconds = 120.0;
  // Whether the corpus entries are also run as they are (the tools' harness
  // leaves that to the readers' harness and the hostile-input tests).
  bool run_seeds = true;

  // The settings of a run: `default_iterations` unless OPL_FUZZ_ITERATIONS
  // says otherwise, and the other variables above.
  static FuzzSettings FromEnvironment(int default_iterations);
};

struct CorpusEntry {
  std::string name;   // file name, e.g. "prototype.csv"
  std::string bytes;  // its contents
};

// The folder of the seed corpus: $OPL_SOURCE_DIR/tests/fuzz/corpus.
std::string CorpusDir();

// The regular files directly in CorpusDir()/<format>/ (sub-folders hold
// files the seeds refer to, not seeds), sorted by name, then those of
// <replay_dir>/<format>/ when set.
std::vector<CorpusEntry> LoadCorpus(const std::string& format, const FuzzSettings& settings);

// What a failure message must be (issue 19 item 7): one line (no line
// break or other control character), at most 1000 bytes besides the
// occurrences of `input_name`, and naming `input_name`. Empty when it is,
// else what is wrong.
std::string CheckErrorMessage(const std::string& message, const std::string& input_name);

// What a target says about one input.
struct TargetResult {
  bool accepted = false;  // the input was read (or the tool exited 0)
  std::string problem;    // empty: fine; else a finding
};

// A target: one input (bytes) and the name of the corpus entry it was made
// from (its extension may choose the format).
using FuzzTarget = std::function<TargetResult(const std::string& input, const std::string& seed_name)>;

struct FuzzStats {
  int inputs = 0;    // corpus entries and mutated inputs run
  int accepted = 0;  // of them, read without error
  int problems = 0;  // findings
  double max_seconds = 0;  // the slowest input
  double total_seconds = 0;
};

// Runs `target` on every corpus entry as it is, then on settings.iterations
// mutated inputs (case i: a corpus entry and 1-4 operators drawn from
// CaseSeed(settings.seed, format, i)). An exception thrown out of the target,
// a problem it reports or an input slower than settings.slow_seconds is a
// finding: a gtest failure naming the format, seed, case and operators, and
// the input saved when settings.findings_dir is set. `max_size` bounds the
// mutated inputs.
FuzzStats RunFuzz(const std::string& format, InputKind kind, const FuzzSettings& settings,
                  const FuzzTarget& target, size_t max_size = size_t{1} << 20);

// The same on a corpus made by the caller (e.g. images rendered by the test);
// `format` names the findings and seeds the cases.
FuzzStats RunFuzzOnCorpus(const std::string& format, const std::vector<CorpusEntry>& corpus,
                          InputKind kind, const FuzzSettings& settings, const FuzzTarget& target,
                          size_t max_size = size_t{1} << 20);

}  // namespace fuzz
}  // namespace opl
