#include "opl/pipeline/measure.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <tuple>

#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "opl/core/message_text.h"

namespace opl {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

std::string JoinInts(const std::vector<int>& ids) {
  std::string out;
  for (size_t i = 0; i < ids.size(); ++i) out += (i ? ", " : "") + std::to_string(ids[i]);
  return out;
}

Eigen::Vector3d StdDevs(const Eigen::Matrix3d& cov) {
  return cov.diagonal().cwiseMax(0.0).cwiseSqrt();
}

nlohmann::ordered_json VectorJson(const Eigen::Vector3d& v) {
  return nlohmann::ordered_json::array({v.x(), v.y(), v.z()});
}

nlohmann::ordered_json MatrixJson(const Eigen::Matrix3d& m) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

// "A found (118 points); B ambiguous: ..." for error messages.
std::string IdentificationBrief(const IdentifyResult& identification) {
  std::string out;
  for (const IdentifiedSource& s : identification.sources) {
    out += (out.empty() ? "" : "; ") + s.name + (s.placement.empty() ? "" : " at " + s.placement) + " " +
           IdentifyOutcomeName(s.outcome) +
           (s.outcome == IdentifyOutcome::kFound
                ? " (" + std::to_string(s.assigned) + " points)"
                : (s.detail.empty() ? std::string() : ": " + s.detail));
  }
  return out;
}

}  // namespace

Status MeasureOptions::Validate() const {
  Status st = locate.Validate();
  if (!st.ok()) return Status::InvalidArgument("locate options: " + st.message());
  st = identify.Validate();
  if (!st.ok()) return Status::InvalidArgument("identify options: " + st.message());
  return Status::Ok();
}

namespace {

// IdentifySpots, one module placement at a time (Spot::placement: the
// spots of two placements are two sets of grids of the same sources): the
// results combined, each placement's sources after the previous one's,
// named with their placement.
Result<IdentifyResult> IdentifyByPlacement(const ModuleCalibration& calibration,
                                           const std::vector<Spot>& spots,
                                           const IdentifyOptions& options) {
  std::vector<std::string> placements;
  for (const Spot& spot : spots) {
    if (std::find(placements.begin(), placements.end(), spot.placement) == placements.end()) {
      placements.push_back(spot.placement);
    }
  }
  if (placements.size() <= 1) return IdentifySpots(calibration, spots, options);
  IdentifyResult combined;
  combined.source_index.assign(spots.size(), -1);
  combined.beam_id.assign(spots.size(), 0);
  for (const std::string& placement : placements) {
    std::vector<size_t> index;
    std::vector<Spot> subset;
    for (size_t i = 0; i < spots.size(); ++i) {
      if (spots[i].placement != placement) continue;
      index.push_back(i);
      subset.push_back(spots[i]);
    }
    Result<IdentifyResult> r = IdentifySpots(calibration, subset, options);
    if (!r.ok()) {
      return Status(r.status().code(),
                    "placement " + QuoteForMessage(placement) + ": " + r.status().message());
    }
    const int offset = static_cast<int>(combined.sources.size());
    for (IdentifiedSource source : r->sources) {
      source.placement = placement;
      combined.sources.push_back(std::move(source));
    }
    for (size_t j = 0; j < index.size(); ++j) {
      const int s = r->source_index[j];
      combined.source_index[index[j]] = s >= 0 ? offset + s : -1;
      combined.beam_id[index[j]] = r->beam_id[j];
    }
    combined.passed_through += r->passed_through;
  }
  return combined;
}

}  // namespace

