#include "opl/io/point_table.h"

#include <utility>

#include "io/csv.h"
#include "io/spot_fields.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

using Delimiter = PointTableFormat::Delimiter;

const char* const kKnownColumns[] = {"id", "x",      "y",    "z",     "sx", "sy",
                                     "sz", "source", "beam", "slice", "-"};
const char kKnownList[] = "id, x, y, z, sx, sy, sz, source, beam, slice, -";

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

std::string Trimmed(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && IsBlank(s[b])) ++b;
  while (e > b && IsBlank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

// Lower case, surrounding blanks removed, `skip` as "-".
std::string Canonical(const std::string& name) {
  std::string c = csv_internal::Lower(Trimmed(name));
  return c == "skip" ? "-" : c;
}

std::string Joined(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? "," : "") + names[i];
  return out;
}

// Checks a mapping; on success `canonical` holds the canonical names.
Status CheckColumns(const std::vector<std::string>& columns, std::vector<std::string>* canonical) {
  if (columns.empty()) {
    return Status::InvalidArgument(
        "--columns: empty (give the columns in file order, e.g. id,x,y,z)");
  }
  canonical->clear();
  for (size_t i = 0; i < columns.size(); ++i) {
    const std::string c = Canonical(columns[i]);
    if (c.empty()) {
      return Status::InvalidArgument("--columns: column " + std::to_string(i + 1) +
                                     " has no name");
    }
    bool known = false;
    for (const char* k : kKnownColumns) known |= c == k;
    if (!known) {
      return Status::InvalidArgument("--columns: unknown column name '" + Trimmed(columns[i]) +
                                     "' (known: " + kKnownList + ")");
    }
    if (c != "-") {
      for (const std::string& before : *canonical) {
        if (before == c) return Status::InvalidArgument("--columns: '" + c + "' given twice");
      }
    }
    canonical->push_back(c);
  }
  auto has = [&](const char* name) {
    for (const std::string& c : *canonical) {
      if (c == name) return true;
    }
    return false;
  };
  for (const char* required : {"x", "y", "z"}) {
    if (!has(required)) {
      return Status::InvalidArgument(std::string("--columns: missing required '") + required +
                                     "'");
    }
  }
  const int num_sigma = has("sx") + has("sy") + has("sz");
  if (num_sigma != 0 && num_sigma != 3) {
    std::string missing;
    for (const char* s : {"sx", "sy", "sz"}) {
      if (!has(s)) missing += std::string(missing.empty() ? "" : ", ") + s;
    }
    return Status::InvalidArgument(
        "--columns: sx, sy, sz must be given all three or none (missing " + missing + ")");
  }
  return Status::Ok();
}

char DelimiterChar(Delimiter d) {
  switch (d) {
    case Delimiter::kComma: return ',';
    case Delimiter::kSemicolon: return ';';
    case Delimiter::kTab: return '\t';
    case Delimiter::kWhitespace: return ' ';
    case Delimiter::kAuto: break;
  }
  return '\0';
}

// How a delimiter is named in a message: "','", "';'", "tab", "whitespace".
std::string DelimiterShown(Delimiter d) {
  switch (d) {
    case Delimiter::kComma: return "','";
    case Delimiter::kSemicolon: return "';'";
    case Delimiter::kTab: return "tab";
    case Delimiter::kWhitespace: return "whitespace";
    case Delimiter::kAuto: break;
  }
  return "auto";
}

// The first data line (record) as the splitter will see it: its line number
// (0 when there is none) and the delimiter it suggests.
std::pair<int, Delimiter> DetectDelimiter(const std::string& text, const PointTableFormat& f) {
  size_t pos = csv_internal::SkipBom(text);
  const size_t n = text.size();
  int line = 1;
  auto next_line = [&] {
    while (pos < n && text[pos] != '\n') ++pos;
    if (pos < n) ++pos;
    ++line;
  };
  while (pos < n && line <= f.skip_rows) next_line();
  while (pos < n) {
    size_t probe = pos;
    while (probe < n && (IsBlank(text[probe]) || text[probe] == '\r')) ++probe;
    if (probe >= n) break;
    if (text[probe] == '\n' || (f.comment != '\0' && text[probe] == f.comment)) {
      pos = probe;
      next_line();
      continue;
    }
    bool comma = false, semicolon = false, tab = false, quoted = false;
    // The first record: a quoted field may run over line breaks.
    for (size_t i = pos; i < n && (quoted || text[i] != '\n'); ++i) {
      const char c = text[i];
      if (c == '"') quoted = !quoted;  // "" inside quotes toggles twice: no effect
      if (quoted) continue;
      comma |= c == ',';
      semicolon |= c == ';';
      tab |= c == '\t';
    }
    const Delimiter d = semicolon ? Delimiter::kSemicolon
                        : comma   ? Delimiter::kComma
                        : tab     ? Delimiter::kTab
                                  : Delimiter::kWhitespace;
    return {line, d};
  }
  return {0, Delimiter::kWhitespace};
}

}  // namespace

