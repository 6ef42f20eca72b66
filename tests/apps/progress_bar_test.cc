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

TEST(ProgressBarTest, RendersAnIdentificationWithoutATotal) {
  IdentifyProgress p;
  p.seeds_tried = 37;
  p.sources_found = 1;
  p.num_sources = 2;
  p.points_assigned = 5041;
  p.points = 10509;
  const std::string line = ProgressBar::RenderIdentify("identify", p, 4.06);
  EXPECT_EQ(line, "identify: 37 seeds tried, 1/2 sources found, 5041/10509 points  4.1 s");
  EXPECT_LE(line.size(), 78u);  // the width Finish erases
  p.seeds_tried = 1;
  EXPECT_EQ(ProgressBar::RenderIdentify("identify", p, 0.0),
            "identify: 1 seed tried, 1/2 sources found, 5041/10509 points  0.0 s");
}

}  // namespace
}  // namespace opl::cli
