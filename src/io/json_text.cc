// CompactNumberArrays (io/json_text.h).
#include "opl/io/json_text.h"

#include <string>

namespace opl {
namespace {

bool IsJsonSpace(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; }
bool IsNumberChar(char c) {
  return (c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.' || c == 'e' || c == 'E';
}

// When text[open] starts an array of numbers only ("[", numbers separated
// by commas, "]", any whitespace between), its one-line form
// "[0.0, 27.5, 0.0]" in *compact and the index after its "]" in *end.
bool CompactNumberArrayAt(const std::string& text, size_t open, std::string* compact, size_t* end) {
  std::string out = "[";
  size_t k = open + 1;
  for (bool first = true;; first = false) {
    while (k < text.size() && IsJsonSpace(text[k])) ++k;
    if (k >= text.size() || !(text[k] == '-' || (text[k] >= '0' && text[k] <= '9'))) return false;
    const size_t start = k;
    while (k < text.size() && IsNumberChar(text[k])) ++k;
    out += (first ? "" : ", ") + text.substr(start, k - start);
    while (k < text.size() && IsJsonSpace(text[k])) ++k;
    if (k >= text.size()) return false;
    if (text[k] == ']') {
      *compact = out + "]";
      *end = k + 1;
      return true;
    }
    if (text[k] != ',') return false;
    ++k;
  }
}

}  // namespace

std::string CompactNumberArrays(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  bool in_string = false;
  for (size_t i = 0; i < text.size();) {
    const char c = text[i];
    if (in_string) {
      const size_t n = c == '\\' && i + 1 < text.size() ? 2 : 1;  // an escape and its character
      out.append(text, i, n);
      in_string = !(c == '"');
      i += n;
      continue;
    }
    std::string compact;
    size_t end = 0;
    if (c == '[' && CompactNumberArrayAt(text, i, &compact, &end)) {
      out += compact;
      i = end;
      continue;
    }
    in_string = c == '"';
    out += c;
    ++i;
  }
  return out;
}

}  // namespace opl
