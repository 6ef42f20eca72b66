#include "opl/io/provenance_stamp.h"

#include <algorithm>
#include <cctype>
#include <cstdint>

#include <nlohmann/json.hpp>
#include <zlib.h>

namespace opl {
namespace {

constexpr char kPngSignature[] = "\x89PNG\r\n\x1a\n";
constexpr size_t kPngSignatureBytes = 8;

std::string LowerExtension(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// `text` ("\n" line breaks) with "\r\n" ones when `crlf`.
std::string WithLineBreaks(const std::string& text, bool crlf) {
  if (!crlf) return text;
  std::string converted;
  for (char c : text) {
    if (c == '\n') converted += '\r';
    converted += c;
  }
  return converted;
}

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

Result<std::string> StampJson(const std::string& path, const std::string& contents,
                              const Provenance& provenance) {
  nlohmann::ordered_json root;
  try {
    root = nlohmann::ordered_json::parse(contents);
  } catch (const nlohmann::json::exception& e) {
    return Status::InvalidArgument(path + ": not JSON, cannot add its provenance: " + e.what());
  }
  if (!root.is_object()) {
    return Status::InvalidArgument(path + ": the JSON root is not an object, cannot add its "
                                          "provenance");
  }
  std::string text = contents;
  if (root.contains("provenance")) {  // an updated file: its old provenance is replaced
    root.erase("provenance");
    text = root.dump(2) + "\n";
  }
  size_t end = text.size();
  while (end > 0 && IsBlank(text[end - 1])) --end;
  const std::string tail = text.substr(end);
  size_t before = end - 1;  // text[end - 1] == '}' (the root is an object)
  while (before > 0 && IsBlank(text[before - 1])) --before;
  const bool empty = before > 0 && text[before - 1] == '{';
  const bool pretty = text.find('\n') < end;
  std::string member = std::string(empty ? "" : ",") + (pretty ? "\n  " : " ") +
                       "\"provenance\": " + FormatProvenanceJson(provenance) +
                       (pretty ? "\n" : "");
  return text.substr(0, before) + member + "}" + tail;
}

Result<std::string> StampHashComments(const std::string& contents, const Provenance& provenance) {
  const std::string bom = "\xEF\xBB\xBF";
  const bool has_bom = contents.compare(0, bom.size(), bom) == 0;
  const bool crlf = contents.find("\r\n") != std::string::npos;
  const std::string block = WithLineBreaks(FormatProvenanceComment(provenance, "# "), crlf);
  if (has_bom) return bom + block + contents.substr(bom.size());
  return block + contents;
}

Result<std::string> StampPly(const std::string& path, const std::string& contents,
                             const Provenance& provenance) {
  size_t line = 0;
  while (line < contents.size()) {
    const size_t eol = contents.find('\n', line);
    if (eol == std::string::npos) break;
    if (contents.compare(line, 7, "format ") == 0) {
      const bool crlf = eol > line && contents[eol - 1] == '\r';
      const std::string block =
          WithLineBreaks(FormatProvenanceComment(provenance, "comment "), crlf);
      return contents.substr(0, eol + 1) + block + contents.substr(eol + 1);
    }
    if (contents.compare(line, 10, "end_header") == 0) break;
    line = eol + 1;
  }
  return Status::InvalidArgument(path + ": a PLY header without a 'format' line, cannot add its "
                                        "provenance");
}

uint32_t ReadBigEndian32(const std::string& bytes, size_t at) {
  return (static_cast<uint32_t>(static_cast<unsigned char>(bytes[at])) << 24) |
         (static_cast<uint32_t>(static_cast<unsigned char>(bytes[at + 1])) << 16) |
         (static_cast<uint32_t>(static_cast<unsigned char>(bytes[at + 2])) << 8) |
         static_cast<uint32_t>(static_cast<unsigned char>(bytes[at + 3]));
}

void AppendBigEndian32(uint32_t value, std::string* out) {
  for (int shift = 24; shift >= 0; shift -= 8) {
    out->push_back(static_cast<char>((value >> shift) & 0xff));
  }
}

std::string PngChunk(const std::string& type, const std::string& data) {
  std::string chunk;
  AppendBigEndian32(static_cast<uint32_t>(data.size()), &chunk);
  const std::string body = type + data;
  chunk += body;
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(body.data()),
                          static_cast<uInt>(body.size()));
  AppendBigEndian32(static_cast<uint32_t>(crc), &chunk);
  return chunk;
}

// The offset of each chunk (length field) in file order; IoError-free: a
// malformed PNG is an InvalidArgument naming `what`.
Result<std::vector<size_t>> PngChunkOffsets(const std::string& png, const std::string& what) {
  if (png.size() < kPngSignatureBytes ||
      png.compare(0, kPngSignatureBytes, kPngSignature, kPngSignatureBytes) != 0) {
    return Status::InvalidArgument(what + ": not a PNG (no PNG signature)");
  }
  std::vector<size_t> offsets;
  size_t at = kPngSignatureBytes;
  while (at + 12 <= png.size()) {
    const uint64_t length = ReadBigEndian32(png, at);
    offsets.push_back(at);
    if (png.compare(at + 4, 4, "IEND") == 0) return offsets;
    at += 12 + length;
  }
  return Status::InvalidArgument(what + ": a PNG without an IEND chunk (truncated)");
}

Result<std::string> StampPng(const std::string& path, const std::string& png,
                             const Provenance& provenance) {
  Result<std::vector<size_t>> offsets = PngChunkOffsets(png, path);
  if (!offsets.ok()) return offsets.status();
  const size_t iend = offsets->back();
  std::string software = "OPL " + provenance.tool + " " + provenance.version;
  for (char& c : software) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  }
  // iTXt: keyword, 0, compression flag 0, method 0, language "", 0,
  // translated keyword "", 0, UTF-8 text.
  const std::string itxt = std::string("opl:provenance") + '\0' + '\0' + '\0' + '\0' + '\0' +
                           FormatProvenanceJson(provenance);
  return png.substr(0, iend) + PngChunk("tEXt", std::string("Software") + '\0' + software) +
         PngChunk("tEXt", std::string("Creation Time") + '\0' + provenance.time_utc) +
         PngChunk("iTXt", itxt) + png.substr(iend);
}

// A JPEG's COM segments (0xFFFE), after SOI and the APPn segments that must
// lead (JFIF APP0, EXIF APP1): the provenance JSON, cut into segments of at
// most 65533 bytes.
Result<std::string> StampJpeg(const std::string& path, const std::string& jpeg,
                              const Provenance& provenance) {
  if (jpeg.size() < 4 || static_cast<unsigned char>(jpeg[0]) != 0xFF ||
      static_cast<unsigned char>(jpeg[1]) != 0xD8) {
    return Status::InvalidArgument(path + ": not a JPEG (no SOI marker)");
  }
  size_t at = 2;
  while (at + 4 <= jpeg.size() && static_cast<unsigned char>(jpeg[at]) == 0xFF &&
         static_cast<unsigned char>(jpeg[at + 1]) >= 0xE0 &&
         static_cast<unsigned char>(jpeg[at + 1]) <= 0xEF) {
    const size_t length = (static_cast<size_t>(static_cast<unsigned char>(jpeg[at + 2])) << 8) |
                          static_cast<unsigned char>(jpeg[at + 3]);
    if (length < 2 || at + 2 + length > jpeg.size()) {
      return Status::InvalidArgument(path + ": a JPEG segment runs past the end of the file");
    }
    at += 2 + length;
  }
  const std::string text = FormatProvenanceJson(provenance);
  std::string segments;
  constexpr size_t kMaxPayload = 65533;
  for (size_t from = 0; from < text.size(); from += kMaxPayload) {
    const std::string part = text.substr(from, kMaxPayload);
    const size_t length = part.size() + 2;
    segments += '\xFF';
    segments += '\xFE';
    segments += static_cast<char>((length >> 8) & 0xff);
    segments += static_cast<char>(length & 0xff);
    segments += part;
  }
  return jpeg.substr(0, at) + segments + jpeg.substr(at);
}

// An SVG's <metadata id="opl-provenance"> element holding the JSON object
// (XML-escaped), the first child of the root <svg> element, after a leading
// <title> if there is one.
Result<std::string> StampSvg(const std::string& path, const std::string& svg,
                             const Provenance& provenance) {
  const size_t root = svg.find("<svg");
  const size_t root_end = root == std::string::npos ? root : svg.find('>', root);
  if (root_end == std::string::npos) {
    return Status::InvalidArgument(path + ": not an SVG (no <svg> element)");
  }
  size_t at = root_end + 1;
  size_t first = at;
  while (first < svg.size() && IsBlank(svg[first])) ++first;
  if (svg.compare(first, 6, "<title") == 0) {
    const size_t close = svg.find("</title>", first);
    if (close != std::string::npos) at = close + 8;
  }
  std::string escaped;
  for (char c : FormatProvenanceJson(provenance)) {
    if (c == '&') escaped += "&amp;";
    else if (c == '<') escaped += "&lt;";
    else if (c == '>') escaped += "&gt;";
    else escaped += c;
  }
  return svg.substr(0, at) + "\n<metadata id=\"opl-provenance\">" + escaped + "</metadata>" +
         svg.substr(at);
}

}  // namespace

