// ScalePointFile (opl/io/scale_point_file.h) on XYZ and points CSV files, the
// format choice, and the streamed CSV against the whole-file PointsCsv.
#include "opl/io/scale_point_file.h"

#include <charconv>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "opl/io/points_csv.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;

std::string Shortest(double v) {
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof(buffer), v).ptr);
}

Status Scale(const std::string& in, const std::string& out, double s,
             PointFileFormat format = PointFileFormat::kAuto, int64_t buffer = int64_t{4} << 20,
             ScalePointFileSummary* summary = nullptr) {
  ScalePointFileOptions options;
  options.format = format;
  options.buffer_bytes = buffer;
  return ScalePointFile(in, out, s, options, summary);
}

TEST(ScaleXyz, ScalesTheFirstThreeFieldsAndKeepsTheRestOfEveryLine) {
  TempDir dir;
  const std::string in = dir.Write("in.xyz",
                                   "# exported by a scanner, units unknown\n"
                                   "1.5 -2.25 1000 255 0 0 extra text\n"
                                   "\n"
                                   "  0.1\t0.2   0.3\r\n"
                                   "   # indented comment 1 2 3\n"
                                   "+4 5e-1 -0 0.5 0.5 0.5\n"
                                   "7 8 9");  // no line break at the end
  ScalePointFileSummary summary;
  ASSERT_TRUE(Scale(in, dir.File("out.xyz"), 2.0, PointFileFormat::kAuto, 4 << 20, &summary).ok());
  EXPECT_EQ(summary.num_points, 4);
  EXPECT_EQ(summary.format, PointFileFormat::kXyz);
  EXPECT_EQ(ReadAll(dir.File("out.xyz")),
            "# exported by a scanner, units unknown\n"
            "3 -4.5 2000 255 0 0 extra text\n"
            "\n"
            "  0.2\t0.4   0.6\r\n"
            "   # indented comment 1 2 3\n"
            "8 1 -0 0.5 0.5 0.5\n"
            "14 16 18");
  // Exactly s * x in double, shortest text.
  const double s = 1.0 / 3.0;
  ASSERT_TRUE(Scale(in, dir.File("third.txt"), s).ok());
  const std::string out = ReadAll(dir.File("third.txt"));
  EXPECT_NE(out.find("\n" + Shortest(s * 1.5) + " " + Shortest(s * -2.25) + " " +
                     Shortest(s * 1000.0) + " 255 0 0 extra text\n"),
            std::string::npos)
      << out;
  EXPECT_EQ(Shortest(s * 0.1), "0.03333333333333333");
}

TEST(ScaleXyz, LinesAcrossBufferBoundaries) {
  std::string text, expected;
  for (int i = 0; i < 2000; ++i) {
    const double x = 0.25 * i, y = -1.0 * i, z = 1e-3 * i;
    if (i % 3 == 0) {  // comment lines are copied
      text += "# c " + std::to_string(i) + "\n";
      expected += "# c " + std::to_string(i) + "\n";
    }
    text += Shortest(x) + " " + Shortest(y) + "\t" + Shortest(z) + " id" + std::to_string(i) + "\n";
    expected += Shortest(3.0 * x) + " " + Shortest(3.0 * y) + "\t" + Shortest(3.0 * z) + " id" +
                std::to_string(i) + "\n";
  }
  TempDir dir;
  const std::string in = dir.Write("in.xyz", text);
  ASSERT_TRUE(Scale(in, dir.File("out.xyz"), 3.0, PointFileFormat::kAuto, 4096).ok());
  EXPECT_EQ(ReadAll(dir.File("out.xyz")), expected);
}

class XyzErrors : public ::testing::Test {
 protected:
  std::string Refused(const std::string& contents) {
    const std::string in = dir_.Write("in.xyz", contents);
    Status st = Scale(in, dir_.File("out.xyz"), 2.0);
    EXPECT_FALSE(st.ok());
    EXPECT_EQ(dir_.Entries(), std::vector<std::string>{"in.xyz"});
    return st.message().substr(st.message().find(':') + 1);
  }
  TempDir dir_;
};

TEST_F(XyzErrors, NamesLineAndField) {
  EXPECT_EQ(Refused("1 2 3\n4 5\n"),
            "2: expected x y z (3 fields separated by spaces or tabs), found 2");
  EXPECT_EQ(Refused("1,2,3\n"),
            "1: expected x y z (3 fields separated by spaces or tabs), found 1 (a CSV file? give "
            "--format csv)");
  EXPECT_EQ(Refused("1 2 3\n# ok\n1 2 abc 4\n"), "3: field 'z': not a number: 'abc'");
  EXPECT_EQ(Refused("1 nan 3\n"), "1: field 'y': not finite: 'nan'");
  EXPECT_EQ(Refused("X Y Z\n1 2 3\n"), "1: field 'x': not a number: 'X'");
  EXPECT_EQ(Refused("1 2 1e300\n"),
            "1: field 'z': beyond the limit of |value| <= 1e12 scene units, got 1e300");
}

