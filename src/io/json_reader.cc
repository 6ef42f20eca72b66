#include "io/json_reader.h"

#include <cmath>
#include <memory>
#include <vector>

#include "opl/core/message_text.h"

namespace opl {
namespace json_internal {
namespace {

using json = nlohmann::json;

// (line, column), 1-based, of byte offset `byte` (0-based) of `text`.
std::pair<size_t, size_t> LineColumn(const std::string& text, size_t byte) {
  size_t line = 1, column = 1;
  for (size_t i = 0; i < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return {line, column};
}

std::string JoinPath(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// Detects duplicate keys (nlohmann keeps the last one silently) and records
// the field path of the first one.
class DuplicateKeyFinder {
 public:
  bool operator()(int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start: {
        std::string path;
        if (!frames_.empty()) {
          const Frame& parent = frames_.back();
          path = parent.is_array ? parent.path + "[" + std::to_string(parent.count) + "]"
                                 : JoinPath(parent.path, parent.last_key);
        }
        frames_.push_back({event == json::parse_event_t::array_start, 0, path, "", {}});
        break;
      }
      case json::parse_event_t::key: {
        if (frames_.empty()) break;
        Frame& f = frames_.back();
        f.last_key = parsed.is_string() ? parsed.get<std::string>() : parsed.dump();
        if (!f.keys.insert(f.last_key).second && duplicate_.empty()) {
          duplicate_ = JoinPath(f.path, f.last_key);
        }
        break;
      }
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!frames_.empty()) frames_.pop_back();
        if (!frames_.empty() && frames_.back().is_array) ++frames_.back().count;
        break;
      case json::parse_event_t::value:
        if (!frames_.empty() && frames_.back().is_array) ++frames_.back().count;
        break;
    }
    return true;
  }
  const std::string& duplicate() const { return duplicate_; }

 private:
  struct Frame {
    bool is_array = false;
    size_t count = 0;
    std::string path;
    std::string last_key;
    std::set<std::string> keys;
  };
  std::vector<Frame> frames_;
  std::string duplicate_;
};

std::string StripNlohmann(const std::string& what) {
  // "[json.exception.parse_error.101] parse error at line 3, column 7: syntax error ..."
  std::string s = what;
  if (!s.empty() && s[0] == '[') {
    const size_t close = s.find("] ");
    if (close != std::string::npos) s = s.substr(close + 2);
  }
  const std::string at = "parse error at line ";
  if (s.compare(0, at.size(), at) == 0) {
    const size_t colon = s.find(": ");
    if (colon != std::string::npos) s = s.substr(colon + 2);
  }
  return s;
}

}  // namespace

std::string JsonErrorForMessage(const std::string& what) {
  std::string s = StripNlohmann(what);
  const std::string last_read = "last read: '";
  const size_t start = s.find(last_read);
  if (start != std::string::npos) {
    const size_t from = start + last_read.size();
    size_t end = s.find("'; expected", from);
    if (end == std::string::npos) end = s.rfind('\'');
    if (end != std::string::npos && end >= from) {
      s = s.substr(0, from) + SafeForMessage(s.substr(from, end - from), 40) + s.substr(end);
    }
  }
  return SafeForMessage(s, 300);
}

std::string WithSafePathPrefix(const std::string& message, const std::string& path) {
  if (message.compare(0, path.size(), path) != 0) return message;
  return SafeForMessage(path) + message.substr(path.size());
}

Status CheckJsonDepth(const std::string& text, const std::string& name) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character, whatever it is
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        const auto [line, column] = LineColumn(text, i);
        return Status::ParseError(name + ":" + std::to_string(line) + ":" +
                                  std::to_string(column) + ": invalid JSON: nested deeper than " +
                                  std::to_string(kMaxJsonDepth) + " levels");
      }
    } else if (c == ']' || c == '}') {
      --depth;  // unbalanced brackets are left to the parser
    }
  }
  return Status::Ok();
}

Result<json> JsonReader::ParseText(const std::string& text) const {
  OPL_RETURN_IF_ERROR(CheckJsonDepth(text, name_));
  json root;
  // nlohmann copies the callback: keep the finder's state behind a shared_ptr.
  auto finder = std::make_shared<DuplicateKeyFinder>();
  try {
    root = json::parse(text, [finder](int depth, json::parse_event_t event, json& parsed) {
      return (*finder)(depth, event, parsed);
    });
  } catch (const json::parse_error& e) {
    const auto [line, column] = LineColumn(text, e.byte > 0 ? e.byte - 1 : 0);
    return Status::ParseError(name_ + ":" + std::to_string(line) + ":" + std::to_string(column) +
                              ": invalid JSON: " + JsonErrorForMessage(e.what()));
  } catch (const json::exception& e) {
    // e.g. out_of_range.406 "number overflow parsing '1e999'": locate the literal.
    const std::string what = JsonErrorForMessage(e.what());
    std::string where = name_;
    const size_t q = what.find('\'');
    const size_t q2 = q == std::string::npos ? q : what.find('\'', q + 1);
    if (q2 != std::string::npos) {
      const size_t at = text.find(what.substr(q + 1, q2 - q - 1));
      if (at != std::string::npos) {
        const auto [line, column] = LineColumn(text, at);
        where += ":" + std::to_string(line) + ":" + std::to_string(column);
      }
    }
    return Status::ParseError(where + ": invalid JSON: " + what +
                              " (numbers must be finite doubles)");
  }
  if (!finder->duplicate().empty()) {
    // The duplicate's path is within this document: no prefix.
    return Status::ParseError(name_ + ": " + finder->duplicate() +
                              ": duplicate key (each field may appear once)");
  }
  return root;
}

