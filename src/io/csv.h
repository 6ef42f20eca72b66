// Private to src/io: a small RFC 4180 CSV reader shared by the spots, points
// and point-table readers, and the field-level parsing they need.
//
// Records end at "\n" or "\r\n". A field that starts with '"' is quoted: it may
// hold delimiters, line breaks and '""' (a literal quote), and the closing quote
// must end the field. Unquoted fields have surrounding spaces and tabs trimmed
// (except the delimiter itself: with tab-separated fields only spaces are
// trimmed); quoted fields are kept exactly. Blank lines (only whitespace) are
// skipped. A UTF-8 byte-order mark at the start is ignored. ParseCsv checks that
// every record has as many fields as the header. Errors are ParseErrors
// "<name>:<line>: <what>", with the line where the record starts (1-based).
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"

namespace opl {
namespace csv_internal {

struct CsvRecord {
  int line = 0;                     // 1-based line where the record starts
  std::vector<std::string> fields;  // values (unquoted, unescaped, trimmed)
  std::vector<std::string> raw;     // each field's exact text in the file
};

struct CsvTable {
  CsvRecord header;
  std::vector<CsvRecord> rows;

  // Index of the column whose (case-insensitive) name is `name`, or -1.
  int FindColumn(const std::string& name) const;
};

// How SplitRecords cuts text into records and fields.
struct SplitOptions {
  // ',', ';' or '\t': one delimiter between two fields (empty fields possible).
  // ' ' means runs of spaces and tabs separate fields (no empty fields unless
  // quoted; leading and trailing blanks of a line are ignored).
  char delimiter = ',';
  // A line whose first non-blank character is `comment` is skipped ('\0': no
  // comment lines). Only whole lines; not inside a quoted field.
  char comment = '\0';
  // The first `skip_lines` physical lines (after a BOM) are skipped unread.
  int skip_lines = 0;
};

// Splits `text` into records (blank, comment and skipped lines left out); no
// field-count check. Errors: a malformed quoted field ("unterminated quoted
// field", "unexpected text after a closing quote", "quote inside an unquoted
// field (quote the whole field)").
Result<std::vector<CsvRecord>> SplitRecords(const std::string& text, const std::string& name,
                                            const SplitOptions& options);

// The text after a UTF-8 byte-order mark, if `text` starts with one (offset 3),
// else 0.
size_t SkipBom(const std::string& text);

// Parses `text`; `name` (usually the file path) prefixes every message. Blank
// lines and comment lines (first non-blank character '#') are skipped. Fails on
// an empty input (no header), an empty or duplicate column name, a malformed
// quoted field or a record whose field count differs from the header's.
Result<CsvTable> ParseCsv(const std::string& text, const std::string& name);

// The field quoted per RFC 4180 when it needs it (comma, quote, line break,
// leading/trailing whitespace or empty), otherwise unchanged.
std::string QuoteCsvField(const std::string& field);

// "<name>:<line>: field '<column>': " — the prefix of a field's messages.
std::string FieldContext(const std::string& name, int line, const std::string& column);

// A finite double: decimal or scientific notation, optional leading '+'.
// ParseError "<context>not a number: 'abc'" / "not finite: 'nan'" /
// "out of range: '1e999'" / "empty value". A value that would be a number with
// its one comma read as a decimal point says so:
// "not a number: '12,5' (decimal commas are not supported)".
Result<double> ParseFiniteDouble(const std::string& text, const std::string& context);

// The finite range of a coordinate (spots, points CSV: |x|, |y|, |z|) and of
// a standard deviation (sx, sy, sz), in scene units (docs/formats.md,
// 'Limits'): a scene in micrometres a thousand km across fits; a value beyond
// is a corrupt field, not a measurement.
inline constexpr double kMaxAbsCoordinate = 1e12;
inline constexpr double kMinSigma = 1e-12;
inline constexpr double kMaxSigma = 1e12;

// ParseFiniteDouble, then |value| <= kMaxAbsCoordinate: ParseError
// "<context>beyond the limit of |value| <= 1e12 scene units, got 1e308" (the
// text parsed as a number, so it is shown as it is).
Result<double> ParseCoordinate(const std::string& text, const std::string& context);

// ParseFiniteDouble, then kMinSigma <= value <= kMaxSigma: ParseError
// "<context>standard deviation must be > 0, got 0" or "<context>standard
// deviation beyond the range 1e-12 to 1e12 scene units, got 1e300".
Result<double> ParseSigma(const std::string& text, const std::string& context);

// A decimal integer that fits in int.
Result<int> ParseInt(const std::string& text, const std::string& context);

// Shows a value in a message: QuoteForMessage(text, 40) (quoted, at most 40
// bytes, control characters escaped).
std::string Shown(const std::string& text);

// ASCII lower case.
std::string Lower(std::string s);

}  // namespace csv_internal
}  // namespace opl
