// Test helper: run the real COLMAP command-line tool (Debian package
// `colmap`, .ci/deps) headless, for the tests that check OPL's COLMAP
// exchange against COLMAP itself. Tests skip when it is not on PATH.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <string>

#include "io/temp_dir.h"

namespace opl {
namespace testing_support {

// True when `colmap` is an executable on PATH.
inline bool ColmapOnPath() {
  return std::system("command -v colmap >/dev/null 2>&1") == 0;
}

struct ColmapRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs `colmap <args>` (args already shell-quoted) with QT_QPA_PLATFORM=offscreen.
inline ColmapRun RunColmap(const std::string& args) {
  TempDir capture;
  const std::string log = capture.File("log");
  const std::string command =
      "QT_QPA_PLATFORM=offscreen colmap " + args + " >'" + log + "' 2>&1";
  const int status = std::system(command.c_str());
  ColmapRun r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.output = ReadAll(log);
  return r;
}

}  // namespace testing_support
}  // namespace opl
