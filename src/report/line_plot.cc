#include "opl/report/line_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

// m * 10^e, correctly rounded when m is an exact integer (|m| < 2^53) and
// |e| <= 22 (the powers of ten that are exact doubles): 3 * 10^-1 is the
// double nearest 0.3, not 0.30000000000000004.
double Scaled(double m, int e) {
  static const std::array<double, 23> kPow = [] {
    std::array<double, 23> p{};
    p[0] = 1;
    for (size_t i = 1; i < p.size(); ++i) p[i] = p[i - 1] * 10;
    return p;
  }();
  if (e >= 0) return e <= 22 ? m * kPow[static_cast<size_t>(e)] : m * std::pow(10.0, e);
  return -e <= 22 ? m / kPow[static_cast<size_t>(-e)] : m * std::pow(10.0, e);
}

// lo <= v <= hi up to a relative 1e-12 (0 < lo < hi; for log ticks).
bool InRange(double v, double lo, double hi) {
  return v >= lo * (1 - 1e-12) && v <= hi * (1 + 1e-12);
}

}  // namespace

std::vector<double> NiceTicks(double lo, double hi, int max_ticks) {
  std::vector<double> ticks;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi) || max_ticks < 1) return ticks;
  const double span = hi - lo;
  if (!std::isfinite(span)) return ticks;
  int e = static_cast<int>(std::floor(std::log10(span / max_ticks))) - 1;
  static const int kMantissas[] = {1, 2, 5};
  for (int iter = 0; iter < 40; ++iter, ++e) {
    for (int m : kMantissas) {
      const double step = Scaled(m, e);
      const double k_lo = std::ceil(lo / step - 1e-9);
      const double k_hi = std::floor(hi / step + 1e-9);
      if (k_hi - k_lo + 1 > max_ticks) continue;
      const int count = static_cast<int>(k_hi - k_lo + 1);  // a counter: k += 1 can stall
      for (int i = 0; i < count; ++i) {                     // beyond 2^53
        const double k = k_lo + i;
        // Exact integer k * m when small enough, then one rounding.
        ticks.push_back(std::fabs(k) < 1e15 ? Scaled(k * m, e) : k * step);
      }
      return ticks;
    }
  }
  return ticks;
}

LogTicks NiceLogTicks(double lo, double hi, int max_ticks) {
  LogTicks out;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo > 0) || !(lo < hi) || max_ticks < 1) {
    return out;
  }
  const double a = std::log10(lo);
  const double b = std::log10(hi);
  const int k0 = static_cast<int>(std::floor(a)) - 1;
  const int k1 = static_cast<int>(std::ceil(b)) + 1;
  struct Candidate {
    double value;
    int mantissa;
    int exponent;
  };
  std::vector<Candidate> all;
  for (int k = k0; k <= k1; ++k) {
    for (int m = 1; m <= 9; ++m) {
      const double v = Scaled(m, k);
      if (InRange(v, lo, hi)) all.push_back({v, m, k});
    }
  }
  std::vector<double> decades, one_two_five, every;
  for (const Candidate& c : all) {
    every.push_back(c.value);
    if (c.mantissa == 1) decades.push_back(c.value);
    if (c.mantissa == 1 || c.mantissa == 2 || c.mantissa == 5) one_two_five.push_back(c.value);
  }
  const auto n = [](const std::vector<double>& v) { return static_cast<int>(v.size()); };
  const double span = b - a;
  if (span >= 2 - 1e-9) {
    for (int every_m = 1;; ++every_m) {
      std::vector<double> major;
      for (const Candidate& c : all) {
        if (c.mantissa == 1 && c.exponent % every_m == 0) major.push_back(c.value);
      }
      if (n(major) <= max_ticks || every_m > 400) {
        out.major = std::move(major);
        break;
      }
    }
    for (const Candidate& c : all) {
      const bool is_major =
          std::find(out.major.begin(), out.major.end(), c.value) != out.major.end();
      if (is_major) continue;
      if (c.mantissa == 1 || span <= 8 + 1e-9) out.minor.push_back(c.value);
    }
    return out;
  }
  if (n(one_two_five) >= 2 && n(one_two_five) <= max_ticks) {
    out.major = one_two_five;
  } else if (n(decades) >= 2 && n(decades) <= max_ticks) {
    out.major = decades;
  } else if (n(every) >= 2 && n(every) <= max_ticks) {
    out.major = every;
  } else {
    out.major = NiceTicks(lo, hi, max_ticks);
  }
  for (double v : every) {
    if (std::find(out.major.begin(), out.major.end(), v) == out.major.end()) {
      out.minor.push_back(v);
    }
  }
  return out;
}

namespace {

// "2.5e-05" -> "2.5e-5", "1e+06" -> "1e6".
std::string CleanExponent(std::string s) {
  const size_t e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mantissa = s.substr(0, e);
  std::string exponent = s.substr(e + 1);
  std::string sign;
  if (!exponent.empty() && (exponent[0] == '+' || exponent[0] == '-')) {
    if (exponent[0] == '-') sign = "-";
    exponent = exponent.substr(1);
  }
  while (exponent.size() > 1 && exponent[0] == '0') exponent = exponent.substr(1);
  return mantissa + "e" + sign + exponent;
}

}  // namespace

