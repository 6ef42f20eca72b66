#include "opl/io/point_table.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"

namespace opl {
namespace {

using ::testing::HasSubstr;
using Delimiter = PointTableFormat::Delimiter;

PointTableFormat Format(const std::string& columns, int skip_rows = 0,
                        Delimiter delimiter = Delimiter::kAuto) {
  Result<PointTableFormat> f = ParseColumnMapping(columns);
  EXPECT_TRUE(f.ok()) << f.status().ToString();
  PointTableFormat format = f.ok() ? *f : PointTableFormat();
  format.skip_rows = skip_rows;
  format.delimiter = delimiter;
  return format;
}

Result<SpotsCsvData> Parse(const std::string& text, const PointTableFormat& format) {
  return ParsePointTable(text, "p.txt", format);
}

// The message of a parse that must fail.
std::string Error(const std::string& text, const PointTableFormat& format) {
  Result<SpotsCsvData> r = Parse(text, format);
  EXPECT_FALSE(r.ok());
  return r.ok() ? std::string("(parsed)") : r.status().message();
}

std::string MappingError(const std::string& spec) {
  Result<PointTableFormat> r = ParseColumnMapping(spec);
  EXPECT_FALSE(r.ok());
  if (r.ok()) return "(parsed)";
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  return r.status().message();
}

Eigen::Matrix3d Diag(double a, double b, double c) {
  return Eigen::Vector3d(a * a, b * b, c * c).asDiagonal();
}

// ---------------------------------------------------------------- mapping

TEST(PointTableMapping, ParsesNamesCaseInsensitiveWithSkipAndSpaces) {
  Result<PointTableFormat> f = ParseColumnMapping(" ID , X,y ,Z,skip,sx,SY,sz,-,source,beam,slice");
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  EXPECT_EQ(f->columns, (std::vector<std::string>{"id", "x", "y", "z", "-", "sx", "sy", "sz", "-",
                                                  "source", "beam", "slice"}));
  EXPECT_EQ(f->skip_rows, 0);
  EXPECT_EQ(f->delimiter, Delimiter::kAuto);
  EXPECT_EQ(f->comment, '#');
  EXPECT_FALSE(f->allow_extra_fields);
  EXPECT_TRUE(f->Validate().ok());
}

TEST(PointTableMapping, ErrorsNameTheProblem) {
  EXPECT_EQ(MappingError("id,x,q,y,z"),
            "--columns: unknown column name 'q' (known: id, x, y, z, sx, sy, sz, source, beam, "
            "slice, -)");
  EXPECT_EQ(MappingError("id,x,y,z,X"), "--columns: 'x' given twice");
  EXPECT_EQ(MappingError("id,x,z"), "--columns: missing required 'y'");
  EXPECT_EQ(MappingError("x,y"), "--columns: missing required 'z'");
  EXPECT_EQ(MappingError("y,z,-"), "--columns: missing required 'x'");
  EXPECT_EQ(MappingError("x,y,z,sx,sy"),
            "--columns: sx, sy, sz must be given all three or none (missing sz)");
  EXPECT_EQ(MappingError("x,y,z,sy"),
            "--columns: sx, sy, sz must be given all three or none (missing sx, sz)");
  EXPECT_EQ(MappingError("x,y,,z"), "--columns: column 3 has no name");
  EXPECT_EQ(MappingError("x,y,z,"), "--columns: column 4 has no name");
  EXPECT_EQ(MappingError(""), "--columns: empty (give the columns in file order, e.g. id,x,y,z)");
  EXPECT_EQ(MappingError("  "), "--columns: empty (give the columns in file order, e.g. id,x,y,z)");
  EXPECT_EQ(MappingError("id,x,y,z,id"), "--columns: 'id' given twice");
  EXPECT_EQ(MappingError("source,x,y,z,Source"), "--columns: 'source' given twice");
  // `-` and `skip` may repeat.
  EXPECT_TRUE(ParseColumnMapping("-,x,-,y,skip,z,SKIP").ok());
}

TEST(PointTableMapping, ValidateChecksEverything) {
  PointTableFormat f;
  EXPECT_EQ(f.Validate().message(),
            "--columns: empty (give the columns in file order, e.g. id,x,y,z)");
  f.columns = {"x", "y", "z"};
  EXPECT_TRUE(f.Validate().ok());
  f.columns = {"X", "Y", "skip", "z"};  // hand-made: case and alias accepted
  EXPECT_TRUE(f.Validate().ok());
  f.columns = {"x", "y", "w"};
  EXPECT_EQ(f.Validate().message(),
            "--columns: unknown column name 'w' (known: id, x, y, z, sx, sy, sz, source, beam, "
            "slice, -)");
  f.columns = {"x", "y", "z"};
  f.skip_rows = -1;
  EXPECT_EQ(f.Validate().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(f.Validate().message(), "--skip-rows: must be >= 0, got -1");
  f.skip_rows = 0;
  f.comment = '"';
  EXPECT_EQ(f.Validate().message(),
            "comment character: cannot be a quote, a blank or a line break");
  f.comment = ' ';
  EXPECT_FALSE(f.Validate().ok());
  f.comment = ';';
  f.delimiter = Delimiter::kSemicolon;
  EXPECT_EQ(f.Validate().message(), "comment character: ';' is the delimiter");
  f.delimiter = Delimiter::kComma;
  EXPECT_TRUE(f.Validate().ok());
  f.comment = '\0';
  EXPECT_TRUE(f.Validate().ok());
  // The parser refuses an invalid format with the same message.
  f.skip_rows = -2;
  Result<SpotsCsvData> r = Parse("1,2,3\n", f);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(), "--skip-rows: must be >= 0, got -2");
}

TEST(PointTableMapping, DelimiterNames) {
  const std::pair<const char*, Delimiter> cases[] = {
      {"auto", Delimiter::kAuto},           {"comma", Delimiter::kComma},
      {",", Delimiter::kComma},             {"semicolon", Delimiter::kSemicolon},
      {";", Delimiter::kSemicolon},         {"tab", Delimiter::kTab},
      {"\t", Delimiter::kTab},              {"\\t", Delimiter::kTab},
      {"whitespace", Delimiter::kWhitespace}, {"SPACE", Delimiter::kWhitespace}};
  for (const auto& [name, d] : cases) {
    Result<Delimiter> r = ParseDelimiterName(name);
    ASSERT_TRUE(r.ok()) << name;
    EXPECT_EQ(*r, d) << name;
  }
  for (Delimiter d : {Delimiter::kAuto, Delimiter::kComma, Delimiter::kSemicolon, Delimiter::kTab,
                      Delimiter::kWhitespace}) {
    Result<Delimiter> back = ParseDelimiterName(DelimiterName(d));
    ASSERT_TRUE(back.ok());
    EXPECT_EQ(*back, d);
  }
  EXPECT_EQ(std::string(DelimiterName(Delimiter::kSemicolon)), "semicolon");
  EXPECT_EQ(ParseDelimiterName("pipe").status().message(),
            "--delimiter: unknown delimiter 'pipe' (known: auto, comma, semicolon, tab, "
            "whitespace)");
}

// ---------------------------------------------------------------- layouts

TEST(PointTable, WhitespaceFileWithIdsAndSigmas) {
  const std::string text =
      "# exported by some package\n"
      "P1 1012.50 3.25 -0.50 0.02 0.02 0.03\n"
      "\n"
      "  P2\t\t1013.00   2.75\t-0.25 0.01 0.04 0.05   \r\n"
      "\"Point 3\" 1e3 -2 +4 1 2 3";  // quoted id with a space, no final line break
  Result<SpotsCsvData> r = Parse(text, Format("id,x,y,z,sx,sy,sz"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 3u);
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P1", "P2", "Point 3"}));
  EXPECT_TRUE(r->has_sigmas);
  EXPECT_TRUE(r->slices.empty());
  EXPECT_TRUE(r->other_columns.empty());
  EXPECT_EQ(r->spots[0].observation.point_in_scene, Eigen::Vector3d(1012.5, 3.25, -0.5));
  EXPECT_EQ(*r->spots[0].observation.cov_in_scene, Diag(0.02, 0.02, 0.03));
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(1013.0, 2.75, -0.25));
  EXPECT_EQ(*r->spots[1].observation.cov_in_scene, Diag(0.01, 0.04, 0.05));
  EXPECT_EQ(r->spots[2].observation.point_in_scene, Eigen::Vector3d(1000.0, -2.0, 4.0));
  EXPECT_EQ(r->spots[0].where, "p.txt:2");
  EXPECT_EQ(r->spots[1].where, "p.txt:4");
  EXPECT_EQ(r->spots[2].where, "p.txt:5");
  // No source or beam column: every spot is unassigned.
  EXPECT_EQ(r->num_unassigned(), 3);
  for (const Spot& s : r->spots) {
    EXPECT_EQ(s.source, "");
    EXPECT_EQ(s.observation.beam_id, 0);
    EXPECT_FALSE(s.assigned());
  }
}

TEST(PointTable, CommaCsvWithHeaderRowSkipped) {
  const std::string text =
      "\xEF\xBB\xBF" "Name,X [mm],Y [mm],Z [mm],Flags\r\n"
      "T1,102.5,33.0,-4.25,ok\r\n"
      "\"T,2\", 7 ,8,9,\"a \"\"b\"\"\"\r\n"
      ",1,2,3,\r\n";  // empty id and empty ignored field
  Result<SpotsCsvData> r = Parse(text, Format("id,x,y,z,-", 1));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 3u);
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"T1", "T,2", ""}));
  EXPECT_FALSE(r->has_sigmas);
  EXPECT_FALSE(r->spots[0].observation.cov_in_scene.has_value());
  EXPECT_EQ(r->spots[0].observation.point_in_scene, Eigen::Vector3d(102.5, 33.0, -4.25));
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(7, 8, 9));
  EXPECT_EQ(r->spots[2].where, "p.txt:4");
  // Without skipping the header its "X [mm]" is not a number.
  EXPECT_EQ(Error(text, Format("id,x,y,z,-")), "p.txt:1: field 'x': not a number: 'X [mm]'");
}

