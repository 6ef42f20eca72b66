// The fuzzing mutator (tests/fuzz/mutator.h): the same seed gives the same
// input, and each operator does what it says, checked on inputs whose result
// can be told exactly.
#include "fuzz/mutator.h"

#include <algorithm>
#include <set>
#include <string>

#include <gtest/gtest.h>

namespace opl {
namespace fuzz {
namespace {

const std::string kCsv = "source,beam,x,y,z\nA,1,1012.5,3.25,-0.5\nB,12,7,8e-3,9\n";

// A PNG header: signature, IHDR of 640 x 480, 8-bit RGB, its CRC; then IEND.
std::string TinyPng() {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  png += std::string("\0\0\0\x0d", 4) + "IHDR";
  png += std::string("\0\0\x02\x80\0\0\x01\xe0\x08\x02\0\0\0", 13);
  const uint32_t crc = Crc32(std::string_view(png).substr(12, 17));
  for (int i = 3; i >= 0; --i) png += static_cast<char>((crc >> (8 * i)) & 0xFF);
  png += std::string("\0\0\0\0IEND\xae\x42\x60\x82", 12);
  return png;
}

// A JPEG header: SOI, an APP0 segment of 16 bytes, a baseline SOF0 of
// 480 x 640 with 3 components, SOS, two bytes of scan, EOI.
std::string TinyJpeg() {
  std::string jpeg("\xFF\xD8", 2);
  jpeg += std::string("\xFF\xE0\x00\x10JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00", 18);
  jpeg += std::string("\xFF\xC0\x00\x11\x08\x01\xE0\x02\x80\x03\x01\x22\x00\x02\x11\x01\x03\x11\x01",
                      19);
  jpeg += std::string("\xFF\xDA\x00\x08\x01\x01\x00\x00\x3F\x00\x12\x34\xFF\xD9", 14);
  return jpeg;
}

uint64_t BigEndianAt(const std::string& s, size_t at, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | static_cast<unsigned char>(s[at + i]);
  return v;
}

TEST(FuzzRng, IsSplitMix64) {
  // splitmix64's published first outputs for seed 0 (Vigna's reference C).
  FuzzRng rng(0);
  EXPECT_EQ(rng.Next(), 0xE220A8397B1DCDAFULL);
  EXPECT_EQ(rng.Next(), 0x6E789E6AA1B965F4ULL);
  EXPECT_EQ(rng.Next(), 0x06C45D188009454FULL);
}

TEST(FuzzRng, BelowStaysInRangeAndCoversIt) {
  FuzzRng rng(42);
  std::set<uint64_t> seen;
  for (int i = 0; i < 2000; ++i) {
    const uint64_t v = rng.Below(7);
    ASSERT_LT(v, 7u);
    seen.insert(v);
  }
  EXPECT_EQ(seen.size(), 7u);
  EXPECT_EQ(rng.Below(0), 0u);
  EXPECT_EQ(rng.Below(1), 0u);
  for (int i = 0; i < 100; ++i) {
    const uint64_t v = rng.InRange(5, 9);
    EXPECT_GE(v, 5u);
    EXPECT_LE(v, 9u);
  }
}

TEST(CaseSeed, DependsOnEveryPart) {
  const uint64_t base = CaseSeed(1, "spots_csv", 0);
  EXPECT_EQ(CaseSeed(1, "spots_csv", 0), base);
  EXPECT_NE(CaseSeed(2, "spots_csv", 0), base);
  EXPECT_NE(CaseSeed(1, "slices_csv", 0), base);
  EXPECT_NE(CaseSeed(1, "spots_csv", 1), base);
  std::set<uint64_t> seeds;
  for (uint64_t i = 0; i < 1000; ++i) seeds.insert(CaseSeed(7, "png", i));
  EXPECT_EQ(seeds.size(), 1000u);
}

TEST(Crc32, MatchesTheStandardCheckValue) {
  EXPECT_EQ(Crc32("123456789"), 0xCBF43926U);  // the CRC-32 check value
  EXPECT_EQ(Crc32(""), 0u);
  // IEND's CRC, as in every PNG.
  EXPECT_EQ(Crc32("IEND"), 0xAE426082U);
}

TEST(NumericTokens, FindsNumbersNotWords) {
  const std::string text = "beam,x\nA1,12,-3.5e-2,true,1e308";
  const auto tokens = NumericTokens(text);
  std::vector<std::string> found;
  for (const auto& [at, length] : tokens) found.push_back(text.substr(at, length));
  EXPECT_EQ(found, (std::vector<std::string>{"12", "-3.5e-2", "1e308"}));
}

TEST(Mutator, SameSeedSameOutputDifferentSeedDifferentOutput) {
  const Mutator mutator;
  const std::vector<std::string> corpus = {kCsv, "x,y,z\n1,2,3\n"};
  std::set<std::string> distinct;
  for (uint64_t seed = 0; seed < 50; ++seed) {
    FuzzRng a(seed), b(seed);
    std::vector<MutationOp> ops_a, ops_b;
    const std::string out_a = mutator.Mutate(kCsv, corpus, InputKind::kText, a, &ops_a);
    const std::string out_b = mutator.Mutate(kCsv, corpus, InputKind::kText, b, &ops_b);
    EXPECT_EQ(out_a, out_b) << seed;
    EXPECT_EQ(ops_a, ops_b) << seed;
    EXPECT_GE(ops_a.size(), 1u);
    EXPECT_LE(ops_a.size(), 4u);
    distinct.insert(out_a);
  }
  // 50 seeds: nearly all different (a truncation to "" may repeat).
  EXPECT_GE(distinct.size(), 45u);
}

TEST(Mutator, PinnedOutputOfOneCase) {
  // The exact output of one case: a change to the generator or to an
  // operator's choices changes every saved finding's case, and must be a
  // decision (update these with it).
  EXPECT_EQ(CaseSeed(1, "spots_csv", 0), 12912887610289358394ULL);
  const Mutator mutator;
  FuzzRng rng(CaseSeed(1, "spots_csv", 0));
  std::vector<MutationOp> ops;
  const std::string out = mutator.Mutate(kCsv, {kCsv}, InputKind::kText, rng, &ops);
  std::string ops_text;
  for (MutationOp op : ops) ops_text += std::string(MutationOpName(op)) + " ";
  EXPECT_EQ(ops_text, "delete_bytes ");
  EXPECT_EQ(out, "source,beam,x,y,z\nA,1,1012.5,3.2B,12,7,8e-3,9\n");
}

TEST(Mutator, ImageKindNeverUsesTextOperators) {
  const Mutator mutator;
  for (uint64_t seed = 0; seed < 300; ++seed) {
    FuzzRng rng(seed);
    std::vector<MutationOp> ops;
    mutator.Mutate(TinyPng(), {TinyPng()}, InputKind::kImage, rng, &ops);
    for (MutationOp op : ops) {
      EXPECT_NE(op, MutationOp::kReplaceNumber);
      EXPECT_NE(op, MutationOp::kInjectSpecial);
    }
  }
  for (uint64_t seed = 0; seed < 300; ++seed) {
    FuzzRng rng(seed);
    std::vector<MutationOp> ops;
    mutator.Mutate(kCsv, {}, InputKind::kText, rng, &ops);
    for (MutationOp op : ops) {
      EXPECT_NE(op, MutationOp::kImageHeader);
      EXPECT_NE(op, MutationOp::kSplice);  // no corpus: no partner
    }
  }
}

TEST(Mutator, BitFlipChangesExactlyOneBit) {
  const Mutator mutator;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.BitFlip(kCsv, rng);
    ASSERT_EQ(out.size(), kCsv.size());
    int bits = 0;
    for (size_t i = 0; i < out.size(); ++i) {
      bits += __builtin_popcount(static_cast<unsigned char>(out[i] ^ kCsv[i]));
    }
    EXPECT_EQ(bits, 1) << seed;
  }
  FuzzRng rng(1);
  EXPECT_EQ(mutator.BitFlip("", rng), "");
}

TEST(Mutator, ByteSetChangesAtMostOneByte) {
  const Mutator mutator;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.ByteSet(kCsv, rng);
    ASSERT_EQ(out.size(), kCsv.size());
    int differ = 0;
    for (size_t i = 0; i < out.size(); ++i) differ += out[i] != kCsv[i];
    EXPECT_LE(differ, 1) << seed;
  }
}

TEST(Mutator, InsertAndDeleteChangeTheLengthWithinTheirBounds) {
  const Mutator mutator;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    FuzzRng rng(seed);
    const std::string inserted = mutator.InsertBytes(kCsv, rng);
    EXPECT_GE(inserted.size(), kCsv.size() + 1);
    EXPECT_LE(inserted.size(), kCsv.size() + 8);
    // The original is the output with one run of bytes removed.
    const size_t added = inserted.size() - kCsv.size();
    bool one_run = false;
    for (size_t at = 0; at + added <= inserted.size() && !one_run; ++at) {
      one_run = inserted.substr(0, at) + inserted.substr(at + added) == kCsv;
    }
    EXPECT_TRUE(one_run) << seed;

    const std::string deleted = mutator.DeleteBytes(kCsv, rng);
    EXPECT_GE(deleted.size() + 1, kCsv.size() - 15);
    EXPECT_LE(deleted.size(), kCsv.size() - 1);
    // The output is the original with one run removed: a common prefix and
    // suffix cover it.
    size_t head = 0;
    while (head < deleted.size() && deleted[head] == kCsv[head]) ++head;
    EXPECT_EQ(kCsv.substr(kCsv.size() - (deleted.size() - head)), deleted.substr(head)) << seed;
  }
  FuzzRng rng(3);
  EXPECT_EQ(mutator.DeleteBytes("", rng), "");
  EXPECT_EQ(mutator.DeleteBytes("a", rng), "");
}