// The streamed CSV gives exactly what PointsCsv::Parse + Scale + Format gives.
std::string WholeFile(const std::string& text, double s) {
  Result<PointsCsv> table = PointsCsv::Parse(text, "p.csv");
  EXPECT_TRUE(table.ok()) << table.status().message();
  if (!table.ok()) return "";
  EXPECT_TRUE(table->Scale(s).ok());
  return table->Format();
}

TEST(ScaleCsv, SameOutputAsThePointsCsvReader) {
  const std::vector<std::string> inputs = {
      "id, \"Z\" ,x,note,y\n"
      "T1,0.3,0.1,\"a, \"\"quoted\"\" note\",0.2\n"
      "\n"
      "  T2  ,-1e-3,10,,7\r\n",
      "\xEF\xBB\xBFx,y,z\r\n1,2,3\r\n \t \r\n4,5,6",
      "name,x,y,z,memo\nA,\"1.5\",+2, 3 ,\"two\nlines\"\nB,1,2,3,\"\"\"\"\n",
      "x,y,z\n",
      "x,y,z,sx,sy,sz\n3,6,9,0.1,0.1,0.1\n",
  };
  TempDir dir;
  for (const std::string& text : inputs) {
    const std::string in = dir.Write("in.csv", text);
    ASSERT_TRUE(Scale(in, dir.File("out.csv"), 1.0 / 3.0).ok()) << text;
    EXPECT_EQ(ReadAll(dir.File("out.csv")), WholeFile(text, 1.0 / 3.0)) << text;
  }
  // Sigmas are not coordinates: copied verbatim, as PointsCsv does.
  const double s = 1.0 / 3.0;
  EXPECT_EQ(ReadAll(dir.File("out.csv")), "x,y,z,sx,sy,sz\n" + Shortest(s * 3.0) + "," +
                                              Shortest(s * 6.0) + "," + Shortest(s * 9.0) +
                                              ",0.1,0.1,0.1\n");
}

TEST(ScaleCsv, RecordsAcrossBufferBoundaries) {
  std::string text = "id,x,y,z,note\n";
  for (int i = 0; i < 3000; ++i) {
    text += "p" + std::to_string(i) + "," + Shortest(0.1 * i) + "," + Shortest(-0.7 * i) + "," +
            Shortest(1e-4 * i) + "," +
            (i % 5 == 0 ? "\"multi\nline, \"\"" + std::to_string(i) + "\"\"\"" : "n") +
            (i % 7 == 0 ? "\r\n" : "\n") + (i % 11 == 0 ? "\n  \n" : "");
  }
  TempDir dir;
  const std::string in = dir.Write("in.csv", text);
  ScalePointFileSummary summary;
  ASSERT_TRUE(Scale(in, dir.File("out.csv"), 1.0 / 3.0, PointFileFormat::kAuto, 4096, &summary).ok());
  EXPECT_EQ(summary.num_points, 3000);
  EXPECT_EQ(ReadAll(dir.File("out.csv")), WholeFile(text, 1.0 / 3.0));
}

TEST(ScaleCsv, SameMessagesAsThePointsCsvReader) {
  const std::vector<std::string> bad = {
      "x,y\n1,2\n",
      "x,y,z\n1,2,3\n1,2,inf\n",
      "x,y,z\n1,2\n",
      "",
      "x,,z\n",
      "x,y,z,X\n",
      "x,y,z\n1,\"2\" 3,4\n",
      "x,y,z\n1,2\"3,4\n",
      "x,y,z\n1,2,\"3\n",
      "x,y,z\n1,2,12,5\n",
      "a,x,y,z\n\"a\nb\",1,2,1e13\n",
  };
  TempDir dir;
  for (const std::string& text : bad) {
    const std::string in = dir.Write("p.csv", text);
    Status st = Scale(in, dir.File("out.csv"), 2.0, PointFileFormat::kAuto, 4096);
    Result<PointsCsv> whole = PointsCsv::Parse(text, in);
    ASSERT_FALSE(whole.ok()) << text;
    EXPECT_EQ(st.message(), whole.status().message()) << text;
    EXPECT_EQ(dir.Entries(), std::vector<std::string>{"p.csv"});
  }
}

