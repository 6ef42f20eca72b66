#include "opl/io/point_cloud_ply.h"

#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_set>

#include "io/point_file_stream.h"
#include "opl/core/format.h"
#include "opl/core/message_text.h"

namespace opl {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

// The whitespace-separated words of a header line (without its line break).
std::vector<std::string_view> Words(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (IsBlank(line[i]) || line[i] == '\r')) ++i;
    const size_t b = i;
    while (i < line.size() && !IsBlank(line[i]) && line[i] != '\r') ++i;
    if (i > b) words.push_back(line.substr(b, i - b));
  }
  return words;
}

bool ParseScalarType(std::string_view word, PlyScalarType* type) {
  struct Name {
    const char* a;
    const char* b;
    PlyScalarType t;
  };
  static const Name kNames[] = {
      {"char", "int8", PlyScalarType::kInt8},       {"uchar", "uint8", PlyScalarType::kUint8},
      {"short", "int16", PlyScalarType::kInt16},    {"ushort", "uint16", PlyScalarType::kUint16},
      {"int", "int32", PlyScalarType::kInt32},      {"uint", "uint32", PlyScalarType::kUint32},
      {"float", "float32", PlyScalarType::kFloat32}, {"double", "float64", PlyScalarType::kFloat64},
  };
  for (const Name& n : kNames) {
    if (word == n.a || word == n.b) {
      *type = n.t;
      return true;
    }
  }
  return false;
}

bool IsIntegerType(PlyScalarType t) {
  return t != PlyScalarType::kFloat32 && t != PlyScalarType::kFloat64;
}

std::string Shown(std::string_view s) { return QuoteForMessage(std::string(s), 40); }

}  // namespace

int PlyScalarBytes(PlyScalarType type) {
  switch (type) {
    case PlyScalarType::kInt8:
    case PlyScalarType::kUint8: return 1;
    case PlyScalarType::kInt16:
    case PlyScalarType::kUint16: return 2;
    case PlyScalarType::kInt32:
    case PlyScalarType::kUint32:
    case PlyScalarType::kFloat32: return 4;
    case PlyScalarType::kFloat64: return 8;
  }
  return 0;
}

const char* PlyScalarTypeName(PlyScalarType type) {
  switch (type) {
    case PlyScalarType::kInt8: return "char";
    case PlyScalarType::kUint8: return "uchar";
    case PlyScalarType::kInt16: return "short";
    case PlyScalarType::kUint16: return "ushort";
    case PlyScalarType::kInt32: return "int";
    case PlyScalarType::kUint32: return "uint";
    case PlyScalarType::kFloat32: return "float";
    case PlyScalarType::kFloat64: return "double";
  }
  return "?";
}

int PlyElement::FindProperty(const std::string& property_name) const {
  for (size_t i = 0; i < properties.size(); ++i) {
    if (properties[i].name == property_name) return static_cast<int>(i);
  }
  return -1;
}

int64_t PlyElement::FixedRecordBytes() const {
  int64_t bytes = 0;
  for (const PlyProperty& p : properties) {
    if (p.is_list) return -1;
    bytes += PlyScalarBytes(p.type);
  }
  return bytes;
}

int PlyHeader::FindElement(const std::string& element_name) const {
  for (size_t i = 0; i < elements.size(); ++i) {
    if (elements[i].name == element_name) return static_cast<int>(i);
  }
  return -1;
}

