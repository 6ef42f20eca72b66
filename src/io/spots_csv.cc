#include "opl/io/spots_csv.h"

#include <algorithm>
#include <cmath>

#include "io/csv.h"
#include "io/spot_fields.h"
#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/io/atomic_file.h"

namespace opl {

using csv_internal::CsvRecord;
using csv_internal::CsvTable;

int SpotsCsvData::num_unassigned() const {
  int count = 0;
  for (const Spot& s : spots) count += s.assigned() ? 0 : 1;
  return count;
}

Result<SpotsCsvData> ParseSpotsCsv(const std::string& text, const std::string& name) {
  Result<CsvTable> parsed = csv_internal::ParseCsv(text, name);
  if (!parsed.ok()) return parsed.status();
  const CsvTable& table = *parsed;
  const std::string header_where = name + ":" + std::to_string(table.header.line) + ": ";

  csv_internal::SpotFieldColumns columns;
  const char* const kAxis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    columns.xyz[k] = table.FindColumn(kAxis[k]);
    if (columns.xyz[k] < 0) {
      return Status::ParseError(header_where + "missing column '" + kAxis[k] +
                                "' (a spots CSV needs x,y,z; source,beam are optional)");
    }
  }
  columns.source = table.FindColumn("source");
  columns.beam = table.FindColumn("beam");
  const char* const kSigma[3] = {"sx", "sy", "sz"};
  int num_sigma = 0;
  for (int k = 0; k < 3; ++k) {
    columns.sigma[k] = table.FindColumn(kSigma[k]);
    if (columns.sigma[k] >= 0) ++num_sigma;
  }
  if (num_sigma != 0 && num_sigma != 3) {
    std::string missing;
    for (int k = 0; k < 3; ++k) {
      if (columns.sigma[k] < 0) missing += std::string(missing.empty() ? "" : ", ") + kSigma[k];
    }
    return Status::ParseError(header_where +
                              "columns sx, sy, sz must be given all three or none (missing " +
                              missing + ")");
  }
  columns.slice = table.FindColumn("slice");
  columns.placement = table.FindColumn("placement");

  SpotsCsvData data;
  data.has_sigmas = columns.has_sigmas();
  for (size_t i = 0; i < table.header.fields.size(); ++i) {
    const int index = static_cast<int>(i);
    bool used = index == columns.slice || index == columns.source || index == columns.beam ||
                index == columns.placement;
    for (int k = 0; k < 3; ++k) used |= index == columns.xyz[k] || index == columns.sigma[k];
    if (!used) data.other_columns.push_back(table.header.fields[i]);
  }
  data.spots.reserve(table.rows.size());
  for (const CsvRecord& row : table.rows) {
    OPL_RETURN_IF_ERROR(csv_internal::AppendSpot(row.fields, row.line, name, columns, &data));
  }
  return data;
}

Result<SpotsCsvData> ReadSpotsCsv(const std::string& path) {
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseSpotsCsv(*text, path);
}

Result<std::string> FormatSpotsCsv(const std::vector<Spot>& spots,
                                   const std::vector<SpotsCsvExtraColumn>& extra) {
  bool sigmas = !spots.empty();
  for (const Spot& s : spots) sigmas = sigmas && s.observation.cov_in_scene.has_value();
  for (const SpotsCsvExtraColumn& c : extra) {
    if (c.values.size() != spots.size()) {
      return Status::InvalidArgument("column '" + c.name + "' has " +
                                     std::to_string(c.values.size()) + " values for " +
                                     std::to_string(spots.size()) + " spots");
    }
  }
  const bool placements = std::any_of(spots.begin(), spots.end(),
                                      [](const Spot& s) { return !s.placement.empty(); });
  std::string out = "source,beam,x,y,z";
  if (sigmas) out += ",sx,sy,sz";
  if (placements) out += ",placement";
  for (const SpotsCsvExtraColumn& c : extra) out += "," + csv_internal::QuoteCsvField(c.name);
  out += "\n";
  for (size_t i = 0; i < spots.size(); ++i) {
    const Spot& s = spots[i];
    const Eigen::Vector3d& p = s.observation.point_in_scene;
    if (s.observation.beam_id < 0) {
      return Status::InvalidArgument("spot " + std::to_string(i) + " (source " + QuoteForMessage(s.source) +
                                     "): beam id must be >= 1 (or 0: unassigned), got " +
                                     std::to_string(s.observation.beam_id));
    }
    if (!p.allFinite()) {
      return Status::InvalidArgument("spot " + std::to_string(i) + " (source " + QuoteForMessage(s.source) +
                                     ", beam " + std::to_string(s.observation.beam_id) +
                                     "): point is not finite");
    }
    // An unassigned beam (id 0) is written as an empty field, which reads back as 0.
    const int beam = s.observation.beam_id;
    out += csv_internal::QuoteCsvField(s.source) + "," + (beam == 0 ? "" : std::to_string(beam));
    for (int k = 0; k < 3; ++k) out += "," + FormatRoundTrip(p[k]);
    if (sigmas) {
      const Eigen::Matrix3d& C = *s.observation.cov_in_scene;
      for (int k = 0; k < 3; ++k) {
        const double sigma = std::sqrt(C(k, k));
        if (!(std::isfinite(sigma) && sigma > 0.0)) {
          return Status::InvalidArgument("spot " + std::to_string(i) + " (source " + QuoteForMessage(s.source) +
                                         ", beam " + std::to_string(s.observation.beam_id) +
                                         "): standard deviation is not finite and > 0");
        }
        out += "," + FormatRoundTrip(sigma);
      }
    }
    if (placements) out += "," + csv_internal::QuoteCsvField(s.placement);
    for (const SpotsCsvExtraColumn& c : extra) {
      out += "," + csv_internal::QuoteCsvField(c.values[i]);
    }
    out += "\n";
  }
  return out;
}

}  // namespace opl
