// Design sweeps (design_sweep.h): each parameter changes the design as
// documented, and the laws method.md expects hold in the Monte Carlo: std of L
// linear in the spot noise, falling with the full angle and with the beams per
// side, fractional uncertainty falling with the separation; at every point the
// Monte Carlo std agrees with the first-order prediction and the Cramer-Rao
// bound within 10 % (300 iterations: the std of a std is 4 %).
#include "opl/uncertainty/design_sweep.h"

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "opl/sim/simulate_slices.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

// The prototype-like design of issue 4: two 11 x 11 sources, 29 deg, origins
// 39 mm apart across and 39 mm apart in depth, screen 1 m away.
ModuleDesign Staggered() {
  ModuleDesign d = test::Prototype();
  d.sources = {test::Source("A", {0, 19.5, 0}), test::Source("B", {-39, -19.5, 0})};
  return d;
}

MonteCarloOptions Options() {
  MonteCarloOptions o;
  o.iterations = 300;
  o.seed = 11;
  o.threads = 2;
  return o;
}

DesignSweep Sweep(SweepParameter p, const std::vector<double>& values) {
  Result<DesignSweep> sweep = RunDesignSweep(Staggered(), p, values, Options());
  EXPECT_TRUE(sweep.ok()) << sweep.status().message();
  if (!sweep.ok()) return DesignSweep();
  for (const DesignSweepPoint& point : sweep->points) {
    const SampleSummary& s = point.report.lengths[0].photo_mm;
    std::printf("%s = %g: std L MC %.5f FO %.5f CRB %.5f mm, u/L %.0f ppm\n",
                SweepParameterName(p), point.value, s.std_dev, s.first_order_std,
                s.cramer_rao_std, 1e6 * s.std_dev / point.report.lengths[0].true_mm);
    EXPECT_EQ(point.report.failed, 0);
    EXPECT_NEAR(s.std_dev / s.first_order_std, 1.0, 0.10) << point.value;
    EXPECT_NEAR(s.std_dev / s.cramer_rao_std, 1.0, 0.10) << point.value;
  }
  return *sweep;
}

double StdL(const DesignSweep& sweep, size_t i) {
  return sweep.points.at(i).report.lengths[0].photo_mm.std_dev;
}
double RelativeL(const DesignSweep& sweep, size_t i) {
  return StdL(sweep, i) / sweep.points.at(i).report.lengths[0].true_mm;
}

TEST(DesignSweepTest, StdOfLIsLinearInSpotNoise) {
  const DesignSweep sweep = Sweep(SweepParameter::kNoiseMm, {0.055, 0.11, 0.22, 0.44});
  ASSERT_EQ(sweep.points.size(), 4u);
  // Same draws at every value (common random numbers): the ratios are the
  // noise ratios up to the nonlinearity of the solve.
  for (size_t i = 1; i < 4; ++i) {
    EXPECT_NEAR(StdL(sweep, i) / StdL(sweep, 0), std::pow(2.0, static_cast<double>(i)),
                0.02 * std::pow(2.0, static_cast<double>(i)));
  }
}

// With the rows of the grid spread over a wider angle, the rays cross at a
// wider angle at the origin: the origin is better determined.
TEST(DesignSweepTest, StdOfLFallsWithFullAngle) {
  const DesignSweep sweep = Sweep(SweepParameter::kFullAngleDeg, {10, 20, 29, 45});
  ASSERT_EQ(sweep.points.size(), 4u);
  for (size_t i = 1; i < 4; ++i) EXPECT_LT(StdL(sweep, i), 0.9 * StdL(sweep, i - 1)) << i;
}

TEST(DesignSweepTest, StdOfLFallsWithBeamsPerSide) {
  const DesignSweep sweep = Sweep(SweepParameter::kBeamsPerSide, {5, 11, 21});
  ASSERT_EQ(sweep.points.size(), 3u);
  for (size_t i = 1; i < 3; ++i) EXPECT_LT(StdL(sweep, i), 0.8 * StdL(sweep, i - 1)) << i;
}

// The origins are located independently, so std L barely moves with the
// separation and u(L)/L falls as 1/L.
TEST(DesignSweepTest, FractionalUncertaintyFallsWithSeparation) {
  const DesignSweep sweep = Sweep(SweepParameter::kSeparationMm, {30, 55.1543, 100, 200});
  ASSERT_EQ(sweep.points.size(), 4u);
  for (size_t i = 1; i < 4; ++i) {
    EXPECT_LT(RelativeL(sweep, i), 0.75 * RelativeL(sweep, i - 1)) << i;
  }
  EXPECT_NEAR(sweep.points[1].report.lengths[0].true_mm, 55.1543, 1e-9);
}