std::string FormatTickLabel(double value, double step) {
  if (value == 0) return "0";
  if (!std::isfinite(value)) return FormatNumber(value);
  char buf[64];
  if (step > 0 && std::isfinite(step)) {
    const int e = static_cast<int>(std::floor(std::log10(step) + 1e-9));
    const int decimals = std::max(0, -e);
    if (std::fabs(value) < 1e6 && decimals <= 4) {
      std::snprintf(buf, sizeof(buf), "%.*f", decimals, value);
      return buf;
    }
    const int digits = static_cast<int>(std::floor(std::log10(std::fabs(value)) + 1e-9)) - e + 1;
    std::snprintf(buf, sizeof(buf), "%.*e", std::clamp(digits, 1, 15) - 1, value);
    return CleanExponent(buf);
  }
  std::snprintf(buf, sizeof(buf), "%.6g", value);
  return CleanExponent(buf);
}

double LinePlotPanelLayout::PixelX(double x) const {
  const double t = log_x ? std::log10(x) : x;
  const double t0 = log_x ? std::log10(x_min) : x_min;
  const double t1 = log_x ? std::log10(x_max) : x_max;
  return plot_area.x + (t - t0) / (t1 - t0) * (plot_area.width - 1);
}

double LinePlotPanelLayout::PixelY(double y) const {
  const double t = log_y ? std::log10(y) : y;
  const double t0 = log_y ? std::log10(y_min) : y_min;
  const double t1 = log_y ? std::log10(y_max) : y_max;
  return plot_area.y + (t1 - t) / (t1 - t0) * (plot_area.height - 1);
}

namespace {

// Colours, BGR as OpenCV stores them.
const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kTextGrey(40, 40, 40);
const cv::Scalar kGridMajor(221, 221, 221);
const cv::Scalar kGridMinor(240, 240, 240);
const cv::Scalar kLegendBorder(160, 160, 160);

// Okabe-Ito, without yellow (too light on white). BGR.
const std::array<cv::Scalar, 7> kPalette = {
    cv::Scalar(178, 114, 0),    // blue          RGB   0,114,178
    cv::Scalar(0, 94, 213),     // vermillion    RGB 213, 94,  0
    cv::Scalar(115, 158, 0),    // bluish green  RGB   0,158,115
    cv::Scalar(167, 121, 204),  // reddish purple RGB 204,121,167
    cv::Scalar(0, 159, 230),    // orange        RGB 230,159,  0
    cv::Scalar(233, 180, 86),   // sky blue      RGB  86,180,233
    cv::Scalar(0, 0, 0),        // black
};
enum class Marker { kCircle, kSquare, kTriangleUp, kDiamond, kTriangleDown, kPlus, kCross };
constexpr int kMarkerCount = 7;

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kTitleFont = cv::FONT_HERSHEY_DUPLEX;
constexpr double kFigureTitleScale = 0.75;
constexpr double kPanelTitleScale = 0.6;
constexpr double kAxisLabelScale = 0.5;
constexpr double kTickScale = 0.45;
constexpr double kLegendScale = 0.45;
constexpr double kMinTextScale = 0.35;
constexpr int kTickLength = 5;
constexpr int kMinorTickLength = 3;
constexpr int kPad = 10;         // panel edge -> outermost text
constexpr int kShift = 4;        // sub-pixel bits for drawing
constexpr double kOne = 1 << kShift;
constexpr double kMarkerRadius = 4.5;
constexpr int kLineThickness = 2;
constexpr int kSwatchWidth = 36;
constexpr int kLegendInset = 8;  // legend <-> plot-area edge

struct TextBox {
  int width = 0;
  int height = 0;    // above the baseline
  int baseline = 0;  // below the baseline
};

TextBox MeasureText(const std::string& text, int font, double scale, int thickness = 1) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &baseline);
  return TextBox{size.width, size.height, baseline};
}

// Digit height (the same for every tick label, so their baselines line up).
TextBox DigitBox(double scale) { return MeasureText("0123456789", kFont, scale); }

// Shrinks `text` (down to kMinTextScale) and if need be cuts it with "..."
// until it is at most `max_width` px wide.
std::pair<std::string, double> FitText(std::string text, int font, double scale, int max_width) {
  if (text.empty() || max_width <= 0) return {text, scale};
  TextBox box = MeasureText(text, font, scale);
  if (box.width <= max_width) return {text, scale};
  scale = std::max(kMinTextScale, scale * max_width / box.width);
  box = MeasureText(text, font, scale);
  while (box.width > max_width && text.size() > 3) {
    const std::string body = text.size() > 3 && text.substr(text.size() - 3) == "..."
                                 ? text.substr(0, text.size() - 3)
                                 : text;
    if (body.size() <= 1) break;
    text = body.substr(0, body.size() - 1) + "...";
    box = MeasureText(text, font, scale);
  }
  return {text, scale};
}

std::string Quoted(const std::string& s) { return s.empty() ? "" : " \"" + s + "\""; }

std::string PanelName(const PlotPanel& p, size_t i) {
  return "LinePlot.panels[" + std::to_string(i) + "]" +
         Quoted(p.title.empty() ? p.y_label : p.title);
}

std::string SeriesName(const PlotSeries& s, size_t j) {
  return "series[" + std::to_string(j) + "]" + Quoted(s.label);
}

bool PointUsable(const PlotSeries& s, size_t k) {
  return !std::isnan(s.x[k]) && !std::isnan(s.y[k]);
}

