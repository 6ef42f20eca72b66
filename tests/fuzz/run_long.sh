#!/usr/bin/env bash
# The long fuzzing run (issue 19 item 10; docs/testing.md, "Fuzzing"): the
# harness of ctest's label "fuzz" with many more mutated inputs.
#
#   tests/fuzz/run_long.sh [ITERATIONS] [SEED] [BUILD_DIR]
#
# ITERATIONS  mutated inputs per reader format (default 20000); each tool
#             case gets ITERATIONS / 100 (at least 20), or
#             $OPL_FUZZ_CLI_ITERATIONS
# SEED        the run's seed (default: the current time); the same seed
#             gives the same inputs
# BUILD_DIR   a built tree (default build; a sanitizer tree works too,
#             e.g. build-asan, slower)
#
# Every finding is saved as FINDINGS/<format>/<seed>_<case>.bin with a line
# in FINDINGS/findings.txt; FINDINGS is $OPL_FUZZ_FINDINGS or
# BUILD_DIR/fuzz_findings/seed<SEED>. Replay them after a fix with
#   OPL_FUZZ_REPLAY=FINDINGS OPL_FUZZ_ITERATIONS=0 OPL_SOURCE_DIR=$PWD \
#     BUILD_DIR/tests/fuzz/test_fuzz_reader_fuzz_test
# and copy those worth keeping into tests/fuzz/corpus/<format>/.
#
# One process at a time (it shares the machine). Outside a sanitizer tree
# the address space is limited to 4 GB (ulimit -v), so that an input which
# makes a reader allocate without bound is a finding (std::bad_alloc thrown
# out of the reader), not the machine's out-of-memory killer. An input that
# takes longer than OPL_FUZZ_SLOW_SECONDS (default 2) is a finding; one that
# hangs for OPL_FUZZ_HANG_SECONDS (default here 60) is saved and ends its
# test, and the run goes on with the next.
#
# Exit status: 0 without findings, 1 with, 2 on a usage error.
set -uo pipefail
cd "$(dirname "$0")/../.."
iterations=${1:-20000}
seed=${2:-$(date +%s)}
build=${3:-build}
case "$iterations$seed" in
  *[!0-9]*) echo "usage: $0 [ITERATIONS] [SEED] [BUILD_DIR] (integers)" >&2; exit 2 ;;
esac
bin=$build/tests/fuzz
# The sequencer's test exists only when the sequencer is built (libgpiod).
tests_to_run="reader_fuzz_test colmap_fuzz_test cli_fuzz_test"
[ -x "$bin/test_fuzz_sequencer_config_fuzz_test" ] && tests_to_run="$tests_to_run sequencer_config_fuzz_test"
for t in $tests_to_run; do
  if [ ! -x "$bin/test_fuzz_$t" ]; then
    echo "$0: $bin/test_fuzz_$t is not built (cmake --build $build --target test_fuzz_$t)" >&2
    exit 2
  fi
done
cli_iterations=${OPL_FUZZ_CLI_ITERATIONS:-$((iterations / 100 > 20 ? iterations / 100 : 20))}
findings=${OPL_FUZZ_FINDINGS:-$build/fuzz_findings/seed$seed}
mkdir -p "$findings"
findings=$(cd "$findings" && pwd)

export OPL_SOURCE_DIR=$PWD OPL_FUZZ_SEED=$seed OPL_FUZZ_FINDINGS=$findings
export OPL_FUZZ_HANG_SECONDS=${OPL_FUZZ_HANG_SECONDS:-60}
if grep -q '^OPL_SANITIZE:STRING=.\+' "$build/CMakeCache.txt" 2>/dev/null; then
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
else
  ulimit -v $((4 * 1024 * 1024))
fi

echo "fuzz: seed $seed, $iterations inputs per reader format, $cli_iterations per tool case;" \
  "findings in $findings"
start=$(date +%s)
failed=0
# Each gtest test alone, so that an abort (a hang, a sanitizer report) ends
# one format and not the run.
for t in $tests_to_run; do
  n=$iterations
  [ "$t" = cli_fuzz_test ] && n=$cli_iterations
  tests=$("$bin/test_fuzz_$t" --gtest_list_tests |
    awk '/^[^ ]/ { suite = $1 } /^  / { print suite $1 }')
  for test in $tests; do
    log=$findings/${test//\//_}.log
    if OPL_FUZZ_ITERATIONS=$n "$bin/test_fuzz_$t" --gtest_filter="$test" >"$log" 2>&1; then
      grep -h '^fuzz \|printed\|line(s)' "$log"
    else
      failed=1
      grep -h '^fuzz \|printed\|line(s)' "$log"
      echo "fuzz: $test FAILED (log: $log)"
    fi
  done
done
echo "fuzz: $(($(date +%s) - start)) s"
if [ -s "$findings/findings.txt" ]; then
  echo "fuzz: $(wc -l <"$findings/findings.txt") finding(s), in $findings/findings.txt:"
  cut -c1-300 "$findings/findings.txt"
  exit 1
fi
[ "$failed" = 0 ] || exit 1
echo "fuzz: no findings"
