#include "opl/core/format.h"

#include <charconv>
#include <cstdio>

#include "opl/core/message_text.h"

namespace opl {

namespace {

void AppendEscaped(unsigned char c, std::string* out) {
  switch (c) {
    case '\n': *out += "\\n"; return;
    case '\r': *out += "\\r"; return;
    case '\t': *out += "\\t"; return;
    default: break;
  }
  if (c < 0x20 || c == 0x7f) {
    static const char kHex[] = "0123456789abcdef";
    *out += "\\x";
    *out += kHex[c >> 4];
    *out += kHex[c & 15];
  } else {
    *out += static_cast<char>(c);
  }
}

}  // namespace

std::string SafeForMessage(const std::string& text, size_t max_bytes) {
  size_t end = text.size();
  const bool cut = end > max_bytes;
  if (cut) {
    end = max_bytes;
    // Not inside a UTF-8 sequence: back off its continuation bytes.
    while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xC0) == 0x80) --end;
  }
  std::string out;
  out.reserve(end + 8);
  for (size_t i = 0; i < end; ++i) AppendEscaped(static_cast<unsigned char>(text[i]), &out);
  if (cut) out += "...";
  return out;
}

std::string QuoteForMessage(const std::string& text, size_t max_bytes) {
  return "'" + SafeForMessage(text, max_bytes) + "'";
}

std::string OneLineMessage(const std::string& message) {
  std::string out;
  out.reserve(message.size());
  for (const char c : message) AppendEscaped(static_cast<unsigned char>(c), &out);
  return out;
}

std::string FormatNumber(double value, int significant_digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", significant_digits, value);
  return buf;
}

std::string FormatRoundTrip(double value) {
  char buffer[64];
  const std::to_chars_result r = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, r.ptr);
}

std::string FormatPrintf(const char* fmt, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), fmt, value);
  return buffer;
}

std::string FormatTriple(const char* fmt, const Eigen::Vector3d& v) {
  return "(" + FormatPrintf(fmt, v.x()) + ", " + FormatPrintf(fmt, v.y()) + ", " +
         FormatPrintf(fmt, v.z()) + ")";
}

}  // namespace opl