Status PointTableFormat::Validate() const {
  std::vector<std::string> canonical;
  OPL_RETURN_IF_ERROR(CheckColumns(columns, &canonical));
  if (skip_rows < 0) {
    return Status::InvalidArgument("--skip-rows: must be >= 0, got " +
                                   std::to_string(skip_rows));
  }
  if (comment == '"' || comment == ' ' || comment == '\t' || comment == '\r' ||
      comment == '\n') {
    return Status::InvalidArgument(
        "comment character: cannot be a quote, a blank or a line break");
  }
  if (comment != '\0' && comment == DelimiterChar(delimiter)) {
    return Status::InvalidArgument(std::string("comment character: '") + comment +
                                   "' is the delimiter");
  }
  switch (delimiter) {
    case Delimiter::kAuto:
    case Delimiter::kComma:
    case Delimiter::kSemicolon:
    case Delimiter::kTab:
    case Delimiter::kWhitespace:
      return Status::Ok();
  }
  return Status::InvalidArgument("delimiter: not a PointTableFormat::Delimiter value");
}

Result<PointTableFormat> ParseColumnMapping(const std::string& spec) {
  PointTableFormat format;
  if (!Trimmed(spec).empty()) {
    size_t begin = 0;
    while (true) {
      const size_t comma = spec.find(',', begin);
      format.columns.push_back(spec.substr(begin, comma - begin));
      if (comma == std::string::npos) break;
      begin = comma + 1;
    }
  }
  std::vector<std::string> canonical;
  OPL_RETURN_IF_ERROR(CheckColumns(format.columns, &canonical));
  format.columns = std::move(canonical);
  return format;
}

Result<PointTableFormat::Delimiter> ParseDelimiterName(const std::string& name) {
  const std::string n = csv_internal::Lower(name);
  if (n == "auto") return Delimiter::kAuto;
  if (n == "comma" || n == ",") return Delimiter::kComma;
  if (n == "semicolon" || n == ";") return Delimiter::kSemicolon;
  if (n == "tab" || n == "\t" || n == "\\t") return Delimiter::kTab;
  if (n == "whitespace" || n == "space") return Delimiter::kWhitespace;
  return Status::InvalidArgument("--delimiter: unknown delimiter " + csv_internal::Shown(name) +
                                 " (known: auto, comma, semicolon, tab, whitespace)");
}

const char* DelimiterName(PointTableFormat::Delimiter delimiter) {
  switch (delimiter) {
    case Delimiter::kAuto: return "auto";
    case Delimiter::kComma: return "comma";
    case Delimiter::kSemicolon: return "semicolon";
    case Delimiter::kTab: return "tab";
    case Delimiter::kWhitespace: return "whitespace";
  }
  return "auto";
}

Result<SpotsCsvData> ParsePointTable(const std::string& text, const std::string& name,
                                     const PointTableFormat& format) {
  std::vector<std::string> columns;
  OPL_RETURN_IF_ERROR(format.Validate());
  OPL_RETURN_IF_ERROR(CheckColumns(format.columns, &columns));

  Delimiter delimiter = format.delimiter;
  std::string delimiter_shown = DelimiterShown(delimiter);
  if (delimiter == Delimiter::kAuto) {
    const std::pair<int, Delimiter> detected = DetectDelimiter(text, format);
    delimiter = detected.second;
    delimiter_shown = DelimiterShown(delimiter) + " detected from line " +
                      std::to_string(detected.first);
  }
  csv_internal::SplitOptions options;
  options.delimiter = DelimiterChar(delimiter);
  options.comment = format.comment;
  options.skip_lines = format.skip_rows;
  Result<std::vector<csv_internal::CsvRecord>> records =
      csv_internal::SplitRecords(text, name, options);
  if (!records.ok()) return records.status();
  if (records->empty()) {
    std::string after;
    if (format.skip_rows > 0) {
      after = " after skipping " + std::to_string(format.skip_rows) +
              (format.skip_rows == 1 ? " row" : " rows");
    }
    return Status::ParseError(name + ": no data lines" + after);
  }

  csv_internal::SpotFieldColumns c;
  for (size_t i = 0; i < columns.size(); ++i) {
    const std::string& col = columns[i];
    const int index = static_cast<int>(i);
    if (col == "id") c.id = index;
    else if (col == "x") c.xyz[0] = index;
    else if (col == "y") c.xyz[1] = index;
    else if (col == "z") c.xyz[2] = index;
    else if (col == "sx") c.sigma[0] = index;
    else if (col == "sy") c.sigma[1] = index;
    else if (col == "sz") c.sigma[2] = index;
    else if (col == "source") c.source = index;
    else if (col == "beam") c.beam = index;
    else if (col == "slice") c.slice = index;
  }

  SpotsCsvData data;
  data.has_sigmas = c.has_sigmas();
  data.spots.reserve(records->size());
  const size_t expected = columns.size();
  for (const csv_internal::CsvRecord& record : *records) {
    const size_t found = record.fields.size();
    if (found < expected || (found > expected && !format.allow_extra_fields)) {
      return Status::ParseError(
          name + ":" + std::to_string(record.line) + ": expected " + std::to_string(expected) +
          " fields (columns " + Joined(columns) + "; delimiter " + delimiter_shown +
          "), found " + std::to_string(found) +
          (found > expected ? " (extra trailing fields are refused unless allowed)" : ""));
    }
    OPL_RETURN_IF_ERROR(csv_internal::AppendSpot(record.fields, record.line, name, c, &data));
  }
  return data;
}

Result<SpotsCsvData> ReadPointTable(const std::string& path, const PointTableFormat& format) {
  OPL_RETURN_IF_ERROR(format.Validate());
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParsePointTable(*text, path, format);
}

}  // namespace opl
