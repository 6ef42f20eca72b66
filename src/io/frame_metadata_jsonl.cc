#include "opl/io/frame_metadata_jsonl.h"

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/json_reader.h"
#include "opl/core/message_text.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

using json = nlohmann::json;
using json_internal::JsonReader;

Status ParseLine(const JsonReader& r, const json& j, FrameMetadata* f) {
  if (!j.is_object()) return r.Error("", "expected a JSON object, got " + JsonReader::Describe(j));
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(r.Require(j, "", "sequence", &v));
  OPL_RETURN_IF_ERROR(r.String(*v, "sequence", &f->sequence));
  if (f->sequence != "measurement" && f->sequence != "calibration" && f->sequence != "manual") {
    return r.Error("sequence", "expected \"measurement\", \"calibration\" or \"manual\", got " +
                                   JsonReader::Describe(*v));
  }
  OPL_RETURN_IF_ERROR(r.Require(j, "", "run", &v));
  OPL_RETURN_IF_ERROR(r.Integer(*v, "run", &f->run));
  if (f->run < 1) return r.Error("run", "must be >= 1, got " + std::to_string(f->run));
  OPL_RETURN_IF_ERROR(r.Require(j, "", "frame", &v));
  OPL_RETURN_IF_ERROR(r.Integer(*v, "frame", &f->frame));
  if (f->frame < 0) return r.Error("frame", "must be >= 0, got " + std::to_string(f->frame));
  if (const json* s = JsonReader::Find(j, "slice"); s != nullptr && !s->is_null()) {
    int slice = 0;
    OPL_RETURN_IF_ERROR(r.Integer(*s, "slice", &slice));
    if (slice < 0) return r.Error("slice", "must be >= 0 or null, got " + std::to_string(slice));
    f->slice = slice;
  } else if (f->sequence != "manual") {
    return r.Error("slice", "missing or null in a " + f->sequence + " frame (only manual triggers have none)");
  }
  if (const json* s = JsonReader::Find(j, "step")) OPL_RETURN_IF_ERROR(r.String(*s, "step", &f->step));
  if (const json* s = JsonReader::Find(j, "step_index"); s != nullptr && !s->is_null()) {
    int index = 0;
    OPL_RETURN_IF_ERROR(r.Integer(*s, "step_index", &index));
    if (index < 0 || index > 3) return r.Error("step_index", "must be 0..3 or null, got " + std::to_string(index));
    f->step_index = index;
  }
  if (const json* t = JsonReader::Find(j, "t_ns")) {
    if (!t->is_number_integer()) return r.Error("t_ns", "expected an integer, got " + JsonReader::Describe(*t));
    f->t_ns = t->get<int64_t>();
  }
  if (const json* t = JsonReader::Find(j, "time")) OPL_RETURN_IF_ERROR(r.String(*t, "time", &f->time));
  if (const json* b = JsonReader::Find(j, "blocker")) {
    std::string blocker;
    OPL_RETURN_IF_ERROR(r.String(*b, "blocker", &blocker));
    if (blocker != "open" && blocker != "closed") {
      return r.Error("blocker", "expected \"open\" or \"closed\", got " + JsonReader::Describe(*b));
    }
  }
  OPL_RETURN_IF_ERROR(r.Require(j, "", "lasers", &v));
  if (!v->is_object() || v->empty()) {
    return r.Error("lasers", "expected an object of laser name: true/false (at least one), got " +
                                 JsonReader::Describe(*v));
  }
  for (const auto& [name, on] : v->items()) {
    if (name.empty()) return r.Error("lasers", "a laser name is empty");
    if (!on.is_boolean()) {
      return r.Error("lasers." + name, "expected true or false, got " + JsonReader::Describe(on));
    }
    f->lasers[name] = on.get<bool>();
  }
  return Status::Ok();
}

}  // namespace

std::vector<std::string> FrameMetadata::LasersOn() const {
  std::vector<std::string> on;
  for (const auto& [name, lit] : lasers) {
    if (lit) on.push_back(name);
  }
  return on;
}

Result<std::vector<FrameMetadata>> ParseFrameMetadataJsonl(const std::string& text,
                                                           const std::string& name_for_messages) {
  std::vector<FrameMetadata> frames;
  size_t begin = 0;
  int line = 0;
  while (begin < text.size()) {
    size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    ++line;
    std::string content = text.substr(begin, end - begin);
    begin = end + 1;
    if (!content.empty() && content.back() == '\r') content.pop_back();
    if (content.find_first_not_of(" \t") == std::string::npos) continue;
    const std::string where = name_for_messages + ":" + std::to_string(line);
    const JsonReader reader(where);
    OPL_RETURN_IF_ERROR(json_internal::CheckJsonDepth(content, where));
    json j;
    try {
      j = json::parse(content);
    } catch (const json::parse_error& e) {
      // "<file>:<line>:<column>: invalid JSON: <what>", as the other JSON readers.
      std::string what = e.what();
      const size_t at = what.find("column ");
      const size_t colon = at == std::string::npos ? at : what.find(": ", at);
      if (colon != std::string::npos) what = what.substr(colon + 2);  // drop "[json.exception...] ... column N"
      return Status::ParseError(where + ":" + std::to_string(e.byte) + ": invalid JSON: " + SafeForMessage(what));
    } catch (const json::exception& e) {  // e.g. a number beyond the double range
      std::string what = e.what();
      const size_t bracket = what.find("] ");  // drop "[json.exception.out_of_range.406] "
      if (bracket != std::string::npos) what = what.substr(bracket + 2);
      return Status::ParseError(where + ": invalid JSON: " + SafeForMessage(what));
    }
    FrameMetadata frame;
    frame.line = line;
    OPL_RETURN_IF_ERROR(ParseLine(reader, j, &frame));
    frames.push_back(std::move(frame));
  }
  if (frames.empty()) {
    return Status::ParseError(name_for_messages + ": no frame (the file holds no metadata line)");
  }
  return frames;
}

Result<std::vector<FrameMetadata>> ReadFrameMetadataJsonl(const std::string& path) {
  Result<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseFrameMetadataJsonl(*text, path);
}

}  // namespace opl