Result<MeasureReport> MeasureScale(const ModuleCalibration& calibration,
                                   const std::vector<Spot>& input_spots,
                                   const MeasureOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (Status st = calibration.Validate(); !st.ok()) {
    return Status::InvalidArgument("module calibration: " + st.message());
  }
  // Unassigned spots: identify them first; the rest uses what was assigned.
  std::optional<IdentifyResult> identification;
  std::vector<Spot> identified;
  const bool identify = std::any_of(input_spots.begin(), input_spots.end(),
                                    [](const Spot& spot) { return !spot.assigned(); });
  if (identify) {
    Result<IdentifyResult> result = IdentifyByPlacement(calibration, input_spots, options.identify);
    if (!result.ok()) return result.status();
    identified = AssignedSpots(input_spots, *result);
    identification = std::move(*result);
  }
  const std::vector<Spot>& spots = identify ? identified : input_spots;
  std::string known_sources;
  for (const SourceCalibration& s : calibration.sources) {
    known_sources += (known_sources.empty() ? "" : ", ") + s.name;
  }

  // Check every spot against the calibration, then group by source.
  // (placement, source, beam) -> spot
  std::map<std::tuple<std::string, std::string, int>, size_t> first_index;
  // (placement, source) -> its observations; placements in order of first appearance
  std::map<std::pair<std::string, std::string>, std::vector<SpotObservation>> by_source;
  std::vector<std::string> placements;
  for (size_t i = 0; i < spots.size(); ++i) {
    const Spot& spot = spots[i];
    const std::string where = spot.where.empty() ? "spot " + std::to_string(i + 1) : spot.where;
    const int beam_id = spot.observation.beam_id;
    const SourceCalibration* source = calibration.FindSource(spot.source);
    if (source == nullptr) {
      return Status::InvalidArgument(where + ": unknown source " + QuoteForMessage(spot.source) +
                                     " (the calibration has " + known_sources + ")");
    }
    if (source->pattern.Find(beam_id) == nullptr) {
      const int n = source->pattern.beams_per_side();
      return Status::InvalidArgument(
          where + ": source " + QuoteForMessage(spot.source) + " has no beam " + std::to_string(beam_id) +
          " in the calibration (" + std::to_string(n) + " x " + std::to_string(n) + " grid, " +
          std::to_string(source->pattern.beams().size()) + " beams calibrated)");
    }
    auto [it, inserted] = first_index.emplace(std::make_tuple(spot.placement, spot.source, beam_id), i);
    if (!inserted) {
      const Spot& first = spots[it->second];
      const std::string first_where =
          first.where.empty() ? "spot " + std::to_string(it->second + 1) : first.where;
      return Status::InvalidArgument(
          where + ": duplicate spot of source " + QuoteForMessage(spot.source) + " beam " +
          std::to_string(beam_id) +
          (spot.placement.empty() ? "" : " at placement " + QuoteForMessage(spot.placement)) +
          " (also at " + first_where + ")");
    }
    if (!spot.observation.point_in_scene.allFinite()) {
      return Status::InvalidArgument(where + ": point is not finite");
    }
    if (std::find(placements.begin(), placements.end(), spot.placement) == placements.end()) {
      placements.push_back(spot.placement);
    }
    by_source[{spot.placement, spot.source}].push_back(spot.observation);
  }

  MeasureReport report;
  report.identification = identification;
  const std::string identified_suffix =
      identification ? " (identification: " + IdentificationBrief(*identification) + ")" : "";
  std::vector<LocatedOrigin> located;
  for (const SourceCalibration& source : calibration.sources) {
    bool any = false;
    for (const std::string& placement : placements) any = any || by_source.count({placement, source.name});
    if (!any) report.sources_without_spots.push_back(source.name);
  }
  for (const std::string& placement : placements) {
    for (const SourceCalibration& source : calibration.sources) {
      auto group = by_source.find({placement, source.name});
      if (group == by_source.end()) continue;
      Result<LocateResult> result = LocateSource(source.pattern, group->second, options.locate);
      if (!result.ok()) {
        return Status(result.status().code(),
                      "source " + QuoteForMessage(source.name) +
                          (placement.empty() ? "" : " at placement " + QuoteForMessage(placement)) +
                          ": " + result.status().message() + identified_suffix);
      }
      LocatedOrigin origin;
      origin.name = source.name;
      origin.placement = placement;
      origin.origin_in_scene = result->scene_from_source.translation;
      origin.origin_covariance = result->origin_covariance;
      located.push_back(origin);
      report.sources.emplace_back(source.name, std::move(result).value());
      report.source_placements.push_back(placement);
    }
  }
  if (located.empty()) {
    return Status::NoSolution("no spots: no source could be located" + identified_suffix);
  }

  Result<ScaleResult> scale = ComputeScaleFactor(calibration, located);
  if (!scale.ok()) {
    std::string located_names;
    for (const LocatedOrigin& o : located) {
      located_names += (located_names.empty() ? "" : ", ") + o.name +
                       (o.placement.empty() ? "" : " at " + o.placement);
    }
    return Status(scale.status().code(), scale.status().message() + " (located: " +
                                             located_names + ")" + identified_suffix);
  }
  report.scale = std::move(scale).value();
  return report;
}