TEST(PointTable, SemicolonFileAndDecimalCommas) {
  const std::string text = "id;x;y;z\nA1;1.5;-2.25;3\n\"A;2\";4;5;6e1\n";
  EXPECT_EQ(Error(text, Format("id,x,y,z")), "p.txt:1: field 'x': not a number: 'x'");
  Result<SpotsCsvData> r = Parse(text, Format("id,x,y,z", 1));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 2u);
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"A1", "A;2"}));
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(4, 5, 60));

  // A European export: semicolons and decimal commas. Auto-detection picks the
  // semicolon (the line has both), and the number error says what is wrong.
  const std::string european = "P1;12,5;3,25;-0,5\n";
  EXPECT_EQ(Error(european, Format("id,x,y,z")),
            "p.txt:1: field 'x': not a number: '12,5' (decimal commas are not supported)");
  EXPECT_EQ(Error(european, Format("id,x,y,z", 0, Delimiter::kSemicolon)),
            "p.txt:1: field 'x': not a number: '12,5' (decimal commas are not supported)");
  EXPECT_EQ(Error("P1;12.5;3,25;-0.5\n", Format("id,x,y,z")),
            "p.txt:1: field 'y': not a number: '3,25' (decimal commas are not supported)");
  // The same in a whitespace or tab file.
  EXPECT_EQ(Error("P1 12,5 3 4\n", Format("id,x,y,z", 0, Delimiter::kWhitespace)),
            "p.txt:1: field 'x': not a number: '12,5' (decimal commas are not supported)");
  // Not every comma is a decimal comma.
  EXPECT_EQ(Error("P1;1,2,5;3;4\n", Format("id,x,y,z")),
            "p.txt:1: field 'x': not a number: '1,2,5'");
  EXPECT_EQ(Error("P1;a,b;3;4\n", Format("id,x,y,z")), "p.txt:1: field 'x': not a number: 'a,b'");
}