Status Validate(const LinePlot& plot) {
  const int n = static_cast<int>(plot.panels.size());
  if (n < 1 || n > kLinePlotMaxPanels) {
    return Status::InvalidArgument("LinePlot.panels: must have 1 to " +
                                   std::to_string(kLinePlotMaxPanels) + " panels, got " +
                                   std::to_string(n));
  }
  if (plot.panel_width_px < kLinePlotMinPanelWidth ||
      plot.panel_width_px > kLinePlotMaxPanelSize) {
    return Status::InvalidArgument("LinePlot.panel_width_px: must be in [" +
                                   std::to_string(kLinePlotMinPanelWidth) + ", " +
                                   std::to_string(kLinePlotMaxPanelSize) + "], got " +
                                   std::to_string(plot.panel_width_px));
  }
  if (plot.panel_height_px < kLinePlotMinPanelHeight ||
      plot.panel_height_px > kLinePlotMaxPanelSize) {
    return Status::InvalidArgument("LinePlot.panel_height_px: must be in [" +
                                   std::to_string(kLinePlotMinPanelHeight) + ", " +
                                   std::to_string(kLinePlotMaxPanelSize) + "], got " +
                                   std::to_string(plot.panel_height_px));
  }
  for (size_t i = 0; i < plot.panels.size(); ++i) {
    const PlotPanel& p = plot.panels[i];
    const std::string pname = PanelName(p, i);
    size_t usable = 0;
    for (size_t j = 0; j < p.series.size(); ++j) {
      const PlotSeries& s = p.series[j];
      const std::string sname = pname + ": " + SeriesName(s, j) + ": ";
      if (s.x.size() != s.y.size()) {
        return Status::InvalidArgument(sname + "x has " + std::to_string(s.x.size()) +
                                       " values but y has " + std::to_string(s.y.size()));
      }
      if (!s.y_err.empty() && s.y_err.size() != s.y.size()) {
        return Status::InvalidArgument(sname + "y_err has " + std::to_string(s.y_err.size()) +
                                       " values but y has " + std::to_string(s.y.size()));
      }
      for (size_t k = 0; k < s.x.size(); ++k) {
        const std::string idx = "[" + std::to_string(k) + "]";
        if (std::isinf(s.x[k])) {
          return Status::InvalidArgument(sname + "x" + idx + " is infinite (use NaN for a gap)");
        }
        if (std::isinf(s.y[k])) {
          return Status::InvalidArgument(sname + "y" + idx + " is infinite (use NaN for a gap)");
        }
        if (!s.y_err.empty() && !std::isnan(s.y_err[k]) &&
            !(std::isfinite(s.y_err[k]) && s.y_err[k] >= 0)) {
          return Status::InvalidArgument(sname + "y_err" + idx +
                                         " must be finite and >= 0 or NaN, got " +
                                         FormatNumber(s.y_err[k]));
        }
        if (p.log_x && !std::isnan(s.x[k]) && s.x[k] <= 0) {
          return Status::InvalidArgument(pname + ": log x axis needs x > 0: " +
                                         SeriesName(s, j) + " has x" + idx + " = " +
                                         FormatNumber(s.x[k]));
        }
        if (p.log_y && !std::isnan(s.y[k]) && s.y[k] <= 0) {
          return Status::InvalidArgument(pname + ": log y axis needs y > 0: " +
                                         SeriesName(s, j) + " has y" + idx + " = " +
                                         FormatNumber(s.y[k]));
        }
        if (PointUsable(s, k)) ++usable;
      }
    }
    if (usable == 0) {
      return Status::InvalidArgument(pname + ": no finite points to plot" +
                                     (p.series.empty() ? " (no series)" : ""));
    }
  }
  return Status::Ok();
}

// Axis range: the data range, widened when it is a single value, plus 5 % of
// the span on each side (in log10 for log axes).
std::pair<double, double> AxisRange(double lo, double hi, bool log) {
  if (log) {
    double a = std::log10(lo), b = std::log10(hi);
    if (!(b - a > 1e-12)) {
      a -= std::log10(2.0);
      b += std::log10(2.0);
    }
    const double pad = 0.05 * (b - a);
    return {std::pow(10.0, a - pad), std::pow(10.0, b + pad)};
  }
  if (!(hi - lo > 1e-12 * std::max(std::fabs(lo), std::fabs(hi)))) {
    const double d = lo == 0 ? 1.0 : 0.1 * std::fabs(lo);
    const double mid = 0.5 * (lo + hi);
    lo = mid - d;
    hi = mid + d;
  }
  const double pad = 0.05 * (hi - lo);
  return {lo - pad, hi + pad};
}

struct AxisTicks {
  std::vector<double> major, minor;
  std::vector<std::string> labels;
};

AxisTicks MakeTicks(double lo, double hi, bool log, int max_ticks) {
  AxisTicks t;
  double step = 0;
  if (log) {
    LogTicks lt = NiceLogTicks(lo, hi, max_ticks);
    t.major = std::move(lt.major);
    t.minor = std::move(lt.minor);
  } else {
    t.major = NiceTicks(lo, hi, max_ticks);
    if (t.major.size() >= 2) step = t.major[1] - t.major[0];
    else step = std::fabs(t.major.empty() ? 1.0 : t.major[0]);
    // Step from the tick values is m * 10^e up to rounding; snap it.
    if (step > 0) {
      const double e = std::floor(std::log10(step) + 1e-9);
      step = std::round(step / std::pow(10.0, e)) * std::pow(10.0, e);
    }
  }
  for (double v : t.major) t.labels.push_back(FormatTickLabel(v, log ? 0.0 : step));
  return t;
}

struct PanelExtras {
  std::string title;
  double title_scale = kPanelTitleScale;
  int title_baseline = 0;
  std::string x_label;
  double x_label_scale = kAxisLabelScale;
  int x_label_baseline = 0;
  std::string y_label;
  double y_label_scale = kAxisLabelScale;
  int y_label_left = 0;
  int x_tick_baseline = 0;
  int y_tick_right = 0;
  std::vector<std::string> legend_labels;
  double legend_scale = kLegendScale;
  int legend_row_height = 0;
};

