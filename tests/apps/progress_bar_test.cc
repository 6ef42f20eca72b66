// The progress bar's text: fill, count, percentage (floored: 100 % only when
// done), rate and time left.
#include "progress_bar.h"

#include <gtest/gtest.h>

namespace opl::cli {
namespace {

TEST(ProgressBarTest, RendersFillCountRateAndTimeLeft) {
  // 2300 of 5000 in 0.5 s: 4600/s, 2700 left -> 0.587 s.
  EXPECT_EQ(ProgressBar::Render("mc", 2300, 5000, 0.5),
            "mc [###########.............] 2300/5000  46%  4600/s  0.6 s left");
  EXPECT_EQ(ProgressBar::Render("sweep", 0, 10, 0.0), "sweep [........................] 0/10   0%");
  EXPECT_EQ(ProgressBar::Render("mc", 999, 1000, 2.0),
            "mc [#######################.] 999/1000  99%  500/s  0.0 s left");
  EXPECT_EQ(ProgressBar::Render("mc", 1000, 1000, 2.0),
            "mc [########################] 1000/1000 100%  500/s  0.0 s left");
  EXPECT_EQ(ProgressBar::Render("x", 3, 0, 1.0).substr(0, 30), "x [########################] 3");
}

}  // namespace
}  // namespace opl::cli
