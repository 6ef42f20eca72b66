// Point tables from other software: 3D points exported by a photogrammetry
// package as CSV or whitespace-separated text, with that package's own column
// order and no (or an unusable) header. The caller says what each column is
// (a column mapping such as `--columns id,x,y,z,sx,sy,sz --skip-rows 1`); the
// points come back as SpotsCsvData, like a spots CSV, so the rest of the
// pipeline does not care where they came from.
// Full description: docs/formats.md, "Point tables from other software".
//
//   # exported by XYZ              --columns id,x,y,z,sx,sy,sz
//   P1  1012.50  3.25 -0.50  0.02 0.02 0.03
//   P2  1013.00  2.75 -0.25  0.02 0.02 0.03
//
// Column names (case-insensitive), each at most once except `-`:
//   id            a point name or label, any text (SpotsCsvData::point_ids)
//   x, y, z       required: the point, scene units, finite
//   sx, sy, sz    standard deviations, all three or none, finite and > 0
//   source, beam  the spot's source and beam when the file has them; empty =
//                 unassigned (beam otherwise an integer >= 1). Without these
//                 columns every spot is unassigned (Spot::assigned() false).
//   slice         an integer >= 0 (SpotsCsvData::slices)
//   - or skip     a column to ignore
// Every data line must have exactly as many fields as the mapping names; with
// `allow_extra_fields` fields after the last mapped one are ignored (fewer
// fields are always an error).
//
// Text rules: the first `skip_rows` physical lines are skipped (a header row,
// a banner); then blank lines and comment lines (first non-blank character
// `comment`) are skipped wherever they are. Lines end in "\n" or "\r\n"; a
// UTF-8 byte-order mark is ignored. Fields may be quoted per RFC 4180 (`"Point
// 1"`, `""` for a quote) with every delimiter, as in the spots CSV; unquoted
// fields have surrounding spaces (and tabs, unless tab is the delimiter)
// trimmed. Numbers use a decimal point: decimal commas are not supported (and
// the message says so). Spot::where is "<file>:<line>", line 1-based physical.
//
// Errors are ParseErrors naming the file, line and field, with the same texts
// as the spots CSV reader:
//   "pts.txt:14: field 'x': not a number: 'abc'"
//   "pts.csv:3: field 'x': not a number: '12,5' (decimal commas are not supported)"
//   "pts.txt:5: expected 7 fields (columns id,x,y,z,sx,sy,sz; delimiter whitespace), found 6"
// A bad mapping is an InvalidArgument:
//   "--columns: unknown column name 'q' (known: id, x, y, z, sx, sy, sz, source, beam, slice, -)"
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/io/spots_csv.h"

namespace opl {

struct PointTableFormat {
  enum class Delimiter {
    // Chosen from the first data line (after skipped, blank and comment
    // lines; characters inside quotes do not count):
    //   comma      if it has a comma and no semicolon,
    //   semicolon  else if it has a semicolon (so a "P1;12,5;3,25" line of a
    //              decimal-comma export is read as semicolon-separated and its
    //              error says that decimal commas are not supported),
    //   tab        else if it has a tab,
    //   whitespace otherwise.
    kAuto,
    kComma,       // ','
    kSemicolon,   // ';'
    kTab,         // one tab between two fields (empty fields possible)
    kWhitespace,  // runs of spaces and tabs; leading and trailing blanks ignored
  };

  // One name per column, in file order (see the header comment); ParseColumnMapping
  // gives them in canonical form: lower case, `skip` as "-".
  std::vector<std::string> columns;
  int skip_rows = 0;  // physical lines skipped at the start (>= 0)
  Delimiter delimiter = Delimiter::kAuto;
  char comment = '#';  // lines starting with it are skipped; '\0': none
  // When true, fields after the last mapped column are ignored; when false
  // (default) a line with more fields than columns is an error, which catches
  // a mapping that does not match the file.
  bool allow_extra_fields = false;

  // InvalidArgument: the messages of ParseColumnMapping for the columns (which
  // may be given in any case, `skip` for `-`), "--skip-rows: must be >= 0, got
  // -1", "comment character: cannot be a quote, a blank or a line break",
  // "comment character: ';' is the delimiter".
  Status Validate() const;
};

// Parses a column mapping "id,x,y,z" (names separated by commas, spaces around
// them ignored, case-insensitive) into a format with default delimiter,
// skip_rows and comment. InvalidArgument, e.g.
//   "--columns: unknown column name 'q' (known: id, x, y, z, sx, sy, sz, source, beam, slice, -)"
//   "--columns: 'x' given twice"
//   "--columns: missing required 'y'"
//   "--columns: sx, sy, sz must be given all three or none (missing sz)"
//   "--columns: column 3 has no name"
//   "--columns: empty (give the columns in file order, e.g. id,x,y,z)"
Result<PointTableFormat> ParseColumnMapping(const std::string& spec);

// Parses a delimiter name: auto, comma, semicolon, tab, whitespace (also ",",
// ";", "\t" and "space"). InvalidArgument
// "--delimiter: unknown delimiter 'x' (known: auto, comma, semicolon, tab, whitespace)".
Result<PointTableFormat::Delimiter> ParseDelimiterName(const std::string& name);

// The name of a delimiter as ParseDelimiterName reads it ("comma", ...).
const char* DelimiterName(PointTableFormat::Delimiter delimiter);

// Parses a point table; `name` (the file path) is used in `where` and in
// messages. InvalidArgument when the format is invalid; ParseError for the
// text, including a table with no data line ("<name>: no data lines ...").
// SpotsCsvData: spots in file order; slices when there is a `slice` column;
// point_ids when there is an `id` column; has_sigmas with sx, sy, sz;
// other_columns always empty.
Result<SpotsCsvData> ParsePointTable(const std::string& text, const std::string& name,
                                     const PointTableFormat& format);

// Reads a file: IoError when it cannot be read, else as ParsePointTable.
Result<SpotsCsvData> ReadPointTable(const std::string& path, const PointTableFormat& format);

}  // namespace opl
