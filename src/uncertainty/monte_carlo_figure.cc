#include "opl/uncertainty/monte_carlo_figure.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "opl/core/format.h"

namespace opl {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kCurvePoints = 241;
constexpr int kMaxLengthPanels = kLinePlotMaxPanels - 1;  // and one for s
constexpr double kHeadroom = 1.5;

double NormalDensity(double z) { return std::exp(-0.5 * z * z) / std::sqrt(2.0 * kPi); }

// One quantity of the report as a panel: `values` and the interval ends in
// the plot's unit, `centre` and `u` the first-order prediction in it.
struct Quantity {
  std::string title, x_label, unit;
  std::vector<double> values;
  double centre = 0.0, u = 0.0;
  bool has_interval = false;
  double low = 0.0, high = 0.0;
};

// The two vertical lines at a and b from 0 to top, as one series.
PlotSeries VerticalLines(std::string label, double a, double b, double top,
                         PlotSeries::Style style) {
  PlotSeries s;
  s.label = std::move(label);
  s.style = style;
  s.x = {a, a, kNaN, b, b};
  s.y = {0.0, top, kNaN, 0.0, top};
  return s;
}

PlotPanel MakePanel(const Quantity& q, double coverage_probability) {
  PlotPanel panel;
  const Histogram h = MonteCarloHistogram(q.values);
  const int bins = static_cast<int>(h.counts.size());
  const double m = static_cast<double>(q.values.size());
  panel.title = q.title + " (" + std::to_string(bins) + " bins)";
  panel.x_label = q.x_label;
  panel.y_label = "iterations per bin";

  PlotSeries hist;
  hist.label = "Monte Carlo, M = " + std::to_string(q.values.size());
  hist.style = PlotSeries::Style::kLine;
  const double hi = h.lo + bins * h.width;
  hist.x.push_back(h.lo);
  hist.y.push_back(0.0);
  int highest = 0;
  for (int j = 0; j < bins; ++j) {
    const double count = h.counts[static_cast<size_t>(j)];
    highest = std::max(highest, h.counts[static_cast<size_t>(j)]);
    hist.x.push_back(h.lo + j * h.width);
    hist.y.push_back(count);
    hist.x.push_back(j + 1 == bins ? hi : h.lo + (j + 1) * h.width);
    hist.y.push_back(count);
  }
  hist.x.push_back(hi);
  hist.y.push_back(0.0);

  const bool has_first_order = q.u > 0.0 && std::isfinite(q.u);
  PlotSeries curve;
  double top = highest;
  if (has_first_order) {
    curve.label = "first order: normal, u = " + FormatPrintf("%.4g", q.u) + " " + q.unit;
    curve.style = PlotSeries::Style::kLine;
    const double a = std::min(h.lo, q.centre - 4.0 * q.u);
    const double b = std::max(hi, q.centre + 4.0 * q.u);
    const double scale = m * h.width / q.u;
    for (int k = 0; k < kCurvePoints; ++k) {
      const double x = a + (b - a) * k / (kCurvePoints - 1);
      curve.x.push_back(x);
      curve.y.push_back(scale * NormalDensity((x - q.centre) / q.u));
    }
    top = std::max(top, scale * NormalDensity(0.0));
  }
  // The interval lines reach above the peak, leaving room for the legend.
  top *= kHeadroom;

  const std::string pct = FormatPrintf("%g", 100.0 * coverage_probability);
  const double k = NormalQuantile(0.5 * (1.0 + coverage_probability));
  panel.series.push_back(std::move(hist));
  if (has_first_order) panel.series.push_back(std::move(curve));
  if (q.has_interval) {
    panel.series.push_back(VerticalLines(pct + " % MC interval (JCGM 101 7.7.1)",
                                         q.low, q.high, top, PlotSeries::Style::kLine));
  }
  if (has_first_order) {
    panel.series.push_back(VerticalLines(
        pct + " % first order, +-" + FormatPrintf("%.3g", k) + " u",
        q.centre - k * q.u, q.centre + k * q.u, top, PlotSeries::Style::kDashed));
  }
  return panel;
}

}  // namespace