struct FullLayout {
  LinePlotLayout pub;
  std::string title;
  double title_scale = kFigureTitleScale;
  int title_baseline = 0;
  std::vector<PanelExtras> extras;
};

double Clamp(double v) { return std::clamp(v, -1e5, 1e5); }

cv::Point Fixed(double x, double y) {
  return cv::Point(static_cast<int>(std::lround(Clamp(x) * kOne)),
                   static_cast<int>(std::lround(Clamp(y) * kOne)));
}

bool HasLine(PlotSeries::Style s) { return s != PlotSeries::Style::kMarkers; }
bool HasMarkers(PlotSeries::Style s) {
  return s == PlotSeries::Style::kMarkers || s == PlotSeries::Style::kLineMarkers;
}

// Runs of consecutive usable points (NaN breaks a run), as pixel positions.
std::vector<std::vector<cv::Point2d>> PixelRuns(const PlotSeries& s,
                                                const LinePlotPanelLayout& L) {
  std::vector<std::vector<cv::Point2d>> runs(1);
  for (size_t k = 0; k < s.x.size(); ++k) {
    if (!PointUsable(s, k)) {
      if (!runs.back().empty()) runs.emplace_back();
      continue;
    }
    runs.back().emplace_back(L.PixelX(s.x[k]), L.PixelY(s.y[k]));
  }
  if (runs.back().empty()) runs.pop_back();
  return runs;
}

// How much of the data the rectangle covers: markers count 10, line samples
// (every 3 px along segments) 1.
double Coverage(const LinePlot& plot, size_t panel, const LinePlotPanelLayout& L,
                const cv::Rect& r) {
  const cv::Rect box(r.x - 4, r.y - 4, r.width + 8, r.height + 8);
  const auto inside = [&](const cv::Point2d& p) {
    return p.x >= box.x && p.x < box.x + box.width && p.y >= box.y && p.y < box.y + box.height;
  };
  double score = 0;
  for (const PlotSeries& s : plot.panels[panel].series) {
    for (const std::vector<cv::Point2d>& run : PixelRuns(s, L)) {
      for (size_t i = 0; i < run.size(); ++i) {
        if (inside(run[i])) score += 10;
        if (i + 1 < run.size() && HasLine(s.style)) {
          const cv::Point2d d = run[i + 1] - run[i];
          const int steps = std::max(1, static_cast<int>(std::hypot(d.x, d.y) / 3));
          for (int t = 1; t < steps; ++t) {
            if (inside(run[i] + d * (static_cast<double>(t) / steps))) score += 1;
          }
        }
      }
    }
  }
  return score;
}

