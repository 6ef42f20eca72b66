#include "opl/model/module_calibration.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

namespace opl {

Status ModuleCalibration::Validate() const {
  if (sources.empty()) return Status::InvalidArgument("module calibration has no sources");
  std::set<std::string> names;
  for (const SourceCalibration& s : sources) {
    if (s.name.empty()) return Status::InvalidArgument("a source has an empty name");
    if (!names.insert(s.name).second) {
      return Status::InvalidArgument("duplicate source name '" + s.name + "'");
    }
    Status st = s.pattern.Validate();
    if (!st.ok()) return Status::InvalidArgument("source '" + s.name + "': " + st.message());
    if (!s.calibration_from_source.translation.allFinite() ||
        !s.calibration_from_source.rotation.coeffs().allFinite()) {
      return Status::InvalidArgument("source '" + s.name + "': pose is not finite");
    }
  }
  std::set<std::pair<std::string, std::string>> pairs;
  for (const Separation& sep : separations) {
    const auto key = std::minmax(sep.from, sep.to);
    if (!pairs.insert({key.first, key.second}).second) {
      return Status::InvalidArgument("separation " + sep.from + "-" + sep.to +
                                     " is given twice (each pair of sources may have one)");
    }
    if (!names.count(sep.from) || !names.count(sep.to)) {
      return Status::InvalidArgument("separation " + sep.from + "-" + sep.to +
                                     " names an unknown source");
    }
    if (sep.from == sep.to) {
      return Status::InvalidArgument("separation " + sep.from + "-" + sep.to +
                                     " joins a source to itself");
    }
    if (!(std::isfinite(sep.length_mm) && sep.length_mm > 0.0)) {
      return Status::InvalidArgument("separation " + sep.from + "-" + sep.to +
                                     ": length_mm must be finite and > 0");
    }
    if (!(std::isfinite(sep.u_length_mm) && sep.u_length_mm >= 0.0)) {
      return Status::InvalidArgument("separation " + sep.from + "-" + sep.to +
                                     ": u_length_mm must be finite and >= 0");
    }
  }
  return Status::Ok();
}

const SourceCalibration* ModuleCalibration::FindSource(const std::string& name) const {
  for (const SourceCalibration& s : sources) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

std::vector<Separation> ModuleCalibration::SeparationsFromOrigins(
    const std::vector<SourceCalibration>& sources) {
  std::vector<Separation> out;
  for (size_t i = 0; i < sources.size(); ++i) {
    for (size_t j = i + 1; j < sources.size(); ++j) {
      const double L = (sources[i].calibration_from_source.translation -
                        sources[j].calibration_from_source.translation)
                           .norm();
      out.push_back({sources[i].name, sources[j].name, L, 0.0});
    }
  }
  return out;
}

}  // namespace opl
