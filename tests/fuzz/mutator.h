// A small deterministic mutator for fuzzing OPL's input readers (issue 19
// item 10; docs/testing.md, "Fuzzing"). No fuzzing engine: our compiler is
// GCC, so libFuzzer is not available, and readers of text formats are better
// served by operators that know about numbers, delimiters and quotes than by
// blind bytes. Every random choice comes from FuzzRng (splitmix64), whose
// output depends on nothing but the seed: the same seed gives the same
// mutated input on every machine and compiler (std:: distributions do not
// promise that).
//
//   FuzzRng rng(CaseSeed(7, "spots_csv", 12));
//   Mutator mutator;
//   std::string input = mutator.Mutate(seed_text, corpus, InputKind::kText, rng);
//
// Operators (each also callable alone, for the tests and for a harness that
// wants one kind of damage):
//   bit flip, byte set, byte insert, byte delete, chunk duplication (a chunk
//   repeated up to a few thousand times: deep nesting, wide headers), splice of
//   two corpus entries, numeric-token replacement with hostile values (NaN,
//   inf, 1e308, -0, huge integers, 2^64, ...), injection of delimiters,
//   quotes, line ends, a byte-order mark, NUL and escape sequences,
//   truncation; for images, header fields (PNG IHDR with its CRC recomputed,
//   chunk lengths; JPEG SOF sizes, precision, components and segment lengths).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace opl {
namespace fuzz {

// splitmix64 (Steele, Lea, Flood 2014): a 64-bit state, every seed valid.
class FuzzRng {
 public:
  explicit FuzzRng(uint64_t seed) : state_(seed) {}
  uint64_t Next();
  // Uniform in [0, n); n must be > 0 (0 gives 0). Rejection sampling, so
  // exact and the same everywhere.
  uint64_t Below(uint64_t n);
  // Uniform in [lo, hi] (lo <= hi).
  uint64_t InRange(uint64_t lo, uint64_t hi) { return lo + Below(hi - lo + 1); }
  bool OneIn(uint64_t n) { return Below(n) == 0; }

 private:
  uint64_t state_;
};

// The seed of case `iteration` of `format` in a run seeded `run_seed`: each
// case can be replayed alone (FNV-1a of the format name, mixed by splitmix64).
uint64_t CaseSeed(uint64_t run_seed, std::string_view format, uint64_t iteration);

enum class InputKind { kText, kImage };

enum class MutationOp {
  kBitFlip,         // one bit of one byte
  kByteSet,         // one byte replaced by a random or boundary value
  kInsertBytes,     // 1..8 random bytes inserted
  kDeleteBytes,     // 1..16 consecutive bytes removed
  kDuplicateChunk,  // a chunk copied 1..4096 times at a random place
  kSplice,          // a prefix of the input joined to a suffix of another entry
  kReplaceNumber,   // a numeric token replaced by a hostile value
  kInjectSpecial,   // a delimiter, quote, line end, BOM, NUL or escape inserted
  kTruncate,        // the input cut at a random length
  kImageHeader,     // a PNG/JPEG header field or segment length set to a hostile value
};

// "bit_flip", "byte_set", ... (the enum's name in snake case).
const char* MutationOpName(MutationOp op);

// The hostile replacements of kReplaceNumber, in order.
const std::vector<std::string>& HostileNumbers();
// The insertions of kInjectSpecial, in order.
const std::vector<std::string>& SpecialTokens();

// CRC-32 (ISO 3309, as PNG uses) of `bytes`.
uint32_t Crc32(std::string_view bytes);

// Numeric tokens of `text`: maximal runs of [0-9+-.eE] holding a digit, as
// (offset, length) pairs in text order.
std::vector<std::pair<size_t, size_t>> NumericTokens(std::string_view text);

class Mutator {
 public:
  // Inputs never grow beyond `max_size` bytes (chunk duplication and
  // insertion stop there).
  explicit Mutator(size_t max_size = size_t{1} << 20) : max_size_(max_size) {}

  // 1 to 4 operators chosen for `kind` (kImageHeader only for images;
  // kReplaceNumber and kInjectSpecial mostly for text), applied in turn.
  // `corpus` gives the other entry of a splice (may be empty: no splice).
  // `applied`, when not null, receives the operators in order.
  std::string Mutate(const std::string& input, const std::vector<std::string>& corpus,
                     InputKind kind, FuzzRng& rng,
                     std::vector<MutationOp>* applied = nullptr) const;

  // One operator. `other` is the splice partner (kSplice only). An operator
  // that cannot apply (e.g. a bit flip of an empty input, a PNG field of a
  // text) returns the input unchanged, except kReplaceNumber on a text without
  // numbers, which inserts a hostile number.
  std::string Apply(MutationOp op, const std::string& input, const std::string& other,
                    FuzzRng& rng) const;

  std::string BitFlip(std::string s, FuzzRng& rng) const;
  std::string ByteSet(std::string s, FuzzRng& rng) const;
  std::string InsertBytes(std::string s, FuzzRng& rng) const;
  std::string DeleteBytes(std::string s, FuzzRng& rng) const;
  std::string DuplicateChunk(const std::string& s, FuzzRng& rng) const;
  std::string Splice(const std::string& a, const std::string& b, FuzzRng& rng) const;
  std::string ReplaceNumber(const std::string& s, FuzzRng& rng) const;
  std::string InjectSpecial(const std::string& s, FuzzRng& rng) const;
  std::string Truncate(const std::string& s, FuzzRng& rng) const;
  // PNG: an IHDR field (width, height, bit depth, colour type, compression,
  // filter, interlace) set to a hostile value and the CRC recomputed (so the
  // decoder reaches its checks of the value), or a chunk's length field;
  // JPEG: a frame header field (precision, height, width, component count, a
  // sampling factor) or any segment's length field. Neither: unchanged.
  std::string ImageHeader(std::string s, FuzzRng& rng) const;

  size_t max_size() const { return max_size_; }

 private:
  size_t max_size_;
};

}  // namespace fuzz
}  // namespace opl