Result<FullLayout> ComputeLayout(const LinePlot& plot) {
  FullLayout F;
  const int n = static_cast<int>(plot.panels.size());
  const int W = plot.panel_width_px;
  const int H = plot.panel_height_px;
  F.pub.image_width = n * W;

  // Figure title row.
  int title_row = 0;
  if (!plot.title.empty()) {
    std::tie(F.title, F.title_scale) =
        FitText(plot.title, kTitleFont, kFigureTitleScale, F.pub.image_width - 2 * kPad);
    const TextBox tb = MeasureText(F.title, kTitleFont, F.title_scale);
    F.title_baseline = 14 + tb.height;
    title_row = F.title_baseline + tb.baseline + 4;
  }
  F.pub.image_height = title_row + H;

  const TextBox digit = DigitBox(kTickScale);
  for (int i = 0; i < n; ++i) {
    const PlotPanel& p = plot.panels[static_cast<size_t>(i)];
    const std::string pname = PanelName(p, static_cast<size_t>(i));
    LinePlotPanelLayout L;
    PanelExtras X;
    L.panel = PixelRect{i * W, title_row, W, H};
    L.log_x = p.log_x;
    L.log_y = p.log_y;

    // Data ranges (error bars included; on a log y axis only positive ends).
    double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
    double y_lo = x_lo, y_hi = -x_lo;
    for (const PlotSeries& s : p.series) {
      for (size_t k = 0; k < s.x.size(); ++k) {
        if (!PointUsable(s, k)) continue;
        x_lo = std::min(x_lo, s.x[k]);
        x_hi = std::max(x_hi, s.x[k]);
        y_lo = std::min(y_lo, s.y[k]);
        y_hi = std::max(y_hi, s.y[k]);
        if (!s.y_err.empty() && std::isfinite(s.y_err[k])) {
          y_hi = std::max(y_hi, s.y[k] + s.y_err[k]);
          const double low = s.y[k] - s.y_err[k];
          if (!p.log_y || low > 0) y_lo = std::min(y_lo, low);
        }
      }
    }
    std::tie(L.x_min, L.x_max) = AxisRange(x_lo, x_hi, p.log_x);
    std::tie(L.y_min, L.y_max) = AxisRange(y_lo, y_hi, p.log_y);

    // Vertical layout.
    int top = L.panel.y + kPad;
    if (!p.title.empty()) {
      std::tie(X.title, X.title_scale) =
          FitText(p.title, kTitleFont, kPanelTitleScale, W - 2 * kPad);
      const TextBox tb = MeasureText(X.title, kTitleFont, X.title_scale);
      X.title_baseline = top + tb.height;
      top = X.title_baseline + tb.baseline + 10;
    } else {
      top += 4;
    }
    const TextBox xl_box = MeasureText(p.x_label.empty() ? "0" : p.x_label, kFont,
                                       kAxisLabelScale);
    int bottom = L.panel.y + H - kPad;
    if (!p.x_label.empty()) {
      X.x_label_baseline = bottom - xl_box.baseline;
      bottom = X.x_label_baseline - xl_box.height - 8;
    }
    X.x_tick_baseline = bottom - digit.baseline;
    bottom = X.x_tick_baseline - digit.height - 4 - kTickLength;  // frame row
    L.plot_area.y = top + 1;
    L.plot_area.height = bottom - L.plot_area.y;
    if (L.plot_area.height < 60) {
      return Status::InvalidArgument(pname + ": panel_height_px " + std::to_string(H) +
                                     " leaves only " + std::to_string(L.plot_area.height) +
                                     " px for the plot; make it larger");
    }

    // Y ticks: as many as fit with a line of space between labels.
    AxisTicks yt;
    for (int max_ticks = std::max(2, L.plot_area.height / 40); max_ticks >= 2; --max_ticks) {
      yt = MakeTicks(L.y_min, L.y_max, p.log_y, max_ticks);
      bool ok = true;
      for (size_t k = 1; k < yt.major.size() && ok; ++k) {
        const double gap = std::fabs(L.PixelY(yt.major[k]) - L.PixelY(yt.major[k - 1]));
        ok = gap >= digit.height + digit.baseline + 8;
      }
      if (ok) break;
    }
    L.y_ticks = yt.major;
    L.y_tick_labels = yt.labels;
    L.y_minor_ticks = yt.minor;
    int y_label_width = 0;
    for (const std::string& s : L.y_tick_labels) {
      y_label_width = std::max(y_label_width, MeasureText(s, kFont, kTickScale).width);
    }

    // Horizontal layout: [pad][y label][8][tick labels][4][tick][frame] plot [right margin].
    int left = L.panel.x + kPad;
    if (!p.y_label.empty()) {
      std::tie(X.y_label, X.y_label_scale) =
          FitText(p.y_label, kFont, kAxisLabelScale, L.plot_area.height);
      const TextBox yb = MeasureText(X.y_label, kFont, X.y_label_scale);
      X.y_label_left = left;
      left += yb.height + yb.baseline + 4 + 8;
    }
    X.y_tick_right = left + y_label_width;
    L.plot_area.x = X.y_tick_right + 4 + kTickLength + 1;
    int right_margin = 24;
    AxisTicks xt;
    for (int attempt = 0; attempt < 2; ++attempt) {
      L.plot_area.width = L.panel.x + W - right_margin - L.plot_area.x;
      if (L.plot_area.width < 80) {
        return Status::InvalidArgument(pname + ": panel_width_px " + std::to_string(W) +
                                       " leaves only " + std::to_string(L.plot_area.width) +
                                       " px for the plot; make it larger");
      }
      for (int max_ticks = std::max(2, L.plot_area.width / 60); max_ticks >= 2; --max_ticks) {
        xt = MakeTicks(L.x_min, L.x_max, p.log_x, max_ticks);
        bool ok = true;
        for (size_t k = 1; k < xt.major.size() && ok; ++k) {
          const double gap = L.PixelX(xt.major[k]) - L.PixelX(xt.major[k - 1]);
          const double need = 0.5 * (MeasureText(xt.labels[k], kFont, kTickScale).width +
                                     MeasureText(xt.labels[k - 1], kFont, kTickScale).width) +
                              10;
          ok = gap >= need;
        }
        if (ok) break;
      }
      // The last label must not run off the panel.
      int overhang = 0;
      if (!xt.major.empty()) {
        const double end = L.PixelX(xt.major.back()) +
                           0.5 * MeasureText(xt.labels.back(), kFont, kTickScale).width;
        overhang = static_cast<int>(std::ceil(end)) - (L.panel.x + W - 6);
      }
      if (overhang <= 0) break;
      right_margin += overhang;
    }
    L.x_ticks = xt.major;
    L.x_tick_labels = xt.labels;
    L.x_minor_ticks = xt.minor;
    if (!p.x_label.empty()) {
      std::tie(X.x_label, X.x_label_scale) =
          FitText(p.x_label, kFont, kAxisLabelScale, L.plot_area.width + 40);
    }

    // Legend: rows for the labelled series, in the corner covering least data.
    std::vector<size_t> labelled;
    for (size_t j = 0; j < p.series.size(); ++j) {
      if (!p.series[j].label.empty()) labelled.push_back(j);
    }
    if (!labelled.empty()) {
      const TextBox lb = MeasureText("Ag", kFont, kLegendScale);
      X.legend_row_height = std::max(lb.height + lb.baseline, 12) + 8;
      const int max_text = std::max(40, L.plot_area.width * 3 / 5 - kSwatchWidth - 26);
      int text_width = 0;
      for (size_t j : labelled) {
        std::string t;
        double sc;
        std::tie(t, sc) = FitText(p.series[j].label, kFont, kLegendScale, max_text);
        // Keep one scale for every row: cut, do not shrink.
        if (sc != kLegendScale) std::tie(t, sc) = FitText(t, kFont, kLegendScale, max_text);
        X.legend_labels.push_back(t);
        text_width = std::max(text_width, MeasureText(t, kFont, kLegendScale).width);
      }
      const int lw = 8 + kSwatchWidth + 8 + text_width + 10;
      const int lh = 6 + static_cast<int>(labelled.size()) * X.legend_row_height + 6;
      const PixelRect& a = L.plot_area;
      const std::array<cv::Rect, 4> corners = {
          cv::Rect(a.x + kLegendInset, a.y + kLegendInset, lw, lh),
          cv::Rect(a.x + a.width - kLegendInset - lw, a.y + kLegendInset, lw, lh),
          cv::Rect(a.x + a.width - kLegendInset - lw, a.y + a.height - kLegendInset - lh, lw,
                   lh),
          cv::Rect(a.x + kLegendInset, a.y + a.height - kLegendInset - lh, lw, lh),
      };
      size_t best = 0;
      double best_score = std::numeric_limits<double>::infinity();
      for (size_t c = 0; c < corners.size(); ++c) {
        const double score = Coverage(plot, static_cast<size_t>(i), L, corners[c]);
        if (score < best_score) {
          best_score = score;
          best = c;
        }
      }
      const cv::Rect r = corners[best];
      L.legend = PixelRect{r.x, r.y, r.width, r.height};
      for (size_t row = 0; row < labelled.size(); ++row) {
        L.legend_series.push_back(static_cast<int>(labelled[row]));
        L.legend_swatches.push_back(PixelRect{r.x + 8,
                                              r.y + 6 + static_cast<int>(row) * X.legend_row_height,
                                              kSwatchWidth, X.legend_row_height});
      }
    }
    F.pub.panels.push_back(std::move(L));
    F.extras.push_back(std::move(X));
  }
  return F;
}