TEST(PointTable, TabFileKeepsEmptyFields) {
  const std::string text =
      "A\t61\t1.5\t2.5\t3.5\n"
      "\t\t4\t5\t6\n"                   // unassigned: empty source and beam
      "B\t\t 7 \t8\t9\n"                // spaces around a tab-separated field are trimmed
      "\"C\tD\"\t3\t10\t11\t12\r\n";    // a quoted tab
  Result<SpotsCsvData> r = Parse(text, Format("source,beam,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 4u);
  EXPECT_EQ(r->spots[0].source, "A");
  EXPECT_EQ(r->spots[0].observation.beam_id, 61);
  EXPECT_TRUE(r->spots[0].assigned());
  EXPECT_EQ(r->spots[1].source, "");
  EXPECT_EQ(r->spots[1].observation.beam_id, 0);
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(4, 5, 6));
  EXPECT_FALSE(r->spots[1].assigned());
  EXPECT_EQ(r->spots[2].source, "B");
  EXPECT_EQ(r->spots[2].observation.beam_id, 0);
  EXPECT_EQ(r->spots[2].observation.point_in_scene, Eigen::Vector3d(7, 8, 9));
  EXPECT_EQ(r->spots[3].source, "C\tD");
  EXPECT_EQ(r->spots[3].observation.beam_id, 3);
  EXPECT_EQ(r->num_unassigned(), 2);
  EXPECT_TRUE(r->point_ids.empty());
  // An empty x in a tab file is an empty value, not a shifted column.
  EXPECT_EQ(Error("A\t1\t\t2\t3\n", Format("source,beam,x,y,z")),
            "p.txt:1: field 'x': empty value");
}

TEST(PointTable, AutoDelimiterFromTheFirstDataLine) {
  // Comma (a semicolon inside quotes does not count).
  Result<SpotsCsvData> r = Parse("# a;b\n\n\"P;1\",1,2,3\n\"Q\",4,5,6\n", Format("id,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P;1", "Q"}));
  // Semicolon (a comma inside quotes does not count).
  r = Parse("\"P,1\";1;2;3\n", Format("id,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids[0], "P,1");
  // Tab, even with spaces around the fields.
  r = Parse("P 1\t1\t2 \t 3\n", Format("id,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids[0], "P 1");
  EXPECT_EQ(r->spots[0].observation.point_in_scene, Eigen::Vector3d(1, 2, 3));
  // Whitespace.
  r = Parse("P1 1 2 3\n", Format("id,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->spots[0].observation.point_in_scene, Eigen::Vector3d(1, 2, 3));
  // Decided on the first data line after the skipped rows, blank and comment
  // lines: the skipped header has commas, the data is whitespace-separated.
  r = Parse("id,x,y,z\n# note, with commas\n\n P1  1  2  3\nP2 4 5 6\n", Format("id,x,y,z", 1));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 2u);
  EXPECT_EQ(r->spots[0].where, "p.txt:4");
  // The message names the detected delimiter and the line it came from.
  EXPECT_EQ(Error("\nP1 1 2 3\nP2 4 5\n", Format("id,x,y,z")),
            "p.txt:3: expected 4 fields (columns id,x,y,z; delimiter whitespace detected from "
            "line 2), found 3");
  EXPECT_EQ(Error("P1,1,2,3\nP2;4;5;6\n", Format("id,x,y,z")),
            "p.txt:2: expected 4 fields (columns id,x,y,z; delimiter ',' detected from line 1), "
            "found 1");
  // An explicit delimiter is used as given.
  EXPECT_EQ(Error("P1,1,2,3\n", Format("id,x,y,z", 0, Delimiter::kWhitespace)),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter whitespace), found 1");
  EXPECT_EQ(Error("P1 1 2 3\n", Format("id,x,y,z", 0, Delimiter::kTab)),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter tab), found 1");
  EXPECT_EQ(Error("P1;1;2;3\n", Format("id,x,y,z", 0, Delimiter::kComma)),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter ','), found 1");
  EXPECT_EQ(Error("P1,1,2,3\n", Format("id,x,y,z", 0, Delimiter::kSemicolon)),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter ';'), found 1");
}

TEST(PointTable, SkipRowsCommentsAndBlankLines) {
  // skip_rows counts physical lines, blank ones included; comment lines are
  // skipped anywhere; line numbers stay those of the file.
  const std::string text =
      "Report of 2026-11-22\n"
      "\n"
      "P1 1 2 3\n"
      "   # indented comment\n"
      "P2 4 5 6\n"
      "#P3 7 8 9\n"
      "P4 10 11 12\n";
  Result<SpotsCsvData> r = Parse(text, Format("id,x,y,z", 2));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P1", "P2", "P4"}));
  EXPECT_EQ(r->spots[2].where, "p.txt:7");
  // Skipping 3 lines also drops P1.
  r = Parse(text, Format("id,x,y,z", 3));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P2", "P4"}));
  // Skipping 1 leaves the blank line (skipped) and then P1.
  EXPECT_TRUE(Parse(text, Format("id,x,y,z", 1)).ok());
  // Skipping none: the banner is a data line.
  EXPECT_EQ(Error(text, Format("id,x,y,z")),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter whitespace detected from "
            "line 1), found 3");
  // Another comment character, or none.
  PointTableFormat f = Format("id,x,y,z", 2);
  f.comment = '%';
  EXPECT_EQ(Error(text, f), "p.txt:4: expected 4 fields (columns id,x,y,z; delimiter whitespace "
                            "detected from line 3), found 3");
  f = Format("id,x,y,z");
  f.comment = '%';
  r = Parse("% comment\nP1 1 2 3\n", f);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->spots.size(), 1u);
  f.comment = '\0';
  EXPECT_EQ(Error("% comment\nP1 1 2 3\n", f),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter whitespace detected from "
            "line 1), found 2");
  r = Parse("#1 1 2 3\n", f);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"#1"}));
  // A comment character inside a line is data, not a comment.
  EXPECT_EQ(Error("P1 1 2 3 # note\n", Format("id,x,y,z")),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter whitespace detected from "
            "line 1), found 6 (extra trailing fields are refused unless allowed)");
}

TEST(PointTable, NoDataLines) {
  EXPECT_EQ(Error("", Format("x,y,z")), "p.txt: no data lines");
  EXPECT_EQ(Error("\xEF\xBB\xBF\n  \r\n# only a comment\n", Format("x,y,z")),
            "p.txt: no data lines");
  EXPECT_EQ(Error("x y z\n", Format("x,y,z", 1)), "p.txt: no data lines after skipping 1 row");
  EXPECT_EQ(Error("1 2 3\n4 5 6\n", Format("x,y,z", 5)),
            "p.txt: no data lines after skipping 5 rows");
  Result<SpotsCsvData> r = Parse("1 2 3\n4 5 6\n", Format("x,y,z", 1));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->spots.size(), 1u);
  EXPECT_EQ(r->spots[0].where, "p.txt:2");
}

