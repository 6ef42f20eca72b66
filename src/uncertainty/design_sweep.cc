#include "opl/uncertainty/design_sweep.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "opl/core/format.h"
#include "opl/core/number_list.h"
#include "opl/model/beam_pattern.h"
#include "opl/sim/simulate_slices.h"

namespace opl {
namespace {

constexpr double kDegToRad = kPi / 180.0;

// The one table of the parameters: --param name, the quantity in words (for
// titles) and its unit (empty: none; the axis label is "noun (unit)").
struct ParameterInfo {
  SweepParameter parameter;
  const char* name;
  const char* noun;
  const char* unit;
};

constexpr ParameterInfo kParameters[] = {
    {SweepParameter::kNoiseMm, "noise_mm", "spot noise sigma, largest axis", "mm"},
    {SweepParameter::kFullAngleDeg, "full_angle_deg", "fan full angle", "deg"},
    {SweepParameter::kBeamsPerSide, "beams_per_side", "beams per side n", ""},
    {SweepParameter::kSeparationMm, "separation_mm", "separation of the origins", "mm"},
    {SweepParameter::kDistanceMm, "distance_mm", "projection distance", "mm"},
    {SweepParameter::kStaggerDeg, "stagger_deg", "stagger of the baseline",
     "deg; 0 side by side, 45 staggered"},
    {SweepParameter::kLayout, "layout", "layout", ""},
};

// The named values of layout (stagger angles, deg).
constexpr double kSideBySideDeg = 0.0;
constexpr double kStaggeredDeg = 45.0;

// In the plot of a categorical sweep, the first order and the bound sit this
// far left and right of their category's x (the Monte Carlo on it).
constexpr double kCategoryDodge = 0.12;

const ParameterInfo* Find(SweepParameter parameter) {
  for (const ParameterInfo& p : kParameters) {
    if (p.parameter == parameter) return &p;
  }
  return nullptr;
}

Status OutOfDomain(SweepParameter parameter, double value, const std::string& rule) {
  return Status::InvalidArgument(std::string(SweepParameterName(parameter)) + " = " +
                                 SweepValueText(parameter, value) + ": " + rule);
}

std::string KnownNames() {
  std::string names;
  for (const ParameterInfo& p : kParameters) names += std::string(names.empty() ? "" : ", ") + p.name;
  return names;
}

std::string Number(double v) { return FormatRoundTrip(v); }

}  // namespace

const std::vector<SweepParameter>& AllSweepParameters() {
  static const std::vector<SweepParameter> all = [] {
    std::vector<SweepParameter> out;
    for (const ParameterInfo& p : kParameters) out.push_back(p.parameter);
    return out;
  }();
  return all;
}

const char* SweepParameterName(SweepParameter parameter) {
  const ParameterInfo* p = Find(parameter);
  return p ? p->name : "?";
}

std::string SweepParameterNoun(SweepParameter parameter) {
  const ParameterInfo* p = Find(parameter);
  return p ? p->noun : "?";
}

std::string SweepParameterLabel(SweepParameter parameter) {
  const ParameterInfo* p = Find(parameter);
  if (!p) return "?";
  return *p->unit ? std::string(p->noun) + " (" + p->unit + ")" : std::string(p->noun);
}

bool IsCategoricalSweep(SweepParameter parameter) { return parameter == SweepParameter::kLayout; }

std::string SweepValueText(SweepParameter parameter, double value) {
  if (parameter == SweepParameter::kLayout) {
    if (value == kSideBySideDeg) return "side_by_side";
    if (value == kStaggeredDeg) return "staggered";
  }
  return FormatNumber(value);
}

Result<SweepParameter> ParseSweepParameter(const std::string& text) {
  for (const ParameterInfo& p : kParameters) {
    if (text == p.name) return p.parameter;
  }
  return Status::InvalidArgument("unknown sweep parameter '" + text + "' (known: " + KnownNames() +
                                 ")");
}

Result<std::vector<double>> ParseSweepValues(const std::string& text_parameter,
                                             const std::string& values) {
  if (text_parameter == "layout") {
    std::vector<double> out;
    size_t start = 0;
    while (true) {
      const size_t at = values.find(',', start);
      const std::string word =
          values.substr(start, at == std::string::npos ? std::string::npos : at - start);
      if (word == "side_by_side") {
        out.push_back(kSideBySideDeg);
      } else if (word == "staggered") {
        out.push_back(kStaggeredDeg);
      } else {
        return Status::InvalidArgument("layout '" + word +
                                       "': expected side_by_side or staggered (or sweep "
                                       "stagger_deg for other angles)");
      }
      if (at == std::string::npos) break;
      start = at + 1;
    }
    return out;
  }
  NumberListSyntax syntax;
  syntax.noun = "value";
  return ParseNumberList(values, syntax);
}

Result<ModuleDesign> ApplySweepValue(const ModuleDesign& base, SweepParameter parameter,
                                     double value) {
  if (!std::isfinite(value)) return OutOfDomain(parameter, value, "not finite");
  ModuleDesign d = base;
  switch (parameter) {
    case SweepParameter::kNoiseMm: {
      const double largest = d.spot_noise_mm.maxCoeff();
      if (!(value > 0.0)) return OutOfDomain(parameter, value, "must be > 0");
      if (!(largest > 0.0)) {
        return OutOfDomain(parameter, value, "the design's spot noise is zero: no axis ratios");
      }
      d.spot_noise_mm *= value / largest;
      break;
    }
    case SweepParameter::kFullAngleDeg:
      if (!(value > 0.0 && value < 180.0)) {
        return OutOfDomain(parameter, value, "must be in (0, 180)");
      }
      for (SourceDesign& s : d.sources) {
        if (s.pattern == PatternModel::kFile) {
          return OutOfDomain(parameter, value,
                             "source '" + s.name + "' has its pattern from a file");
        }
        s.full_angle_deg = value;
      }
      break;
    case SweepParameter::kBeamsPerSide: {
      const double n = std::round(value);
      if (n != value || n < 3 || std::fmod(n, 2.0) == 0.0 || n > kMaxBeamsPerSide) {
        return OutOfDomain(parameter, value,
                           "must be an odd integer in [3, " + std::to_string(kMaxBeamsPerSide) +
                               "]");
      }
      for (SourceDesign& s : d.sources) {
        if (s.pattern == PatternModel::kFile) {
          return OutOfDomain(parameter, value,
                             "source '" + s.name + "' has its pattern from a file");
        }
        s.beams_per_side = static_cast<int>(n);
      }
      break;
    }
    case SweepParameter::kSeparationMm: {
      if (!(value > 0.0)) return OutOfDomain(parameter, value, "must be > 0");
      if (d.sources.size() < 2) return OutOfDomain(parameter, value, "needs two sources");
      const double current = (d.sources[0].scene_from_source.translation -
                              d.sources[1].scene_from_source.translation)
                                 .norm();
      if (!(current > 0.0)) {
        return OutOfDomain(parameter, value, "the first two origins coincide: no baseline");
      }
      Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
      for (const SourceDesign& s : d.sources) centroid += s.scene_from_source.translation;
      centroid /= static_cast<double>(d.sources.size());
      for (SourceDesign& s : d.sources) {
        Eigen::Vector3d& o = s.scene_from_source.translation;
        o = centroid + (value / current) * (o - centroid);
      }
      break;
    }
    case SweepParameter::kDistanceMm: {
      if (!(value > 0.0)) return OutOfDomain(parameter, value, "must be > 0");
      Result<ModuleViewpoint> view = MeanViewpoint(d);
      if (!view.ok()) return view.status();
      const std::optional<Eigen::Vector3d> hit =
          d.surface.IntersectRay(view->origin_mm, view->viewing_direction);
      if (!hit) {
        return OutOfDomain(parameter, value,
                           std::string("the ") + d.surface.TypeName() +
                               " is not hit along the module's viewing direction");
      }
      const double current = (*hit - view->origin_mm).dot(view->viewing_direction);
      d.surface = d.surface.Transformed(
          Rigid3d(Eigen::Matrix3d::Identity(), (value - current) * view->viewing_direction));
      break;
    }
    case SweepParameter::kLayout:
    case SweepParameter::kStaggerDeg: {
      if (parameter == SweepParameter::kLayout && value != kSideBySideDeg &&
          value != kStaggeredDeg) {
        return OutOfDomain(parameter, value, "must be 0 (side_by_side) or 45 (staggered)");
      }
      if (!(value >= 0.0 && value <= 90.0)) {
        return OutOfDomain(parameter, value, "must be in [0, 90]");
      }
      if (d.sources.size() != 2) {
        return OutOfDomain(parameter, value,
                           "needs exactly two sources, the design has " +
                               std::to_string(d.sources.size()));
      }
      Result<ModuleViewpoint> view = MeanViewpoint(d);
      if (!view.ok()) return view.status();
      const Eigen::Vector3d& v = view->viewing_direction;
      Eigen::Vector3d& a = d.sources[0].scene_from_source.translation;
      Eigen::Vector3d& b = d.sources[1].scene_from_source.translation;
      const Eigen::Vector3d baseline = a - b;
      const double length = baseline.norm();
      if (!(length > 0.0)) {
        return OutOfDomain(parameter, value, "the two origins coincide: no baseline");
      }
      Eigen::Vector3d lateral = baseline - baseline.dot(v) * v;
      if (lateral.norm() < 1e-9 * length) lateral = view->up.cross(v);  // in line: pick a side
      lateral.normalize();
      const Eigen::Vector3d midpoint = 0.5 * (a + b);
      const double angle = value * kDegToRad;
      const Eigen::Vector3d half =
          0.5 * length * (std::cos(angle) * lateral + std::sin(angle) * v);
      a = midpoint + half;
      b = midpoint - half;
      break;
    }
  }
  if (Status st = d.Validate(); !st.ok()) {
    return OutOfDomain(parameter, value, st.message());
  }
  return d;
}

Result<DesignSweep> RunDesignSweep(const ModuleDesign& base, SweepParameter parameter,
                                   const std::vector<double>& values,
                                   const MonteCarloOptions& options) {
  if (values.empty()) return Status::InvalidArgument("no values to sweep");
  DesignSweep sweep;
  sweep.parameter = parameter;
  // The progress counts every trial of the sweep in an int.
  if (static_cast<long long>(values.size()) * options.iterations >
      std::numeric_limits<int>::max()) {
    return Status::InvalidArgument(std::to_string(values.size()) + " values of " +
                                   std::to_string(options.iterations) +
                                   " iterations each are more than 2^31 - 1 trials in all");
  }
  const int total = static_cast<int>(values.size()) * options.iterations;
  for (size_t i = 0; i < values.size(); ++i) {
    const std::string where = std::string(SweepParameterName(parameter)) + " = " +
                              SweepValueText(parameter, values[i]) + ": ";
    Result<ModuleDesign> design = ApplySweepValue(base, parameter, values[i]);
    if (!design.ok()) return design.status();  // names the parameter and value
    MonteCarloOptions point_options = options;
    if (options.progress) {
      const int offset = static_cast<int>(i) * options.iterations;
      point_options.progress = [&options, offset, total](int done, int) {
        options.progress(offset + done, total);
      };
    }
    Result<MonteCarloReport> report = RunMeasurementMonteCarlo(*design, point_options);
    if (!report.ok()) {
      return Status(report.status().code(), where + report.status().message());
    }
    sweep.points.push_back({values[i], std::move(*report)});
  }
  return sweep;
}

std::string DesignSweep::ToCsv() const {
  std::string out =
      "parameter,value,from,to,true_mm,mean_mm,std_mm,std_u_mm,first_order_std_mm,"
      "cramer_rao_std_mm,ci95_low_mm,ci95_high_mm,u_rel_ppm,s_std_ppm,s_first_order_std_ppm,"
      "s_cramer_rao_std_ppm,iterations,failed\n";
  const std::string name = SweepParameterName(parameter);
  for (const DesignSweepPoint& p : points) {
    const MonteCarloReport& r = p.report;
    for (const MonteCarloLength& l : r.lengths) {
      const SampleSummary& s = l.photo_mm;
      const double std_u = r.succeeded > 1 ? s.std_dev / std::sqrt(2.0 * (r.succeeded - 1)) : 0.0;
      const std::string low = s.has_interval ? Number(s.symmetric.low) : "";
      const std::string high = s.has_interval ? Number(s.symmetric.high) : "";
      out += name + "," + Number(p.value) + "," + l.from + "," + l.to + "," + Number(l.true_mm) +
             "," + Number(s.mean) + "," + Number(s.std_dev) + "," + Number(std_u) + "," +
             Number(s.first_order_std) + "," + Number(s.cramer_rao_std) + "," + low + "," + high +
             "," + Number(1e6 * s.std_dev / l.true_mm) + "," +
             Number(1e6 * r.scale_factor.std_dev) + "," +
             Number(1e6 * r.scale_factor.first_order_std) + "," +
             Number(1e6 * r.scale_factor.cramer_rao_std) + "," + std::to_string(r.iterations) +
             "," + std::to_string(r.failed) + "\n";
    }
  }
  return out;
}

LinePlot DesignSweep::ToPlot() const {
  const bool categorical = IsCategoricalSweep(parameter);
  LinePlot plot;
  plot.title = "Design sweep over the " + SweepParameterNoun(parameter) +
               (points.empty() ? std::string()
                               : " (" + std::to_string(points.front().report.iterations) +
                                     " Monte Carlo iterations per point, " +
                                     SpotWeightingName(points.front().report.weighting) +
                                     " weighting)");
  PlotPanel absolute, relative;
  absolute.title = "standard deviation of L";
  absolute.x_label = relative.x_label = SweepParameterLabel(parameter);
  if (categorical) {
    // A categorical axis: a named tick at 1, 2, ... per value, in sweep order.
    for (size_t i = 0; i < points.size(); ++i) {
      std::string name = SweepValueText(parameter, points[i].value);
      std::replace(name.begin(), name.end(), '_', ' ');
      absolute.x_categories.push_back(PlotCategory{static_cast<double>(i + 1), name});
    }
    relative.x_categories = absolute.x_categories;
  }
  absolute.y_label = "std of L (mm)";
  relative.title = "relative uncertainty of L";
  relative.y_label = "u(L) / L (ppm)";
  const size_t lengths = points.empty() ? 0 : points.front().report.lengths.size();
  for (size_t k = 0; k < lengths; ++k) {
    const MonteCarloLength& first = points.front().report.lengths[k];
    const std::string suffix = lengths > 1 ? " " + first.from + "-" + first.to : std::string();
    PlotSeries mc, fo, crb;
    mc.label = "Monte Carlo" + suffix;
    mc.style = PlotSeries::Style::kMarkers;
    fo.label = "first order" + suffix;
    fo.style = categorical ? PlotSeries::Style::kMarkers : PlotSeries::Style::kLineMarkers;
    crb.label = "Cramer-Rao bound" + suffix;
    crb.style = categorical ? PlotSeries::Style::kMarkers : PlotSeries::Style::kDashed;
    PlotSeries mc_rel = mc, fo_rel = fo, crb_rel = crb;
    for (size_t i = 0; i < points.size(); ++i) {
      const DesignSweepPoint& p = points[i];
      const MonteCarloLength& l = p.report.lengths[k];
      const SampleSummary& s = l.photo_mm;
      const int m = p.report.succeeded;
      const double std_u = m > 1 ? s.std_dev / std::sqrt(2.0 * (m - 1)) : 0.0;
      const double to_ppm = 1e6 / l.true_mm;
      // A category's three markers side by side (they often coincide).
      const double x = categorical ? static_cast<double>(i + 1) : p.value;
      const double dodge = categorical ? kCategoryDodge : 0.0;
      for (PlotSeries* series : {&mc, &mc_rel}) series->x.push_back(x);
      for (PlotSeries* series : {&fo, &fo_rel}) series->x.push_back(x - dodge);
      for (PlotSeries* series : {&crb, &crb_rel}) series->x.push_back(x + dodge);
      mc.y.push_back(s.std_dev);
      mc.y_err.push_back(std_u);
      fo.y.push_back(s.first_order_std);
      crb.y.push_back(s.cramer_rao_std);
      mc_rel.y.push_back(s.std_dev * to_ppm);
      mc_rel.y_err.push_back(std_u * to_ppm);
      fo_rel.y.push_back(s.first_order_std * to_ppm);
      crb_rel.y.push_back(s.cramer_rao_std * to_ppm);
    }
    // Drawn in this order: the dashed bound over the solid first order.
    absolute.series.push_back(std::move(fo));
    absolute.series.push_back(std::move(crb));
    absolute.series.push_back(std::move(mc));
    relative.series.push_back(std::move(fo_rel));
    relative.series.push_back(std::move(crb_rel));
    relative.series.push_back(std::move(mc_rel));
  }
  plot.panels = {std::move(absolute), std::move(relative)};
  return plot;
}

}  // namespace opl