void PutText(cv::Mat& img, const std::string& text, cv::Point origin, double scale,
             const cv::Scalar& colour, int font = kFont) {
  cv::putText(img, text, origin, font, scale, colour, 1, cv::LINE_AA);
}

void PutTextCentred(cv::Mat& img, const std::string& text, int centre_x, int baseline,
                    double scale, const cv::Scalar& colour, int font = kFont) {
  const TextBox box = MeasureText(text, font, scale);
  PutText(img, text, cv::Point(centre_x - box.width / 2, baseline), scale, colour, font);
}

// Text rotated 90 degrees counter-clockwise (reads bottom-up), its left edge
// at `left`, centred on `centre_y`.
void PutTextVertical(cv::Mat& img, const std::string& text, int left, int centre_y,
                     double scale, const cv::Scalar& colour) {
  const TextBox box = MeasureText(text, kFont, scale);
  cv::Mat label(box.height + box.baseline + 4, box.width + 4, CV_8UC3, kWhite);
  PutText(label, text, cv::Point(2, 2 + box.height), scale, colour);
  cv::Mat rotated;
  cv::rotate(label, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const cv::Rect dst(left - 2, centre_y - rotated.rows / 2, rotated.cols, rotated.rows);
  const cv::Rect clipped = dst & cv::Rect(0, 0, img.cols, img.rows);
  if (clipped.area() > 0) {
    rotated(cv::Rect(clipped.x - dst.x, clipped.y - dst.y, clipped.width, clipped.height))
        .copyTo(img(clipped));
  }
}

void DrawMarker(cv::Mat& img, cv::Point2d c, Marker m, const cv::Scalar& colour) {
  const double r = kMarkerRadius;
  const auto poly = [&](std::vector<cv::Point2d> pts) {
    std::vector<cv::Point> fixed;
    for (const cv::Point2d& p : pts) fixed.push_back(Fixed(c.x + p.x, c.y + p.y));
    cv::fillConvexPoly(img, fixed, colour, cv::LINE_AA, kShift);
  };
  const auto line = [&](double x0, double y0, double x1, double y1) {
    cv::line(img, Fixed(c.x + x0, c.y + y0), Fixed(c.x + x1, c.y + y1), colour, 2, cv::LINE_AA,
             kShift);
  };
  switch (m) {
    case Marker::kCircle:
      cv::circle(img, Fixed(c.x, c.y), static_cast<int>(std::lround(r * kOne)), colour,
                 cv::FILLED, cv::LINE_AA, kShift);
      break;
    case Marker::kSquare: {
      const double s = r * 0.85;
      poly({{-s, -s}, {s, -s}, {s, s}, {-s, s}});
      break;
    }
    case Marker::kTriangleUp:
      poly({{0, -r * 1.15}, {r * 1.05, r * 0.75}, {-r * 1.05, r * 0.75}});
      break;
    case Marker::kDiamond:
      poly({{0, -r * 1.2}, {r * 1.0, 0}, {0, r * 1.2}, {-r * 1.0, 0}});
      break;
    case Marker::kTriangleDown:
      poly({{0, r * 1.15}, {r * 1.05, -r * 0.75}, {-r * 1.05, -r * 0.75}});
      break;
    case Marker::kPlus:
      line(-r, 0, r, 0);
      line(0, -r, 0, r);
      break;
    case Marker::kCross: {
      const double s = r * 0.8;
      line(-s, -s, s, s);
      line(-s, s, s, -s);
      break;
    }
  }
}

// A polyline, solid or dashed (9 px on, 6 px off, the pattern continuing
// across vertices).
void DrawPolyline(cv::Mat& img, const std::vector<cv::Point2d>& pts, bool dashed,
                  const cv::Scalar& colour) {
  if (pts.size() == 1) {  // an isolated point of a line-only series: a dot
    cv::circle(img, Fixed(pts[0].x, pts[0].y), static_cast<int>(1.5 * kOne), colour, cv::FILLED,
               cv::LINE_AA, kShift);
    return;
  }
  constexpr double kOn = 9, kOff = 6;
  double phase = 0;  // distance into the current on+off period
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    const cv::Point2d a = pts[i], b = pts[i + 1];
    if (!dashed) {
      cv::line(img, Fixed(a.x, a.y), Fixed(b.x, b.y), colour, kLineThickness, cv::LINE_AA,
               kShift);
      continue;
    }
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    if (len <= 0) continue;
    const cv::Point2d dir = (b - a) * (1.0 / len);
    // Each step ends a dash or a gap or the segment, and advances by at
    // least 1e-6 px, so this always terminates.
    double pos = 0;
    while (len - pos > 1e-6) {
      const bool on = phase < kOn;
      const double until = on ? kOn - phase : kOn + kOff - phase;
      const double end = std::min(len, pos + std::max(until, 1e-6));
      if (on) {
        const cv::Point2d p0 = a + dir * pos, p1 = a + dir * end;
        cv::line(img, Fixed(p0.x, p0.y), Fixed(p1.x, p1.y), colour, kLineThickness, cv::LINE_AA,
                 kShift);
      }
      phase += end - pos;
      pos = end;
      if (phase >= kOn + kOff - 1e-9) phase = 0;
    }
  }
}

