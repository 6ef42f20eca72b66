#include "opl/pipeline/verify_lengths.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "io/csv.h"
#include "opl/core/message_text.h"

namespace opl {
namespace {

// A length's error as a linear function of the tag centres' errors (a
// gradient per tag) plus independent terms (variances) and shared terms
// (a gradient on the shared components z).
struct LinearError {
  std::map<int, Eigen::Vector3d> tag_gradient;
  double independent_variance = 0.0;
  Eigen::VectorXd shared_gradient;  // on z; empty when none

  // Adds `a` to tag `id`'s gradient (a tag may enter twice: a check length
  // sharing a tag with the bar). Eigen leaves a default-constructed vector
  // uninitialised, so the entry starts from zero here.
  void Add(int id, const Eigen::Vector3d& a) {
    tag_gradient.emplace(id, Eigen::Vector3d::Zero()).first->second += a;
  }
};

class ErrorModel {
 public:
  explicit ErrorModel(const FrontEndResult& fe) : fe_(fe) {
    split_ = !fe.tag_center_own_covariances.empty() &&
             fe.tag_center_own_covariances.size() == fe.tag_centers.size();
  }
  bool split() const { return split_; }

  double Variance(const LinearError& e) const {
    double var = e.independent_variance;
    Eigen::VectorXd shared = e.shared_gradient;
    for (const auto& [id, a] : e.tag_gradient) {
      if (!split_) {
        var += a.dot(fe_.tag_center_covariances.at(id) * a);
        continue;
      }
      var += a.dot(fe_.tag_center_own_covariances.at(id) * a);
      const Eigen::MatrixXd& K = fe_.tag_center_shared_factors.at(id);
      if (K.cols() == 0) continue;
      if (shared.size() == 0) shared = Eigen::VectorXd::Zero(K.cols());
      if (shared.size() == K.cols()) shared += K.transpose() * a;
    }
    return var + (shared.size() ? shared.squaredNorm() : 0.0);
  }