TEST(Mutator, DuplicateChunkRepeatsAPartOfTheInput) {
  const Mutator mutator(4096);
  bool long_run = false;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.DuplicateChunk("[1]", rng);
    ASSERT_GT(out.size(), 3u) << seed;
    ASSERT_LE(out.size(), 4096u) << seed;
    // Only bytes of the input, and the input is a subsequence of it.
    EXPECT_EQ(out.find_first_not_of("[1]"), std::string::npos) << seed;
    long_run |= out.size() > 1000;
  }
  EXPECT_TRUE(long_run) << "one case in four repeats a chunk up to thousands of times";
  const Mutator full(3);
  FuzzRng rng(0);
  EXPECT_EQ(full.DuplicateChunk("abc", rng), "abc") << "at max_size nothing is added";
}

TEST(Mutator, SpliceJoinsAPrefixAndASuffix) {
  const Mutator mutator;
  const std::string a = "aaaaaaaaaa", b = "bbbbbbbbbb";
  for (uint64_t seed = 0; seed < 100; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.Splice(a, b, rng);
    const size_t as = out.find_first_not_of('a');
    const std::string tail = as == std::string::npos ? "" : out.substr(as);
    EXPECT_EQ(tail.find_first_not_of('b'), std::string::npos) << out;
    EXPECT_LE(out.size(), a.size() + b.size());
  }
}