void DrawPanel(cv::Mat& img, const LinePlot& plot, size_t index, const LinePlotPanelLayout& L,
               const PanelExtras& X) {
  const PlotPanel& p = plot.panels[index];
  const PixelRect& a = L.plot_area;
  const int right = a.x + a.width;    // first column right of the area (frame)
  const int bottom = a.y + a.height;  // first row below the area (frame)
  const int plot_centre_x = a.x + a.width / 2;

  if (!X.title.empty()) {
    PutTextCentred(img, X.title, plot_centre_x, X.title_baseline, X.title_scale, kBlack,
                   kTitleFont);
  }

  // Grid lines: minor (log axes) first, then major.
  const auto vline = [&](double x, const cv::Scalar& c) {
    const int px = static_cast<int>(std::lround(L.PixelX(x)));
    if (px >= a.x && px < right) cv::line(img, {px, a.y}, {px, bottom - 1}, c, 1, cv::LINE_8);
  };
  const auto hline = [&](double y, const cv::Scalar& c) {
    const int py = static_cast<int>(std::lround(L.PixelY(y)));
    if (py >= a.y && py < bottom) cv::line(img, {a.x, py}, {right - 1, py}, c, 1, cv::LINE_8);
  };
  for (double x : L.x_minor_ticks) vline(x, kGridMinor);
  for (double y : L.y_minor_ticks) hline(y, kGridMinor);
  for (double x : L.x_ticks) vline(x, kGridMajor);
  for (double y : L.y_ticks) hline(y, kGridMajor);

  // Data, clipped to the plot area: error bars and lines, then markers on top.
  cv::Mat area = img(cv::Rect(a.x, a.y, a.width, a.height));
  const auto local = [&](cv::Point2d q) { return cv::Point2d(q.x - a.x, q.y - a.y); };
  for (size_t j = 0; j < p.series.size(); ++j) {
    const PlotSeries& s = p.series[j];
    const cv::Scalar& colour = kPalette[j % kPalette.size()];
    if (!s.y_err.empty()) {
      for (size_t k = 0; k < s.x.size(); ++k) {
        if (!PointUsable(s, k) || !std::isfinite(s.y_err[k]) || s.y_err[k] <= 0) continue;
        const double px = L.PixelX(s.x[k]) - a.x;
        const double hi = L.PixelY(s.y[k] + s.y_err[k]) - a.y;
        const double low_value = s.y[k] - s.y_err[k];
        const bool low_on_axis = !L.log_y || low_value > 0;
        const double lo = low_on_axis ? L.PixelY(low_value) - a.y : a.height + 10.0;
        cv::line(area, Fixed(px, lo), Fixed(px, hi), colour, 1, cv::LINE_AA, kShift);
        cv::line(area, Fixed(px - 3.5, hi), Fixed(px + 3.5, hi), colour, 1, cv::LINE_AA, kShift);
        if (low_on_axis) {
          cv::line(area, Fixed(px - 3.5, lo), Fixed(px + 3.5, lo), colour, 1, cv::LINE_AA,
                   kShift);
        }
      }
    }
    if (HasLine(s.style)) {
      for (const std::vector<cv::Point2d>& run : PixelRuns(s, L)) {
        std::vector<cv::Point2d> pts;
        for (const cv::Point2d& q : run) pts.push_back(local(q));
        DrawPolyline(area, pts, s.style == PlotSeries::Style::kDashed, colour);
      }
    }
  }
  for (size_t j = 0; j < p.series.size(); ++j) {
    const PlotSeries& s = p.series[j];
    if (!HasMarkers(s.style)) continue;
    const Marker m = static_cast<Marker>(j % kMarkerCount);
    for (const std::vector<cv::Point2d>& run : PixelRuns(s, L)) {
      for (const cv::Point2d& q : run) DrawMarker(area, local(q), m, kPalette[j % kPalette.size()]);
    }
  }

  // Frame, ticks and tick labels.
  cv::rectangle(img, cv::Point(a.x - 1, a.y - 1), cv::Point(right, bottom), kBlack, 1,
                cv::LINE_8);
  const TextBox digit = DigitBox(kTickScale);
  for (size_t k = 0; k < L.x_ticks.size(); ++k) {
    const int px = static_cast<int>(std::lround(L.PixelX(L.x_ticks[k])));
    cv::line(img, {px, bottom + 1}, {px, bottom + kTickLength}, kBlack, 1, cv::LINE_8);
    PutTextCentred(img, L.x_tick_labels[k], px, X.x_tick_baseline, kTickScale, kTextGrey);
  }
  for (double x : L.x_minor_ticks) {
    const int px = static_cast<int>(std::lround(L.PixelX(x)));
    if (px < a.x || px >= right) continue;
    cv::line(img, {px, bottom + 1}, {px, bottom + kMinorTickLength}, kBlack, 1, cv::LINE_8);
  }
  for (size_t k = 0; k < L.y_ticks.size(); ++k) {
    const int py = static_cast<int>(std::lround(L.PixelY(L.y_ticks[k])));
    cv::line(img, {a.x - 2, py}, {a.x - 1 - kTickLength, py}, kBlack, 1, cv::LINE_8);
    const TextBox box = MeasureText(L.y_tick_labels[k], kFont, kTickScale);
    PutText(img, L.y_tick_labels[k], cv::Point(X.y_tick_right - box.width, py + digit.height / 2),
            kTickScale, kTextGrey);
  }
  for (double y : L.y_minor_ticks) {
    const int py = static_cast<int>(std::lround(L.PixelY(y)));
    if (py < a.y || py >= bottom) continue;
    cv::line(img, {a.x - 2, py}, {a.x - 1 - kMinorTickLength, py}, kBlack, 1, cv::LINE_8);
  }

  // Axis labels.
  if (!X.x_label.empty()) {
    PutTextCentred(img, X.x_label, plot_centre_x, X.x_label_baseline, X.x_label_scale, kBlack);
  }
  if (!X.y_label.empty()) {
    PutTextVertical(img, X.y_label, X.y_label_left, a.y + a.height / 2, X.y_label_scale, kBlack);
  }

  // Legend: drawn into its own box, then copied over the plot area (clipped
  // to it, should the box be larger than the area).
  if (L.legend.width > 0) {
    const PixelRect& g = L.legend;
    cv::Mat box(g.height, g.width, CV_8UC3, kWhite);
    cv::rectangle(box, cv::Rect(0, 0, g.width, g.height), kLegendBorder, 1, cv::LINE_8);
    const TextBox lb = MeasureText("Ag", kFont, kLegendScale);
    for (size_t row = 0; row < L.legend_series.size(); ++row) {
      const size_t j = static_cast<size_t>(L.legend_series[row]);
      const PlotSeries& s = p.series[j];
      const cv::Scalar& colour = kPalette[j % kPalette.size()];
      const PixelRect& sw = L.legend_swatches[row];
      const int x0 = sw.x - g.x, y0 = sw.y - g.y;  // the swatch in the box
      const double cx = x0 + sw.width / 2;
      const double cy = y0 + sw.height / 2;
      if (HasLine(s.style)) {
        DrawPolyline(box, {{x0 + 1.0, cy}, {x0 + sw.width - 1.0, cy}},
                     s.style == PlotSeries::Style::kDashed, colour);
      }
      if (!s.y_err.empty() && !HasLine(s.style)) {  // a small error bar behind the marker
        cv::line(box, Fixed(cx, cy - 7), Fixed(cx, cy + 7), colour, 1, cv::LINE_AA, kShift);
        cv::line(box, Fixed(cx - 3.5, cy - 7), Fixed(cx + 3.5, cy - 7), colour, 1, cv::LINE_AA,
                 kShift);
        cv::line(box, Fixed(cx - 3.5, cy + 7), Fixed(cx + 3.5, cy + 7), colour, 1, cv::LINE_AA,
                 kShift);
      }
      if (HasMarkers(s.style)) {
        DrawMarker(box, {cx, cy}, static_cast<Marker>(j % kMarkerCount), colour);
      }
      PutText(box, X.legend_labels[row],
              cv::Point(x0 + sw.width + 8, y0 + (sw.height + lb.height) / 2), kLegendScale,
              kBlack);
    }
    const cv::Rect dst(g.x, g.y, g.width, g.height);
    const cv::Rect clipped = dst & cv::Rect(a.x, a.y, a.width, a.height);
    if (clipped.area() > 0) {
      box(cv::Rect(clipped.x - dst.x, clipped.y - dst.y, clipped.width, clipped.height))
          .copyTo(img(clipped));
    }
  }
}

