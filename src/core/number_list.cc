#include "opl/core/number_list.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

#include "opl/core/format.h"

namespace opl {
namespace {

std::string Trim(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return std::string();
  const size_t last = s.find_last_not_of(" \t");
  return s.substr(first, last - first + 1);
}

// A finite decimal number filling all of `item` (trimmed), or an error
// naming it within the whole `text`.
Result<double> ParseNumber(const std::string& item, const std::string& text,
                           const NumberListSyntax& syntax) {
  const std::string s = Trim(item);
  double value = 0.0;
  const char* begin = s.data();
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') ++begin;  // from_chars takes no '+'
  const char* end = s.data() + s.size();
  const std::from_chars_result r = std::from_chars(begin, end, value);
  if (s.empty() || r.ec != std::errc() || r.ptr != end || !std::isfinite(value)) {
    return Status::InvalidArgument(syntax.noun + " list '" + text + "': '" + s +
                                   "' is not a finite number");
  }
  return value;
}

std::vector<std::string> Split(const std::string& s, char separator) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    const size_t at = s.find(separator, start);
    parts.push_back(s.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) break;
    start = at + 1;
  }
  return parts;
}

}  // namespace

Result<std::vector<double>> ParseNumberList(const std::string& text,
                                            const NumberListSyntax& syntax_rules) {
  const NumberListSyntax& r = syntax_rules;
  const std::string syntax = " (expected first:step:last, e.g. " + r.range_example +
                             ", or a comma-separated list, e.g. " + r.list_example + ")";
  if (Trim(text).empty()) return Status::InvalidArgument("empty " + r.noun + " list" + syntax);
  const bool is_range = text.find(':') != std::string::npos;
  if (is_range && text.find(',') != std::string::npos) {
    return Status::InvalidArgument(r.noun + " list '" + text + "': mixes ':' and ','" + syntax);
  }
  if (!is_range) {
    std::vector<double> values;
    for (const std::string& item : Split(text, ',')) {
      Result<double> value = ParseNumber(item, text, r);
      if (!value.ok()) return value.status();
      values.push_back(*value);
      if (values.size() > kMaxValues) {
        return Status::InvalidArgument(r.noun + " list '" + text.substr(0, 40) +
                                       "...': more than " + std::to_string(kMaxValues) +
                                       " " + r.noun + "s");
      }
    }
    return values;
  }

  const std::vector<std::string> parts = Split(text, ':');
  if (parts.size() != 3) {
    return Status::InvalidArgument(r.noun + " list '" + text + "': a range has three fields" +
                                   syntax);
  }
  double field[3];
  for (int i = 0; i < 3; ++i) {
    Result<double> value = ParseNumber(parts[i], text, r);
    if (!value.ok()) return value.status();
    field[i] = *value;
  }
  const double first = field[0], step = field[1], last = field[2];
  if (!(step > 0.0)) {
    return Status::InvalidArgument(r.noun + " list '" + text + "': step must be > 0, got " +
                                   FormatNumber(step));
  }
  if (!(first <= last)) {
    return Status::InvalidArgument(r.noun + " list '" + text + "': first (" + FormatNumber(first) +
                                   ") must be <= last (" + FormatNumber(last) + ")");
  }
  // Number of whole steps; one more when the next value lands on `last`
  // within 1e-9 relative (rounding of (last - first) / step).
  const double span = (last - first) / step;
  if (!(span < static_cast<double>(kMaxValues))) {
    return Status::InvalidArgument(r.noun + " list '" + text + "' gives more than " +
                                   std::to_string(kMaxValues) + " " + r.noun + "s");
  }
  auto steps = static_cast<size_t>(std::floor(span));
  const double tolerance = 1e-9 * std::max(std::abs(last), std::abs(first));
  bool ends_on_last = std::abs(first + static_cast<double>(steps) * step - last) <= tolerance;
  if (!ends_on_last &&
      std::abs(first + static_cast<double>(steps + 1) * step - last) <= tolerance) {
    ++steps;
    ends_on_last = true;
  }
  std::vector<double> values;
  values.reserve(steps + 1);
  for (size_t i = 0; i <= steps; ++i) values.push_back(first + static_cast<double>(i) * step);
  if (ends_on_last) values.back() = last;
  if (values.size() > kMaxValues) {
    return Status::InvalidArgument(r.noun + " list '" + text + "' gives more than " +
                                   std::to_string(kMaxValues) + " " + r.noun + "s");
  }
  return values;
}

}  // namespace opl