TEST(DesignSweepTest, ApplyEachParameter) {
  const ModuleDesign base = Staggered();
  Result<ModuleDesign> d = ApplySweepValue(base, SweepParameter::kNoiseMm, 0.22);
  ASSERT_TRUE(d.ok());
  EXPECT_NEAR(d->spot_noise_mm.x(), 0.22, 1e-15);
  EXPECT_NEAR(d->spot_noise_mm.y(), 0.146, 1e-15);

  d = ApplySweepValue(base, SweepParameter::kSeparationMm, 100.0);
  ASSERT_TRUE(d.ok());
  const Eigen::Vector3d a = d->sources[0].scene_from_source.translation;
  const Eigen::Vector3d b = d->sources[1].scene_from_source.translation;
  EXPECT_NEAR((a - b).norm(), 100.0, 1e-12);
  EXPECT_NEAR((a + b).x(), -39.0, 1e-12);  // midpoint kept
  EXPECT_NEAR((a - b).normalized().dot(Eigen::Vector3d(1, 1, 0).normalized()), 1.0, 1e-15);

  // Staggered -> side by side: the same 55.15 mm, now all across (along y).
  d = ApplySweepValue(base, SweepParameter::kStaggerDeg, 0.0);
  ASSERT_TRUE(d.ok());
  const Eigen::Vector3d side = d->sources[0].scene_from_source.translation -
                               d->sources[1].scene_from_source.translation;
  EXPECT_NEAR(side.y(), 39.0 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(side.x(), 0.0, 1e-12);
  // ... and back to 45 deg: the staggered design again.
  Result<ModuleDesign> back = ApplySweepValue(*d, SweepParameter::kStaggerDeg, 45.0);
  ASSERT_TRUE(back.ok());
  EXPECT_NEAR((back->sources[0].scene_from_source.translation - Eigen::Vector3d(0, 19.5, 0)).norm(),
              0.0, 1e-12);
  EXPECT_NEAR((back->sources[1].scene_from_source.translation - Eigen::Vector3d(-39, -19.5, 0)).norm(),
              0.0, 1e-12);

  // The screen 1500 mm from the mean origin (-19.5, 0, 0) along +X.
  d = ApplySweepValue(base, SweepParameter::kDistanceMm, 1500.0);
  ASSERT_TRUE(d.ok());
  const std::optional<Eigen::Vector3d> hit =
      d->surface.IntersectRay(Eigen::Vector3d(-19.5, 0, 0), Eigen::Vector3d::UnitX());
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->x(), 1480.5, 1e-9);

  d = ApplySweepValue(base, SweepParameter::kBeamsPerSide, 7);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->sources[1].beams_per_side, 7);
  d = ApplySweepValue(base, SweepParameter::kFullAngleDeg, 40);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->sources[0].full_angle_deg, 40.0);
}

TEST(DesignSweepTest, Errors) {
  const ModuleDesign base = Staggered();
  EXPECT_EQ(ApplySweepValue(base, SweepParameter::kBeamsPerSide, 8).status().message(),
            "beams_per_side = 8: must be an odd integer in [3, 201]");
  EXPECT_EQ(ApplySweepValue(base, SweepParameter::kNoiseMm, 0).status().message(),
            "noise_mm = 0: must be > 0");
  EXPECT_EQ(ApplySweepValue(base, SweepParameter::kStaggerDeg, 91).status().message(),
            "stagger_deg = 91: must be in [0, 90]");
  EXPECT_EQ(ApplySweepValue(base, SweepParameter::kFullAngleDeg, 180).status().message(),
            "full_angle_deg = 180: must be in (0, 180)");
  EXPECT_EQ(ParseSweepParameter("angle").status().message(),
            "unknown sweep parameter 'angle' (known: noise_mm, full_angle_deg, beams_per_side, "
            "separation_mm, distance_mm, stagger_deg, layout)");
  Result<std::vector<double>> layout = ParseSweepValues("layout", "side_by_side,staggered");
  ASSERT_TRUE(layout.ok());
  EXPECT_EQ(*layout, (std::vector<double>{0.0, 45.0}));
  EXPECT_EQ(ParseSweepValues("layout", "diagonal").status().message(),
            "layout 'diagonal': expected side_by_side or staggered (or sweep stagger_deg for "
            "other angles)");
  Result<std::vector<double>> range = ParseSweepValues("noise_mm", "0.05:0.05:0.2");
  ASSERT_TRUE(range.ok());
  EXPECT_EQ(range->size(), 4u);
  EXPECT_EQ(range->back(), 0.2);
  EXPECT_EQ(ParseSweepValues("noise_mm", "0.05:x:0.2").status().message(),
            "value list '0.05:x:0.2': 'x' is not a finite number");
  Result<DesignSweep> sweep = RunDesignSweep(base, SweepParameter::kBeamsPerSide, {8}, Options());
  EXPECT_EQ(sweep.status().message(), "beams_per_side = 8: must be an odd integer in [3, 201]");
  EXPECT_EQ(RunDesignSweep(base, SweepParameter::kNoiseMm, {}, Options()).status().message(),
            "no values to sweep");
}