Histogram MonteCarloHistogram(const std::vector<double>& values, int min_bins, int max_bins) {
  Histogram h;
  if (values.empty()) return h;
  min_bins = std::max(1, min_bins);
  max_bins = std::max(min_bins, max_bins);
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  const double lo = sorted.front(), hi = sorted.back();
  const size_t n = sorted.size();
  int bins = min_bins;
  if (hi > lo) {
    // The 25 % and 75 % order statistics (1-based ceil(n/4), ceil(3n/4)).
    const double q1 = sorted[(n + 3) / 4 - 1];
    const double q3 = sorted[(3 * n + 3) / 4 - 1];
    const double fd = 2.0 * (q3 - q1) / std::cbrt(static_cast<double>(n));
    if (fd > 0.0) {
      const double wanted = std::ceil((hi - lo) / fd);
      bins = static_cast<int>(std::clamp(wanted, static_cast<double>(min_bins),
                                         static_cast<double>(max_bins)));
    }
    h.lo = lo;
    h.width = (hi - lo) / bins;
  } else {
    h.width = std::max(std::fabs(lo), 1.0) * 1e-6;
    h.lo = lo - (bins / 2 + 0.5) * h.width;  // v in the middle of bin bins / 2
  }
  h.counts.assign(static_cast<size_t>(bins), 0);
  for (double v : sorted) {
    const double at = std::floor((v - h.lo) / h.width);
    const int j = static_cast<int>(std::clamp(at, 0.0, static_cast<double>(bins - 1)));
    ++h.counts[static_cast<size_t>(j)];
  }
  return h;
}

double NormalQuantile(double p) {
  if (!(p > 0.0 && p < 1.0)) return kNaN;
  // Bisection on Phi(x) = erfc(-x / sqrt 2) / 2, then two Newton steps.
  double a = -40.0, b = 40.0;
  for (int i = 0; i < 200 && b - a > 1e-13; ++i) {
    const double mid = 0.5 * (a + b);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? a : b) = mid;
  }
  double x = 0.5 * (a + b);
  for (int i = 0; i < 2; ++i) {
    const double density = NormalDensity(x);
    if (density > 0.0) x -= (0.5 * std::erfc(-x / std::sqrt(2.0)) - p) / density;
  }
  return x;
}

LinePlot MonteCarloFigure(const MonteCarloReport& report) {
  LinePlot plot;
  const size_t lengths = std::min(report.lengths.size(), static_cast<size_t>(kMaxLengthPanels));
  plot.title = "Monte Carlo of a measurement (JCGM 101): " + std::to_string(report.succeeded) +
               " of " + std::to_string(report.iterations) + " iterations, seed " +
               std::to_string(report.seed) + ", " + SpotWeightingName(report.weighting) +
               " weighting";
  if (report.lengths.size() > lengths) {
    plot.title += "; lengths 1-" + std::to_string(lengths) + " of " +
                  std::to_string(report.lengths.size()) + " shown";
  }
  const double p = report.coverage_probability;
  for (size_t k = 0; k < lengths; ++k) {
    const MonteCarloLength& l = report.lengths[k];
    Quantity q;
    q.title = "length " + l.from + "-" + l.to;
    q.x_label = "L " + l.from + "-" + l.to + " (mm)";
    q.unit = "mm";
    q.values = l.samples_mm;
    q.centre = l.true_mm;
    q.u = l.photo_mm.first_order_std;
    q.has_interval = l.photo_mm.has_interval;
    q.low = l.photo_mm.symmetric.low;
    q.high = l.photo_mm.symmetric.high;
    plot.panels.push_back(MakePanel(q, p));
  }
  Quantity s;
  s.title = "scale factor s";
  s.x_label = "s - 1 (ppm)";
  s.unit = "ppm";
  for (double v : report.scale_samples) s.values.push_back(1e6 * (v - 1.0));
  s.centre = 0.0;
  s.u = 1e6 * report.scale_factor.first_order_std;
  s.has_interval = report.scale_factor.has_interval;
  s.low = 1e6 * (report.scale_factor.symmetric.low - 1.0);
  s.high = 1e6 * (report.scale_factor.symmetric.high - 1.0);
  plot.panels.push_back(MakePanel(s, p));
  return plot;
}

}  // namespace opl
