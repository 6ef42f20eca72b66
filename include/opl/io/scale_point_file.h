// Scaling a point file by the scale factor, streamed: what opl_measure --apply
// does (docs/formats.md, "Point files"; docs/cli.md).
//
//   ScalePointFileOptions options;            // format from the extension
//   ScalePointFileSummary summary;
//   Status st = ScalePointFile("scan.ply", "scan_mm.ply", s, options, &summary);
//   if (!st.ok()) { /* summary.output_failed ? cannot write : bad input */ }
//
// Every coordinate x, y, z of every point is multiplied by s (mm per scene
// unit); everything else in the file is kept. The output has the format of the
// input (a PLY stays a PLY of the same encoding). Three formats:
//
// - PLY (.ply): ascii, binary_little_endian, binary_big_endian; the vertex
//   element's x, y, z (float or double) are scaled, every other property,
//   element, comment and header line kept byte for byte, plus one comment
//   saying OPL scaled the file (opl/io/point_cloud_ply.h).
// - XYZ (.xyz, .txt): headerless text, one point a line, "x y z [anything]":
//   the first three fields (separated by spaces or tabs) are scaled, the rest
//   of the line (its separators, further fields, the line break: "\n" or
//   "\r\n") copied byte for byte. Blank lines and comment lines (the first
//   character that is not a space or tab is '#') are copied. Leading spaces
//   are kept; a UTF-8 byte-order mark is kept.
// - Points CSV (.csv): opl/io/points_csv.h, the same rules, messages and
//   output as PointsCsv (x, y, z columns by name; every other field verbatim;
//   blank lines dropped; "\n" line ends).
//
// Text numbers (XYZ, CSV, ASCII PLY double) are written as the shortest text
// that reads back to exactly s * x in double (std::to_chars); a float property
// of an ASCII PLY as the shortest text of the float it rounds to. XYZ and CSV
// coordinates obey the limits of docs/formats.md (finite, |x| <= 1e12).
//
// Streaming: the file is read and written through two buffers of
// `buffer_bytes` each, whatever its size (10 million points take the same
// memory as ten); nothing is allocated per point. A line, CSV record or binary
// PLY record must fit in the buffer.
//
// Errors: one line naming the file and the line (text formats, PLY header) or
// the element index (from 0) and byte offset (binary PLY), e.g.
//   "scan.xyz:7: field 'z': not a number: 'abc'"
//   "scan.ply: byte 1036: vertex 84 of 100 is cut off by the end of the file (truncated, or wrong counts in the header)"
// The output is written atomically (AtomicFileWriter): on any error nothing
// is left at `out_path` (an existing file there is untouched).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "opl/core/status.h"
#include "opl/io/output_set.h"
#include "opl/io/provenance.h"

namespace opl {

enum class PointFileFormat {
  kAuto,  // from the input's extension (.ply; .xyz or .txt; .csv), case-insensitive
  kPly,
  kXyz,
  kCsv,
};

// "auto", "ply", "xyz", "csv".
const char* PointFileFormatName(PointFileFormat format);
// The format named "ply", "xyz" or "csv" (or "auto"); InvalidArgument otherwise.
Result<PointFileFormat> ParsePointFileFormat(const std::string& name);
// The format of a path by its extension: InvalidArgument
// "scene.dat: cannot tell the point file format from the extension '.dat'
// (.ply, .xyz, .txt or .csv; or give the format)".
Result<PointFileFormat> PointFileFormatFromPath(const std::string& path);

struct ScalePointFileOptions {
  // kAuto: from the input path's extension.
  PointFileFormat format = PointFileFormat::kAuto;
  // Bytes of each of the two buffers (input, output). At least 4096; default
  // 4 MiB (larger buys nothing measurable, docs/formats.md).
  int64_t buffer_bytes = int64_t{4} << 20;
  // When set, the output carries this provenance (io/provenance_stamp.h):
  // "comment opl ..." lines after the PLY's own OPL comment, "# opl ..."
  // lines first in XYZ and CSV.
  const Provenance* provenance = nullptr;
  // When set, the output is staged in this set (finished, not yet renamed):
  // it appears with the run's other outputs at outputs->Commit().
  OutputSet* outputs = nullptr;
  // Called after every read with (bytes read so far, input file size).
  std::function<void(int64_t bytes_read, int64_t bytes_total)> progress;

  // False with `why` naming the field, its value and the constraint.
  bool IsValid(std::string* why) const;
};

struct ScalePointFileSummary {
  PointFileFormat format = PointFileFormat::kAuto;  // the format used
  int64_t num_points = 0;      // points scaled (PLY vertices, XYZ lines, CSV rows)
  int64_t bytes_read = 0;      // input size
  int64_t bytes_written = 0;   // output size (0 when nothing was written)
  // True when the failure was writing `out_path` (exit code 5 in the tools),
  // false when it was the input or the arguments (exit code 3).
  bool output_failed = false;

  // "1000000 points (ply) scaled, 39000123 bytes written".
  std::string BriefReport() const;
};

// Scales `in_path` into `out_path` (atomically). InvalidArgument when s is not
// finite and > 0 or the options are invalid; IoError when a file cannot be
// read or written; ParseError for malformed input. `summary` may be null.
Status ScalePointFile(const std::string& in_path, const std::string& out_path, double s,
                      const ScalePointFileOptions& options, ScalePointFileSummary* summary);

// Checks what can be checked before a long run without writing anything: the
// input opens and is a regular file, its format is known, and its header (PLY
// header, CSV header row) is valid with x, y, z to scale. The body is checked
// while scaling. Same messages as ScalePointFile.
Status CheckPointFile(const std::string& in_path, const ScalePointFileOptions& options);

}  // namespace opl