Result<PlyHeader> ParsePlyHeader(std::string_view text, const std::string& name) {
  PlyHeader header;
  bool have_format = false, ended = false;
  std::unordered_set<std::string> element_names, property_names;
  size_t pos = 0;
  int line = 0;
  while (pos < text.size() && !ended) {
    ++line;
    const size_t nl = text.find('\n', pos);
    const size_t line_end = nl == std::string_view::npos ? text.size() : nl;
    const std::string_view raw = text.substr(pos, line_end - pos);
    const size_t line_begin = pos;
    pos = nl == std::string_view::npos ? text.size() : nl + 1;
    const std::vector<std::string_view> w = Words(raw);
    auto error = [&](const std::string& what) {
      return Status::ParseError(name + ":" + std::to_string(line) + ": " + what);
    };
    if (line == 1) {
      if (w.size() != 1 || w[0] != "ply") {
        return Status::ParseError(name + ": not a PLY file (the first line is not 'ply')");
      }
      if (!raw.empty() && raw.back() == '\r') header.line_break = "\r\n";
      continue;
    }
    if (w.empty()) return error("empty header line");
    const std::string_view key = w[0];
    if (key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      if (have_format) return error("a second 'format' line");
      if (!header.elements.empty()) return error("'format' after an element");
      if (w.size() != 3) return error("expected 'format <encoding> 1.0', got " + Shown(raw));
      if (w[1] == "ascii") {
        header.encoding = PlyEncoding::kAscii;
      } else if (w[1] == "binary_little_endian") {
        header.encoding = PlyEncoding::kBinaryLittleEndian;
      } else if (w[1] == "binary_big_endian") {
        header.encoding = PlyEncoding::kBinaryBigEndian;
      } else {
        return error("unknown format " + Shown(w[1]) +
                     " (ascii, binary_little_endian or binary_big_endian)");
      }
      if (w[2] != "1.0") return error("unsupported PLY version " + Shown(w[2]) + " (1.0)");
      have_format = true;
    } else if (key == "element") {
      if (!have_format) return error("'element' before the 'format' line");
      if (w.size() != 3) return error("expected 'element <name> <count>', got " + Shown(raw));
      PlyElement element;
      element.name = std::string(w[1]);
      element.header_line = line;
      const std::from_chars_result r =
          std::from_chars(w[2].data(), w[2].data() + w[2].size(), element.count);
      if (r.ec != std::errc() || r.ptr != w[2].data() + w[2].size() || element.count < 0) {
        return error("element " + QuoteForMessage(element.name) + ": not a count: " + Shown(w[2]));
      }
      if (!element_names.insert(element.name).second) {
        return error("a second element " + QuoteForMessage(element.name));
      }
      if (header.elements.empty()) header.first_element_offset = line_begin;
      header.elements.push_back(std::move(element));
      property_names.clear();
    } else if (key == "property") {
      if (header.elements.empty()) return error("'property' before any 'element'");
      PlyElement& element = header.elements.back();
      PlyProperty property;
      if (w.size() >= 2 && w[1] == "list") {
        if (w.size() != 5) {
          return error("expected 'property list <count type> <type> <name>', got " + Shown(raw));
        }
        property.is_list = true;
        if (!ParseScalarType(w[2], &property.count_type)) {
          return error("unknown type " + Shown(w[2]));
        }
        if (!IsIntegerType(property.count_type)) {
          return error("the count of list " + QuoteForMessage(std::string(w[4])) +
                       " must be an integer type, got " +
                       Shown(w[2]));
        }
        if (!ParseScalarType(w[3], &property.type)) return error("unknown type " + Shown(w[3]));
        property.name = std::string(w[4]);
      } else {
        if (w.size() != 3) return error("expected 'property <type> <name>', got " + Shown(raw));
        if (!ParseScalarType(w[1], &property.type)) return error("unknown type " + Shown(w[1]));
        property.name = std::string(w[2]);
      }
      if (!property_names.insert(property.name).second) {
        return error("a second property " + QuoteForMessage(property.name) + " in element " +
                     QuoteForMessage(element.name));
      }
      element.properties.push_back(std::move(property));
    } else if (key == "end_header") {
      if (w.size() != 1) return error("text after 'end_header'");
      if (nl == std::string_view::npos) return error("no line break after 'end_header'");
      ended = true;
    } else {
      return error("unknown header line " + Shown(raw));
    }
  }
  if (!ended) return Status::ParseError(name + ": the header has no 'end_header' line");
  if (!have_format) return Status::ParseError(name + ": the header has no 'format' line");
  header.text = std::string(text.substr(0, pos));
  return header;
}

