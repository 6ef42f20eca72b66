#include "opl/io/spots_csv.h"

#include <chrono>
#include <cmath>
#include <limits>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "opl/core/message_text.h"

namespace opl {
namespace {

// opl::SafeForMessage / QuoteForMessage (opl/core/message_text.h), which every
// reader uses to echo file content (issue 19 item 7).
TEST(SafeForMessage, EscapesControlCharactersAndCuts) {
  EXPECT_EQ(SafeForMessage("A\x1b[31m\n\r\t\x7f\x01z"), "A\\x1b[31m\\n\\r\\t\\x7f\\x01z");
  EXPECT_EQ(QuoteForMessage("cam0"), "'cam0'");
  EXPECT_EQ(SafeForMessage(std::string(300, 'a')), std::string(200, 'a') + "...");
  EXPECT_EQ(SafeForMessage("abcdef", 3), "abc...");
  // Not inside a UTF-8 character: "\xc3\xa9" is one (e acute).
  EXPECT_EQ(SafeForMessage("ab\xc3\xa9", 3), "ab...");
  EXPECT_EQ(SafeForMessage("ab\xc3\xa9", 4), "ab\xc3\xa9");
  EXPECT_EQ(OneLineMessage("a\nb\x1b"), "a\\nb\\x1b");
}

using ::testing::HasSubstr;

Status ParseError(const std::string& text) {
  Result<SpotsCsvData> r = ParseSpotsCsv(text, "s.csv");
  return r.ok() ? Status::Ok() : r.status();
}

TEST(SpotsCsv, ParsesTheMinimalColumns) {
  Result<SpotsCsvData> r = ParseSpotsCsv("source,beam,x,y,z\nA,61,1012.5,3.25,-0.5\nB,1,1,2,3e2\n",
                                         "s.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 2u);
  EXPECT_FALSE(r->has_sigmas);
  EXPECT_TRUE(r->slices.empty());
  const Spot& a = r->spots[0];
  EXPECT_EQ(a.source, "A");
  EXPECT_EQ(a.observation.beam_id, 61);
  EXPECT_EQ(a.observation.point_in_scene, Eigen::Vector3d(1012.5, 3.25, -0.5));
  EXPECT_FALSE(a.observation.cov_in_scene.has_value());
  EXPECT_EQ(a.where, "s.csv:2");
  EXPECT_EQ(r->spots[1].where, "s.csv:3");
  EXPECT_EQ(r->spots[1].observation.point_in_scene.z(), 300.0);
}

TEST(SpotsCsv, ColumnsInAnyOrderWithExtraColumnsAndSigmas) {
  const std::string text =
      "note,Z,sz,y,beam,sy,x,sx,source,score\n"
      "first,3.5,0.3,2.5,7,0.2,1.5,0.1,A,99\n";
  Result<SpotsCsvData> r = ParseSpotsCsv(text, "s.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 1u);
  const SpotObservation& o = r->spots[0].observation;
  EXPECT_EQ(r->spots[0].source, "A");
  EXPECT_EQ(o.beam_id, 7);
  EXPECT_EQ(o.point_in_scene, Eigen::Vector3d(1.5, 2.5, 3.5));
  ASSERT_TRUE(o.cov_in_scene.has_value());
  EXPECT_TRUE(r->has_sigmas);
  Eigen::Matrix3d expected = Eigen::Vector3d(0.1 * 0.1, 0.2 * 0.2, 0.3 * 0.3).asDiagonal();
  EXPECT_EQ(*o.cov_in_scene, expected);
  EXPECT_EQ(r->other_columns, (std::vector<std::string>{"note", "score"}));
}

TEST(SpotsCsv, QuotedNamesCrlfBlankLinesAndSliceColumn) {
  const std::string text =
      "\xEF\xBB\xBFsource,beam,x,y,z,slice\r\n"
      "\r\n"
      "\"Laser, \"\"left\"\"\",5,1,2,3,0\r\n"
      "   \n"
      "\"multi\nline\",6, 4 , 5 ,6,2\r\n"
      "B,7,7,8,9,1";  // no final line break
  Result<SpotsCsvData> r = ParseSpotsCsv(text, "s.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 3u);
  EXPECT_EQ(r->spots[0].source, "Laser, \"left\"");
  EXPECT_EQ(r->spots[0].where, "s.csv:3");
  EXPECT_EQ(r->spots[1].source, "multi\nline");
  EXPECT_EQ(r->spots[1].where, "s.csv:5");
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(r->spots[2].where, "s.csv:7");  // line count includes the quoted line break
  EXPECT_EQ(r->slices, (std::vector<int>{0, 2, 1}));
}

TEST(SpotsCsv, WrongFieldCountNamesFileAndLine) {
  Status st = ParseError("source,beam,x,y,z\nA,1,1,2,3\nA,2,1,2\n");
  EXPECT_EQ(st.code(), StatusCode::kParseError);
  EXPECT_EQ(st.message(), "s.csv:3: expected 5 fields (as the header), found 4");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,1,2,3,\n").message(),
            "s.csv:2: expected 5 fields (as the header), found 6");
}

TEST(SpotsCsv, NotANumberNamesLineAndField) {
  EXPECT_EQ(ParseError("source,beam,x,y,z\n\nA,1,abc,2,3\n").message(),
            "s.csv:3: field 'x': not a number: 'abc'");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,1,2,3mm\n").message(),
            "s.csv:2: field 'z': not a number: '3mm'");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,1,,3\n").message(),
            "s.csv:2: field 'y': empty value");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1.5,1,2,3\n").message(),
            "s.csv:2: field 'beam': not an integer: '1.5'");
}

TEST(SpotsCsv, NanAndInfinityAreRejectedWithLineAndField) {
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,1,nan,3\n").message(),
            "s.csv:2: field 'y': not finite: 'nan'");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,1,2,3\nA,2,-inf,2,3\n").message(),
            "s.csv:3: field 'x': not finite: '-inf'");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,1,2,1e999\n").message(),
            "s.csv:2: field 'z': out of range: '1e999'");
  EXPECT_EQ(ParseError("source,beam,x,y,z,sx,sy,sz\nA,1,1,2,3,0.1,NaN,0.1\n").message(),
            "s.csv:2: field 'sy': not finite: 'NaN'");
}

