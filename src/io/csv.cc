#include "io/csv.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <system_error>
#include <unordered_set>

#include "opl/core/message_text.h"

namespace opl {
namespace csv_internal {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

// Splits one text into records per SplitOptions.
class Splitter {
 public:
  Splitter(const std::string& text, const std::string& name, const SplitOptions& options)
      : text_(text), name_(name), delimiter_(options.delimiter),
        whitespace_(options.delimiter == ' '), comment_(options.comment),
        skip_lines_(options.skip_lines) {}

  Result<std::vector<CsvRecord>> Run() {
    std::vector<CsvRecord> records;
    pos_ = SkipBom(text_);
    while (pos_ < n_ && line_ <= skip_lines_) SkipRestOfLine();
    while (pos_ < n_) {
      // Skip blank and comment lines.
      size_t probe = pos_;
      while (probe < n_ && (IsBlank(text_[probe]) || text_[probe] == '\r')) ++probe;
      if (probe >= n_) break;
      if (text_[probe] == '\n' || (comment_ != '\0' && text_[probe] == comment_)) {
        pos_ = probe;
        SkipRestOfLine();
        continue;
      }
      if (whitespace_) pos_ = probe;  // leading blanks are not an empty field
      Result<CsvRecord> record = Record();
      if (!record.ok()) return record.status();
      records.push_back(std::move(*record));
    }
    return records;
  }

 private:
  // Blank, and not the delimiter (a tab delimiter is not trimmed away).
  bool Trimmable(char c) const { return IsBlank(c) && (whitespace_ || c != delimiter_); }
  // At pos: a line break ("\n", or "\r" then "\n" or the end).
  bool AtLineEnd(size_t i) const {
    if (i >= n_) return false;
    return text_[i] == '\n' || (text_[i] == '\r' && (i + 1 >= n_ || text_[i + 1] == '\n'));
  }
  bool EndsUnquotedField(size_t i) const {
    const char c = text_[i];
    if (c == '\n') return true;
    if (whitespace_) return IsBlank(c) || c == '\r';
    return c == delimiter_;
  }
  void SkipRestOfLine() {
    while (pos_ < n_ && text_[pos_] != '\n') ++pos_;
    if (pos_ < n_) ++pos_;
    ++line_;
  }
  Status Error(int line, const std::string& what) const {
    return Status::ParseError(name_ + ":" + std::to_string(line) + ": " + what);
  }

  Result<CsvRecord> Record() {
    CsvRecord record;
    record.line = line_;
    while (true) {
      // One field starting at pos_.
      size_t start = pos_;
      while (start < n_ && Trimmable(text_[start])) ++start;
      std::string value;
      const size_t raw_begin = pos_;
      size_t raw_end;
      if (start < n_ && text_[start] == '"') {
        const int quote_line = line_;
        size_t i = start + 1;
        bool closed = false;
        while (i < n_) {
          if (text_[i] == '"') {
            if (i + 1 < n_ && text_[i + 1] == '"') {
              value += '"';
              i += 2;
              continue;
            }
            closed = true;
            ++i;
            break;
          }
          if (text_[i] == '\n') ++line_;
          value += text_[i++];
        }
        if (!closed) return Error(quote_line, "unterminated quoted field");
        // After the closing quote: blanks, then the delimiter or the line end
        // (with whitespace as the delimiter, a blank or the line end).
        if (!whitespace_) {
          while (i < n_ && Trimmable(text_[i])) ++i;
        }
        const bool separator = i < n_ && (whitespace_ ? IsBlank(text_[i]) : text_[i] == delimiter_);
        if (i < n_ && !AtLineEnd(i) && !separator) {
          return Error(line_, "unexpected text after a closing quote");
        }
        raw_end = i;
        pos_ = i;
      } else {
        size_t i = start;
        while (i < n_ && !EndsUnquotedField(i)) {
          if (text_[i] == '"') {
            return Error(line_, "quote inside an unquoted field (quote the whole field)");
          }
          ++i;
        }
        raw_end = i;
        if (raw_end > raw_begin && text_[raw_end - 1] == '\r' && (i >= n_ || text_[i] == '\n')) {
          --raw_end;  // CRLF
        }
        value = text_.substr(raw_begin, raw_end - raw_begin);
        size_t b = 0, e = value.size();
        while (b < e && Trimmable(value[b])) ++b;
        while (e > b && Trimmable(value[e - 1])) --e;
        value = value.substr(b, e - b);
        pos_ = i;
      }
      record.fields.push_back(std::move(value));
      record.raw.push_back(text_.substr(raw_begin, raw_end - raw_begin));
      if (whitespace_) {
        // A run of blanks (and a CR before the line break) ends the field.
        while (pos_ < n_ && (IsBlank(text_[pos_]) || (text_[pos_] == '\r' && !AtLineEnd(pos_)))) {
          ++pos_;
        }
        if (pos_ < n_ && text_[pos_] == '\r') ++pos_;
        if (pos_ >= n_) return record;
        if (text_[pos_] == '\n') {
          ++pos_;
          ++line_;
          return record;
        }
        continue;  // the next field starts here
      }
      if (pos_ < n_ && text_[pos_] == '\r') ++pos_;  // CR of CRLF after a quoted field
      if (pos_ >= n_) return record;
      if (text_[pos_] == delimiter_) {
        ++pos_;
      } else {  // '\n'
        ++pos_;
        ++line_;
        return record;
      }
    }
  }

