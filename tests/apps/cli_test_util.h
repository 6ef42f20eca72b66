// Test helpers shared by the command-line tests: run a built tool as a user
// would (through the shell) and capture its exit code, stdout and stderr.
// The test target defines OPL_MEASURE_EXE, OPL_SIMULATE_EXE and
// OPL_CALIBRATE_EXE (the tools'
// paths) and OPL_EXAMPLES_DIR (tests/apps/CMakeLists.txt).
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <string>

#include "io/temp_dir.h"

namespace opl {
namespace cli_test {

struct RunResult {
  int exit_code = -1;
  std::string out, err;
};

// Runs `prefix 'exe' args` through the shell (args already shell-quoted
// where needed), capturing stdout and stderr.
inline RunResult RunInShell(const std::string& prefix, const std::string& exe,
                            const std::string& args) {
  testing_support::TempDir capture;
  const std::string out = capture.File("stdout"), err = capture.File("stderr");
  const std::string command = prefix + "'" + exe + "' " + args + " >'" + out + "' 2>'" + err + "'";
  const int status = std::system(command.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = testing_support::ReadAll(out);
  r.err = testing_support::ReadAll(err);
  return r;
}

// Runs `exe args` (args already shell-quoted where needed).
inline RunResult Run(const std::string& exe, const std::string& args) {
  return RunInShell("", exe, args);
}

// Runs `exe args` as Run does, with every file it writes limited to
// `max_file_bytes` (rounded down to 512-byte blocks; the shell's `ulimit -f`,
// with SIGXFSZ ignored so a write past it fails with EFBIG, as on a full
// disk, instead of killing the process).
inline RunResult RunWithFileSizeLimit(const std::string& exe, const std::string& args,
                                      long max_file_bytes) {
  return RunInShell("trap '' XFSZ; ulimit -f " + std::to_string(max_file_bytes / 512) + " && ",
                    exe, args);
}

inline RunResult Measure(const std::string& args) { return Run(OPL_MEASURE_EXE, args); }
inline RunResult Simulate(const std::string& args) { return Run(OPL_SIMULATE_EXE, args); }
inline RunResult Calibrate(const std::string& args) { return Run(OPL_CALIBRATE_EXE, args); }

}  // namespace cli_test
}  // namespace opl