TEST(SpotsCsv, SigmasAllThreeOrNoneAndPositive) {
  EXPECT_EQ(ParseError("source,beam,x,y,z,sx,sz\nA,1,1,2,3,1,1\n").message(),
            "s.csv:1: columns sx, sy, sz must be given all three or none (missing sy)");
  EXPECT_EQ(ParseError("source,beam,x,y,z,sx,sy,sz\nA,1,1,2,3,0.1,0,0.1\n").message(),
            "s.csv:2: field 'sy': standard deviation must be > 0, got 0");
  EXPECT_EQ(ParseError("source,beam,x,y,z,sx,sy,sz\nA,1,1,2,3,-0.1,1,0.1\n").message(),
            "s.csv:2: field 'sx': standard deviation must be > 0, got -0.1");
}

TEST(SpotsCsv, HeaderProblems) {
  EXPECT_EQ(ParseError("").message(), "s.csv: empty file (no header row)");
  EXPECT_EQ(ParseError("\n  \n").message(), "s.csv: empty file (no header row)");
  EXPECT_EQ(ParseError("source,beam,x,y\nA,1,2,3\n").message(),
            "s.csv:1: missing column 'z' (a spots CSV needs x,y,z; source,beam are optional)");
  EXPECT_EQ(ParseError("source,beam,y,z\nA,1,2,3\n").message(),
            "s.csv:1: missing column 'x' (a spots CSV needs x,y,z; source,beam are optional)");
  EXPECT_EQ(ParseError("source,beam,x,y,z,X\n").message(), "s.csv:1: duplicate column 'X'");
  EXPECT_EQ(ParseError("source,beam,,x,y,z\n").message(), "s.csv:1: header column 3 has no name");
}

TEST(SpotsCsv, ManyColumnsAreCheckedInLinearTime) {
  // Issue 19: the duplicate-column check was pairwise (16k columns: 4.2 s,
  // 100k: never ended). 200k distinct columns, then a duplicate at the end.
  std::string header = "source,beam,x,y,z";
  for (int i = 0; i < 200000; ++i) header += ",c" + std::to_string(i);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(ParseError(header + ",C17\n").message(), "s.csv:1: duplicate column 'C17'");
  EXPECT_TRUE(ParseSpotsCsv(header + "\n", "s.csv").ok());
#if defined(__SANITIZE_ADDRESS__)
  const double limit_s = 10.0;  // the sanitizer build; pairwise it would take minutes
#else
  const double limit_s = 1.0;
#endif
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
            limit_s);
}