TEST(Mutator, ReplaceNumberPutsAHostileValueWhereANumberWas) {
  const Mutator mutator;
  // '|' is in no hostile value, so the row splits back into its two fields.
  const std::string text = "x|y\n12|34\n";
  const auto& hostile = HostileNumbers();
  std::set<std::string> values;
  for (uint64_t seed = 0; seed < 400; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.ReplaceNumber(text, rng);
    ASSERT_EQ(out.substr(0, 4), "x|y\n") << "the header has no number";
    ASSERT_EQ(out.back(), '\n');
    const std::string row = out.substr(4, out.size() - 5);
    const size_t bar = row.find('|');
    ASSERT_NE(bar, std::string::npos) << row;
    const std::string left = row.substr(0, bar), right = row.substr(bar + 1);
    // Exactly one of the two numbers was replaced, by a listed value.
    ASSERT_TRUE((left == "12") != (right == "34")) << row;
    const std::string value = left == "12" ? right : left;
    EXPECT_NE(std::find(hostile.begin(), hostile.end(), value), hostile.end()) << row;
    values.insert(value);
  }
  EXPECT_GE(values.size(), hostile.size() - 3) << "the hostile values are all used";
  // No number at all: one is inserted.
  FuzzRng rng(5);
  const std::string out = mutator.ReplaceNumber("abc", rng);
  bool inserted = false;
  for (size_t at = 0; at <= 3; ++at) {
    const std::string value = out.substr(at, out.size() - 3);
    inserted |= out.substr(0, at) + out.substr(at + value.size()) == "abc" &&
                std::find(hostile.begin(), hostile.end(), value) != hostile.end();
  }
  EXPECT_TRUE(inserted) << out;
}