TEST(ScalePointFile, FormatFromExtensionOrOption) {
  EXPECT_EQ(*PointFileFormatFromPath("a/b.PLY"), PointFileFormat::kPly);
  EXPECT_EQ(*PointFileFormatFromPath("scan.txt"), PointFileFormat::kXyz);
  EXPECT_EQ(*PointFileFormatFromPath("d.x/scan.xyz"), PointFileFormat::kXyz);
  EXPECT_EQ(*PointFileFormatFromPath("p.csv"), PointFileFormat::kCsv);
  EXPECT_EQ(PointFileFormatFromPath("scan.pts").status().message(),
            "scan.pts: cannot tell the point file format from the extension '.pts' (.ply, .xyz, "
            ".txt or .csv; or give the format)");
  EXPECT_EQ(PointFileFormatFromPath("d.x/scan").status().message(),
            "d.x/scan: cannot tell the point file format from the name (no extension) (.ply, "
            ".xyz, .txt or .csv; or give the format)");
  EXPECT_EQ(ParsePointFileFormat("las").status().message(),
            "unknown point file format 'las' (auto, ply, xyz or csv)");

  TempDir dir;
  const std::string in = dir.Write("scan.pts", "1 2 3\n");
  Status st = Scale(in, dir.File("out.pts"), 2.0);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(Scale(in, dir.File("out.pts"), 2.0, PointFileFormat::kXyz).ok());
  EXPECT_EQ(ReadAll(dir.File("out.pts")), "2 4 6\n");
  // A CSV read as XYZ is refused with a hint, not misread.
  EXPECT_FALSE(Scale(dir.Write("p.txt", "x,y,z\n1,2,3\n"), dir.File("o.txt"), 2.0).ok());
}

TEST(ScalePointFile, RefusesBadArgumentsAndMissingFilesWritingNothing) {
  TempDir dir;
  const std::string in = dir.Write("in.xyz", "1 2 3\n");
  EXPECT_EQ(Scale(in, dir.File("o.xyz"), 0.0).message(), "scale factor must be finite and > 0, got 0");
  EXPECT_EQ(Scale(in, dir.File("o.xyz"), 2.0, PointFileFormat::kAuto, 100).message(),
            "ScalePointFileOptions::buffer_bytes must be in [4096, 2^30], got 100");
  ScalePointFileSummary summary;
  Status st = Scale(dir.File("none.xyz"), dir.File("o.xyz"), 2.0, PointFileFormat::kAuto, 4 << 20,
                    &summary);
  EXPECT_EQ(st.message(), dir.File("none.xyz") + ": cannot open: No such file or directory");
  EXPECT_FALSE(summary.output_failed);
  EXPECT_EQ(Scale("/dev/zero", dir.File("o.xyz"), 2.0, PointFileFormat::kXyz).message(),
            "/dev/zero: cannot read: not a regular file (a device, FIFO or socket)");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"in.xyz"});
  // An output that cannot be written is an output failure (exit 5 in the tools).
  st = Scale(in, dir.File("no/such/dir/o.xyz"), 2.0, PointFileFormat::kAuto, 4 << 20, &summary);
  EXPECT_FALSE(st.ok());
  EXPECT_TRUE(summary.output_failed);
  EXPECT_THAT(st.message(), ::testing::HasSubstr("cannot write: cannot create a temporary file"));
  // A line longer than the buffer.
  dir.Write("long.xyz", "1 2 3 " + std::string(5000, 'a') + "\n");
  EXPECT_EQ(Scale(dir.File("long.xyz"), dir.File("o.xyz"), 2.0, PointFileFormat::kAuto, 4096)
                .message(),
            dir.File("long.xyz") + ":1: line longer than 4096 bytes");
  // A bad input leaves an existing output as it was.
  dir.Write("o.xyz", "old");
  dir.Write("bad.xyz", "1 2 3\n1 2\n");
  EXPECT_FALSE(Scale(dir.File("bad.xyz"), dir.File("o.xyz"), 2.0).ok());
  EXPECT_EQ(ReadAll(dir.File("o.xyz")), "old");
}

TEST(ScalePointFile, CheckReadsOnlyTheHeader) {
  TempDir dir;
  ScalePointFileOptions options;
  EXPECT_TRUE(CheckPointFile(dir.Write("a.csv", "x,y,z\n1,2,bad\n"), options).ok());
  EXPECT_EQ(CheckPointFile(dir.Write("b.csv", "x,y\n"), options).message(),
            dir.File("b.csv") + ":1: missing column 'z' (a points CSV needs x, y and z columns)");
  EXPECT_EQ(CheckPointFile(dir.Write("c.ply", "ply\nformat ascii 1.0\nend_header\n"), options)
                .message(),
            dir.File("c.ply") + ": no element 'vertex' (nothing to scale)");
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"a.csv", "b.csv", "c.ply"}));
}

}  // namespace
}  // namespace opl