TEST(SpotsCsv, EmptySourceOrBeamMeansUnassigned) {
  const std::string text =
      "source,beam,x,y,z\n"
      "A,61,1,2,3\n"
      ",,4,5,6\n"
      "B,,7,8,9\n"
      "\"\",12,10,11,12\n"
      " , ,13,14,15\n";  // blanks only: empty after trimming
  Result<SpotsCsvData> r = ParseSpotsCsv(text, "s.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 5u);
  EXPECT_TRUE(r->spots[0].assigned());
  EXPECT_EQ(r->spots[1].source, "");
  EXPECT_EQ(r->spots[1].observation.beam_id, 0);
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(r->spots[1].where, "s.csv:3");
  EXPECT_FALSE(r->spots[1].assigned());
  // One of the two is kept as a hint, but the spot is not assigned.
  EXPECT_EQ(r->spots[2].source, "B");
  EXPECT_EQ(r->spots[2].observation.beam_id, 0);
  EXPECT_FALSE(r->spots[2].assigned());
  EXPECT_EQ(r->spots[3].source, "");
  EXPECT_EQ(r->spots[3].observation.beam_id, 12);
  EXPECT_FALSE(r->spots[3].assigned());
  EXPECT_FALSE(r->spots[4].assigned());
  EXPECT_EQ(r->num_unassigned(), 4);
  EXPECT_TRUE(r->point_ids.empty());
}

TEST(SpotsCsv, SourceAndBeamColumnsMayBeAbsent) {
  Result<SpotsCsvData> r = ParseSpotsCsv("x,y,z,note\n1,2,3,a\n4,5,6,b\n", "s.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 2u);
  EXPECT_EQ(r->num_unassigned(), 2);
  EXPECT_EQ(r->spots[1].source, "");
  EXPECT_EQ(r->spots[1].observation.beam_id, 0);
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(r->other_columns, (std::vector<std::string>{"note"}));

  Result<SpotsCsvData> beams_only = ParseSpotsCsv("beam,x,y,z\n7,1,2,3\n", "s.csv");
  ASSERT_TRUE(beams_only.ok()) << beams_only.status().ToString();
  EXPECT_EQ(beams_only->spots[0].observation.beam_id, 7);
  EXPECT_EQ(beams_only->spots[0].source, "");
  EXPECT_EQ(beams_only->num_unassigned(), 1);

  Result<SpotsCsvData> sources_only = ParseSpotsCsv("source,x,y,z\nA,1,2,3\n", "s.csv");
  ASSERT_TRUE(sources_only.ok()) << sources_only.status().ToString();
  EXPECT_EQ(sources_only->spots[0].source, "A");
  EXPECT_EQ(sources_only->spots[0].observation.beam_id, 0);
  EXPECT_EQ(sources_only->num_unassigned(), 1);

  Result<SpotsCsvData> none = ParseSpotsCsv("source,beam,x,y,z\nA,1,1,2,3\n", "s.csv");
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(none->num_unassigned(), 0);
}

TEST(SpotsCsv, APresentBeamMustStillBeAnIdAndSliceNonNegative) {
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,0,1,2,3\n").message(),
            "s.csv:2: field 'beam': beam id must be >= 1, got 0");
  EXPECT_EQ(ParseError("source,beam,x,y,z\n,-3,1,2,3\n").message(),
            "s.csv:2: field 'beam': beam id must be >= 1, got -3");
  EXPECT_EQ(ParseError("source,beam,x,y,z\n,x1,1,2,3\n").message(),
            "s.csv:2: field 'beam': not an integer: 'x1'");
  EXPECT_EQ(ParseError("source,beam,x,y,z,slice\nA,1,1,2,3,-1\n").message(),
            "s.csv:2: field 'slice': slice must be >= 0, got -1");
}

TEST(SpotsCsv, DecimalCommaInAQuotedFieldSaysSo) {
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,\"12,5\",2,3\n").message(),
            "s.csv:2: field 'x': not a number: '12,5' (decimal commas are not supported)");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA,1,\"1,2,5\",2,3\n").message(),
            "s.csv:2: field 'x': not a number: '1,2,5'");
}

