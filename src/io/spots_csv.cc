#include "opl/io/spots_csv.h"

#include <cmath>

#include "io/csv.h"
#include "opl/io/atomic_file.h"

namespace opl {

using csv_internal::CsvRecord;
using csv_internal::CsvTable;
using csv_internal::FieldContext;

Result<SpotsCsvData> ParseSpotsCsv(const std::string& text, const std::string& name) {
  Result<CsvTable> parsed = csv_internal::ParseCsv(text, name);
  if (!parsed.ok()) return parsed.status();
  const CsvTable& table = *parsed;
  const std::string header_where = name + ":" + std::to_string(table.header.line) + ": ";

  int column[5];
  const char* const kRequired[5] = {"source", "beam", "x", "y", "z"};
  for (int i = 0; i < 5; ++i) {
    column[i] = table.FindColumn(kRequired[i]);
    if (column[i] < 0) {
      return Status::ParseError(header_where + "missing column '" + kRequired[i] +
                                "' (a spots CSV needs source,beam,x,y,z)");
    }
  }
  const char* const kSigma[3] = {"sx", "sy", "sz"};
  int sigma_column[3];
  int num_sigma = 0;
  for (int i = 0; i < 3; ++i) {
    sigma_column[i] = table.FindColumn(kSigma[i]);
    if (sigma_column[i] >= 0) ++num_sigma;
  }
  if (num_sigma != 0 && num_sigma != 3) {
    std::string missing;
    for (int i = 0; i < 3; ++i) {
      if (sigma_column[i] < 0) missing += std::string(missing.empty() ? "" : ", ") + kSigma[i];
    }
    return Status::ParseError(header_where +
                              "columns sx, sy, sz must be given all three or none (missing " +
                              missing + ")");
  }
  const int slice_column = table.FindColumn("slice");

  SpotsCsvData data;
  data.has_sigmas = num_sigma == 3;
  for (const std::string& field : table.header.fields) {
    const int index = table.FindColumn(field);
    bool used = index == slice_column;
    for (int k = 0; k < 5; ++k) used |= index == column[k];
    for (int k = 0; k < 3; ++k) used |= index == sigma_column[k];
    if (!used) data.other_columns.push_back(field);
  }
  data.spots.reserve(table.rows.size());
  for (const CsvRecord& row : table.rows) {
    const std::string where = name + ":" + std::to_string(row.line);
    Spot spot;
    spot.where = where;
    spot.source = row.fields[column[0]];
    if (spot.source.empty()) {
      return Status::ParseError(FieldContext(name, row.line, "source") + "empty source name");
    }
    const std::string& beam_text = row.fields[column[1]];
    if (beam_text.empty()) {
      return Status::ParseError(FieldContext(name, row.line, "beam") + "empty beam id");
    }
    Result<int> beam = csv_internal::ParseInt(beam_text, FieldContext(name, row.line, "beam"));
    if (!beam.ok()) return beam.status();
    if (*beam < 1) {
      return Status::ParseError(FieldContext(name, row.line, "beam") +
                                "beam id must be >= 1, got " + beam_text);
    }
    spot.observation.beam_id = *beam;
    for (int k = 0; k < 3; ++k) {
      Result<double> v = csv_internal::ParseFiniteDouble(
          row.fields[column[2 + k]], FieldContext(name, row.line, kRequired[2 + k]));
      if (!v.ok()) return v.status();
      spot.observation.point_in_scene[k] = *v;
    }
    if (data.has_sigmas) {
      Eigen::Vector3d sigma;
      for (int k = 0; k < 3; ++k) {
        const std::string context = FieldContext(name, row.line, kSigma[k]);
        Result<double> v = csv_internal::ParseFiniteDouble(row.fields[sigma_column[k]], context);
        if (!v.ok()) return v.status();
        if (!(*v > 0.0)) {
          return Status::ParseError(context + "standard deviation must be > 0, got " +
                                    row.fields[sigma_column[k]]);
        }
        sigma[k] = *v;
      }
      spot.observation.cov_in_scene = sigma.cwiseAbs2().asDiagonal().toDenseMatrix();
    }
    if (slice_column >= 0) {
      const std::string context = FieldContext(name, row.line, "slice");
      Result<int> slice = csv_internal::ParseInt(row.fields[slice_column], context);
      if (!slice.ok()) return slice.status();
      if (*slice < 0) {
        return Status::ParseError(context + "slice must be >= 0, got " + row.fields[slice_column]);
      }
      data.slices.push_back(*slice);
    }
    data.spots.push_back(std::move(spot));
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
  std::string out = "source,beam,x,y,z";
  if (sigmas) out += ",sx,sy,sz";
  for (const SpotsCsvExtraColumn& c : extra) out += "," + csv_internal::QuoteCsvField(c.name);
  out += "\n";
  for (size_t i = 0; i < spots.size(); ++i) {
    const Spot& s = spots[i];
    const Eigen::Vector3d& p = s.observation.point_in_scene;
    if (!p.allFinite()) {
      return Status::InvalidArgument("spot " + std::to_string(i) + " (source '" + s.source +
                                     "', beam " + std::to_string(s.observation.beam_id) +
                                     "): point is not finite");
    }
    out += csv_internal::QuoteCsvField(s.source) + "," + std::to_string(s.observation.beam_id);
    for (int k = 0; k < 3; ++k) out += "," + csv_internal::FormatDoubleExact(p[k]);
    if (sigmas) {
      const Eigen::Matrix3d& C = *s.observation.cov_in_scene;
      for (int k = 0; k < 3; ++k) {
        const double sigma = std::sqrt(C(k, k));
        if (!(std::isfinite(sigma) && sigma > 0.0)) {
          return Status::InvalidArgument("spot " + std::to_string(i) + " (source '" + s.source +
                                         "', beam " + std::to_string(s.observation.beam_id) +
                                         "): standard deviation is not finite and > 0");
        }
        out += "," + csv_internal::FormatDoubleExact(sigma);
      }
    }
    for (const SpotsCsvExtraColumn& c : extra) {
      out += "," + csv_internal::QuoteCsvField(c.values[i]);
    }
    out += "\n";
  }
  return out;
}

}  // namespace opl
