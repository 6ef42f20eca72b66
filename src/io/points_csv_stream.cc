// The points CSV (opl/io/points_csv.h), streamed: the same rules, messages and
// output as PointsCsv::Parse + Scale + Format (tests/io/scale_point_file_test.cc
// compares them), a record at a time. Records are cut exactly as
// csv_internal::SplitRecords cuts them (src/io/csv.cc), on a window that may end
// mid-record: whenever the parser would look past the window before the end of
// the file it asks for more input and starts the record again.
#include <unordered_set>

#include "io/csv.h"
#include "opl/core/message_text.h"
#include "io/point_file_stream.h"

namespace opl {
namespace point_file_internal {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

struct FieldSpan {
  size_t raw_begin, raw_end;      // the field's exact text
  size_t value_begin, value_end;  // its value (trimmed, or inside the quotes)
  bool escaped_quotes;            // a quoted value with "" in it
};

enum class Parsed { kRecord, kNeedMore, kError };

class CsvScaler {
 public:
  CsvScaler(InputFile& in, OutputBuffer* out, double s, ScaleCounts* counts)
      : in_(in), out_(out), s_(s), counts_(counts) {}

  Status Run(bool header_only) {
    OPL_RETURN_IF_ERROR(in_.Ensure(3));
    if (in_.size() >= 3 && std::memcmp(in_.data(), "\xEF\xBB\xBF", 3) == 0) pos_ = 3;
    bool have_header = false;
    while (true) {
      // Blank lines (only spaces, tabs, CRs) are skipped.
      size_t probe = pos_;
      while (probe < in_.size() && (IsBlank(in_.data()[probe]) || in_.data()[probe] == '\r')) {
        ++probe;
      }
      if (probe >= in_.size()) {
        if (in_.at_eof()) break;
        OPL_RETURN_IF_ERROR(More());
        continue;
      }
      if (in_.data()[probe] == '\n') {
        pos_ = probe + 1;
        ++line_;
        continue;
      }
      if (in_.data()[probe] == '#') {  // a comment line (provenance...): copied as it is
        const char* nl = static_cast<const char*>(
            std::memchr(in_.data() + probe, '\n', in_.size() - probe));
        if (nl == nullptr && !in_.at_eof()) {
          OPL_RETURN_IF_ERROR(More());
          continue;
        }
        const size_t end = nl != nullptr ? static_cast<size_t>(nl - in_.data()) + 1 : in_.size();
        if (!header_only) out_->Append(in_.data() + pos_, end - pos_);
        if (nl == nullptr) out_->Append("\n");
        pos_ = end;
        ++line_;
        continue;
      }
      size_t end = 0;
      int64_t end_line = 0;
      Status error;
      const Parsed parsed = Record(&end, &end_line, &error);
      if (parsed == Parsed::kError) return error;
      if (parsed == Parsed::kNeedMore) {
        OPL_RETURN_IF_ERROR(More());
        continue;
      }
      if (!have_header) {
        OPL_RETURN_IF_ERROR(Header());
        have_header = true;
        if (header_only) return Status::Ok();
      } else {
        OPL_RETURN_IF_ERROR(Row());
        if (out_->failed()) return Status::Ok();
      }
      pos_ = end;
      line_ = end_line;
    }
    if (!have_header) return Status::ParseError(in_.path() + ": empty file (no header row)");
    return Status::Ok();
  }

 private:
  // Consumes what is done and reads more; a record that does not fit in the
  // buffer is an error.
  Status More() {
    in_.Consume(pos_);
    pos_ = 0;
    Result<size_t> added = in_.Fill();
    if (!added.ok()) return added.status();
    if (*added == 0 && !in_.at_eof()) {
      return Error(line_, "record longer than " + std::to_string(in_.capacity()) +
                              " bytes (an unterminated quoted field?)");
    }
    return Status::Ok();
  }
  Status Error(int64_t line, const std::string& what) const {
    return Status::ParseError(in_.path() + ":" + std::to_string(line) + ": " + what);
  }

