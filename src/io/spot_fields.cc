#include "io/spot_fields.h"

#include <utility>

#include <Eigen/Core>

#include "io/csv.h"

namespace opl {
namespace csv_internal {

Status AppendSpot(const std::vector<std::string>& fields, int line, const std::string& name,
                  const SpotFieldColumns& columns, SpotsCsvData* data) {
  const std::string where = name + ":" + std::to_string(line);
  Spot spot;
  spot.where = where;
  if (columns.source >= 0) spot.source = fields[columns.source];
  if (columns.placement >= 0) spot.placement = fields[columns.placement];
  if (columns.beam >= 0 && !fields[columns.beam].empty()) {
    const std::string& text = fields[columns.beam];
    const std::string context = FieldContext(name, line, "beam");
    Result<int> beam = ParseInt(text, context);
    if (!beam.ok()) return beam.status();
    if (*beam < 1) return Status::ParseError(context + "beam id must be >= 1, got " + text);
    spot.observation.beam_id = *beam;
  }
  const char* const kAxis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    Result<double> v =
        ParseCoordinate(fields[columns.xyz[k]], FieldContext(name, line, kAxis[k]));
    if (!v.ok()) return v.status();
    spot.observation.point_in_scene[k] = *v;
  }
  if (columns.has_sigmas()) {
    const char* const kSigma[3] = {"sx", "sy", "sz"};
    Eigen::Vector3d sigma;
    for (int k = 0; k < 3; ++k) {
      const std::string& text = fields[columns.sigma[k]];
      const std::string context = FieldContext(name, line, kSigma[k]);
      Result<double> v = ParseSigma(text, context);
      if (!v.ok()) return v.status();
      sigma[k] = *v;
    }
    spot.observation.cov_in_scene = sigma.cwiseAbs2().asDiagonal().toDenseMatrix();
  }
  int slice = 0;
  if (columns.slice >= 0) {
    const std::string& text = fields[columns.slice];
    const std::string context = FieldContext(name, line, "slice");
    Result<int> v = ParseInt(text, context);
    if (!v.ok()) return v.status();
    if (*v < 0) return Status::ParseError(context + "slice must be >= 0, got " + text);
    slice = *v;
  }
  if (columns.slice >= 0) data->slices.push_back(slice);
  if (columns.id >= 0) data->point_ids.push_back(fields[columns.id]);
  data->spots.push_back(std::move(spot));
  return Status::Ok();
}

}  // namespace csv_internal
}  // namespace opl