Status JsonReader::Error(const std::string& path, const std::string& what) const {
  const std::string full = prefix_.empty() ? path : (path.empty() ? prefix_ : prefix_ + "." + path);
  // A path may hold a key from the file: escaped and cut (issue 19 item 7).
  return Status::ParseError(name_ + ": " + (full.empty() ? "" : SafeForMessage(full) + ": ") +
                            what);
}

std::string JsonReader::Describe(const json& v) {
  // Escaped: nlohmann escapes control characters below 0x20 in strings, not DEL.
  const std::string d = v.dump();
  return d.size() > 40 ? SafeForMessage(d, 37) : SafeForMessage(d, 40);
}

Status JsonReader::CheckObject(const json& v, const std::string& path) const {
  if (!v.is_object()) return Error(path, "expected an object, got " + Describe(v));
  return Status::Ok();
}

Status JsonReader::CheckArray(const json& v, const std::string& path) const {
  if (!v.is_array()) return Error(path, "expected an array, got " + Describe(v));
  return Status::Ok();
}

Status JsonReader::CheckKeys(const json& obj, const std::string& path,
                             const std::set<std::string>& allowed) const {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (!allowed.count(it.key())) {
      std::string list;
      for (const std::string& k : allowed) list += (list.empty() ? "" : ", ") + k;
      return Error(Join(path, it.key()), "unknown field (allowed here: " + list + ")");
    }
  }
  return Status::Ok();
}

Status JsonReader::Require(const json& obj, const std::string& path, const std::string& key,
                           const json** out) const {
  *out = Find(obj, key);
  if (*out == nullptr) return Error(Join(path, key), "missing field");
  return Status::Ok();
}

Status JsonReader::Number(const json& v, const std::string& path, double* out) const {
  if (!v.is_number()) return Error(path, "expected a number, got " + Describe(v));
  *out = v.get<double>();
  if (!std::isfinite(*out)) return Error(path, "not a finite number");
  return Status::Ok();
}

Status JsonReader::Integer(const json& v, const std::string& path, int* out) const {
  if (!v.is_number_integer()) return Error(path, "expected an integer, got " + Describe(v));
  if (v.is_number_unsigned() && v.get<unsigned long long>() > 1000000000ULL) {
    return Error(path, "integer out of range");
  }
  const auto x = v.get<long long>();
  if (x < -1000000000LL || x > 1000000000LL) return Error(path, "integer out of range");
  *out = static_cast<int>(x);
  return Status::Ok();
}

Status JsonReader::String(const json& v, const std::string& path, std::string* out) const {
  if (!v.is_string()) return Error(path, "expected a string, got " + Describe(v));
  *out = v.get<std::string>();
  return Status::Ok();
}

Status JsonReader::Vec3(const json& v, const std::string& path, Eigen::Vector3d* out) const {
  if (!v.is_array() || v.size() != 3) {
    return Error(path, "expected an array of 3 numbers, got " + Describe(v));
  }
  for (int k = 0; k < 3; ++k) {
    OPL_RETURN_IF_ERROR(Number(v[static_cast<size_t>(k)], Index(path, static_cast<size_t>(k)),
                               &(*out)[k]));
  }
  return Status::Ok();
}

Status JsonReader::RequiredNumber(const json& obj, const std::string& path, const std::string& key,
                                  double* out) const {
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(Require(obj, path, key, &v));
  return Number(*v, Join(path, key), out);
}

Status JsonReader::RequiredVec3(const json& obj, const std::string& path, const std::string& key,
                                Eigen::Vector3d* out) const {
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(Require(obj, path, key, &v));
  return Vec3(*v, Join(path, key), out);
}

Status JsonReader::NonZeroVec3(const json& obj, const std::string& path, const std::string& key,
                               Eigen::Vector3d* out) const {
  OPL_RETURN_IF_ERROR(RequiredVec3(obj, path, key, out));
  if (out->norm() == 0.0) return Error(Join(path, key), "must not be the zero vector");
  return Status::Ok();
}

Status JsonReader::OptionalNumber(const json& obj, const std::string& path, const std::string& key,
                                  double* out) const {
  const json* v = Find(obj, key);
  return v == nullptr ? Status::Ok() : Number(*v, Join(path, key), out);
}

Status JsonReader::OptionalInteger(const json& obj, const std::string& path,
                                   const std::string& key, int* out) const {
  const json* v = Find(obj, key);
  return v == nullptr ? Status::Ok() : Integer(*v, Join(path, key), out);
}

Status JsonReader::CheckFormatAndVersion(const json& root, const std::string& format,
                                         int version) const {
  const json* v = nullptr;
  std::string got;
  OPL_RETURN_IF_ERROR(Require(root, "", "format", &v));
  OPL_RETURN_IF_ERROR(String(*v, "format", &got));
  if (got != format) return Error("format", "expected \"" + format + "\", got " + Describe(*v));
  int got_version = 0;
  OPL_RETURN_IF_ERROR(Require(root, "", "version", &v));
  OPL_RETURN_IF_ERROR(Integer(*v, "version", &got_version));
  if (got_version != version) {
    return Error("version", "unsupported version " + std::to_string(got_version) +
                                " (this reader reads version " + std::to_string(version) + ")");
  }
  return Status::Ok();
}

}  // namespace json_internal
}  // namespace opl
