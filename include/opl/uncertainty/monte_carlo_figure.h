// The figure of a measurement Monte Carlo (opl_simulate mc --plot;
// docs/uncertainty.md, "The Monte Carlo figure"): per length L (the first
// three) and for the scale factor s one panel with
//   - the histogram of the Monte Carlo values (a step line: counts per bin,
//     bins by MonteCarloHistogram);
//   - the first-order (GUM) prediction, the normal density N(true, u^2) with
//     u the first-order standard deviation, scaled to counts per bin
//     (M * bin width * density), so its area is M like the histogram's;
//   - the 100p % coverage interval of the samples, probabilistically
//     symmetric (JCGM 101 7.7.1, SampleSummary::symmetric), as two vertical
//     lines (left out when M is too small for one);
//   - the first-order interval true +- k u, k the normal quantile of
//     (1 + p) / 2 (1.96 for p = 0.95), as two dashed vertical lines.
// L in mm; s as s - 1 in ppm. The centre of the first-order prediction is
// the noise-free value: the design's separation for L, 1 for s.
#pragma once

#include <vector>

#include "opl/report/line_plot.h"
#include "opl/uncertainty/monte_carlo.h"

namespace opl {

// Equal-width bins over [lo, lo + bins * width] holding every value.
struct Histogram {
  double lo = 0.0;
  double width = 0.0;       // > 0
  std::vector<int> counts;  // bins; value v is in bin floor((v - lo) / width), the top edge in the last
};

// The histogram of `values` (finite; not empty) over [min, max] in
// Freedman-Diaconis bins: width 2 IQR / M^(1/3) (IQR between the 25 % and
// 75 % order statistics), the number of bins ceil((max - min) / width)
// clamped to [min_bins, max_bins] and the width then (max - min) / bins.
// Equal values (max = min): min_bins bins of width max(|v|, 1) * 1e-6, v in
// the middle of bin min_bins / 2. An empty histogram for no values.
Histogram MonteCarloHistogram(const std::vector<double>& values, int min_bins = 10,
                              int max_bins = 100);

// The standard normal quantile: x with Phi(x) = p, p in (0, 1) (NaN
// otherwise); to 1e-12.
double NormalQuantile(double p);

// The figure described above: one panel per length (the first three of
// report.lengths; the title says when more are left out) and one for s.
// The series of each panel, in this order (legend labels in quotes):
//   0 "Monte Carlo, M = ...": the histogram's step line (kLine): points
//     (lo, 0), then per bin (left edge, count), (right edge, count), then
//     (hi, 0);
//   1 "first order: normal, u = ...": the scaled density (kLine), 241 points
//     over [min(lo, true - 4u), max(hi, true + 4u)] (left out when u = 0);
//   2 "95 % MC interval (JCGM 101 7.7.1)": x = low, low, NaN,
//     high, high against y = 0, top, NaN, 0, top (kLine; left out without
//     an interval);
//   3 "95 % first order, +-1.96 u": the same at true -+ k u (kDashed; left
//     out when u = 0);
// top = 1.5 times the highest count or density (room for the legend above
// the peak).
LinePlot MonteCarloFigure(const MonteCarloReport& report);

}  // namespace opl