TEST(DesignSweepTest, CsvAndPlot) {
  MonteCarloOptions options = Options();
  options.iterations = 50;
  Result<DesignSweep> sweep = RunDesignSweep(Staggered(), SweepParameter::kNoiseMm, {0.1, 0.2}, options);
  ASSERT_TRUE(sweep.ok()) << sweep.status().message();
  const std::string csv = sweep->ToCsv();
  std::vector<std::string> lines;
  for (size_t start = 0, at; (at = csv.find('\n', start)) != std::string::npos; start = at + 1) {
    lines.push_back(csv.substr(start, at - start));
  }
  ASSERT_EQ(lines.size(), 3u);  // header + one length at two values
  EXPECT_EQ(lines[0].substr(0, 40), "parameter,value,from,to,true_mm,mean_mm,");
  EXPECT_EQ(lines[1].substr(0, 19), "noise_mm,0.1,A,B,55");
  const SampleSummary& s = sweep->points[1].report.lengths[0].photo_mm;
  // The std column reads back exactly.
  size_t field = 0, start = 0;
  for (; field < 6; ++field) start = lines[2].find(',', start) + 1;
  EXPECT_EQ(std::stod(lines[2].substr(start)), s.std_dev);

  const LinePlot plot = sweep->ToPlot();
  ASSERT_EQ(plot.panels.size(), 2u);
  ASSERT_EQ(plot.panels[0].series.size(), 3u);
  EXPECT_EQ(plot.panels[0].series[2].label, "Monte Carlo");
  EXPECT_EQ(plot.panels[0].series[2].y[1], s.std_dev);
  EXPECT_NEAR(plot.panels[1].series[2].y[1], 1e6 * s.std_dev / (39.0 * std::sqrt(2.0)), 1e-9);
  EXPECT_EQ(plot.panels[0].x_label, "spot noise sigma, largest axis (mm)");
  EXPECT_EQ(plot.title.substr(0, 47), "Design sweep over the spot noise sigma, largest");
  // Drawn in this order: first order (solid line with markers), the dashed
  // bound over it, the Monte Carlo markers on top; the legend lists the same.
  for (const PlotPanel& panel : plot.panels) {
    ASSERT_EQ(panel.series.size(), 3u);
    EXPECT_EQ(panel.series[0].label, "first order");
    EXPECT_EQ(panel.series[0].style, PlotSeries::Style::kLineMarkers);
    EXPECT_EQ(panel.series[1].label, "Cramer-Rao bound");
    EXPECT_EQ(panel.series[1].style, PlotSeries::Style::kDashed);
    EXPECT_EQ(panel.series[2].style, PlotSeries::Style::kMarkers);
    EXPECT_EQ(panel.series[0].x, (std::vector<double>{0.1, 0.2}));
  }
}