 private:
  const FrontEndResult& fe_;
  bool split_ = false;
};

ScaledLength Finish(double measured, double variance, double calibrated, double u_calibrated) {
  ScaledLength l;
  l.measured_mm = measured;
  l.u_measured_mm = std::sqrt(std::max(0.0, variance));
  l.error_mm = measured - calibrated;
  l.u_error_mm = std::hypot(l.u_measured_mm, u_calibrated);
  l.expanded_u_error_mm = 2.0 * l.u_error_mm;
  return l;
}

std::string Fixed(double v, int decimals) {
  const std::string fmt = "%." + std::to_string(decimals) + "f";
  return FormatPrintf(fmt.c_str(), v);
}

std::string Pad(const std::string& s, size_t width) {
  return s.size() >= width ? s + " " : std::string(width - s.size(), ' ') + s;
}

}  // namespace

Status CheckSceneHasCheckLengths(const Scene& scene) {
  if (!scene.check_lengths.empty()) return Status::Ok();
  return Status::InvalidArgument(
      "check_lengths: the scene lists no check length (pairs of tags with calibrated "
      "distances; docs/verify.md)");
}

std::vector<std::pair<int, int>> CheckLengthTags(const Scene& scene) {
  std::vector<std::pair<int, int>> tags;
  for (const SceneCheckLength& c : scene.check_lengths) tags.emplace_back(c.tag_1, c.tag_2);
  return tags;
}

Result<VerifyReport> VerifyLengths(const Scene& scene, const ImageMeasureReport& measured) {
  OPL_RETURN_IF_ERROR(CheckSceneHasCheckLengths(scene));
  const FrontEndResult& fe = measured.front_end;
  const ScaleResult& scale = measured.measure.scale;
  if (!(scale.scale_factor > 0.0)) return Status::NoSolution("the measurement has no scale factor");
  const ErrorModel model(fe);
  auto center = [&](int id) -> const Eigen::Vector3d* {
    const auto it = fe.tag_centers.find(id);
    return it == fe.tag_centers.end() ? nullptr : &it->second;
  };

  VerifyReport report;
  report.correlations_kept = model.split() && measured.scale_shared_gradient.size() > 0;
  report.scale_factor = scale.scale_factor;
  report.u_scale_factor = scale.u_scale_factor;
  const double s = scale.scale_factor;
  // s's own variance, and its shared gradient g (header comment).
  const double s_own_var = report.correlations_kept
                               ? measured.u_scale_factor_own * measured.u_scale_factor_own
                               : scale.u_scale_factor * scale.u_scale_factor;

  // The bar.
  double d_bar = 0.0;
  Eigen::Vector3d e_bar = Eigen::Vector3d::Zero();
  if (scene.artifact) {
    const Eigen::Vector3d* b1 = center(scene.artifact->tag_1);
    const Eigen::Vector3d* b2 = center(scene.artifact->tag_2);
    if (b1 == nullptr || b2 == nullptr) {
      report.warnings.push_back("no bar column: artifact tag " +
                                std::to_string(b1 == nullptr ? scene.artifact->tag_1
                                                             : scene.artifact->tag_2) +
                                " was not adjusted (not seen from two camera positions)");
    } else {
      d_bar = (*b2 - *b1).norm();
      if (d_bar > 0.0) {
        e_bar = (*b2 - *b1) / d_bar;
        report.bar_scale_factor = scene.artifact->length_mm / d_bar;
        LinearError e;
        const double sb = *report.bar_scale_factor;
        e.Add(scene.artifact->tag_2, -sb / d_bar * e_bar);
        e.Add(scene.artifact->tag_1, sb / d_bar * e_bar);
        e.independent_variance = std::pow(scene.artifact->length_sigma_mm / d_bar, 2);
        report.u_bar_scale_factor = std::sqrt(model.Variance(e));
      }
    }
  }

  // OPL in the adjustment: its lengths, when it was asked for them.
  const ProjectorAdjustmentResult* projector = nullptr;
  if (measured.projector) {
    if (measured.projector->lengths_mm.size() == scene.check_lengths.size()) {
      projector = &*measured.projector;
      report.projector_scale_factor = projector->scale_factor;
      report.u_projector_scale_factor = projector->u_scale_factor;
    } else {
      report.warnings.push_back(
          "no column for the scale inside the adjustment: it was not asked for the check lengths "
          "(ImageMeasureOptions::projector_tag_lengths = CheckLengthTags(scene))");
    }
  } else if (!measured.projector_status.ok()) {
    report.warnings.push_back("no column for the scale inside the adjustment: " +
                              measured.scale_method_note);
  }

  for (const SceneCheckLength& check : scene.check_lengths) {
    const Eigen::Vector3d* t1 = center(check.tag_1);
    const Eigen::Vector3d* t2 = center(check.tag_2);
    if (t1 == nullptr || t2 == nullptr) {
      return Status::NoSolution("check length " + QuoteForMessage(check.name) + ": tag " +
                                std::to_string(t1 == nullptr ? check.tag_1 : check.tag_2) +
                                " was not adjusted (not seen from two camera positions)");
    }
    CheckLengthResult r;
    r.name = check.name;
    r.tag_1 = check.tag_1;
    r.tag_2 = check.tag_2;
    r.calibrated_mm = check.length_mm;
    r.u_calibrated_mm = check.length_sigma_mm;
    const double d = (*t2 - *t1).norm();
    r.unscaled = d;
    const Eigen::Vector3d e = d > 0.0 ? Eigen::Vector3d((*t2 - *t1) / d) : Eigen::Vector3d::Zero();

    LinearError opl;
    opl.Add(check.tag_2, s * e);
    opl.Add(check.tag_1, -(s * e));
    opl.independent_variance = d * d * s_own_var;
    if (report.correlations_kept) opl.shared_gradient = d * measured.scale_shared_gradient;
    r.opl = Finish(s * d, model.Variance(opl), check.length_mm, check.length_sigma_mm);

    if (report.bar_scale_factor) {
      const double sb = *report.bar_scale_factor;
      LinearError bar;
      bar.Add(check.tag_2, sb * e);
      bar.Add(check.tag_1, -(sb * e));
      bar.Add(scene.artifact->tag_2, -(sb * (d / d_bar) * e_bar));
      bar.Add(scene.artifact->tag_1, sb * (d / d_bar) * e_bar);
      bar.independent_variance = std::pow(d / d_bar * scene.artifact->length_sigma_mm, 2);
      r.bar = Finish(sb * d, model.Variance(bar), check.length_mm, check.length_sigma_mm);
    }
    if (projector != nullptr) {
      const size_t k = report.lengths.size();
      r.projector = Finish(projector->lengths_mm[k], std::pow(projector->u_lengths_mm[k], 2),
                           check.length_mm, check.length_sigma_mm);
    }
    report.lengths.push_back(r);
  }

  // Summary and the test's conditions.
  double sum_opl = 0.0, sum_bar = 0.0, sum_projector = 0.0;
  for (const CheckLengthResult& r : report.lengths) {
    report.longest_mm = std::max(report.longest_mm, r.calibrated_mm);
    report.max_abs_error_opl_mm = std::max(report.max_abs_error_opl_mm, std::abs(r.opl.error_mm));
    sum_opl += r.opl.error_mm * r.opl.error_mm;
    if (r.bar) {
      report.max_abs_error_bar_mm = std::max(report.max_abs_error_bar_mm, std::abs(r.bar->error_mm));
      sum_bar += r.bar->error_mm * r.bar->error_mm;
    }
    if (r.projector) {
      report.max_abs_error_projector_mm =
          std::max(report.max_abs_error_projector_mm, std::abs(r.projector->error_mm));
      sum_projector += r.projector->error_mm * r.projector->error_mm;
    }
  }
  const double n = static_cast<double>(report.lengths.size());
  report.rms_error_opl_mm = std::sqrt(sum_opl / n);
  if (report.bar_scale_factor) report.rms_error_bar_mm = std::sqrt(sum_bar / n);
  if (projector != nullptr) report.rms_error_projector_mm = std::sqrt(sum_projector / n);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const auto& [id, c] : fe.tag_centers) {
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  report.space_diagonal_mm = fe.tag_centers.empty() ? 0.0 : s * (hi - lo).norm();
  if (report.lengths.size() < 7) {
    report.warnings.push_back(std::to_string(report.lengths.size()) +
                              " check lengths: VDI/VDE 2634-1 asks for at least 7 positions");
  }
  if (report.longest_mm < 2.0 / 3.0 * report.space_diagonal_mm) {
    report.warnings.push_back("the longest check length (" + Fixed(report.longest_mm, 1) +
                              " mm) is under 2/3 of the volume's space diagonal (" +
                              Fixed(report.space_diagonal_mm, 1) +
                              " mm, box of the tag centres): VDI/VDE 2634-1 asks for at least 2/3");
  }
  if (!report.correlations_kept) {
    report.warnings.push_back(
        "the front end gave no split of the errors into own and shared parts: the tags' and s's "
        "errors are taken as independent (u(E) approximate)");
  }
  return report;
}

std::string VerifyReport::ToText() const {
  std::string out = "Length measurement error E = L - L_cal (VDI/VDE 2634-1, ISO 10360-13), mm; "
                    "U(E) expanded, k = 2\n";
  const bool has_bar = bar_scale_factor.has_value();
  const bool has_projector = projector_scale_factor.has_value();
  out += "columns: OPL = scaled by the laser module (two-step)";
  if (has_projector) out += "; adj = OPL inside the bundle adjustment";
  if (has_bar) out += "; bar = scaled by the scene's bar";
  out += "\n";
  out += Pad("check", 14) + Pad("tags", 10) + Pad("L_cal", 12) + Pad("L (OPL)", 12) +
         Pad("E (OPL)", 10) + Pad("U(E)", 9) +
         (has_projector ? Pad("L (adj)", 12) + Pad("E (adj)", 10) + Pad("U(E)", 9) : "") +
         (has_bar ? Pad("L (bar)", 12) + Pad("E (bar)", 10) + Pad("U(E)", 9) : "") + "\n";
  for (const CheckLengthResult& r : lengths) {
    out += Pad(r.name, 14) + Pad(std::to_string(r.tag_1) + "-" + std::to_string(r.tag_2), 10) +
           Pad(Fixed(r.calibrated_mm, 3), 12) + Pad(Fixed(r.opl.measured_mm, 3), 12) +
           Pad(Fixed(r.opl.error_mm, 3), 10) + Pad(Fixed(r.opl.expanded_u_error_mm, 3), 9);
    if (has_projector && r.projector) {
      out += Pad(Fixed(r.projector->measured_mm, 3), 12) + Pad(Fixed(r.projector->error_mm, 3), 10) +
             Pad(Fixed(r.projector->expanded_u_error_mm, 3), 9);
    }
    if (has_bar && r.bar) {
      out += Pad(Fixed(r.bar->measured_mm, 3), 12) + Pad(Fixed(r.bar->error_mm, 3), 10) +
             Pad(Fixed(r.bar->expanded_u_error_mm, 3), 9);
    }
    out += "\n";
  }
  int within_opl = 0, within_bar = 0, within_projector = 0;
  for (const CheckLengthResult& r : lengths) {
    within_opl += r.opl.within_uncertainty() ? 1 : 0;
    within_bar += r.bar && r.bar->within_uncertainty() ? 1 : 0;
    within_projector += r.projector && r.projector->within_uncertainty() ? 1 : 0;
  }
  out += "OPL: s = " + FormatPrintf("%.9f", scale_factor) + " +- " + FormatPrintf("%.9f", u_scale_factor) +
         "; max |E| " + Fixed(max_abs_error_opl_mm, 3) + " mm, RMS E " + Fixed(rms_error_opl_mm, 3) +
         " mm; |E| <= U(E) for " + std::to_string(within_opl) + " of " + std::to_string(lengths.size()) + "\n";
  if (has_projector) {
    out += "adj: s = " + FormatPrintf("%.9f", *projector_scale_factor) + " +- " +
           FormatPrintf("%.9f", u_projector_scale_factor) + "; max |E| " +
           Fixed(max_abs_error_projector_mm, 3) + " mm, RMS E " + Fixed(rms_error_projector_mm, 3) +
           " mm; |E| <= U(E) for " + std::to_string(within_projector) + " of " +
           std::to_string(lengths.size()) + "\n";
  }
  if (has_bar) {
    out += "bar: s = " + FormatPrintf("%.9f", *bar_scale_factor) + " +- " +
           FormatPrintf("%.9f", u_bar_scale_factor) + "; max |E| " + Fixed(max_abs_error_bar_mm, 3) +
           " mm, RMS E " + Fixed(rms_error_bar_mm, 3) + " mm; |E| <= U(E) for " +
           std::to_string(within_bar) + " of " + std::to_string(lengths.size()) + "\n";
  }
  out += "volume: space diagonal " + Fixed(space_diagonal_mm, 1) + " mm, longest check length " +
         Fixed(longest_mm, 1) + " mm\n";
  for (const std::string& w : warnings) out += "warning: " + w + "\n";
  return out;
}

std::string VerifyReport::ToCsv() const {
  std::string out =
      "name,tag_1,tag_2,calibrated_mm,u_calibrated_mm,opl_mm,u_opl_mm,opl_error_mm,"
      "opl_expanded_u_error_mm,bar_mm,u_bar_mm,bar_error_mm,bar_expanded_u_error_mm,"
      "adjustment_mm,u_adjustment_mm,adjustment_error_mm,adjustment_expanded_u_error_mm\n";
  for (const CheckLengthResult& r : lengths) {
    out += csv_internal::QuoteCsvField(r.name) + "," + std::to_string(r.tag_1) + "," + std::to_string(r.tag_2) + "," +
           FormatRoundTrip(r.calibrated_mm) + "," + FormatRoundTrip(r.u_calibrated_mm) + "," +
           FormatRoundTrip(r.opl.measured_mm) + "," + FormatRoundTrip(r.opl.u_measured_mm) + "," +
           FormatRoundTrip(r.opl.error_mm) + "," + FormatRoundTrip(r.opl.expanded_u_error_mm) + ",";
    if (r.bar) {
      out += FormatRoundTrip(r.bar->measured_mm) + "," + FormatRoundTrip(r.bar->u_measured_mm) + "," +
             FormatRoundTrip(r.bar->error_mm) + "," + FormatRoundTrip(r.bar->expanded_u_error_mm);
    } else {
      out += ",,,";
    }
    out += ",";
    if (r.projector) {
      out += FormatRoundTrip(r.projector->measured_mm) + "," + FormatRoundTrip(r.projector->u_measured_mm) +
             "," + FormatRoundTrip(r.projector->error_mm) + "," +
             FormatRoundTrip(r.projector->expanded_u_error_mm);
    } else {
      out += ",,,";
    }
    out += "\n";
  }
  return out;
}

std::string VerifyReport::ToJson() const {
  using nlohmann::ordered_json;
  auto scaled = [](const ScaledLength& l) {
    return ordered_json{{"measured_mm", l.measured_mm},
                        {"u_measured_mm", l.u_measured_mm},
                        {"error_mm", l.error_mm},
                        {"u_error_mm", l.u_error_mm},
                        {"expanded_u_error_mm", l.expanded_u_error_mm},
                        {"within_uncertainty", l.within_uncertainty()}};
  };
  ordered_json doc;
  doc["format"] = "opl.verify_report";
  doc["version"] = 1;
  doc["coverage_factor"] = 2;
  doc["scale_factor"] = scale_factor;
  doc["u_scale_factor"] = u_scale_factor;
  doc["bar_scale_factor"] = bar_scale_factor ? ordered_json(*bar_scale_factor) : ordered_json(nullptr);
  doc["u_bar_scale_factor"] = bar_scale_factor ? ordered_json(u_bar_scale_factor) : ordered_json(nullptr);
  ordered_json rows = ordered_json::array();
  for (const CheckLengthResult& r : lengths) {
    ordered_json row = {{"name", r.name},
                        {"tag_1", r.tag_1},
                        {"tag_2", r.tag_2},
                        {"calibrated_mm", r.calibrated_mm},
                        {"u_calibrated_mm", r.u_calibrated_mm},
                        {"unscaled", r.unscaled},
                        {"opl", scaled(r.opl)}};
    row["bar"] = r.bar ? scaled(*r.bar) : ordered_json(nullptr);
    row["adjustment"] = r.projector ? scaled(*r.projector) : ordered_json(nullptr);
    rows.push_back(std::move(row));
  }
  doc["lengths"] = std::move(rows);
  doc["max_abs_error_opl_mm"] = max_abs_error_opl_mm;
  doc["rms_error_opl_mm"] = rms_error_opl_mm;
  doc["max_abs_error_bar_mm"] = bar_scale_factor ? ordered_json(max_abs_error_bar_mm) : ordered_json(nullptr);
  doc["rms_error_bar_mm"] = bar_scale_factor ? ordered_json(rms_error_bar_mm) : ordered_json(nullptr);
  const bool adj = projector_scale_factor.has_value();
  doc["adjustment_scale_factor"] = adj ? ordered_json(*projector_scale_factor) : ordered_json(nullptr);
  doc["u_adjustment_scale_factor"] = adj ? ordered_json(u_projector_scale_factor) : ordered_json(nullptr);
  doc["max_abs_error_adjustment_mm"] = adj ? ordered_json(max_abs_error_projector_mm) : ordered_json(nullptr);
  doc["rms_error_adjustment_mm"] = adj ? ordered_json(rms_error_projector_mm) : ordered_json(nullptr);
  doc["space_diagonal_mm"] = space_diagonal_mm;
  doc["longest_mm"] = longest_mm;
  doc["correlations_kept"] = correlations_kept;
  doc["warnings"] = warnings;
  return doc.dump(2) + "\n";
}

LinePlot VerifyReport::ToPlot(const std::string& scene_name) const {
  LinePlot plot;
  plot.title = "Length measurement error, " + scene_name + ": E +- U(E) (k = 2)";
  double lo = INFINITY, hi = -INFINITY;
  for (const CheckLengthResult& r : lengths) {
    lo = std::min(lo, r.calibrated_mm);
    hi = std::max(hi, r.calibrated_mm);
  }
  // Columns drawn apart by 1 % of the lengths' span (a single length: 1 %
  // of itself) so that their error bars do not hide each other.
  const double shift = 0.01 * (hi > lo ? hi - lo : std::max(1.0, std::abs(hi)));
  PlotSeries opl_series, projector_series, bar_series, zero;
  opl_series.label = "OPL, two-step (module alone)";
  projector_series.label = "OPL in the adjustment (module alone)";
  bar_series.label = "bar (the scene's artifact)";
  opl_series.style = projector_series.style = bar_series.style = PlotSeries::Style::kMarkers;
  zero.style = PlotSeries::Style::kDashed;
  auto add = [](PlotSeries* series, double x, const ScaledLength& l) {
    series->x.push_back(x);
    series->y.push_back(l.error_mm);
    series->y_err.push_back(l.expanded_u_error_mm);
  };
  for (const CheckLengthResult& r : lengths) {
    add(&opl_series, r.calibrated_mm - shift, r.opl);
    if (r.projector) add(&projector_series, r.calibrated_mm, *r.projector);
    if (r.bar) add(&bar_series, r.calibrated_mm + shift, *r.bar);
  }
  if (!lengths.empty()) {
    zero.x = {lo - 2.0 * shift, hi + 2.0 * shift};
    zero.y = {0.0, 0.0};
  }
  PlotPanel all;
  all.x_label = "calibrated length L_cal (mm)";
  all.y_label = "E = L - L_cal (mm)";
  const bool small = !projector_series.x.empty() || !bar_series.x.empty();
  // Empty series keep each column's colour in both panels.
  PlotSeries none;
  none.style = PlotSeries::Style::kMarkers;
  none.x = {NAN};
  none.y = {NAN};
  auto or_none = [&](const PlotSeries& s) { return s.x.empty() ? none : s; };
  if (!small) {
    all.series = {std::move(opl_series), std::move(zero)};
    plot.panels.push_back(std::move(all));
    plot.panel_width_px = 900;
    plot.panel_height_px = 560;
    return plot;
  }
  // The two-step column's U(E) can be far larger than the others': a second
  // panel shows the adjustment's and the bar's columns on their own scale.
  all.title = "every column";
  PlotPanel close = all;
  close.title = "in the adjustment and bar, their own scale";
  PlotSeries unlabelled_none = none;
  close.series = {unlabelled_none, or_none(projector_series), or_none(bar_series), zero};
  all.series = {std::move(opl_series), or_none(projector_series), or_none(bar_series), std::move(zero)};
  plot.panels = {std::move(all), std::move(close)};
  plot.panel_width_px = 640;
  plot.panel_height_px = 520;
  return plot;
}

}  // namespace opl
