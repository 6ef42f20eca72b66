#include "io/csv.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <system_error>

namespace opl {
namespace csv_internal {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

std::string Trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && IsBlank(s[b])) ++b;
  while (e > b && IsBlank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Shows a value in a message: at most 40 characters, control characters escaped.
std::string Shown(const std::string& s) {
  std::string out;
  for (char c : s.substr(0, 40)) {
    if (c == '\n') out += "\\n";
    else if (c == '\r') out += "\\r";
    else out += c;
  }
  if (s.size() > 40) out += "...";
  return "'" + out + "'";
}

}  // namespace

int CsvTable::FindColumn(const std::string& name) const {
  const std::string wanted = Lower(name);
  for (size_t i = 0; i < header.fields.size(); ++i) {
    if (Lower(header.fields[i]) == wanted) return static_cast<int>(i);
  }
  return -1;
}

Result<CsvTable> ParseCsv(const std::string& text, const std::string& name) {
  std::vector<CsvRecord> records;
  size_t pos = 0;
  const size_t n = text.size();
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) pos = 3;
  int line = 1;
  while (pos < n) {
    // Skip blank lines.
    size_t probe = pos;
    while (probe < n && (IsBlank(text[probe]) || text[probe] == '\r')) ++probe;
    if (probe >= n) break;
    if (text[probe] == '\n') {
      pos = probe + 1;
      ++line;
      continue;
    }
    CsvRecord record;
    record.line = line;
    bool end_of_record = false;
    while (!end_of_record) {
      // One field starting at pos.
      size_t start = pos;
      while (start < n && IsBlank(text[start])) ++start;
      std::string value;
      size_t raw_begin = pos, raw_end;
      if (start < n && text[start] == '"') {
        const int quote_line = line;
        size_t i = start + 1;
        bool closed = false;
        while (i < n) {
          if (text[i] == '"') {
            if (i + 1 < n && text[i + 1] == '"') {
              value += '"';
              i += 2;
              continue;
            }
            closed = true;
            ++i;
            break;
          }
          if (text[i] == '\n') ++line;
          value += text[i++];
        }
        if (!closed) {
          return Status::ParseError(name + ":" + std::to_string(quote_line) +
                                    ": unterminated quoted field");
        }
        while (i < n && IsBlank(text[i])) ++i;
        if (i < n && text[i] != ',' && text[i] != '\n' &&
            !(text[i] == '\r' && (i + 1 >= n || text[i + 1] == '\n'))) {
          return Status::ParseError(name + ":" + std::to_string(line) +
                                    ": unexpected text after a closing quote");
        }
        raw_end = i;
        pos = i;
      } else {
        size_t i = start;
        while (i < n && text[i] != ',' && text[i] != '\n') {
          if (text[i] == '"') {
            return Status::ParseError(name + ":" + std::to_string(line) +
                                      ": quote inside an unquoted field (quote the whole field)");
          }
          ++i;
        }
        raw_end = i;
        if (raw_end > raw_begin && text[raw_end - 1] == '\r' && (i >= n || text[i] == '\n')) {
          --raw_end;  // CRLF
        }
        value = Trim(text.substr(raw_begin, raw_end - raw_begin));
        pos = i;
      }
      std::string raw = text.substr(raw_begin, raw_end - raw_begin);
      record.fields.push_back(std::move(value));
      record.raw.push_back(std::move(raw));
      if (pos < n && text[pos] == '\r') ++pos;  // CR of CRLF after a quoted field
      if (pos >= n) {
        end_of_record = true;
      } else if (text[pos] == ',') {
        ++pos;
      } else {  // '\n'
        ++pos;
        ++line;
        end_of_record = true;
      }
    }
    records.push_back(std::move(record));
  }

  if (records.empty()) return Status::ParseError(name + ": empty file (no header row)");
  CsvTable table;
  table.header = std::move(records.front());
  const size_t num_columns = table.header.fields.size();
  for (size_t i = 0; i < num_columns; ++i) {
    const std::string& column = table.header.fields[i];
    const std::string where = name + ":" + std::to_string(table.header.line) + ": ";
    if (column.empty()) {
      return Status::ParseError(where + "header column " + std::to_string(i + 1) +
                                " has no name");
    }
    for (size_t j = 0; j < i; ++j) {
      if (Lower(table.header.fields[j]) == Lower(column)) {
        return Status::ParseError(where + "duplicate column '" + column + "'");
      }
    }
  }
  for (size_t r = 1; r < records.size(); ++r) {
    if (records[r].fields.size() != num_columns) {
      return Status::ParseError(name + ":" + std::to_string(records[r].line) + ": expected " +
                                std::to_string(num_columns) + " fields (as the header), found " +
                                std::to_string(records[r].fields.size()));
    }
    table.rows.push_back(std::move(records[r]));
  }
  return table;
}

std::string QuoteCsvField(const std::string& field) {
  const bool needs = field.empty() || field.find_first_of(",\"\r\n") != std::string::npos ||
                     IsBlank(field.front()) || IsBlank(field.back());
  if (!needs) return field;
  std::string out = "\"";
  for (char c : field) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string FieldContext(const std::string& name, int line, const std::string& column) {
  return name + ":" + std::to_string(line) + ": field '" + column + "': ";
}

Result<double> ParseFiniteDouble(const std::string& text, const std::string& context) {
  if (text.empty()) return Status::ParseError(context + "empty value");
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (*begin == '+' && text.size() > 1 && begin[1] != '-') ++begin;
  double value = 0.0;
  const std::from_chars_result r = std::from_chars(begin, end, value);
  if (r.ec == std::errc::result_out_of_range) {
    return Status::ParseError(context + "out of range: " + Shown(text));
  }
  if (r.ec != std::errc() || r.ptr != end) {
    return Status::ParseError(context + "not a number: " + Shown(text));
  }
  if (!std::isfinite(value)) return Status::ParseError(context + "not finite: " + Shown(text));
  return value;
}

Result<int> ParseInt(const std::string& text, const std::string& context) {
  if (text.empty()) return Status::ParseError(context + "empty value");
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (*begin == '+' && text.size() > 1 && begin[1] != '-') ++begin;
  int value = 0;
  const std::from_chars_result r = std::from_chars(begin, end, value);
  if (r.ec == std::errc::result_out_of_range) {
    return Status::ParseError(context + "out of range: " + Shown(text));
  }
  if (r.ec != std::errc() || r.ptr != end) {
    return Status::ParseError(context + "not an integer: " + Shown(text));
  }
  return value;
}

std::string FormatDoubleExact(double value) {
  char buffer[64];
  const std::to_chars_result r = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, r.ptr);
}

}  // namespace csv_internal
}  // namespace opl
