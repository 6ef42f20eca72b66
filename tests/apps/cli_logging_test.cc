// The tools' handling of the solvers' glog output (apps/cli_common.h): quiet
// by default, every level with ShowSolverLogging (a tool's --verbose), and
// never the "Logging before InitGoogleLogging()" preamble.
#include <string>

#include <glog/logging.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli_common.h"

namespace opl {
namespace {

using ::testing::HasSubstr;

TEST(CliLogging, QuietUnlessShown) {
  cli::QuietSolverLogging("cli_logging_test");
  cli::QuietSolverLogging("cli_logging_test");  // a second call is harmless
  testing::internal::CaptureStderr();
  LOG(WARNING) << "Linear solver failure (quiet)";
  LOG(ERROR) << "an error the tool reports in its own words";
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");

  cli::ShowSolverLogging();
  testing::internal::CaptureStderr();
  LOG(WARNING) << "Linear solver failure (shown)";
  const std::string shown = testing::internal::GetCapturedStderr();
  EXPECT_THAT(shown, HasSubstr("Linear solver failure (shown)"));
  EXPECT_THAT(shown, ::testing::Not(HasSubstr("before InitGoogleLogging")));
}

}  // namespace
}  // namespace opl