// Every parameter --param accepts has its label with the unit in words: the
// one table of design_sweep.cc, checked entry by entry.
TEST(DesignSweepTest, EveryParameterHasAHumanLabel) {
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"noise_mm", "spot noise sigma, largest axis (mm)"},
      {"full_angle_deg", "fan full angle (deg)"},
      {"beams_per_side", "beams per side n"},
      {"separation_mm", "separation of the origins (mm)"},
      {"distance_mm", "projection distance (mm)"},
      {"stagger_deg", "stagger of the baseline (deg; 0 side by side, 45 staggered)"},
      {"layout", "layout"},
  };
  ASSERT_EQ(AllSweepParameters().size(), expected.size());
  std::string known;
  for (size_t i = 0; i < expected.size(); ++i) {
    const SweepParameter p = AllSweepParameters()[i];
    EXPECT_EQ(SweepParameterName(p), expected[i].first);
    Result<SweepParameter> parsed = ParseSweepParameter(expected[i].first);
    ASSERT_TRUE(parsed.ok()) << expected[i].first;
    EXPECT_EQ(*parsed, p);
    EXPECT_EQ(SweepParameterLabel(p), expected[i].second);
    EXPECT_EQ(SweepParameterLabel(p).find('_'), std::string::npos);
    EXPECT_EQ(SweepParameterNoun(p).find('_'), std::string::npos);
    EXPECT_EQ(IsCategoricalSweep(p), expected[i].first == "layout");
    known += (i ? ", " : "") + expected[i].first;
  }
  // ... and the error for an unknown name lists exactly these.
  EXPECT_EQ(ParseSweepParameter("angle").status().message(),
            "unknown sweep parameter 'angle' (known: " + known + ")");
  EXPECT_EQ(SweepValueText(SweepParameter::kLayout, 0), "side_by_side");
  EXPECT_EQ(SweepValueText(SweepParameter::kLayout, 45), "staggered");
  EXPECT_EQ(SweepValueText(SweepParameter::kStaggerDeg, 45), "45");
}

// layout is categorical: markers only at 1, 2 (first order and bound beside
// the Monte Carlo), a categorical x axis whose ticks at 1 and 2 carry the
// names (and no numeric tick between them); the same designs as stagger_deg
// at 0 and 45.
TEST(DesignSweepTest, LayoutSweepIsDrawnAsCategories) {
  MonteCarloOptions options = Options();
  options.iterations = 40;
  Result<std::vector<double>> values = ParseSweepValues("layout", "staggered,side_by_side");
  ASSERT_TRUE(values.ok());
  Result<DesignSweep> sweep = RunDesignSweep(Staggered(), SweepParameter::kLayout, *values, options);
  ASSERT_TRUE(sweep.ok()) << sweep.status().message();
  Result<DesignSweep> stagger =
      RunDesignSweep(Staggered(), SweepParameter::kStaggerDeg, {45.0, 0.0}, options);
  ASSERT_TRUE(stagger.ok());
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(StdL(*sweep, i), StdL(*stagger, i));  // the same designs, the same draws
  }
  const LinePlot plot = sweep->ToPlot();
  ASSERT_EQ(plot.panels.size(), 2u);
  for (const PlotPanel& panel : plot.panels) {
    EXPECT_EQ(panel.x_label, "layout");
    ASSERT_EQ(panel.x_categories.size(), 2u);
    EXPECT_EQ(panel.x_categories[0].x, 1.0);
    EXPECT_EQ(panel.x_categories[0].label, "staggered");
    EXPECT_EQ(panel.x_categories[1].x, 2.0);
    EXPECT_EQ(panel.x_categories[1].label, "side by side");
    ASSERT_EQ(panel.series.size(), 3u);
    for (const PlotSeries& s : panel.series) EXPECT_EQ(s.style, PlotSeries::Style::kMarkers);
    EXPECT_EQ(panel.series[2].label, "Monte Carlo");
    EXPECT_EQ(panel.series[2].x, (std::vector<double>{1.0, 2.0}));
    ASSERT_EQ(panel.series[0].x.size(), 2u);
    ASSERT_EQ(panel.series[1].x.size(), 2u);
    for (size_t i = 0; i < 2; ++i) {
      EXPECT_NEAR(panel.series[0].x[i], i + 1 - 0.12, 1e-15);  // first order
      EXPECT_NEAR(panel.series[1].x[i], i + 1 + 0.12, 1e-15);  // bound
    }
  }
  EXPECT_EQ(plot.title.substr(0, 28), "Design sweep over the layout");
  EXPECT_EQ(sweep->ToCsv().substr(sweep->ToCsv().find('\n') + 1, 11), "layout,45,A");
  EXPECT_EQ(ApplySweepValue(Staggered(), SweepParameter::kLayout, 30).status().message(),
            "layout = 30: must be 0 (side_by_side) or 45 (staggered)");
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok()) << layout.status().message();
  for (const LinePlotPanelLayout& panel : layout->panels) {
    EXPECT_EQ(panel.x_ticks, (std::vector<double>{1.0, 2.0}));
    EXPECT_EQ(panel.x_tick_labels, (std::vector<std::string>{"staggered", "side by side"}));
    EXPECT_TRUE(panel.x_minor_ticks.empty());
    EXPECT_DOUBLE_EQ(panel.x_min, 0.5);
    EXPECT_DOUBLE_EQ(panel.x_max, 2.5);
  }
}

}  // namespace
}  // namespace opl
