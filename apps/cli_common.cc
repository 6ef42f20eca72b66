#include "cli_common.h"

#include <cstdio>
#include <exception>
#include <iostream>

#include <glog/logging.h>

namespace opl {
namespace cli {

std::string HelpFooter(const std::string& examples) {
  return "\nExamples:\n" + examples +
         "\nExit codes:\n"
         "  0  success\n"
         "  1  internal error (a bug; please report it)\n"
         "  2  usage error (unknown or missing option, option value not of its type)\n"
         "  3  bad input (file unreadable or malformed, invalid value); the message\n"
         "     names the file and line or field\n"
         "  4  no solution (valid data that do not determine a pose or a scale)\n"
         "  5  an output could not be written (nothing is left half-written)\n"
         "On any error one line '<tool>: <message>' goes to stderr and no output\n"
         "file is created or changed.\n"
         "\nFile formats: docs/formats.md; tools and options: docs/cli.md (OPL source tree).\n";
}

int ExitCodeForInputStatus(const Status& status) {
  if (status.ok()) return kExitOk;
  return status.code() == StatusCode::kNoSolution ? kExitNoSolution : kExitBadInput;
}

int Fail(const std::string& tool, const std::string& message, int exit_code) {
  std::cerr << tool << ": " << message << std::endl;
  return exit_code;
}

int FailInput(const std::string& tool, const Status& status) {
  return Fail(tool, status.message(), ExitCodeForInputStatus(status));
}

int FailWrite(const std::string& tool, const Status& status) {
  return Fail(tool, status.message(), kExitWriteFailed);
}

std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);  // prints the help on stdout, returns 0
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return Fail(app.get_name(), std::string(e.what()) + " (see --help)", kExitUsage);
  }
  return std::nullopt;
}

void QuietSolverLogging(const std::string& tool) {
  // glog keeps the pointer it is given: a string that outlives main.
  static const std::string* const name = new std::string(tool);
  static const bool initialised = [] {
    FLAGS_logtostderr = true;  // never log files in /tmp
    FLAGS_minloglevel = google::GLOG_FATAL;
    google::InitGoogleLogging(name->c_str());
    return true;
  }();
  (void)initialised;
}

void ShowSolverLogging() { FLAGS_minloglevel = google::GLOG_INFO; }

int RunTool(const std::string& tool, const std::function<int()>& body) {
  QuietSolverLogging(tool);
  try {
    return body();
  } catch (const std::exception& e) {
    return Fail(tool, std::string("internal error: ") + e.what(), kExitInternalError);
  } catch (...) {
    return Fail(tool, "internal error: unknown exception", kExitInternalError);
  }
}

int PrintToStdout(const std::string& tool, const std::string& text) {
  std::cout << text;
  std::cout.flush();
  if (!std::cout) return Fail(tool, "cannot write to standard output", kExitWriteFailed);
  return kExitOk;
}

}  // namespace cli
}  // namespace opl
