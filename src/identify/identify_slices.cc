#include "opl/identify/identify_slices.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace opl {

Result<SessionIdentification> IdentifySessionSlices(const ModuleCalibration& nominal,
                                                    const std::vector<Spot>& spots,
                                                    const std::vector<int>& slices,
                                                    IdentifyOptions options) {
  if (spots.size() != slices.size()) {
    return Status::InvalidArgument(std::to_string(spots.size()) + " spots but " +
                                   std::to_string(slices.size()) + " slices");
  }
  options.directions_nominal = true;
  double closest = std::numeric_limits<double>::infinity();
  for (const SourceCalibration& s : nominal.sources) {
    options.expected_rotation.emplace(s.name, s.calibration_from_source.RotationMatrix());
    for (const SourceCalibration& t : nominal.sources) {
      if (&s == &t) continue;
      closest = std::min(closest, (s.calibration_from_source.translation -
                                   t.calibration_from_source.translation).norm());
    }
  }
  // Origins: each hypothesis must be nearer its own nominal origin than to
  // any other source's (0.4 of the closest distance between two origins).
  if (options.expected_origin.empty() && std::isfinite(closest) && closest > 0.0) {
    for (const SourceCalibration& s : nominal.sources) {
      options.expected_origin.emplace(s.name, s.calibration_from_source.translation);
    }
    options.expected_origin_tolerance = 0.4 * closest;
  }
  std::map<int, std::vector<size_t>> by_slice;
  for (size_t i = 0; i < spots.size(); ++i) by_slice[slices[i]].push_back(i);

  SessionIdentification session;
  std::vector<int> source_of(spots.size(), -1), beam_of(spots.size(), 0);
  for (const auto& [slice, indices] : by_slice) {
    std::vector<Spot> slice_spots;
    slice_spots.reserve(indices.size());
    for (size_t i : indices) slice_spots.push_back(spots[i]);
    Result<IdentifyResult> r = IdentifySpots(nominal, slice_spots, options);
    if (!r.ok()) return r.status();
    SliceIdentification s;
    s.slice = slice;
    s.points = static_cast<int>(indices.size());
    s.assigned = r->num_assigned();
    std::string found, problems;
    for (const IdentifiedSource& src : r->sources) {
      if (src.outcome == IdentifyOutcome::kFound) {
        found += (found.empty() ? "" : ", ") + src.name;
      } else if (src.outcome == IdentifyOutcome::kAmbiguous) {
        problems += (problems.empty() ? "" : "; ") + src.name + " ambiguous: " + src.detail;
      }
    }
    // Passed-through spots name their source themselves.
    for (size_t k = 0; k < indices.size(); ++k) {
      if (r->source_index[k] >= 0 && found.find(r->sources[r->source_index[k]].name) == std::string::npos &&
          slice_spots[k].assigned()) {
        found += (found.empty() ? "" : ", ") + r->sources[r->source_index[k]].name;
      }
    }
    s.source = found;
    if (found.empty()) {
      s.detail = problems.empty() ? "no source identified" : "no source identified (" + problems + ")";
    } else if (found.find(',') != std::string::npos) {
      s.detail = "more than one source in one slice: " + found;
    }
    for (size_t k = 0; k < indices.size(); ++k) {
      source_of[indices[k]] = r->source_index[k];
      beam_of[indices[k]] = r->beam_id[k];
    }
    session.per_slice.push_back(std::move(s));
  }
  for (size_t i = 0; i < spots.size(); ++i) {
    if (source_of[i] < 0) {
      ++session.unassigned;
      continue;
    }
    Spot spot = spots[i];
    spot.source = nominal.sources[static_cast<size_t>(source_of[i])].name;
    spot.observation.beam_id = beam_of[i];
    session.spots.push_back(std::move(spot));
    session.slices.push_back(slices[i]);
  }
  return session;
}

std::string SessionIdentification::ToText() const {
  const int total = static_cast<int>(spots.size()) + unassigned;
  std::string out = "Identification: " + std::to_string(spots.size()) + " of " +
                    std::to_string(total) + " spots assigned in " +
                    std::to_string(per_slice.size()) + " slices\n";
  for (const SliceIdentification& s : per_slice) {
    if (s.detail.empty()) continue;
    out += "  slice " + std::to_string(s.slice) + " (" + std::to_string(s.points) +
           " spots): " + s.detail + "\n";
  }
  return out;
}

}  // namespace opl