std::string MeasureReport::ToText() const {
  std::string out;
  if (identification) {
    out += "Identification: " + std::to_string(identification->num_assigned()) + " of " +
           std::to_string(identification->source_index.size()) + " points assigned, " +
           std::to_string(identification->num_unassigned()) + " unassigned\n";
    for (const IdentifiedSource& s : identification->sources) {
      out += "  " + s.name + (s.placement.empty() ? "" : " at placement " + s.placement) + ": " +
             IdentifyOutcomeName(s.outcome);
      if (s.outcome == IdentifyOutcome::kFound) {
        out += ", " + std::to_string(s.assigned) + " points, rms " +
               FormatPrintf("%.1f", s.rms_residual_rad * 1e6) + " urad";
      } else if (!s.detail.empty()) {
        out += ": " + s.detail;
      }
      out += "\n";
    }
  }
  for (size_t k = 0; k < sources.size(); ++k) {
    const auto& [name, r] = sources[k];
    const std::vector<int> outliers = r.OutlierBeamIds();
    const std::string placement = k < source_placements.size() ? source_placements[k] : "";
    out += "Source " + name + (placement.empty() ? "" : " at placement " + placement) + ": " +
           std::to_string(r.num_spots) + " spots, " +
           std::to_string(r.num_inliers) + " used, " + std::to_string(outliers.size()) +
           " outliers" + (outliers.empty() ? "" : " (beams " + JoinInts(outliers) + ")") + "\n";
    out += "  origin          " + FormatTriple("%.6f", r.scene_from_source.translation) +
           " scene units\n";
    out += "  origin std dev  " + FormatTriple("%.6f", StdDevs(r.origin_covariance)) + " scene units\n";
    out += "  rotation x,y,z  " + FormatTriple("%.6f", r.rotation_xyz_rad * kRadToDeg) +
           " deg (R = Rx Ry Rz), std dev " +
           FormatTriple("%.6f", StdDevs(r.rotation_xyz_covariance) * kRadToDeg) + " deg\n";
    out += "  rms residual    " + FormatPrintf("%.3f", r.rms_residual_rad * 1e6) + " urad" +
           (r.weighted ? ", chi2/dof " + FormatPrintf("%.3f", r.variance_factor) +
                             " (weighted by spot sigmas)"
                       : std::string(" (unweighted; covariance from the residuals)")) +
           "\n";
  }
  for (const std::string& name : sources_without_spots) {
    out += "Source " + name + ": no spots, not located\n";
  }
  out += "Lengths (photo in scene units, cal in mm, s_ij in mm per scene unit):\n";
  for (const LengthScale& l : scale.lengths) {
    out += "  " + l.from + "-" + l.to + (l.placement.empty() ? "" : " at " + l.placement) +
           ": photo " + FormatPrintf("%.6f", l.photo) + " +- " +
           FormatPrintf("%.6f", l.u_photo) + ", cal " + FormatPrintf("%.6f", l.cal_mm) + " +- " +
           FormatPrintf("%.6f", l.u_cal_mm) + ", s_ij " + FormatPrintf("%.9f", l.scale) + " +- " +
           FormatPrintf("%.9f", l.u_scale) + "\n";
  }
  out += "Scale factor s = " + FormatPrintf("%.9f", scale.scale_factor) + " +- " +
         FormatPrintf("%.9f", scale.u_scale_factor) + " mm per scene unit (" +
         FormatPrintf("%.1f", scale.u_scale_factor / scale.scale_factor * 1e6) + " ppm, k = 1)\n";
  out += "Expanded uncertainty U = " + FormatPrintf("%.9f", 2.0 * scale.u_scale_factor) +
         " (k = 2: s - U .. s + U covers the true scale with about 95 % probability when s is "
         "normally distributed)\n";
  if (scale.dof > 0) {
    out += "Consistency chi2/dof = " + FormatPrintf("%.3f", scale.chi2) + "/" +
           std::to_string(scale.dof) + " = " +
           FormatPrintf("%.3f", scale.chi2 / scale.dof) + ", max normalized deviation " +
           FormatPrintf("%.3f", scale.max_normalized_deviation) + "\n";
  }
  return out;
}

