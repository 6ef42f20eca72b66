// The public types of opl/identify/identify_spots.h other than the search
// itself: the outcome names, IdentifyOptions::Validate, IdentifyResult's
// counts and text, and AssignedSpots.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "opl/core/format.h"
#include "opl/identify/identify_spots.h"

namespace opl {

const char* IdentifyOutcomeName(IdentifyOutcome outcome) {
  switch (outcome) {
    case IdentifyOutcome::kFound:
      return "found";
    case IdentifyOutcome::kNotFound:
      return "not found";
    case IdentifyOutcome::kAmbiguous:
      return "ambiguous";
  }
  return "?";
}

Status IdentifyOptions::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("IdentifyOptions." + field + " = " + FormatNumber(value, 6) + ": " + rule);
  };
  if (num_threads < 1 || num_threads > 256) {
    return bad("num_threads", num_threads, "must be in [1, 256]");
  }
  if (!(assign_gate_sigma > 0.0 && std::isfinite(assign_gate_sigma))) {
    return bad("assign_gate_sigma", assign_gate_sigma, "must be finite and > 0");
  }
  if (!(min_sigma_rad > 0.0 && min_sigma_rad < 0.1)) {
    return bad("min_sigma_rad", min_sigma_rad, "must be in (0, 0.1)");
  }
  if (!(score_gate_fraction > 0.0 && score_gate_fraction <= 0.5)) {
    return bad("score_gate_fraction", score_gate_fraction, "must be in (0, 0.5]");
  }
  if (!(nominal_tolerance_rad >= 0.0 && nominal_tolerance_rad < 0.1)) {
    return bad("nominal_tolerance_rad", nominal_tolerance_rad, "must be in [0, 0.1)");
  }
  if (min_spots < 4) return bad("min_spots", min_spots, "must be >= 4");
  if (!(min_fraction >= 0.0 && min_fraction <= 1.0)) return bad("min_fraction", min_fraction, "must be in [0, 1]");
  if (!(conflict_margin_chi2 >= 0.0 && std::isfinite(conflict_margin_chi2))) {
    return bad("conflict_margin_chi2", conflict_margin_chi2, "must be finite and >= 0");
  }
  if (!(ambiguity_chi2 >= 0.0 && std::isfinite(ambiguity_chi2))) {
    return bad("ambiguity_chi2", ambiguity_chi2, "must be finite and >= 0");
  }
  if (neighbours < 4 || neighbours > 64) return bad("neighbours", neighbours, "must be in [4, 64]");
  if (max_seeds < 1) return bad("max_seeds", max_seeds, "must be >= 1");
  if (!(expected_rotation_tolerance_deg > 0.0 && expected_rotation_tolerance_deg < 45.0)) {
    return bad("expected_rotation_tolerance_deg", expected_rotation_tolerance_deg,
               "must be in (0, 45) (the symmetries of a square grid are 90 deg apart)");
  }
  if (!expected_origin.empty() && !(expected_origin_tolerance > 0.0 && std::isfinite(expected_origin_tolerance))) {
    return bad("expected_origin_tolerance", expected_origin_tolerance,
               "must be finite and > 0 when expected_origin is given");
  }
  for (const auto& [name, o] : expected_origin) {
    if (!o.allFinite()) {
      return Status::InvalidArgument("IdentifyOptions.expected_origin['" + name + "']: not finite");
    }
  }
  for (const auto& [name, r] : expected_rotation) {
    if (!r.allFinite() || (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
        std::abs(r.determinant() - 1.0) > 1e-6) {
      return Status::InvalidArgument("IdentifyOptions.expected_rotation['" + name +
                                     "']: not a proper rotation");
    }
  }
  if (max_refined < 1) return bad("max_refined", max_refined, "must be >= 1");
  if (!(max_sigma_fraction > 0.0 && max_sigma_fraction <= 0.5)) {
    return bad("max_sigma_fraction", max_sigma_fraction, "must be in (0, 0.5]");
  }
  return Status::Ok();
}

int IdentifyResult::num_assigned() const {
  return static_cast<int>(std::count_if(source_index.begin(), source_index.end(), [](int s) { return s >= 0; }));
}

int IdentifyResult::num_unassigned() const {
  return static_cast<int>(source_index.size()) - num_assigned();
}

std::string IdentifyResult::ToText() const {
  std::ostringstream os;
  for (const IdentifiedSource& s : sources) {
    os << "source " << s.name << (s.placement.empty() ? "" : " at placement " + s.placement) << ": "
       << IdentifyOutcomeName(s.outcome);
    if (s.outcome == IdentifyOutcome::kFound) {
      os << ", " << s.assigned << " points, rms " << FormatNumber(s.rms_residual_rad * 1e6, 4) << " urad";
    }
    if (!s.detail.empty()) os << " (" << s.detail << ")";
    os << "\n";
  }
  os << num_assigned() << " of " << source_index.size() << " points assigned";
  if (passed_through > 0) os << " (" << passed_through << " given)";
  os << ", " << num_unassigned() << " unassigned\n";
  return os.str();
}

std::vector<Spot> AssignedSpots(const std::vector<Spot>& spots, const IdentifyResult& result) {
  std::vector<Spot> out;
  if (result.source_index.size() != spots.size() || result.beam_id.size() != spots.size()) return out;
  for (size_t i = 0; i < spots.size(); ++i) {
    const int s = result.source_index[i];
    if (s < 0 || s >= static_cast<int>(result.sources.size())) continue;
    Spot spot = spots[i];
    spot.source = result.sources[s].name;
    spot.observation.beam_id = result.beam_id[i];
    out.push_back(std::move(spot));
  }
  return out;
}

}  // namespace opl