TEST(SpotsCsv, UnassignedSpotsRoundTrip) {
  std::vector<Spot> spots(3);
  spots[0].source = "A";
  spots[0].observation.beam_id = 5;
  spots[1].observation.point_in_scene = Eigen::Vector3d(0.1, -2, 3e-7);
  spots[2].source = "B";  // source known, beam not
  Result<std::string> text = FormatSpotsCsv(spots);
  ASSERT_TRUE(text.ok()) << text.status().ToString();
  EXPECT_EQ(*text, "source,beam,x,y,z\nA,5,0,0,0\n\"\",,0.1,-2,3e-07\nB,,0,0,0\n");
  Result<SpotsCsvData> back = ParseSpotsCsv(*text, "t.csv");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->spots.size(), 3u);
  for (size_t i = 0; i < spots.size(); ++i) {
    EXPECT_EQ(back->spots[i].source, spots[i].source);
    EXPECT_EQ(back->spots[i].observation.beam_id, spots[i].observation.beam_id);
    EXPECT_EQ(back->spots[i].observation.point_in_scene, spots[i].observation.point_in_scene);
  }
  EXPECT_EQ(back->num_unassigned(), 2);
  spots[0].observation.beam_id = -1;
  EXPECT_EQ(FormatSpotsCsv(spots).status().message(),
            "spot 0 (source 'A'): beam id must be >= 1 (or 0: unassigned), got -1");
}

TEST(SpotsCsv, GroupSpotsBySourceLeavesUnassignedOut) {
  Result<SpotsCsvData> r =
      ParseSpotsCsv("source,beam,x,y,z\nB,2,1,2,3\n,,4,5,6\nA,1,7,8,9\nA,,1,1,1\nB,3,0,0,1\n",
                    "s.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const auto groups = GroupSpotsBySource(r->spots);
  ASSERT_EQ(groups.size(), 2u);
  ASSERT_EQ(groups.at("A").size(), 1u);
  EXPECT_EQ(groups.at("A")[0].beam_id, 1);
  ASSERT_EQ(groups.at("B").size(), 2u);
  EXPECT_EQ(groups.at("B")[1].point_in_scene, Eigen::Vector3d(0, 0, 1));
}

TEST(SpotsCsv, MalformedQuotes) {
  EXPECT_EQ(ParseError("source,beam,x,y,z\n\"A,1,1,2,3\n").message(),
            "s.csv:2: unterminated quoted field");
  EXPECT_EQ(ParseError("source,beam,x,y,z\n\"A\"x,1,1,2,3\n").message(),
            "s.csv:2: unexpected text after a closing quote");
  EXPECT_EQ(ParseError("source,beam,x,y,z\nA\"B,1,1,2,3\n").message(),
            "s.csv:2: quote inside an unquoted field (quote the whole field)");
}

// Within the coordinate limit of 1e12 (docs/formats.md, Limits).
TEST(SpotsCsv, FormatThenParseIsBitExact) {
  std::vector<Spot> spots(3);
  const double tricky[] = {0.1, 1.0 / 3.0, -2.0 / 7.0, 1e-300, 123456789.123456789,
                           std::nextafter(1.0, 2.0), -0.0, 5e-324, 999999999999.99988};
  int k = 0;
  for (size_t i = 0; i < spots.size(); ++i) {
    spots[i].source = i == 1 ? "with,comma \"q\"" : "A";
    spots[i].observation.beam_id = static_cast<int>(i) + 1;
    for (int c = 0; c < 3; ++c) spots[i].observation.point_in_scene[c] = tricky[k++ % 9];
    spots[i].observation.cov_in_scene =
        Eigen::Vector3d(0.01 * (i + 1), 1e-8, 2.0 / 3.0).asDiagonal().toDenseMatrix();
  }
  Result<std::string> text = FormatSpotsCsv(spots, {{"slice", {"0", "1", "2"}}, {"note", {"a", "b,c", ""}}});
  ASSERT_TRUE(text.ok()) << text.status().ToString();
  EXPECT_EQ(text->substr(0, text->find('\n')), "source,beam,x,y,z,sx,sy,sz,slice,note");
  Result<SpotsCsvData> back = ParseSpotsCsv(*text, "t.csv");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->spots.size(), 3u);
  EXPECT_EQ(back->slices, (std::vector<int>{0, 1, 2}));
  for (size_t i = 0; i < spots.size(); ++i) {
    EXPECT_EQ(back->spots[i].source, spots[i].source);
    EXPECT_EQ(back->spots[i].observation.beam_id, spots[i].observation.beam_id);
    for (int c = 0; c < 3; ++c) {
      const double a = spots[i].observation.point_in_scene[c];
      const double b = back->spots[i].observation.point_in_scene[c];
      EXPECT_EQ(std::signbit(a), std::signbit(b));
      EXPECT_EQ(a, b);
    }
    // sigma = sqrt(var), written exactly; var read back = sigma^2 (within 1 ulp).
    for (int c = 0; c < 3; ++c) {
      EXPECT_DOUBLE_EQ((*back->spots[i].observation.cov_in_scene)(c, c),
                       (*spots[i].observation.cov_in_scene)(c, c));
    }
  }
}

