// The Monte Carlo figure (monte_carlo_figure.h): its histogram bins
// (Freedman-Diaconis, clamped), the normal quantile, and the series the figure
// is built from: the histogram holds every sample, the first-order curve has
// the histogram's area, the interval lines sit at the JCGM 101 order
// statistics and at true +- 1.96 u.
#include "opl/uncertainty/monte_carlo_figure.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "opl/core/format.h"

namespace opl {
namespace {

TEST(MonteCarloHistogramTest, FreedmanDiaconisBins) {
  // 1 .. 1000: IQR = 750 - 250 = 500, bin width 2 * 500 / 1000^(1/3) = 100,
  // range 999: 10 bins of 99.9.
  std::vector<double> values(1000);
  std::iota(values.begin(), values.end(), 1.0);
  std::shuffle(values.begin(), values.end(), std::mt19937(3));
  const Histogram h = MonteCarloHistogram(values);
  ASSERT_EQ(h.counts.size(), 10u);
  EXPECT_DOUBLE_EQ(h.lo, 1.0);
  EXPECT_NEAR(h.width, 99.9, 1e-12);
  for (int c : h.counts) EXPECT_EQ(c, 100);  // bin j holds 100 j + 1 .. 100 j + 100

  // 4000 draws of N(0, 1): IQR 1.349, width 0.17, range about 7: about 41 bins.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  std::vector<double> draws(4000);
  for (double& v : draws) v = normal(rng);
  const Histogram n = MonteCarloHistogram(draws);
  EXPECT_GE(n.counts.size(), 35u);
  EXPECT_LE(n.counts.size(), 50u);
  EXPECT_EQ(std::accumulate(n.counts.begin(), n.counts.end(), 0), 4000);
}

TEST(MonteCarloHistogramTest, ClampedAndDegenerate) {
  // One far outlier: Freedman-Diaconis asks for ~10^4 bins, clamped to 100.
  std::vector<double> values(1000);
  std::iota(values.begin(), values.end(), 1.0);
  values.push_back(1e6);
  const Histogram wide = MonteCarloHistogram(values);
  EXPECT_EQ(wide.counts.size(), 100u);
  EXPECT_EQ(wide.counts.front(), 1000);
  EXPECT_EQ(wide.counts.back(), 1);  // the top edge is in the last bin
  // Five distinct values: FD asks for 1 or 2 bins; at least 10.
  EXPECT_EQ(MonteCarloHistogram({1, 2, 3, 4, 5}).counts.size(), 10u);
  // Equal values: 10 bins around them, all in the middle one.
  const Histogram same = MonteCarloHistogram({55.0, 55.0, 55.0});
  ASSERT_EQ(same.counts.size(), 10u);
  EXPECT_EQ(same.counts[5], 3);
  EXPECT_NEAR(same.width, 55e-6, 1e-18);
  EXPECT_TRUE(MonteCarloHistogram({}).counts.empty());
}

TEST(NormalQuantileTest, KnownValues) {
  EXPECT_NEAR(NormalQuantile(0.975), 1.959963984540054, 1e-12);
  EXPECT_NEAR(NormalQuantile(0.995), 2.5758293035489004, 1e-12);
  EXPECT_NEAR(NormalQuantile(0.1), -1.2815515655446004, 1e-12);
  EXPECT_NEAR(NormalQuantile(0.5), 0.0, 1e-12);
  EXPECT_TRUE(std::isnan(NormalQuantile(1.0)));
  EXPECT_TRUE(std::isnan(NormalQuantile(0.0)));
}

// A report as RunMeasurementMonteCarlo makes it, from `m` draws: lengths
// L_k ~ N(true_k, (1.1 u_k)^2) and s ~ N(1 + 20e-6, (3000e-6)^2), the
// first-order u_k = 0.2 (k + 1) mm and 2900 ppm.
MonteCarloReport SyntheticReport(int m, int lengths) {
  MonteCarloReport r;
  r.iterations = m;
  r.succeeded = m;
  r.seed = 5;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  for (int k = 0; k < lengths; ++k) {
    MonteCarloLength l;
    l.from = std::string(1, static_cast<char>('A' + k));
    l.to = std::string(1, static_cast<char>('B' + k));
    l.true_mm = 55.0 + 10.0 * k;
    const double u = 0.2 * (k + 1);
    for (int i = 0; i < m; ++i) l.samples_mm.push_back(l.true_mm + 1.1 * u * normal(rng));
    l.photo_mm = Summarize(l.samples_mm, r.coverage_probability);
    l.photo_mm.first_order_std = u;
    r.lengths.push_back(l);
  }
  for (int i = 0; i < m; ++i) r.scale_samples.push_back(1.0 + 20e-6 + 3000e-6 * normal(rng));
  r.scale_factor = Summarize(r.scale_samples, r.coverage_probability);
  r.scale_factor.first_order_std = 2900e-6;
  for (int i = 0; i < m; ++i) r.sample_iterations.push_back(i);
  return r;
}

// The JCGM 101 7.7.1 interval, computed here from its definition.
std::pair<double, double> SymmetricInterval(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const int m = static_cast<int>(v.size());
  const double pm = p * m;
  const int q = pm == std::floor(pm) ? static_cast<int>(pm) : static_cast<int>(std::floor(pm + 0.5));
  const int r = (m - q) % 2 == 0 ? (m - q) / 2 : (m - q + 1) / 2;
  return {v[static_cast<size_t>(r - 1)], v[static_cast<size_t>(r + q - 1)]};
}

double TrapezoidArea(const PlotSeries& s) {
  double area = 0.0;
  for (size_t i = 1; i < s.x.size(); ++i) area += 0.5 * (s.y[i] + s.y[i - 1]) * (s.x[i] - s.x[i - 1]);
  return area;
}

// Checks one panel: `values` in the panel's unit, centre and u of the first
// order in it.
void CheckPanel(const PlotPanel& panel, const std::vector<double>& values, double centre,
                double u) {
  const int m = static_cast<int>(values.size());
  ASSERT_EQ(panel.series.size(), 4u);
  const PlotSeries& hist = panel.series[0];
  const PlotSeries& curve = panel.series[1];
  const PlotSeries& mc_interval = panel.series[2];
  const PlotSeries& fo_interval = panel.series[3];
  EXPECT_EQ(hist.style, PlotSeries::Style::kLine);
  EXPECT_EQ(hist.label, "Monte Carlo, M = " + std::to_string(m));
  EXPECT_EQ(curve.style, PlotSeries::Style::kLine);
  EXPECT_EQ(mc_interval.label, "95 % MC interval (JCGM 101 7.7.1)");
  EXPECT_EQ(mc_interval.style, PlotSeries::Style::kLine);
  EXPECT_EQ(fo_interval.label, "95 % first order, +-1.96 u");
  EXPECT_EQ(fo_interval.style, PlotSeries::Style::kDashed);

  // The step line: (lo, 0), per bin its two corners, (hi, 0).
  ASSERT_GE(hist.x.size(), 2u * 10 + 2);
  const size_t bins = (hist.x.size() - 2) / 2;
  EXPECT_NE(panel.title.find("(" + std::to_string(bins) + " bins)"), std::string::npos)
      << panel.title;
  double counted = 0.0;
  for (size_t j = 0; j < bins; ++j) {
    EXPECT_EQ(hist.y[1 + 2 * j], hist.y[2 + 2 * j]);
    counted += hist.y[1 + 2 * j];
  }
  EXPECT_EQ(counted, m);  // every sample in one bin
  const double width = hist.x[2] - hist.x[1];
  EXPECT_NEAR(hist.x.front(), *std::min_element(values.begin(), values.end()), 1e-9 * width);
  EXPECT_NEAR(hist.x.back(), *std::max_element(values.begin(), values.end()), 1e-9 * width);
  // Counts per bin recomputed from the samples.
  for (size_t j = 0; j < bins; ++j) {
    const double a = hist.x[1 + 2 * j], b = hist.x[2 + 2 * j];
    const auto in = std::count_if(values.begin(), values.end(), [&](double v) {
      return v >= a && (v < b || j + 1 == bins);
    });
    EXPECT_NEAR(hist.y[1 + 2 * j], static_cast<double>(in), 1.0) << j;  // edge rounding
  }

  // The normal density scaled to counts: its area is M bins' worth, its
  // peak M width / (sqrt(2 pi) u) at the centre.
  EXPECT_NEAR(TrapezoidArea(curve) / width, m, 0.01 * m);
  const auto peak = std::max_element(curve.y.begin(), curve.y.end()) - curve.y.begin();
  const double density_peak = m * width / (std::sqrt(2.0 * kPi) * u);
  EXPECT_NEAR(curve.x[static_cast<size_t>(peak)], centre, curve.x[1] - curve.x[0]);
  EXPECT_NEAR(curve.y[static_cast<size_t>(peak)], density_peak, 1e-3 * density_peak);

  // The intervals: the order statistics of JCGM 101 7.7.1, and centre +- 1.96 u.
  const std::pair<double, double> sym = SymmetricInterval(values, 0.95);
  ASSERT_EQ(mc_interval.x.size(), 5u);
  EXPECT_NEAR(mc_interval.x[0], sym.first, 1e-9 * u);
  EXPECT_EQ(mc_interval.x[1], mc_interval.x[0]);
  EXPECT_TRUE(std::isnan(mc_interval.x[2]));
  EXPECT_NEAR(mc_interval.x[3], sym.second, 1e-9 * u);
  EXPECT_NEAR(fo_interval.x[0], centre - 1.959963984540054 * u, 1e-9 * u);
  EXPECT_NEAR(fo_interval.x[3], centre + 1.959963984540054 * u, 1e-9 * u);
  // The lines reach 1.5 times the highest count or density.
  const double highest = std::max(*std::max_element(hist.y.begin(), hist.y.end()), density_peak);
  EXPECT_NEAR(mc_interval.y[1], 1.5 * highest, 1e-12 * highest);
  EXPECT_EQ(mc_interval.y[0], 0.0);
}

TEST(MonteCarloFigureTest, SeriesOfOneLengthAndScale) {
  const MonteCarloReport r = SyntheticReport(3000, 1);
  const LinePlot plot = MonteCarloFigure(r);
  ASSERT_EQ(plot.panels.size(), 2u);
  EXPECT_EQ(plot.panels[0].x_label, "L A-B (mm)");
  EXPECT_EQ(plot.panels[1].x_label, "s - 1 (ppm)");
  EXPECT_EQ(plot.panels[0].y_label, "iterations per bin");
  EXPECT_EQ(plot.title,
            "Monte Carlo of a measurement (JCGM 101): 3000 of 3000 iterations, seed 5, efficient "
            "weighting");
  CheckPanel(plot.panels[0], r.lengths[0].samples_mm, 55.0, 0.2);
  std::vector<double> ppm;
  for (double s : r.scale_samples) ppm.push_back(1e6 * (s - 1.0));
  CheckPanel(plot.panels[1], ppm, 0.0, 2900.0);
  EXPECT_EQ(plot.panels[1].series[1].label, "first order: normal, u = 2900 ppm");
  EXPECT_EQ(plot.panels[0].series[1].label, "first order: normal, u = 0.2 mm");
  // The figure is valid for the plotter.
  EXPECT_TRUE(LayoutLinePlot(plot).ok());
}

TEST(MonteCarloFigureTest, AtMostThreeLengthPanels) {
  const MonteCarloReport r = SyntheticReport(200, 5);
  const LinePlot plot = MonteCarloFigure(r);
  ASSERT_EQ(plot.panels.size(), 4u);
  EXPECT_EQ(plot.panels[2].x_label, "L C-D (mm)");
  EXPECT_EQ(plot.panels[3].title.substr(0, 14), "scale factor s");
  EXPECT_NE(plot.title.find("; lengths 1-3 of 5 shown"), std::string::npos) << plot.title;
  CheckPanel(plot.panels[2], r.lengths[2].samples_mm, 75.0, 0.6);
  EXPECT_TRUE(LayoutLinePlot(plot).ok());
}

TEST(MonteCarloFigureTest, NoIntervalForFewSamples) {
  const MonteCarloReport r = SyntheticReport(10, 1);  // M - q < 1 for 95 %
  ASSERT_FALSE(r.lengths[0].photo_mm.has_interval);
  const LinePlot plot = MonteCarloFigure(r);
  ASSERT_EQ(plot.panels[0].series.size(), 3u);  // histogram, curve, first-order interval
  EXPECT_EQ(plot.panels[0].series[2].label, "95 % first order, +-1.96 u");
  EXPECT_EQ(plot.panels[0].series[0].x.size(), 2u * 10 + 2);  // at least 10 bins
  EXPECT_TRUE(LayoutLinePlot(plot).ok());
}

}  // namespace
}  // namespace opl