  const std::string& text_;
  const std::string& name_;
  const size_t n_ = text_.size();
  const char delimiter_;
  const bool whitespace_;
  const char comment_;
  const int skip_lines_;
  size_t pos_ = 0;
  int line_ = 1;
};

}  // namespace

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string Shown(const std::string& s) { return QuoteForMessage(s, 40); }

size_t SkipBom(const std::string& text) {
  return text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
}

Result<std::vector<CsvRecord>> SplitRecords(const std::string& text, const std::string& name,
                                            const SplitOptions& options) {
  return Splitter(text, name, options).Run();
}

int CsvTable::FindColumn(const std::string& name) const {
  const std::string wanted = Lower(name);
  for (size_t i = 0; i < header.fields.size(); ++i) {
    if (Lower(header.fields[i]) == wanted) return static_cast<int>(i);
  }
  return -1;
}

Result<CsvTable> ParseCsv(const std::string& text, const std::string& name) {
  SplitOptions options;
  options.comment = '#';  // the provenance lines OPL writes (io/provenance_stamp.h)
  Result<std::vector<CsvRecord>> split = SplitRecords(text, name, options);
  if (!split.ok()) return split.status();
  std::vector<CsvRecord>& records = *split;
  if (records.empty()) return Status::ParseError(name + ": empty file (no header row)");
  CsvTable table;
  table.header = std::move(records.front());
  const size_t num_columns = table.header.fields.size();
  const std::string where = name + ":" + std::to_string(table.header.line) + ": ";
  // Linear in the number of columns (a pairwise check took 4 s for 16k columns).
  std::unordered_set<std::string> seen;
  seen.reserve(num_columns);
  for (size_t i = 0; i < num_columns; ++i) {
    const std::string& column = table.header.fields[i];
    if (column.empty()) {
      return Status::ParseError(where + "header column " + std::to_string(i + 1) +
                                " has no name");
    }
    if (!seen.insert(Lower(column)).second) {
      return Status::ParseError(where + "duplicate column " + QuoteForMessage(column));
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
    std::string hint;
    const size_t comma = text.find(',');
    if (comma != std::string::npos && text.find(',', comma + 1) == std::string::npos) {
      std::string dotted = text;
      dotted[comma] = '.';
      if (ParseFiniteDouble(dotted, std::string()).ok()) {
        hint = " (decimal commas are not supported)";
      }
    }
    return Status::ParseError(context + "not a number: " + Shown(text) + hint);
  }
  if (!std::isfinite(value)) return Status::ParseError(context + "not finite: " + Shown(text));
  return value;
}

Result<double> ParseCoordinate(const std::string& text, const std::string& context) {
  Result<double> v = ParseFiniteDouble(text, context);
  if (v.ok() && !(std::abs(*v) <= kMaxAbsCoordinate)) {
    return Status::ParseError(context + "beyond the limit of |value| <= 1e12 scene units, got " + text);
  }
  return v;
}

Result<double> ParseSigma(const std::string& text, const std::string& context) {
  Result<double> v = ParseFiniteDouble(text, context);
  if (!v.ok()) return v;
  if (!(*v > 0.0)) {
    return Status::ParseError(context + "standard deviation must be > 0, got " + text);
  }
  if (!(*v >= kMinSigma && *v <= kMaxSigma)) {
    return Status::ParseError(context + "standard deviation beyond the range 1e-12 to 1e12 scene "
                              "units, got " + text);
  }
  return v;
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


}  // namespace csv_internal
}  // namespace opl