// The module placement (issue 20): written when a spot has one, read back
// (quoted names too); a column of the reader, not one of other_columns.
TEST(SpotsCsv, PlacementColumnRoundTrips) {
  std::vector<Spot> spots(3);
  for (size_t i = 0; i < spots.size(); ++i) {
    spots[i].source = "A";
    spots[i].observation.beam_id = static_cast<int>(i) + 1;
    spots[i].observation.point_in_scene = Eigen::Vector3d(1.0 * i, 2, 3);
  }
  spots[0].placement = "centre";
  spots[1].placement = "aside, high";
  Result<std::string> text = FormatSpotsCsv(spots, {{"note", {"a", "b", "c"}}});
  ASSERT_TRUE(text.ok()) << text.status().ToString();
  EXPECT_EQ(*text,
            "source,beam,x,y,z,placement,note\nA,1,0,2,3,centre,a\nA,2,1,2,3,\"aside, high\",b\nA,3,2,2,3,\"\",c\n");
  Result<SpotsCsvData> back = ParseSpotsCsv(*text, "t.csv");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->spots.size(), 3u);
  EXPECT_EQ(back->spots[0].placement, "centre");
  EXPECT_EQ(back->spots[1].placement, "aside, high");
  EXPECT_EQ(back->spots[2].placement, "");
  EXPECT_EQ(back->other_columns, std::vector<std::string>{"note"});
  // No placement anywhere: no column.
  for (Spot& s : spots) s.placement.clear();
  EXPECT_EQ(FormatSpotsCsv(spots)->substr(0, 18), "source,beam,x,y,z\n");
}

TEST(SpotsCsv, FormatWithoutCovariancesHasNoSigmaColumns) {
  std::vector<Spot> spots(1);
  spots[0].source = "A";
  spots[0].observation.beam_id = 3;
  spots[0].observation.point_in_scene = Eigen::Vector3d(1, 2.5, -3);
  Result<std::string> text = FormatSpotsCsv(spots);
  ASSERT_TRUE(text.ok());
  EXPECT_EQ(*text, "source,beam,x,y,z\nA,3,1,2.5,-3\n");
  spots[0].observation.point_in_scene.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(FormatSpotsCsv(spots).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(FormatSpotsCsv({}, {{"slice", {"1"}}}).status().code(), StatusCode::kInvalidArgument);
}

TEST(SpotsCsv, ReadFileUsesThePathInWhereAndMessages) {
  testing_support::TempDir dir;
  const std::string path = dir.Write("spots.csv", "source,beam,x,y,z\nA,1,1,2,3\nA,2,1,x,3\n");
  Result<SpotsCsvData> r = ReadSpotsCsv(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), path + ":3: field 'y': not a number: 'x'");
  Result<SpotsCsvData> missing = ReadSpotsCsv(dir.File("none.csv"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_THAT(missing.status().message(), HasSubstr("none.csv"));
}

}  // namespace
}  // namespace opl