  // One record from pos_ into fields_ (SplitRecords' rules for ','); its end
  // and the line after it. kNeedMore when the window ends before the record
  // is known to end.
  Parsed Record(size_t* record_end, int64_t* end_line, Status* error) {
    const char* const d = in_.data();
    const size_t n = in_.size();
    const bool eof = in_.at_eof();
    int64_t line = line_;
    fields_.clear();
    size_t i = pos_;
    while (true) {
      size_t start = i;
      while (start < n && IsBlank(d[start])) ++start;
      if (start >= n && !eof) return Parsed::kNeedMore;
      FieldSpan f;
      f.raw_begin = i;
      f.escaped_quotes = false;
      if (start < n && d[start] == '"') {
        const int64_t quote_line = line;
        size_t j = start + 1;
        bool closed = false;
        while (j < n) {
          if (d[j] == '"') {
            if (j + 1 >= n && !eof) return Parsed::kNeedMore;
            if (j + 1 < n && d[j + 1] == '"') {
              f.escaped_quotes = true;
              j += 2;
              continue;
            }
            closed = true;
            break;
          }
          if (d[j] == '\n') ++line;
          ++j;
        }
        if (!closed) {
          if (!eof) return Parsed::kNeedMore;
          *error = Error(quote_line, "unterminated quoted field");
          return Parsed::kError;
        }
        f.value_begin = start + 1;
        f.value_end = j;
        ++j;  // the closing quote
        while (j < n && IsBlank(d[j])) ++j;
        if (j >= n && !eof) return Parsed::kNeedMore;
        if (j < n && d[j] == '\r' && j + 1 >= n && !eof) return Parsed::kNeedMore;
        const bool line_end =
            j < n && (d[j] == '\n' || (d[j] == '\r' && (j + 1 >= n || d[j + 1] == '\n')));
        if (j < n && !line_end && d[j] != ',') {
          *error = Error(line, "unexpected text after a closing quote");
          return Parsed::kError;
        }
        f.raw_end = j;
        i = j;
        if (i < n && d[i] == '\r') ++i;  // CR of CRLF
      } else {
        size_t j = start;
        while (j < n && d[j] != '\n' && d[j] != ',') {
          if (d[j] == '"') {
            *error = Error(line, "quote inside an unquoted field (quote the whole field)");
            return Parsed::kError;
          }
          ++j;
        }
        if (j >= n && !eof) return Parsed::kNeedMore;
        f.raw_end = j;
        if (f.raw_end > f.raw_begin && d[f.raw_end - 1] == '\r' && (j >= n || d[j] == '\n')) {
          --f.raw_end;  // CRLF
        }
        f.value_begin = f.raw_begin;
        f.value_end = f.raw_end;
        while (f.value_begin < f.value_end && IsBlank(d[f.value_begin])) ++f.value_begin;
        while (f.value_end > f.value_begin && IsBlank(d[f.value_end - 1])) --f.value_end;
        i = j;
      }
      fields_.push_back(f);
      if (i >= n) {
        if (!eof) return Parsed::kNeedMore;
        *record_end = n;
        *end_line = line;
        return Parsed::kRecord;
      }
      if (d[i] == ',') {
        ++i;
        continue;
      }
      *record_end = i + 1;  // after '\n'
      *end_line = line + 1;
      return Parsed::kRecord;
    }
  }

  // A field's value (quotes unescaped).
  std::string Value(const FieldSpan& f) const {
    std::string v(in_.data() + f.value_begin, f.value_end - f.value_begin);
    if (f.escaped_quotes) {
      std::string u;
      for (size_t i = 0; i < v.size(); ++i) {
        u += v[i];
        if (v[i] == '"' && i + 1 < v.size() && v[i + 1] == '"') ++i;
      }
      v = u;
    }
    return v;
  }

  Status Header() {
    num_columns_ = fields_.size();
    std::unordered_set<std::string> seen;
    std::vector<std::string> names;
    for (size_t i = 0; i < fields_.size(); ++i) {
      names.push_back(Value(fields_[i]));
      if (names.back().empty()) {
        return Error(line_, "header column " + std::to_string(i + 1) + " has no name");
      }
      if (!seen.insert(csv_internal::Lower(names.back())).second) {
        return Error(line_, "duplicate column " + QuoteForMessage(names.back()));
      }
    }
    const char* const kAxis[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      column_[k] = -1;
      for (size_t i = 0; i < names.size(); ++i) {
        if (csv_internal::Lower(names[i]) == kAxis[k]) column_[k] = static_cast<int>(i);
      }
      if (column_[k] < 0) {
        return Error(line_, std::string("missing column '") + kAxis[k] +
                                "' (a points CSV needs x, y and z columns)");
      }
    }
    for (size_t i = 0; i < fields_.size(); ++i) {
      if (i) out_->Append(",", 1);
      out_->Append(in_.data() + fields_[i].raw_begin, fields_[i].raw_end - fields_[i].raw_begin);
    }
    out_->Append("\n", 1);
    return Status::Ok();
  }

  Status Row() {
    if (fields_.size() != num_columns_) {
      return Error(line_, "expected " + std::to_string(num_columns_) +
                              " fields (as the header), found " + std::to_string(fields_.size()));
    }
    static const char* const kAxis[3] = {"x", "y", "z"};
    double v[3];
    for (int k = 0; k < 3; ++k) {
      const FieldSpan& f = fields_[static_cast<size_t>(column_[k])];
      if (f.escaped_quotes ||
          !ParseCoordinateFast(in_.data() + f.value_begin, in_.data() + f.value_end, &v[k])) {
        Result<double> parsed = csv_internal::ParseCoordinate(
            Value(f), in_.path() + ":" + std::to_string(line_) + ": field '" + kAxis[k] + "': ");
        if (!parsed.ok()) return parsed.status();
        v[k] = *parsed;
      }
    }
    for (size_t i = 0; i < fields_.size(); ++i) {
      if (i) out_->Append(",", 1);
      int axis = -1;
      for (int k = 0; k < 3; ++k) axis = column_[k] == static_cast<int>(i) ? k : axis;
      if (axis >= 0) {
        char number[32];
        out_->Append(number, static_cast<size_t>(WriteShortest(number, s_ * v[axis]) - number));
      } else {
        out_->Append(in_.data() + fields_[i].raw_begin, fields_[i].raw_end - fields_[i].raw_begin);
      }
    }
    out_->Append("\n", 1);
    ++counts_->num_points;
    return Status::Ok();
  }

  InputFile& in_;
  OutputBuffer* out_;
  const double s_;
  ScaleCounts* counts_;
  size_t pos_ = 0;       // window offset of the next record
  int64_t line_ = 1;     // its 1-based line
  std::vector<FieldSpan> fields_;  // of the current record (capacity reused)
  size_t num_columns_ = 0;
  int column_[3] = {-1, -1, -1};
};

}  // namespace

Status ScaleCsv(InputFile& in, OutputBuffer* out, double s, bool header_only,
                ScaleCounts* counts) {
  return CsvScaler(in, out, s, counts).Run(header_only);
}

}  // namespace point_file_internal
}  // namespace opl
