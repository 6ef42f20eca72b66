// Private to src/io: reading a strict JSON document field by field, shared by
// the module design reader and the scene reader so that both apply the same
// rules with the same messages.
//
// Every error is a ParseError of one line, "<name>: <field path>: <what>",
// where the field path is `prefix` joined with the path inside the document
// (e.g. "module.sources[1].full_angle_deg" for a design inlined in a scene).
// JSON syntax errors are "<name>:<line>:<column>: invalid JSON: ...";
// duplicate keys are errors (nlohmann would keep the last one silently).
#pragma once

#include <set>
#include <string>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "opl/core/status.h"

namespace opl {
namespace json_internal {

// The deepest nesting of arrays and objects a JSON input may have (OPL's own
// documents nest 4 levels; docs/formats.md, "Limits"). nlohmann's DOM and the
// duplicate-key finder keep per-level state, so an 80 KB file of '[' took GBs.
constexpr int kMaxJsonDepth = 64;

// OK, or ParseError "<name>:<line>:<column>: invalid JSON: nested deeper than
// 64 levels" at the bracket opening level 65. A linear scan outside strings,
// run before parsing (the parser then reports any other syntax error).
Status CheckJsonDepth(const std::string& text, const std::string& name);

// nlohmann's exception text made fit for a one-line message (issue 19 item
// 7): the "[json.exception...] parse error at line L, column C: " head
// dropped, the token after "last read: " cut at 40 bytes (it may be a whole
// 1 MB line), control characters escaped (nlohmann escapes < 0x20 but not
// DEL) and the whole cut at 300 bytes.
std::string JsonErrorForMessage(const std::string& what);

// `message` (of a reader given `path`, a path taken from a JSON file, e.g. a
// scene's module or a design's pattern_file) with its leading `path` escaped
// and cut like any other echoed text (SafeForMessage): the path is the
// file's content, and may hold control characters or be 80 KB long.
std::string WithSafePathPrefix(const std::string& message, const std::string& path);

class JsonReader {
 public:
  using json = nlohmann::json;

  // `name` starts every message; `prefix` is prepended to every field path.
  explicit JsonReader(std::string name, std::string prefix = "")
      : name_(std::move(name)), prefix_(std::move(prefix)) {}

  // Parses `text` (syntax, finite numbers, no duplicate key).
  Result<json> ParseText(const std::string& text) const;

  const std::string& name() const { return name_; }

  // ParseError "<name>: <prefix.path>: <what>" (the path part omitted when empty).
  Status Error(const std::string& path, const std::string& what) const;

  // The value, abbreviated to 40 characters, for messages.
  static std::string Describe(const json& v);
  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  static std::string Index(const std::string& path, size_t i) {
    return path + "[" + std::to_string(i) + "]";
  }
  // The field, or nullptr when absent.
  static const json* Find(const json& obj, const std::string& key) {
    const auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
  }

  Status CheckObject(const json& v, const std::string& path) const;
  Status CheckArray(const json& v, const std::string& path) const;
  // Unknown fields are errors (the message lists the allowed ones).
  Status CheckKeys(const json& obj, const std::string& path,
                   const std::set<std::string>& allowed) const;
  Status Require(const json& obj, const std::string& path, const std::string& key,
                 const json** out) const;
  Status Number(const json& v, const std::string& path, double* out) const;
  Status Integer(const json& v, const std::string& path, int* out) const;
  Status String(const json& v, const std::string& path, std::string* out) const;
  Status Vec3(const json& v, const std::string& path, Eigen::Vector3d* out) const;
  Status RequiredNumber(const json& obj, const std::string& path, const std::string& key,
                        double* out) const;
  Status RequiredVec3(const json& obj, const std::string& path, const std::string& key,
                      Eigen::Vector3d* out) const;
  Status NonZeroVec3(const json& obj, const std::string& path, const std::string& key,
                     Eigen::Vector3d* out) const;
  // The field when present (else `out` is left as it is).
  Status OptionalNumber(const json& obj, const std::string& path, const std::string& key,
                        double* out) const;
  Status OptionalInteger(const json& obj, const std::string& path, const std::string& key,
                         int* out) const;
  // The "format" and "version" fields of a document's top level.
  Status CheckFormatAndVersion(const json& root, const std::string& format, int version) const;

 private:
  std::string name_;
  std::string prefix_;
};

}  // namespace json_internal
}  // namespace opl
