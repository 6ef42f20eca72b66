#include "fuzz/mutator.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <utility>

namespace opl {
namespace fuzz {

uint64_t FuzzRng::Next() {
  uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

uint64_t FuzzRng::Below(uint64_t n) {
  if (n == 0) return 0;
  // The largest multiple of n that fits: values at or above it are redrawn,
  // so that every residue is equally likely.
  const uint64_t limit = UINT64_MAX - UINT64_MAX % n;
  uint64_t v = Next();
  while (v >= limit) v = Next();
  return v % n;
}

uint64_t CaseSeed(uint64_t run_seed, std::string_view format, uint64_t iteration) {
  uint64_t h = 0xCBF29CE484222325ULL;  // FNV-1a, 64 bit
  for (unsigned char c : format) h = (h ^ c) * 0x100000001B3ULL;
  FuzzRng mix(run_seed ^ h);
  mix.Next();
  FuzzRng rng(mix.Next() ^ (iteration * 0xD1B54A32D192ED03ULL));
  return rng.Next();
}

const char* MutationOpName(MutationOp op) {
  switch (op) {
    case MutationOp::kBitFlip: return "bit_flip";
    case MutationOp::kByteSet: return "byte_set";
    case MutationOp::kInsertBytes: return "insert_bytes";
    case MutationOp::kDeleteBytes: return "delete_bytes";
    case MutationOp::kDuplicateChunk: return "duplicate_chunk";
    case MutationOp::kSplice: return "splice";
    case MutationOp::kReplaceNumber: return "replace_number";
    case MutationOp::kInjectSpecial: return "inject_special";
    case MutationOp::kTruncate: return "truncate";
    case MutationOp::kImageHeader: return "image_header";
  }
  return "?";
}

const std::vector<std::string>& HostileNumbers() {
  static const std::vector<std::string> kValues = {
      "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e309", "1.8e308",
      "4.9e-324", "1e-320", "-0", "-0.0", "0", "1", "-1", "2", "3", "201", "203", "46341",
      "100001", "2147483647", "2147483648", "-2147483648", "-2147483649", "4294967296",
      "9223372036854775807", "9223372036854775808", "18446744073709551615",
      "18446744073709551616", "99999999999999999999999", "1e12", "1.5e12", "1e-300",
      "0x10", "1,5", "1.2.3", "+5", "1e", "e5", ".", "-", "",
      "3.14159265358979323846264338327950288419716939937510"};
  return kValues;
}

const std::vector<std::string>& SpecialTokens() {
  static const std::vector<std::string> kTokens = {
      ",", ";", "\t", " ", "\"", "\"\"", "'", "\r\n", "\n", "\r", "\xEF\xBB\xBF",
      std::string(1, '\0'), "\x1b[2J\x1b[31m", "\x07", "\xFF\xFE", "\xC3\x28", "{", "}", "[",
      "]", ":", "\\", "\\u0000", "\\ud800", "#", "//", "/*", "null", "true", "\"\":"};
  return kTokens;
}

uint32_t Crc32(std::string_view bytes) {
  static const std::array<uint32_t, 256> kTable = [] {
    std::array<uint32_t, 256> table{};
    for (uint32_t n = 0; n < 256; ++n) {
      uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320U ^ (c >> 1) : c >> 1;
      table[n] = c;
    }
    return table;
  }();
  uint32_t c = 0xFFFFFFFFU;
  for (unsigned char b : bytes) c = kTable[(c ^ b) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFU;
}

std::vector<std::pair<size_t, size_t>> NumericTokens(std::string_view text) {
  auto numeric = [](char c) {
    return (c >= '0' && c <= '9') || c == '+' || c == '-' || c == '.' || c == 'e' || c == 'E';
  };
  std::vector<std::pair<size_t, size_t>> tokens;
  size_t i = 0;
  while (i < text.size()) {
    if (!numeric(text[i])) {
      ++i;
      continue;
    }
    size_t j = i;
    bool digit = false;
    while (j < text.size() && numeric(text[j])) digit |= (text[j] >= '0' && text[j] <= '9'), ++j;
    // "e"/"E" inside a word ("beam", "true") is not a number: a run must
    // hold a digit and not be glued to a letter.
    const bool glued = (i > 0 && std::isalpha(static_cast<unsigned char>(text[i - 1]))) ||
                       (j < text.size() && std::isalpha(static_cast<unsigned char>(text[j])));
    if (digit && !glued) tokens.emplace_back(i, j - i);
    i = j;
  }
  return tokens;
}

namespace {

void PutBigEndian(std::string* s, size_t at, uint64_t value, int bytes) {
  for (int i = bytes - 1; i >= 0; --i, value >>= 8) (*s)[at + i] = static_cast<char>(value & 0xFF);
}

uint64_t GetBigEndian(const std::string& s, size_t at, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | static_cast<unsigned char>(s[at + i]);
  return v;
}

template <typename T>
const T& Pick(const std::vector<T>& values, FuzzRng& rng) {
  return values[rng.Below(values.size())];
}

bool IsPng(const std::string& s) {
  return s.size() >= 8 && s.compare(0, 8, std::string("\x89PNG\r\n\x1a\n", 8)) == 0;
}
bool IsJpeg(const std::string& s) {
  return s.size() >= 3 && static_cast<unsigned char>(s[0]) == 0xFF &&
         static_cast<unsigned char>(s[1]) == 0xD8 && static_cast<unsigned char>(s[2]) == 0xFF;
}

std::string PngHeader(std::string s, FuzzRng& rng) {
  // Chunks: (offset of the length field, length).
  std::vector<std::pair<size_t, uint64_t>> chunks;
  for (size_t at = 8; at + 12 <= s.size();) {
    const uint64_t length = GetBigEndian(s, at, 4);
    chunks.emplace_back(at, length);
    if (length > s.size() - at - 12) break;
    at += 12 + length;
  }
  const bool ihdr = s.size() >= 33 && s.compare(12, 4, "IHDR") == 0;
  if (ihdr && !rng.OneIn(4)) {
    static const std::vector<uint64_t> kSizes = {0, 1, 2, 7, 32768, 32769, 65535, 100000,
                                                 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF};
    static const std::vector<uint64_t> kBytes = {0, 1, 2, 3, 4, 5, 6, 7, 8, 15, 16, 17, 255};
    const uint64_t field = rng.Below(7);  // width, height, depth, colour, compression, filter, interlace
    if (field < 2) {
      PutBigEndian(&s, 16 + 4 * field, Pick(kSizes, rng), 4);
    } else {
      PutBigEndian(&s, 24 + (field - 2), Pick(kBytes, rng), 1);
    }
    PutBigEndian(&s, 29, Crc32(std::string_view(s).substr(12, 17)), 4);
    return s;
  }
  if (chunks.empty()) return s;
  const auto& [at, length] = Pick(chunks, rng);
  static const std::vector<uint64_t> kLengths = {0, 1, 13, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF};
  uint64_t value = Pick(kLengths, rng);
  if (rng.OneIn(3)) value = (length + (rng.OneIn(2) ? 1 : 0xFFFFFFFF)) & 0xFFFFFFFF;  // +-1
  PutBigEndian(&s, at, value, 4);
  return s;
}

std::string JpegHeader(std::string s, FuzzRng& rng) {
  // Segments with a length: (offset of the marker's 0xFF, length).
  std::vector<std::pair<size_t, uint64_t>> segments;
  std::vector<size_t> frames;  // offsets of SOF segments
  size_t at = 2;
  while (at + 4 <= s.size() && static_cast<unsigned char>(s[at]) == 0xFF) {
    const unsigned char marker = static_cast<unsigned char>(s[at + 1]);
    if (marker == 0xFF) {
      ++at;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD9)) {
      at += 2;
      continue;
    }
    const uint64_t length = GetBigEndian(s, at + 2, 2);
    segments.emplace_back(at, length);
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 &&
                     marker != 0xCC;
    if (sof && at + 10 <= s.size()) frames.push_back(at);
    if (marker == 0xDA) break;  // the scan's entropy-coded data follows
    at += 2 + length;
  }
  if (!frames.empty() && !rng.OneIn(3)) {
    const size_t sof = Pick(frames, rng);
    static const std::vector<uint64_t> kSides = {0, 1, 2, 8, 32768, 32769, 65500, 65535};
    static const std::vector<uint64_t> kBytes = {0, 1, 2, 3, 4, 5, 8, 12, 16, 0x0F, 0x11,
                                                 0x22, 0x44, 0x55, 0xF0, 0xFF};
    switch (rng.Below(5)) {
      case 0: PutBigEndian(&s, sof + 4, Pick(kBytes, rng), 1); break;   // precision
      case 1: PutBigEndian(&s, sof + 5, Pick(kSides, rng), 2); break;   // height
      case 2: PutBigEndian(&s, sof + 7, Pick(kSides, rng), 2); break;   // width
      case 3: PutBigEndian(&s, sof + 9, Pick(kBytes, rng), 1); break;   // components
      default:                                                          // a sampling factor
        if (sof + 12 <= s.size()) {
          const size_t components = std::min<size_t>(static_cast<unsigned char>(s[sof + 9]),
                                                     (s.size() - sof - 10) / 3);
          if (components > 0) {
            PutBigEndian(&s, sof + 11 + 3 * rng.Below(components), Pick(kBytes, rng), 1);
          }
        }
    }
    return s;
  }
  if (segments.empty()) return s;
  const auto& [segment, length] = Pick(segments, rng);
  static const std::vector<uint64_t> kLengths = {0, 1, 2, 3, 0x7FFF, 0xFFFF};
  uint64_t value = Pick(kLengths, rng);
  if (rng.OneIn(3)) value = (length + (rng.OneIn(2) ? 1 : 0xFFFF)) & 0xFFFF;  // +-1
  PutBigEndian(&s, segment + 2, value, 2);
  return s;
}

}  // namespace

std::string Mutator::BitFlip(std::string s, FuzzRng& rng) const {
  if (s.empty()) return s;
  const size_t at = rng.Below(s.size());
  s[at] = static_cast<char>(static_cast<unsigned char>(s[at]) ^ (1U << rng.Below(8)));
  return s;
}

std::string Mutator::ByteSet(std::string s, FuzzRng& rng) const {
  if (s.empty()) return s;
  static const std::vector<unsigned char> kBytes = {0x00, 0x01, 0x7F, 0x80, 0xFF, '0', '9'};
  const size_t at = rng.Below(s.size());
  s[at] = static_cast<char>(rng.OneIn(2) ? Pick(kBytes, rng) : rng.Below(256));
  return s;
}

std::string Mutator::InsertBytes(std::string s, FuzzRng& rng) const {
  if (s.size() >= max_size_) return s;
  const size_t count = std::min<size_t>(rng.InRange(1, 8), max_size_ - s.size());
  std::string bytes;
  for (size_t i = 0; i < count; ++i) bytes += static_cast<char>(rng.Below(256));
  s.insert(rng.Below(s.size() + 1), bytes);
  return s;
}

std::string Mutator::DeleteBytes(std::string s, FuzzRng& rng) const {
  if (s.empty()) return s;
  const size_t count = rng.InRange(1, std::min<size_t>(16, s.size()));
  s.erase(rng.Below(s.size() - count + 1), count);
  return s;
}

std::string Mutator::DuplicateChunk(const std::string& s, FuzzRng& rng) const {
  if (s.empty() || s.size() >= max_size_) return s;
  const size_t length = rng.InRange(1, std::min<size_t>(64, s.size()));
  const size_t from = rng.Below(s.size() - length + 1);
  // Mostly a few copies; one time in four a long run (deep nesting from "[",
  // wide headers from ",x", long lines), up to max_size.
  size_t copies = rng.OneIn(4) ? rng.InRange(2, 4096) : rng.InRange(1, 3);
  copies = std::min(copies, (max_size_ - s.size()) / length);
  if (copies == 0) return s;
  std::string chunk;
  chunk.reserve(length * copies);
  for (size_t i = 0; i < copies; ++i) chunk.append(s, from, length);
  std::string out = s;
  out.insert(rng.Below(s.size() + 1), chunk);
  return out;
}

std::string Mutator::Splice(const std::string& a, const std::string& b, FuzzRng& rng) const {
  const size_t cut_a = rng.Below(a.size() + 1), cut_b = rng.Below(b.size() + 1);
  std::string out = a.substr(0, cut_a) + b.substr(cut_b);
  if (out.size() > max_size_) out.resize(max_size_);
  return out;
}

std::string Mutator::ReplaceNumber(const std::string& s, FuzzRng& rng) const {
  const std::string& value = Pick(HostileNumbers(), rng);
  const std::vector<std::pair<size_t, size_t>> tokens = NumericTokens(s);
  std::string out = s;
  if (tokens.empty()) {
    out.insert(rng.Below(s.size() + 1), value);
  } else {
    const auto& [at, length] = Pick(tokens, rng);
    out.replace(at, length, value);
  }
  if (out.size() > max_size_) out.resize(max_size_);
  return out;
}

std::string Mutator::InjectSpecial(const std::string& s, FuzzRng& rng) const {
  const std::string& token = Pick(SpecialTokens(), rng);
  std::string out = s;
  // A byte-order mark belongs at the start (where readers look for it).
  const bool at_start = token == "\xEF\xBB\xBF" && rng.OneIn(2);
  out.insert(at_start ? 0 : rng.Below(s.size() + 1), token);
  if (out.size() > max_size_) out.resize(max_size_);
  return out;
}

std::string Mutator::Truncate(const std::string& s, FuzzRng& rng) const {
  if (s.empty()) return s;
  return s.substr(0, rng.Below(s.size()));
}

std::string Mutator::ImageHeader(std::string s, FuzzRng& rng) const {
  if (IsPng(s)) return PngHeader(std::move(s), rng);
  if (IsJpeg(s)) return JpegHeader(std::move(s), rng);
  return s;
}

std::string Mutator::Apply(MutationOp op, const std::string& input, const std::string& other,
                           FuzzRng& rng) const {
  switch (op) {
    case MutationOp::kBitFlip: return BitFlip(input, rng);
    case MutationOp::kByteSet: return ByteSet(input, rng);
    case MutationOp::kInsertBytes: return InsertBytes(input, rng);
    case MutationOp::kDeleteBytes: return DeleteBytes(input, rng);
    case MutationOp::kDuplicateChunk: return DuplicateChunk(input, rng);
    case MutationOp::kSplice: return Splice(input, other, rng);
    case MutationOp::kReplaceNumber: return ReplaceNumber(input, rng);
    case MutationOp::kInjectSpecial: return InjectSpecial(input, rng);
    case MutationOp::kTruncate: return Truncate(input, rng);
    case MutationOp::kImageHeader: return ImageHeader(input, rng);
  }
  return input;
}

std::string Mutator::Mutate(const std::string& input, const std::vector<std::string>& corpus,
                            InputKind kind, FuzzRng& rng,
                            std::vector<MutationOp>* applied) const {
  // Weights per operator, in MutationOp order: text readers fail mostly on
  // numbers and delimiters, image decoders on header fields and truncation.
  static const std::array<uint64_t, 10> kText = {2, 1, 1, 2, 2, 1, 4, 3, 1, 0};
  static const std::array<uint64_t, 10> kImage = {3, 3, 1, 1, 1, 1, 0, 0, 2, 4};
  std::array<uint64_t, 10> weights = kind == InputKind::kText ? kText : kImage;
  if (corpus.empty()) weights[static_cast<int>(MutationOp::kSplice)] = 0;
  uint64_t total = 0;
  for (uint64_t w : weights) total += w;

  const int count = rng.OneIn(2) ? 1 : static_cast<int>(rng.InRange(2, 4));
  std::string out = input;
  for (int i = 0; i < count; ++i) {
    uint64_t r = rng.Below(total);
    int op = 0;
    while (r >= weights[op]) r -= weights[op++];
    const MutationOp chosen = static_cast<MutationOp>(op);
    const std::string& other =
        chosen == MutationOp::kSplice ? corpus[rng.Below(corpus.size())] : out;
    out = Apply(chosen, out, other, rng);
    if (applied != nullptr) applied->push_back(chosen);
  }
  return out;
}

}  // namespace fuzz
}  // namespace opl
