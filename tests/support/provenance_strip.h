// Tests that compare what a tool wrote (two runs, or a file against its
// expected contents) compare it without the provenance the tool stamps in
// (io/provenance_stamp.h): its time and command line differ by run. The
// provenance itself is checked in tests/io/provenance_stamp_test.cc and
// tests/apps/provenance_cli_test.cc.
#pragma once

#include <string>

#include "io/temp_dir.h"

namespace opl {
namespace testing_support {

// `text` without OPL's provenance: the "# opl ..." lines of a CSV/XYZ, the
// "comment opl ..." lines of a PLY header, and the "provenance" member the
// stamp appended to a JSON object. Other text is returned unchanged.
inline std::string StripProvenance(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  size_t line = 0;
  while (line < text.size()) {
    size_t eol = text.find('\n', line);
    eol = eol == std::string::npos ? text.size() : eol + 1;
    size_t start = line;
    if (line == 0 && text.compare(0, 3, "\xEF\xBB\xBF") == 0) {
      out += text.substr(0, 3);
      start = 3;
    }
    if (text.compare(start, 6, "# opl ") != 0 && text.compare(start, 12, "comment opl ") != 0) {
      out.append(text, start, eol - start);
    }
    line = eol;
  }
  const size_t member = out.rfind("\"provenance\": {");
  if (member == std::string::npos) return out;
  size_t comma = member;
  while (comma > 0 && out[comma - 1] != ',' && out[comma - 1] != '{') --comma;
  if (comma == 0) return out;
  const bool only_member = out[comma - 1] == '{';
  const size_t from = only_member ? comma : comma - 1;
  size_t root_close = out.find_last_of('}');
  if (root_close == std::string::npos || root_close <= member) return out;
  // The provenance object is the root's last member: it ends at the '}'
  // before the root's closing brace (and its line break, when pretty).
  size_t to = root_close;
  if (to > 0 && out[to - 1] == '\n') --to;
  return out.substr(0, from) + out.substr(to);
}

// A file the tool wrote, without its provenance.
inline std::string ReadOutput(const std::string& path) { return StripProvenance(ReadAll(path)); }

}  // namespace testing_support
}  // namespace opl