TEST(Mutator, InjectSpecialInsertsOneToken) {
  const Mutator mutator;
  bool bom_first = false, nul = false, crlf = false;
  for (uint64_t seed = 0; seed < 500; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.InjectSpecial(kCsv, rng);
    const size_t added = out.size() - kCsv.size();
    bool found = false;
    for (size_t at = 0; at + added <= out.size() && !found; ++at) {
      const std::string token = out.substr(at, added);
      found = out.substr(0, at) + out.substr(at + added) == kCsv &&
              std::find(SpecialTokens().begin(), SpecialTokens().end(), token) !=
                  SpecialTokens().end();
    }
    EXPECT_TRUE(found) << seed;
    bom_first |= out.rfind("\xEF\xBB\xBF", 0) == 0;
    nul |= out.find('\0') != std::string::npos;
    crlf |= out.find("\r\n") != std::string::npos;
  }
  EXPECT_TRUE(bom_first);
  EXPECT_TRUE(nul);
  EXPECT_TRUE(crlf);
}

TEST(Mutator, TruncateKeepsAProperPrefix) {
  const Mutator mutator;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.Truncate(kCsv, rng);
    EXPECT_LT(out.size(), kCsv.size());
    EXPECT_EQ(kCsv.rfind(out, 0), 0u);
  }
}

TEST(Mutator, PngHeaderFieldsKeepAValidCrc) {
  const Mutator mutator;
  const std::string png = TinyPng();
  int ihdr_changes = 0, length_changes = 0;
  for (uint64_t seed = 0; seed < 300; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.ImageHeader(png, rng);
    ASSERT_EQ(out.size(), png.size());
    if (out.compare(16, 13, png, 16, 13) != 0) {
      ++ihdr_changes;
      // The decoder must see a well-formed chunk with a bad value, not a CRC error.
      EXPECT_EQ(BigEndianAt(out, 29, 4), Crc32(std::string_view(out).substr(12, 17))) << seed;
    } else if (out != png) {
      ++length_changes;
      EXPECT_TRUE(out.compare(8, 4, png, 8, 4) != 0 || out.compare(33, 4, png, 33, 4) != 0)
          << "only a length field changed";
    }
  }
  EXPECT_GT(ihdr_changes, 150);
  EXPECT_GT(length_changes, 20);
  // Width 0x7FFFFFFF or similar appears among them.
  bool huge = false;
  for (uint64_t seed = 0; seed < 300 && !huge; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.ImageHeader(png, rng);
    huge = BigEndianAt(out, 16, 4) >= 100000 || BigEndianAt(out, 20, 4) >= 100000;
  }
  EXPECT_TRUE(huge);
}

TEST(Mutator, JpegHeaderFieldsOfTheFrameAndSegments) {
  const Mutator mutator;
  const std::string jpeg = TinyJpeg();
  const size_t sof = jpeg.find("\xFF\xC0");
  ASSERT_EQ(sof, 20u);
  int frame_changes = 0, other_changes = 0;
  for (uint64_t seed = 0; seed < 300; ++seed) {
    FuzzRng rng(seed);
    const std::string out = mutator.ImageHeader(jpeg, rng);
    ASSERT_EQ(out.size(), jpeg.size());
    int differ = 0;
    size_t where = 0;
    for (size_t i = 0; i < out.size(); ++i) {
      if (out[i] != jpeg[i]) ++differ, where = i;
    }
    EXPECT_LE(differ, 2) << seed;
    if (differ == 0) continue;  // a value equal to the old one
    if (where >= sof + 4 && where < sof + 19) {
      ++frame_changes;
    } else {
      ++other_changes;
      // A length field: 2 bytes after a marker.
      EXPECT_TRUE(where == 4 || where == 5 || where == 22 || where == 23 || where == 41 ||
                  where == 42)
          << seed << " at " << where;
    }
  }
  EXPECT_GT(frame_changes, 120);
  EXPECT_GT(other_changes, 40);
  FuzzRng rng(0);
  EXPECT_EQ(mutator.ImageHeader(kCsv, rng), kCsv) << "neither PNG nor JPEG: unchanged";
}

TEST(Mutator, MaxSizeIsNeverExceeded) {
  const Mutator mutator(200);
  std::string input = kCsv;
  for (uint64_t seed = 0; seed < 2000; ++seed) {
    FuzzRng rng(seed);
    input = mutator.Mutate(input.empty() ? kCsv : input, {kCsv, kCsv + kCsv}, InputKind::kText,
                           rng);
    ASSERT_LE(input.size(), 200u) << seed;
  }
}

}  // namespace
}  // namespace fuzz
}  // namespace opl