TEST(PointTable, FieldCountsAndExtraTrailingFields) {
  const PointTableFormat f = Format("id,x,y,z");
  EXPECT_EQ(Error("P1 1 2 3\nP2 1 2\n", f),
            "p.txt:2: expected 4 fields (columns id,x,y,z; delimiter whitespace detected from "
            "line 1), found 3");
  EXPECT_EQ(Error("P1,1,2,3,\n", f),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter ',' detected from line 1), "
            "found 5 (extra trailing fields are refused unless allowed)");
  PointTableFormat extra = f;
  extra.allow_extra_fields = true;
  Result<SpotsCsvData> r = Parse("P1 1 2 3 0.1 0.2 flag\nP2 4 5 6\n", extra);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 2u);
  EXPECT_EQ(r->spots[0].observation.point_in_scene, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(r->spots[1].observation.point_in_scene, Eigen::Vector3d(4, 5, 6));
  // Fewer fields are an error even then.
  EXPECT_EQ(Error("P1 1 2\n", extra),
            "p.txt:1: expected 4 fields (columns id,x,y,z; delimiter whitespace detected from "
            "line 1), found 3");
}

TEST(PointTable, SkippedColumnsAreNotRead) {
  Result<SpotsCsvData> r =
      Parse("17 P1 abc 1.25 2.5 3.75 zz\n", Format("-,id,skip,x,y,z,-"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P1"}));
  EXPECT_EQ(r->spots[0].observation.point_in_scene, Eigen::Vector3d(1.25, 2.5, 3.75));
}

TEST(PointTable, SourceBeamAndSliceColumns) {
  const std::string text =
      "A 61 0 1 2 3\n"
      "B 7 2 4 5 6\n"
      "\"\" \"\" 1 7 8 9\n";  // quoted empty source and beam: unassigned
  Result<SpotsCsvData> r = Parse(text, Format("source,beam,slice,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), 3u);
  EXPECT_EQ(r->slices, (std::vector<int>{0, 2, 1}));
  EXPECT_EQ(r->spots[0].source, "A");
  EXPECT_EQ(r->spots[0].observation.beam_id, 61);
  EXPECT_EQ(r->spots[1].source, "B");
  EXPECT_EQ(r->spots[1].observation.beam_id, 7);
  EXPECT_TRUE(r->spots[1].assigned());
  EXPECT_FALSE(r->spots[2].assigned());
  EXPECT_EQ(r->spots[2].observation.beam_id, 0);
  EXPECT_EQ(r->num_unassigned(), 1);
  const PointTableFormat f = Format("source,beam,slice,x,y,z");
  EXPECT_EQ(Error("A 0 0 1 2 3\n", f), "p.txt:1: field 'beam': beam id must be >= 1, got 0");
  EXPECT_EQ(Error("A -2 0 1 2 3\n", f), "p.txt:1: field 'beam': beam id must be >= 1, got -2");
  EXPECT_EQ(Error("A 6.0 0 1 2 3\n", f), "p.txt:1: field 'beam': not an integer: '6.0'");
  EXPECT_EQ(Error("A 6 -1 1 2 3\n", f), "p.txt:1: field 'slice': slice must be >= 0, got -1");
  EXPECT_EQ(Error("A 6 s 1 2 3\n", f), "p.txt:1: field 'slice': not an integer: 's'");
  EXPECT_EQ(Error("A,6,,1,2,3\n", f), "p.txt:1: field 'slice': empty value");
}

// ---------------------------------------------------------------- numbers and errors

TEST(PointTable, NumberErrorsNameFileLineAndField) {
  const PointTableFormat f = Format("id,x,y,z,sx,sy,sz");
  EXPECT_EQ(Error("P1 1 2 3 1 1 1\n\nP2 abc 2 3 1 1 1\n", f),
            "p.txt:3: field 'x': not a number: 'abc'");
  EXPECT_EQ(Error("P1 1 2mm 3 1 1 1\n", f), "p.txt:1: field 'y': not a number: '2mm'");
  EXPECT_EQ(Error("P1 1 2 nan 1 1 1\n", f), "p.txt:1: field 'z': not finite: 'nan'");
  EXPECT_EQ(Error("P1 -inf 2 3 1 1 1\n", f), "p.txt:1: field 'x': not finite: '-inf'");
  EXPECT_EQ(Error("P1 1 2 1e999 1 1 1\n", f), "p.txt:1: field 'z': out of range: '1e999'");
  EXPECT_EQ(Error("P1 1 2 3 0.1 0 0.1\n", f),
            "p.txt:1: field 'sy': standard deviation must be > 0, got 0");
  EXPECT_EQ(Error("P1 1 2 3 -0.1 1 1\n", f),
            "p.txt:1: field 'sx': standard deviation must be > 0, got -0.1");
  EXPECT_EQ(Error("P1 1 2 3 1 1 inf\n", f), "p.txt:1: field 'sz': not finite: 'inf'");
  EXPECT_EQ(Error("P1,1,,3,1,1,1\n", f), "p.txt:1: field 'y': empty value");
  EXPECT_EQ(Error("P1 1 2 \"\" 1 1 1\n", f), "p.txt:1: field 'z': empty value");
}

TEST(PointTable, MalformedQuotes) {
  const PointTableFormat f = Format("id,x,y,z");
  EXPECT_EQ(Error("P1 1 2 3\n\"P2 4 5 6\n", f), "p.txt:2: unterminated quoted field");
  EXPECT_EQ(Error("\"P1\"x 1 2 3\n", f), "p.txt:1: unexpected text after a closing quote");
  EXPECT_EQ(Error("P\"1 1 2 3\n", f),
            "p.txt:1: quote inside an unquoted field (quote the whole field)");
  EXPECT_EQ(Error("\"P1\"x;1;2;3\n", f), "p.txt:1: unexpected text after a closing quote");
  // A quoted field may hold a line break; the next record's line counts it.
  Result<SpotsCsvData> r = Parse("\"P\n1\",1,2,3\nP2,4,5,6\n", f);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P\n1", "P2"}));
  EXPECT_EQ(r->spots[0].where, "p.txt:1");
  EXPECT_EQ(r->spots[1].where, "p.txt:3");
}

// Within the coordinate limit of 1e12 (docs/formats.md, Limits).
TEST(PointTable, NumbersReadExactlyAsWritten) {
  const std::vector<std::string> texts = {
      "1012.5", "1012.50", "0.1", "-0.0", "3.25", "-0.5", "1e-300", "123456789.123456789",
      "2.2250738585072014e-308", "4.9e-324", "999999999999.99988", "+4", "0.30000000000000004",
      "3.141592653589793238462643383279", "-1013.0000000000001", "6.02214076e11", "1E3", ".5",
      "5."};
  std::string table;
  for (size_t i = 0; i < texts.size(); ++i) {
    table += "P" + std::to_string(i) + " " + texts[i] + " " + texts[i] + " " + texts[i] + "\n";
  }
  Result<SpotsCsvData> r = Parse(table, Format("id,x,y,z"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->spots.size(), texts.size());
  for (size_t i = 0; i < texts.size(); ++i) {
    const double expected = std::strtod(texts[i].c_str(), nullptr);
    for (int k = 0; k < 3; ++k) {
      const double got = r->spots[i].observation.point_in_scene[k];
      EXPECT_EQ(std::memcmp(&got, &expected, sizeof(double)), 0)
          << texts[i] << " read as " << got << ", strtod gives " << expected;
    }
  }
  EXPECT_EQ(r->spots[0].observation.point_in_scene.x(), 1012.5);
  EXPECT_TRUE(std::signbit(r->spots[3].observation.point_in_scene.x()));
}

TEST(PointTable, ReadFileUsesThePath) {
  testing_support::TempDir dir;
  const std::string path = dir.Write(
      "export.csv", "Name,X,Y,Z,SX,SY,SZ\nP1,1012.50,3.25,-0.50,0.02,0.02,0.03\nP2,1,2,x,1,1,1\n");
  PointTableFormat f = Format("id,x,y,z,sx,sy,sz", 1);
  Result<SpotsCsvData> r = ReadPointTable(path, f);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kParseError);
  EXPECT_EQ(r.status().message(), path + ":3: field 'z': not a number: 'x'");
  const std::string good = dir.Write("good.txt", "P1 1012.50 3.25 -0.50 0.02 0.02 0.03\n");
  r = ReadPointTable(good, f = Format("id,x,y,z,sx,sy,sz"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->spots[0].where, good + ":1");
  EXPECT_EQ(r->point_ids, (std::vector<std::string>{"P1"}));
  Result<SpotsCsvData> missing = ReadPointTable(dir.File("none.txt"), f);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_THAT(missing.status().message(), HasSubstr("none.txt"));
  // An invalid format is reported before the file is read.
  f.columns = {"x", "y"};
  EXPECT_EQ(ReadPointTable(dir.File("none.txt"), f).status().message(),
            "--columns: missing required 'z'");
}

}  // namespace
}  // namespace opl