Status CheckScalablePly(const PlyHeader& header, const std::string& name) {
  const int v = header.FindElement("vertex");
  if (v < 0) return Status::ParseError(name + ": no element 'vertex' (nothing to scale)");
  const PlyElement& vertex = header.elements[static_cast<size_t>(v)];
  const std::string where = name + ":" + std::to_string(vertex.header_line) + ": ";
  for (const char* axis : {"x", "y", "z"}) {
    const int p = vertex.FindProperty(axis);
    if (p < 0) return Status::ParseError(where + "element 'vertex' has no property '" + axis + "'");
    const PlyProperty& property = vertex.properties[static_cast<size_t>(p)];
    if (property.is_list || IsIntegerType(property.type)) {
      return Status::ParseError(where + "property '" + axis + "' of element 'vertex' is " +
                                (property.is_list ? std::string("a list")
                                                  : std::string(PlyScalarTypeName(property.type))) +
                                ": OPL scales float or double coordinates");
    }
  }
  return Status::Ok();
}


namespace point_file_internal {
namespace {

// The largest PLY header read (it must fit in the input buffer too).
constexpr size_t kMaxHeaderBytes = 1 << 20;

uint16_t Swap(uint16_t v) { return __builtin_bswap16(v); }
uint32_t Swap(uint32_t v) { return __builtin_bswap32(v); }
uint64_t Swap(uint64_t v) { return __builtin_bswap64(v); }

// The host's byte order (x86 and ARM Linux: little endian).
bool HostIsLittleEndian() {
  const uint16_t one = 1;
  unsigned char first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// Reads an integer of `type` at p (file byte order: `swap` when it differs
// from the host's).
int64_t ReadInteger(const char* p, PlyScalarType type, bool swap) {
  switch (type) {
    case PlyScalarType::kInt8: return static_cast<int8_t>(*p);
    case PlyScalarType::kUint8: return static_cast<uint8_t>(*p);
    case PlyScalarType::kInt16:
    case PlyScalarType::kUint16: {
      uint16_t u;
      std::memcpy(&u, p, 2);
      if (swap) u = Swap(u);
      return type == PlyScalarType::kInt16 ? static_cast<int64_t>(static_cast<int16_t>(u)) : u;
    }
    case PlyScalarType::kInt32:
    case PlyScalarType::kUint32: {
      uint32_t u;
      std::memcpy(&u, p, 4);
      if (swap) u = Swap(u);
      return type == PlyScalarType::kInt32 ? static_cast<int64_t>(static_cast<int32_t>(u)) : u;
    }
    default: return -1;  // not an integer type (refused by ParsePlyHeader)
  }
}

// Scales the value of type T (float or double) at p in place. False when the
// result overflows T (the value is then left as it was); `before`, `after`
// say what it was and would be. Non-finite values are kept.
template <typename T, typename Bits>
bool ScaleInPlace(char* p, double s, bool swap, double* before, double* after) {
  Bits bits;
  std::memcpy(&bits, p, sizeof(T));
  if (swap) bits = Swap(bits);
  T v;
  std::memcpy(&v, &bits, sizeof(T));
  if (!std::isfinite(v)) return true;
  const T r = static_cast<T>(s * static_cast<double>(v));
  if (!std::isfinite(r)) {
    *before = static_cast<double>(v);
    *after = s * static_cast<double>(v);
    return false;
  }
  std::memcpy(&bits, &r, sizeof(T));
  if (swap) bits = Swap(bits);
  std::memcpy(p, &bits, sizeof(T));
  return true;
}

const char* const kAxis[3] = {"x", "y", "z"};

class PlyScaler {
 public:
  PlyScaler(InputFile& in, OutputBuffer* out, double s, ScaleCounts* counts,
            const std::string& comment_lines)
      : in_(in), out_(out), s_(s), counts_(counts), comment_lines_(comment_lines) {}

  Status Run(bool header_only) {
    OPL_RETURN_IF_ERROR(ReadHeader());
    if (header_only) return Status::Ok();
    // The header as it was, with OPL's comment before the first element.
    const std::string& text = header_.text;
    out_->Append(text.data(), header_.first_element_offset);
    out_->Append("comment OPL scaled vertex x, y, z by s = " + FormatRoundTrip(s_) +
                 header_.line_break);
    for (char c : comment_lines_) {
      if (c == '\n') {
        out_->Append(header_.line_break);
      } else {
        out_->Append(&c, 1);
      }
    }
    out_->Append(text.data() + header_.first_element_offset,
                 text.size() - header_.first_element_offset);
    swap_ = (header_.encoding == PlyEncoding::kBinaryBigEndian) == HostIsLittleEndian();
    const bool ascii = header_.encoding == PlyEncoding::kAscii;
    line_number_ = 1;
    for (char c : text) line_number_ += c == '\n';
    for (const PlyElement& element : header_.elements) {
      const bool is_vertex = element.name == "vertex";
      for (int k = 0; k < 3; ++k) axis_[k] = is_vertex ? element.FindProperty(kAxis[k]) : -1;
      if (ascii) {
        OPL_RETURN_IF_ERROR(AsciiElement(element));
      } else if (element.FixedRecordBytes() >= 0) {
        OPL_RETURN_IF_ERROR(FixedBinaryElement(element));
      } else {
        OPL_RETURN_IF_ERROR(VariableBinaryElement(element));
      }
      if (out_->failed()) return Status::Ok();
    }
    return ascii ? AsciiTail() : BinaryTail();
  }

 private:
  Status ReadHeader() {
    // The header ends at the first line "end_header": read until it is in.
    OPL_RETURN_IF_ERROR(in_.Ensure(4));
    if (in_.size() < 4 || std::string_view(in_.data(), 3) != "ply" ||
        (in_.data()[3] != '\n' && in_.data()[3] != '\r')) {
      return Status::ParseError(in_.path() + ": not a PLY file (the first line is not 'ply')");
    }
    size_t searched = 0;
    while (true) {
      const std::string_view window(in_.data(), in_.size());
      size_t line_begin = searched;
      while (true) {
        const size_t nl = window.find('\n', line_begin);
        if (nl == std::string_view::npos) break;
        std::string_view line = window.substr(line_begin, nl - line_begin);
        while (!line.empty() && (line.back() == '\r' || IsBlank(line.back()))) line.remove_suffix(1);
        if (line.substr(0, 10) == "end_header") {
          Result<PlyHeader> parsed = ParsePlyHeader(window.substr(0, nl + 1), in_.path());
          if (!parsed.ok()) return parsed.status();
          OPL_RETURN_IF_ERROR(CheckScalablePly(*parsed, in_.path()));
          header_ = std::move(*parsed);
          in_.Consume(header_.text.size());
          return Status::Ok();
        }
        line_begin = nl + 1;
      }
      searched = line_begin;
      if (in_.size() >= kMaxHeaderBytes || in_.full() || in_.at_eof()) {
        // Parse what there is: a malformed line is named; else it is the
        // missing end_header (at the end of the file, or beyond the limit).
        Result<PlyHeader> parsed = ParsePlyHeader(window.substr(0, searched), in_.path());
        const std::string no_end = in_.path() + ": the header has no 'end_header' line";
        if (!parsed.ok() && (in_.at_eof() || parsed.status().message() != no_end)) {
          return parsed.status();
        }
        return Status::ParseError(no_end + " in its first " + std::to_string(in_.size()) +
                                  " bytes (a longer header is refused)");
      }
      Result<size_t> added = in_.Fill();
      if (!added.ok()) return added.status();
    }
  }

  std::string RecordWhere(const PlyElement& element, int64_t index, int64_t offset) const {
    return in_.path() + ": byte " + std::to_string(offset) + ": " +
           SafeForMessage(element.name, 40) + " " + std::to_string(index) + " of " +
           std::to_string(element.count);
  }
  Status Truncated(const PlyElement& element, int64_t index, int64_t offset) const {
    return Status::ParseError(RecordWhere(element, index, offset) +
                              " is cut off by the end of the file (truncated, or wrong counts "
                              "in the header)");
  }
  Status Overflow(const std::string& where, int k, double before, double after) const {
    char text[32];
    char* end = coordinate_type_[k] == PlyScalarType::kFloat32
                    ? WriteShortest(text, static_cast<float>(before))
                    : WriteShortest(text, before);
    return Status::ParseError(where + ": property '" + kAxis[k] + "': " + std::string(text, end) +
                              " * s = " + FormatNumber(after, 6) + " is beyond the range of " +
                              PlyScalarTypeName(coordinate_type_[k]));
  }

  // Scales the x, y, z of the binary vertex record at p (offsets given).
  Status ScaleBinaryRecord(char* p, const int64_t offsets[3], const PlyElement& element,
                           int64_t index, int64_t file_offset) {
    for (int k = 0; k < 3; ++k) {
      double before = 0.0, after = 0.0;
      const bool ok =
          coordinate_type_[k] == PlyScalarType::kFloat32
              ? ScaleInPlace<float, uint32_t>(p + offsets[k], s_, swap_, &before, &after)
              : ScaleInPlace<double, uint64_t>(p + offsets[k], s_, swap_, &before, &after);
      if (!ok) return Overflow(RecordWhere(element, index, file_offset), k, before, after);
    }
    return Status::Ok();
  }

  void SetCoordinateTypes(const PlyElement& element) {
    for (int k = 0; k < 3; ++k) {
      if (axis_[k] >= 0) coordinate_type_[k] = element.properties[static_cast<size_t>(axis_[k])].type;
    }
  }

  Status FixedBinaryElement(const PlyElement& element) {
    const int64_t record = element.FixedRecordBytes();
    const bool is_vertex = axis_[0] >= 0;
    int64_t offsets[3] = {0, 0, 0};
    if (is_vertex) {
      SetCoordinateTypes(element);
      for (int k = 0; k < 3; ++k) {
        for (int i = 0; i < axis_[k]; ++i) offsets[k] += PlyScalarBytes(element.properties[static_cast<size_t>(i)].type);
      }
    }
    if (record == 0) return Status::Ok();  // no properties: no bytes
    if (record > static_cast<int64_t>(in_.capacity())) {
      return Status::ParseError(in_.path() + ": element " + QuoteForMessage(element.name) +
                                ": records of " +
                                std::to_string(record) + " bytes are larger than the " +
                                std::to_string(in_.capacity()) + "-byte buffer");
    }
    const size_t r = static_cast<size_t>(record);
    int64_t index = 0;
    while (index < element.count) {
      if (in_.size() < r) {
        OPL_RETURN_IF_ERROR(in_.Ensure(r));
        if (in_.size() < r) return Truncated(element, index, in_.offset());
      }
      const int64_t k = std::min<int64_t>(element.count - index,
                                          static_cast<int64_t>(in_.size() / r));
      char* p = in_.mutable_data();
      if (is_vertex) {
        for (int64_t i = 0; i < k; ++i) {
          OPL_RETURN_IF_ERROR(ScaleBinaryRecord(p + i * record, offsets, element, index + i,
                                                in_.offset() + i * record));
        }
        counts_->num_points += k;
      }
      out_->Append(p, static_cast<size_t>(k) * r);
      in_.Consume(static_cast<size_t>(k) * r);
      index += k;
      if (out_->failed()) return Status::Ok();
    }
    return Status::Ok();
  }

  // The size of the binary record at p (its x, y, z offsets in `offsets` for
  // the vertex), or 0 when it does not end within `avail` bytes.
  Result<size_t> VariableRecord(const char* p, size_t avail, const PlyElement& element,
                                int64_t index, int64_t offsets[3]) const {
    size_t at = 0;
    for (size_t i = 0; i < element.properties.size(); ++i) {
      const PlyProperty& property = element.properties[i];
      for (int k = 0; k < 3; ++k) {
        if (axis_[k] == static_cast<int>(i)) offsets[k] = static_cast<int64_t>(at);
      }
      if (!property.is_list) {
        at += static_cast<size_t>(PlyScalarBytes(property.type));
        continue;
      }
      const size_t count_bytes = static_cast<size_t>(PlyScalarBytes(property.count_type));
      if (at + count_bytes > avail) return size_t{0};
      const int64_t count = ReadInteger(p + at, property.count_type, swap_);
      if (count < 0) {
        return Status::ParseError(RecordWhere(element, index, in_.offset() + (p - in_.data())) +
                                  ": list " + QuoteForMessage(property.name) +
                                  " has a negative count " +
                                  std::to_string(count));
      }
      at += count_bytes + static_cast<size_t>(count) * static_cast<size_t>(PlyScalarBytes(property.type));
    }
    return at <= avail ? at : size_t{0};
  }

  Status VariableBinaryElement(const PlyElement& element) {
    SetCoordinateTypes(element);
    const bool is_vertex = axis_[0] >= 0;
    int64_t index = 0;
    size_t pos = 0;  // records [0, pos) of the window are done
    while (index < element.count) {
      int64_t offsets[3] = {0, 0, 0};
      Result<size_t> size = VariableRecord(in_.data() + pos, in_.size() - pos, element, index, offsets);
      if (!size.ok()) return size.status();
      if (*size == 0) {  // more input needed
        out_->Append(in_.data(), pos);
        in_.Consume(pos);
        pos = 0;
        if (out_->failed()) return Status::Ok();
        Result<size_t> added = in_.Fill();
        if (!added.ok()) return added.status();
        if (*added == 0) {
          if (in_.at_eof()) return Truncated(element, index, in_.offset());
          return Status::ParseError(RecordWhere(element, index, in_.offset()) +
                                    " is larger than the " + std::to_string(in_.capacity()) +
                                    "-byte buffer");
        }
        continue;
      }
      if (is_vertex) {
        OPL_RETURN_IF_ERROR(ScaleBinaryRecord(in_.mutable_data() + pos, offsets, element, index,
                                              in_.offset() + static_cast<int64_t>(pos)));
        ++counts_->num_points;
      }
      pos += *size;
      ++index;
    }
    out_->Append(in_.data(), pos);
    in_.Consume(pos);
    return Status::Ok();
  }

  Status BinaryTail() {
    OPL_RETURN_IF_ERROR(in_.Ensure(1));
    if (in_.size() == 0) return Status::Ok();
    return Status::ParseError(in_.path() + ": byte " + std::to_string(in_.offset()) + ": " +
                              std::to_string(in_.file_size() - in_.offset()) +
                              " bytes after the last element (wrong counts in the header?)");
  }

  // ASCII: one record a line, values separated by spaces or tabs.
  Status AsciiElement(const PlyElement& element) {
    SetCoordinateTypes(element);
    const bool is_vertex = axis_[0] >= 0;
    Line line;
    for (int64_t index = 0; index < element.count; ++index) {
      Result<bool> more = NextLine(in_, &pos_, line_number_, &line);
      if (!more.ok()) return more.status();
      auto where = [&] {  // only on errors: no allocation per record
        return in_.path() + ":" + std::to_string(line_number_) + ": " +
               SafeForMessage(element.name, 40) + " " + std::to_string(index);
      };
      if (!*more) {
        return Status::ParseError(in_.path() + ":" + std::to_string(line_number_) +
                                  ": the file ends at " + SafeForMessage(element.name, 40) + " " +
                                  std::to_string(index) + " of " + std::to_string(element.count) +
                                  " (truncated, or wrong counts in the header)");
      }
      const char* const data = in_.data();
      const char* p = data + line.begin;
      const char* const e = data + line.end;
      auto next_token = [&](const char** b, const char** te) {
        while (p < e && (IsBlank(*p) || *p == '\r')) ++p;
        if (p == e) return false;
        *b = p;
        while (p < e && !IsBlank(*p) && *p != '\r') ++p;
        *te = p;
        return true;
      };
      const char* copied = data + line.begin;
      for (size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& property = element.properties[i];
        const char *b, *te;
        if (!next_token(&b, &te)) {
          return Status::ParseError(where() + ": too few values (no value for property " +
                                    QuoteForMessage(property.name) + ")");
        }
        if (property.is_list) {
          int64_t count = -1;
          const std::from_chars_result r = std::from_chars(b, te, count);
          if (r.ec != std::errc() || r.ptr != te || count < 0) {
            return Status::ParseError(where() + ": list " + QuoteForMessage(property.name) +
                                      ": not a count: " +
                                      Shown(std::string_view(b, static_cast<size_t>(te - b))));
          }
          for (int64_t j = 0; j < count; ++j) {
            if (!next_token(&b, &te)) {
              return Status::ParseError(where() + ": too few values (list " +
                                        QuoteForMessage(property.name) +
                                        " has " + std::to_string(j) + " of its " +
                                        std::to_string(count) + ")");
            }
          }
          continue;
        }
        if (!is_vertex) continue;
        int k = -1;
        for (int a = 0; a < 3; ++a) k = axis_[a] == static_cast<int>(i) ? a : k;
        if (k < 0) continue;
        char number[32];
        char* number_end = nullptr;
        const char* nb = (te - b > 1 && *b == '+' && b[1] != '-') ? b + 1 : b;
        bool parsed = false, finite = true;
        double before = 0.0, after = 0.0;
        if (coordinate_type_[k] == PlyScalarType::kFloat32) {
          float v;
          const std::from_chars_result r = std::from_chars(nb, te, v);
          parsed = r.ec == std::errc() && r.ptr == te;
          finite = std::isfinite(v);
          if (parsed && finite) {
            const float scaled = static_cast<float>(s_ * static_cast<double>(v));
            before = v;
            after = s_ * static_cast<double>(v);
            if (std::isfinite(scaled)) number_end = WriteShortest(number, scaled);
          }
        } else {
          double v;
          const std::from_chars_result r = std::from_chars(nb, te, v);
          parsed = r.ec == std::errc() && r.ptr == te;
          finite = std::isfinite(v);
          if (parsed && finite) {
            before = v;
            after = s_ * v;
            if (std::isfinite(after)) number_end = WriteShortest(number, after);
          }
        }
        if (!parsed) {
          return Status::ParseError(where() + ": property '" + kAxis[k] + "': not a number: " +
                                    Shown(std::string_view(b, static_cast<size_t>(te - b))));
        }
        if (!finite) continue;  // NaN, inf: kept as written
        if (number_end == nullptr) return Overflow(where(), k, before, after);
        out_->Append(copied, static_cast<size_t>(b - copied));
        out_->Append(number, static_cast<size_t>(number_end - number));
        copied = te;
      }
      const char *b, *te;
      if (next_token(&b, &te)) {
        return Status::ParseError(where() + ": more values than its " +
                                  std::to_string(element.properties.size()) + " properties");
      }
      out_->Append(copied, static_cast<size_t>(data + line.next - copied));
      if (is_vertex) ++counts_->num_points;
      pos_ = line.next;
      ++line_number_;
      if (out_->failed()) return Status::Ok();
    }
    return Status::Ok();
  }

  // After the last element of an ASCII PLY only whitespace may follow (kept).
  Status AsciiTail() {
    Line line;
    while (true) {
      Result<bool> more = NextLine(in_, &pos_, line_number_, &line);
      if (!more.ok()) return more.status();
      if (!*more) return Status::Ok();
      for (size_t i = line.begin; i < line.end; ++i) {
        const char c = in_.data()[i];
        if (!IsBlank(c) && c != '\r') {
          return Status::ParseError(in_.path() + ":" + std::to_string(line_number_) +
                                    ": text after the last element (wrong counts in the header?)");
        }
      }
      out_->Append(in_.data() + line.begin, line.next - line.begin);
      pos_ = line.next;
      ++line_number_;
    }
  }

  InputFile& in_;
  OutputBuffer* out_;
  const double s_;
  ScaleCounts* counts_;
  const std::string comment_lines_;
  PlyHeader header_;
  bool swap_ = false;
  int axis_[3] = {-1, -1, -1};  // property indices of x, y, z in the current element
  PlyScalarType coordinate_type_[3] = {PlyScalarType::kFloat32, PlyScalarType::kFloat32,
                                       PlyScalarType::kFloat32};
  size_t pos_ = 0;           // ASCII: window offset of the next line
  int64_t line_number_ = 1;  // ASCII: its 1-based line number
};

}  // namespace

Status ScalePly(InputFile& in, OutputBuffer* out, double s, bool header_only,
                ScaleCounts* counts, const std::string& comment_lines) {
  return PlyScaler(in, out, s, counts, comment_lines).Run(header_only);
}

}  // namespace point_file_internal

}  // namespace opl
