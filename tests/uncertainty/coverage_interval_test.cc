// JCGM 101:2008 7.7 coverage intervals: the order statistics chosen on
// hand-made samples, and the 95 % interval of a large normal sample.
#include "opl/uncertainty/coverage_interval.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "opl/sim/random.h"

namespace opl {
namespace {

TEST(CoverageIndexQTest, FollowsJcgm101) {
  EXPECT_EQ(CoverageIndexQ(100, 0.95), 95);   // p M integer (to rounding)
  EXPECT_EQ(CoverageIndexQ(1000, 0.95), 950);
  EXPECT_EQ(CoverageIndexQ(50, 0.95), 48);    // 47.5 -> floor(48.0)
  EXPECT_EQ(CoverageIndexQ(30, 0.95), 29);    // 28.5 -> 29
  EXPECT_EQ(CoverageIndexQ(19, 0.95), 18);    // 18.05 -> floor(18.55)
  EXPECT_EQ(CoverageIndexQ(10, 0.95), 10);    // 9.5 -> 10: no interval
}

// y_k = k^2, k = 1..100, given shuffled. M = 100, q = 95, M - q = 5 (odd):
// symmetric r = int((5 + 1) / 2) = 3 -> [y_3, y_98]; the widths
// y_(r+95) - y_r grow with r, so the shortest is r = 1 -> [y_1, y_96].
TEST(CoverageIntervalTest, HandMadeSampleIncreasingGaps) {
  std::vector<double> values;
  for (int k = 1; k <= 100; ++k) values.push_back(static_cast<double>(k * k));
  std::mt19937_64 rng(3);
  for (size_t i = values.size() - 1; i > 0; --i) {
    std::swap(values[i], values[UniformIndex(i + 1, rng)]);
  }
  Result<CoverageInterval> sym = ComputeCoverageInterval(
      values, 0.95, CoverageIntervalKind::kProbabilisticallySymmetric);
  ASSERT_TRUE(sym.ok()) << sym.status().message();
  EXPECT_EQ(sym->q, 95);
  EXPECT_EQ(sym->r, 3);
  EXPECT_EQ(sym->low, 9.0);
  EXPECT_EQ(sym->high, 98.0 * 98.0);
  Result<CoverageInterval> shortest =
      ComputeCoverageInterval(values, 0.95, CoverageIntervalKind::kShortest);
  ASSERT_TRUE(shortest.ok());
  EXPECT_EQ(shortest->r, 1);
  EXPECT_EQ(shortest->low, 1.0);
  EXPECT_EQ(shortest->high, 96.0 * 96.0);
}

// y_(j) = -(101 - j)^2: the widths (101 - r)^2 - (6 - r)^2 = 95 (107 - 2r)
// shrink with r, so the shortest is the last r = M - q = 5 -> [y_5, y_100].
TEST(CoverageIntervalTest, HandMadeSampleShrinkingGaps) {
  std::vector<double> values;
  for (int k = 1; k <= 100; ++k) values.push_back(-static_cast<double>(k * k));
  Result<CoverageInterval> shortest =
      ComputeCoverageInterval(values, 0.95, CoverageIntervalKind::kShortest);
  ASSERT_TRUE(shortest.ok());
  EXPECT_EQ(shortest->r, 5);
  EXPECT_EQ(shortest->low, -96.0 * 96.0);
  EXPECT_EQ(shortest->high, -1.0);
}

// M = 50: q = 48, M - q = 2 (even): symmetric r = 1 -> [y_1, y_49].
// M = 20: q = 19, M - q = 1: r = int(2 / 2) = 1 -> [y_1, y_20].
TEST(CoverageIntervalTest, SmallSamples) {
  std::vector<double> fifty, twenty;
  for (int k = 1; k <= 50; ++k) fifty.push_back(k);
  for (int k = 1; k <= 20; ++k) twenty.push_back(k);
  Result<CoverageInterval> a =
      ComputeCoverageInterval(fifty, 0.95, CoverageIntervalKind::kProbabilisticallySymmetric);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->low, 1.0);
  EXPECT_EQ(a->high, 49.0);
  Result<CoverageInterval> b =
      ComputeCoverageInterval(twenty, 0.95, CoverageIntervalKind::kProbabilisticallySymmetric);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->low, 1.0);
  EXPECT_EQ(b->high, 20.0);
}

TEST(CoverageIntervalTest, RejectsBadInput) {
  std::vector<double> ten(10, 1.0);
  Result<CoverageInterval> r =
      ComputeCoverageInterval(ten, 0.95, CoverageIntervalKind::kShortest);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("10 values"), std::string::npos) << r.status().message();
  std::vector<double> hundred(100, 1.0);
  EXPECT_FALSE(ComputeCoverageInterval(hundred, 1.0, CoverageIntervalKind::kShortest).ok());
  EXPECT_FALSE(ComputeCoverageInterval(hundred, 0.0, CoverageIntervalKind::kShortest).ok());
  hundred[7] = std::nan("");
  EXPECT_FALSE(ComputeCoverageInterval(hundred, 0.95, CoverageIntervalKind::kShortest).ok());
}

// For a large normal sample both 95 % intervals are mean +- 1.96 sigma within
// sampling error (the 2.5 % quantile of 2e5 draws scatters by ~0.006 sigma).
TEST(CoverageIntervalTest, LargeNormalSample) {
  const double mean = 5.0, sigma = 2.0;
  std::mt19937_64 rng(11);
  NormalGenerator normal;
  std::vector<double> values(200000);
  for (double& v : values) v = mean + sigma * normal(rng);
  for (CoverageIntervalKind kind :
       {CoverageIntervalKind::kProbabilisticallySymmetric, CoverageIntervalKind::kShortest}) {
    Result<CoverageInterval> ci = ComputeCoverageInterval(values, 0.95, kind);
    ASSERT_TRUE(ci.ok());
    EXPECT_NEAR(ci->low, mean - 1.959964 * sigma, 0.03 * sigma);
    EXPECT_NEAR(ci->high, mean + 1.959964 * sigma, 0.03 * sigma);
  }
}

}  // namespace
}  // namespace opl
