#include "opl/io/points_csv.h"

#include <cmath>

#include "io/csv.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"

namespace opl {

Result<PointsCsv> PointsCsv::Parse(const std::string& text, const std::string& name) {
  Result<csv_internal::CsvTable> parsed = csv_internal::ParseCsv(text, name);
  if (!parsed.ok()) return parsed.status();
  const csv_internal::CsvTable& table = *parsed;
  PointsCsv out;
  const char* const kAxis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    out.column_[k] = table.FindColumn(kAxis[k]);
    if (out.column_[k] < 0) {
      return Status::ParseError(name + ":" + std::to_string(table.header.line) +
                                ": missing column '" + kAxis[k] +
                                "' (a points CSV needs x, y and z columns)");
    }
  }
  int id_column = table.FindColumn("id");
  if (id_column < 0) id_column = table.FindColumn("name");
  for (size_t i = 0; i < table.header.raw.size(); ++i) {
    out.header_line_ += (i ? "," : "") + table.header.raw[i];
  }
  for (const csv_internal::CsvRecord& row : table.rows) {
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) {
      Result<double> v = csv_internal::ParseCoordinate(
          row.fields[out.column_[k]], csv_internal::FieldContext(name, row.line, kAxis[k]));
      if (!v.ok()) return v.status();
      p[k] = *v;
    }
    out.points_.push_back(p);
    out.lines_.push_back(row.line);
    out.raw_.push_back(row.raw);
    if (id_column >= 0) out.ids_.push_back(row.fields[id_column]);
  }
  return out;
}

Result<PointsCsv> PointsCsv::Read(const std::string& path) {
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return Parse(*text, path);
}

Status PointsCsv::Scale(double s) {
  if (!(std::isfinite(s) && s > 0.0)) {
    return Status::InvalidArgument("scale factor must be finite and > 0, got " +
                                   FormatRoundTrip(s));
  }
  for (Eigen::Vector3d& p : points_) p *= s;
  return Status::Ok();
}

std::string PointsCsv::Format() const {
  std::string out = header_line_ + "\n";
  for (size_t r = 0; r < raw_.size(); ++r) {
    const std::vector<std::string>& fields = raw_[r];
    for (size_t i = 0; i < fields.size(); ++i) {
      if (i) out += ',';
      int axis = -1;
      for (int k = 0; k < 3; ++k) {
        if (column_[k] == static_cast<int>(i)) axis = k;
      }
      out += axis >= 0 ? FormatRoundTrip(points_[r][axis]) : fields[i];
    }
    out += '\n';
  }
  return out;
}

}  // namespace opl