Result<std::string> StampProvenance(const std::string& path, const std::string& contents,
                                    const Provenance& provenance) {
  const std::string ext = LowerExtension(path);
  if (ext == ".json") return StampJson(path, contents, provenance);
  if (ext == ".csv" || ext == ".xyz" || ext == ".txt") {
    return StampHashComments(contents, provenance);
  }
  if (ext == ".ply") return StampPly(path, contents, provenance);
  if (ext == ".png") return StampPng(path, contents, provenance);
  if (ext == ".jpg" || ext == ".jpeg") return StampJpeg(path, contents, provenance);
  if (ext == ".svg") return StampSvg(path, contents, provenance);
  return Status::InvalidArgument(path + ": no provenance format for '" +
                                 (ext.empty() ? std::string("(no extension)") : ext) +
                                 "' files");
}

Result<std::vector<std::pair<std::string, std::string>>> PngTextChunks(const std::string& png) {
  Result<std::vector<size_t>> offsets = PngChunkOffsets(png, "PNG");
  if (!offsets.ok()) return offsets.status();
  std::vector<std::pair<std::string, std::string>> chunks;
  for (size_t at : *offsets) {
    const size_t length = ReadBigEndian32(png, at);
    const std::string type = png.substr(at + 4, 4);
    if (type != "tEXt" && type != "iTXt") continue;
    if (at + 8 + length > png.size()) {
      return Status::InvalidArgument("PNG: a " + type + " chunk runs past the end of the file");
    }
    const std::string data = png.substr(at + 8, length);
    const size_t zero = data.find('\0');
    if (zero == std::string::npos) {
      return Status::InvalidArgument("PNG: a " + type + " chunk without a keyword separator");
    }
    std::string text = data.substr(zero + 1);
    if (type == "iTXt") {  // flag, method, language\0, translated keyword\0
      if (text.size() < 2 || text[0] != '\0') {
        return Status::InvalidArgument("PNG: a compressed iTXt chunk (not read)");
      }
      size_t p = text.find('\0', 2);
      if (p != std::string::npos) p = text.find('\0', p + 1);
      if (p == std::string::npos) {
        return Status::InvalidArgument("PNG: a malformed iTXt chunk");
      }
      text = text.substr(p + 1);
    }
    chunks.emplace_back(data.substr(0, zero), text);
  }
  return chunks;
}

}  // namespace opl