cv::Mat Render(const LinePlot& plot, const FullLayout& F) {
  cv::Mat img(F.pub.image_height, F.pub.image_width, CV_8UC3, kWhite);
  if (!F.title.empty()) {
    PutTextCentred(img, F.title, F.pub.image_width / 2, F.title_baseline, F.title_scale, kBlack,
                   kTitleFont);
  }
  for (size_t i = 0; i < F.pub.panels.size(); ++i) {
    DrawPanel(img, plot, i, F.pub.panels[i], F.extras[i]);
  }
  return img;
}

Status InternalError(const char* what) {
  return Status::IoError(std::string("line plot: cannot render the PNG: ") + what);
}

}  // namespace

Result<LinePlotLayout> LayoutLinePlot(const LinePlot& plot) {
  OPL_RETURN_IF_ERROR(Validate(plot));
  try {
    Result<FullLayout> layout = ComputeLayout(plot);
    if (!layout.ok()) return layout.status();
    return std::move(layout->pub);
  } catch (const std::exception& e) {  // cv::Exception, std::bad_alloc
    return InternalError(e.what());
  }
}

Result<std::vector<unsigned char>> RenderLinePlotPng(const LinePlot& plot) {
  OPL_RETURN_IF_ERROR(Validate(plot));
  try {
    Result<FullLayout> layout = ComputeLayout(plot);
    if (!layout.ok()) return layout.status();
    const cv::Mat img = Render(plot, *layout);
    std::vector<unsigned char> png;
    if (!cv::imencode(".png", img, png)) return InternalError("PNG encoder failed");
    return png;
  } catch (const std::exception& e) {  // cv::Exception, std::bad_alloc
    return InternalError(e.what());
  }
}

Status WriteLinePlotPng(const LinePlot& plot, const std::string& path) {
  Result<std::vector<unsigned char>> png = RenderLinePlotPng(plot);
  if (!png.ok()) return png.status();
  return WriteFileAtomically(path, std::string(png->begin(), png->end()));
}

}  // namespace opl