std::string MeasureReport::ToJson() const {
  using nlohmann::ordered_json;
  ordered_json doc;
  doc["format"] = "opl.measure_report";
  doc["version"] = 1;
  doc["units"] = {{"origin", "scene units"},
                  {"origin_cov", "scene units^2"},
                  {"rotation_xyz_rad", "rad"},
                  {"rms_residual_urad", "microradians"},
                  {"photo", "scene units"},
                  {"cal", "mm"},
                  {"scale_factor", "mm per scene unit"}};
  ordered_json source_array = ordered_json::array();
  for (size_t k = 0; k < sources.size(); ++k) {
    const auto& [name, r] = sources[k];
    ordered_json s;
    s["name"] = name;
    if (k < source_placements.size() && !source_placements[k].empty()) {
      s["placement"] = source_placements[k];
    }
    s["origin"] = VectorJson(r.scene_from_source.translation);
    s["origin_cov"] = MatrixJson(r.origin_covariance);
    s["origin_std"] = VectorJson(StdDevs(r.origin_covariance));
    s["rotation_xyz_rad"] = VectorJson(r.rotation_xyz_rad);
    s["rotation_xyz_cov_rad2"] = MatrixJson(r.rotation_xyz_covariance);
    s["rms_residual_urad"] = r.rms_residual_rad * 1e6;
    s["variance_factor"] = r.variance_factor;
    s["weighted"] = r.weighted;
    s["n_spots"] = r.num_spots;
    s["n_inliers"] = r.num_inliers;
    s["outliers"] = r.OutlierBeamIds();
    source_array.push_back(std::move(s));
  }
  doc["sources"] = std::move(source_array);
  doc["sources_without_spots"] = sources_without_spots;
  if (identification) {
    ordered_json id;
    id["points"] = identification->source_index.size();
    id["assigned"] = identification->num_assigned();
    id["unassigned"] = identification->num_unassigned();
    ordered_json id_sources = ordered_json::array();
    for (const IdentifiedSource& s : identification->sources) {
      ordered_json entry = {{"name", s.name},
                            {"outcome", IdentifyOutcomeName(s.outcome)},
                            {"detail", s.detail},
                            {"assigned", s.assigned},
                            {"rms_residual_urad", s.rms_residual_rad * 1e6}};
      if (!s.placement.empty()) entry["placement"] = s.placement;
      id_sources.push_back(std::move(entry));
    }
    id["sources"] = std::move(id_sources);
    doc["identification"] = std::move(id);
  }
  ordered_json lengths = ordered_json::array();
  for (const LengthScale& l : scale.lengths) {
    ordered_json length = {{"from", l.from}, {"to", l.to}};
    if (!l.placement.empty()) length["placement"] = l.placement;
    length["photo"] = l.photo;
    length["u_photo"] = l.u_photo;
    length["cal"] = l.cal_mm;
    length["u_cal"] = l.u_cal_mm;
    length["scale"] = l.scale;
    length["u_scale"] = l.u_scale;
    lengths.push_back(std::move(length));
  }
  doc["lengths"] = std::move(lengths);
  doc["scale_factor"] = scale.scale_factor;
  doc["u_scale_factor"] = scale.u_scale_factor;
  doc["expanded_u_scale_factor"] = 2.0 * scale.u_scale_factor;
  doc["coverage_factor"] = 2;
  doc["chi2"] = scale.chi2;
  doc["dof"] = scale.dof;
  doc["max_normalized_deviation"] = scale.max_normalized_deviation;
  return doc.dump(2) + "\n";
}

}  // namespace opl
