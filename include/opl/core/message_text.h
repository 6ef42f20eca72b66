// Echoing file content in messages safely (issue 19 item 7): every message
// of the tools is one line on stderr, whatever a file holds.
#pragma once

#include <cstddef>
#include <string>

namespace opl {

// Text from an input file (a CSV field, a source or camera name, a JSON key)
// made safe to echo in a one-line message (issue 19 item 7): control
// characters are shown as escapes ("\n", "\r", "\t", "\x1b"; DEL as
// "\x7f"), and text longer than `max_bytes` is cut there (not inside a UTF-8
// character) and ends with "...". Other bytes, UTF-8 included, are kept.
std::string SafeForMessage(const std::string& text, size_t max_bytes = 200);

// SafeForMessage in single quotes: "'A\x1b[31m'".
std::string QuoteForMessage(const std::string& text, size_t max_bytes = 200);

// A whole message made one safe line: every control character escaped as in
// SafeForMessage, nothing cut (the last guard of the tools' stderr line).
std::string OneLineMessage(const std::string& message);

}  // namespace opl
