// Headerless XYZ, streamed (opl/io/scale_point_file.h, docs/formats.md): every line "x y z
// [anything...]", the first three whitespace-separated fields scaled and the
// rest of the line copied byte for byte.

#include "io/csv.h"
#include "io/point_file_stream.h"

namespace opl {
namespace point_file_internal {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

}  // namespace

Status ScaleXyz(InputFile& in, OutputBuffer* out, double s, bool header_only,
                ScaleCounts* counts) {
  if (header_only) return Status::Ok();  // no header: every line is checked as it comes
  size_t pos = 0;
  int64_t line_number = 1;
  OPL_RETURN_IF_ERROR(in.Ensure(3));
  if (in.size() >= 3 && std::memcmp(in.data(), "\xEF\xBB\xBF", 3) == 0) {
    out->Append(in.data(), 3);  // a UTF-8 byte-order mark, kept
    pos = 3;
  }
  static const char* const kAxis[3] = {"x", "y", "z"};
  Line line;
  while (true) {
    Result<bool> more = NextLine(in, &pos, line_number, &line);
    if (!more.ok()) return more.status();
    if (!*more) break;
    const char* const data = in.data();
    const char* const b = data + line.begin;
    const char* const e = data + line.end;
    const char* const content_end = (e > b && e[-1] == '\r') ? e - 1 : e;
    const char* p = b;
    while (p < content_end && IsBlank(*p)) ++p;
    if (p == content_end || *p == '#') {  // blank or comment: kept as it is
      out->Append(b, line.next - line.begin);
    } else {
      const char* field_begin[3];
      const char* field_end[3];
      int found = 0;
      for (; found < 3 && p < content_end; ++found) {
        field_begin[found] = p;
        while (p < content_end && !IsBlank(*p)) ++p;
        field_end[found] = p;
        while (p < content_end && IsBlank(*p)) ++p;
      }
      const std::string where = in.path() + ":" + std::to_string(line_number) + ": ";
      if (found < 3) {
        const bool commas = std::memchr(b, ',', static_cast<size_t>(content_end - b)) != nullptr;
        return Status::ParseError(where + "expected x y z (3 fields separated by spaces or tabs), found " +
                                  std::to_string(found) +
                                  (commas ? " (a CSV file? give --format csv)" : ""));
      }
      double v[3];
      for (int k = 0; k < 3; ++k) {
        if (!ParseCoordinateFast(field_begin[k], field_end[k], &v[k])) {
          const std::string text(field_begin[k], field_end[k]);
          Result<double> parsed = csv_internal::ParseCoordinate(
              text, where + "field '" + kAxis[k] + "': ");
          if (!parsed.ok()) return parsed.status();
          v[k] = *parsed;  // (not reached: the fast path takes every valid number)
        }
      }
      // Everything around the three fields, byte for byte.
      const char* copied = b;
      for (int k = 0; k < 3; ++k) {
        out->Append(copied, static_cast<size_t>(field_begin[k] - copied));
        char number[32];
        out->Append(number, static_cast<size_t>(WriteShortest(number, s * v[k]) - number));
        copied = field_end[k];
      }
      out->Append(copied, static_cast<size_t>(data + line.next - copied));
      ++counts->num_points;
    }
    if (out->failed()) return Status::Ok();
    pos = line.next;
    ++line_number;
  }
  return Status::Ok();
}

}  // namespace point_file_internal
}  // namespace opl
