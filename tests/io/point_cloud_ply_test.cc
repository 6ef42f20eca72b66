// PLY scaling (opl/io/point_cloud_ply.h, opl/io/scale_point_file.h) against
// files written byte by byte here: every value of the output is compared with
// bytes built independently from the known scaled values.
#include "opl/io/point_cloud_ply.h"

#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "opl/io/scale_point_file.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;
using ::testing::HasSubstr;

// Appends `v` in little or big endian byte order.
template <typename T>
void Put(std::string* out, T v, bool big_endian) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &v, sizeof(T));
  if (big_endian) std::reverse(bytes, bytes + sizeof(T));
  out->append(bytes, sizeof(T));
}

// A binary PLY with face before vertex, a double y, a normal, a colour, a list
// in the vertex and a face list. `x0` etc. are the coordinates written.
struct BinaryPly {
  std::string header, faces, body_before_vertex;
  std::string file;
};

std::string Header(const std::string& format) {
  return "ply\n"
         "format " + format + " 1.0\n"
         "comment made by hand\n"
         "obj_info scanner 7\n"
         "element face 1\n"
         "property list uchar int vertex_indices\n"
         "element vertex 2\n"
         "property float x\n"
         "property double y\n"
         "property float nx\n"
         "property float z\n"
         "property uchar red\n"
         "property list uchar short tags\n"
         "end_header\n";
}

std::string Faces(bool be) {
  std::string f;
  Put<uint8_t>(&f, 3, be);
  for (int32_t i : {0, 1, 1}) Put<int32_t>(&f, i, be);
  return f;
}

// The two vertices with the given coordinates.
std::string Vertices(bool be, float x0, double y0, float z0, float x1, double y1, float z1) {
  std::string v;
  Put<float>(&v, x0, be);
  Put<double>(&v, y0, be);
  Put<float>(&v, 0.6f, be);  // nx: a direction, never scaled
  Put<float>(&v, z0, be);
  Put<uint8_t>(&v, 200, be);
  Put<uint8_t>(&v, 2, be);
  Put<int16_t>(&v, 7, be);
  Put<int16_t>(&v, -8, be);
  Put<float>(&v, x1, be);
  Put<double>(&v, y1, be);
  Put<float>(&v, -0.8f, be);
  Put<float>(&v, z1, be);
  Put<uint8_t>(&v, 17, be);
  Put<uint8_t>(&v, 0, be);
  return v;
}

std::string WithComment(const std::string& header, const std::string& s_text) {
  const size_t at = header.find("element ");
  return header.substr(0, at) + "comment OPL scaled vertex x, y, z by s = " + s_text + "\n" +
         header.substr(at);
}

Status Scale(const std::string& in, const std::string& out, double s,
             ScalePointFileSummary* summary = nullptr, int64_t buffer = int64_t{4} << 20) {
  ScalePointFileOptions options;
  options.buffer_bytes = buffer;
  return ScalePointFile(in, out, s, options, summary);
}

class PlyScale : public ::testing::TestWithParam<bool> {};  // big endian?

TEST_P(PlyScale, BinaryScalesXyzOnlyAndKeepsEveryOtherByte) {
  const bool be = GetParam();
  const std::string header = Header(be ? "binary_big_endian" : "binary_little_endian");
  TempDir dir;
  const std::string in = dir.Write(
      "in.ply", header + Faces(be) + Vertices(be, 1.5f, -2.25, 0.3f, 3.0f, 1e-3, -4.0f));
  ScalePointFileSummary summary;
  ASSERT_TRUE(Scale(in, dir.File("out.ply"), 2.0, &summary).ok());
  EXPECT_EQ(summary.num_points, 2);
  EXPECT_EQ(summary.format, PointFileFormat::kPly);
  // s = 2 is exact in float and double: every coordinate doubles, nothing else moves.
  const std::string expected =
      WithComment(header, "2") + Faces(be) + Vertices(be, 3.0f, -4.5, 0.6f, 6.0f, 2e-3, -8.0f);
  EXPECT_EQ(ReadAll(dir.File("out.ply")), expected);
  EXPECT_EQ(summary.bytes_written, static_cast<int64_t>(expected.size()));

  // s = 1/3: each coordinate is s * x in double, rounded to the property's type.
  const double s = 1.0 / 3.0;
  ASSERT_TRUE(Scale(in, dir.File("third.ply"), s).ok());
  EXPECT_EQ(ReadAll(dir.File("third.ply")),
            WithComment(header, "0.3333333333333333") + Faces(be) +
                Vertices(be, static_cast<float>(s * 1.5), s * -2.25,
                         static_cast<float>(s * static_cast<double>(0.3f)), 1.0f, s * 1e-3,
                         static_cast<float>(s * -4.0)));
  // Not float(float(s) * x): that differs for 0.3f, so the test tells them apart.
  EXPECT_NE(static_cast<float>(s * static_cast<double>(0.3f)), static_cast<float>(s) * 0.3f);
}

INSTANTIATE_TEST_SUITE_P(ByteOrder, PlyScale, ::testing::Bool());

TEST(PlyScale, AsciiKeepsEveryOtherTextAndWritesShortestNumbers) {
  const std::string header =
      "ply\r\n"
      "format ascii 1.0\r\n"
      "comment made by hand\r\n"
      "element vertex 3\r\n"
      "property float x\r\n"
      "property float y\r\n"
      "property double z\r\n"
      "property uchar red\r\n"
      "property list uchar int tags\r\n"
      "element face 1\r\n"
      "property list uchar int vertex_indices\r\n"
      "end_header\r\n";
  const std::string body =
      "1.5 -2.25  0.1 200 2 7 -8\r\n"
      "  nan +4 1e-3 017 0\r\n"
      "0.1\t0.2\t0.30000000000000004 1 1 5 \r\n"
      "3 0 1 2\r\n"
      "\r\n";
  TempDir dir;
  const std::string in = dir.Write("in.ply", header + body);
  ScalePointFileSummary summary;
  ASSERT_TRUE(Scale(in, dir.File("out.ply"), 2.0, &summary).ok());
  EXPECT_EQ(summary.num_points, 3);
  const size_t at = header.find("element ");
  EXPECT_EQ(ReadAll(dir.File("out.ply")),
            header.substr(0, at) + "comment OPL scaled vertex x, y, z by s = 2\r\n" +
                header.substr(at) +
                "3 -4.5  0.2 200 2 7 -8\r\n"
                "  nan 8 0.002 017 0\r\n"  // NaN kept; other fields as written
                "0.2\t0.4\t0.6000000000000001 1 1 5 \r\n"
                "3 0 1 2\r\n"
                "\r\n");
  // float x, y: the shortest text of float(s * x); double z: of s * z.
  const double s = 1.0 / 3.0;
  ASSERT_TRUE(Scale(in, dir.File("third.ply"), s).ok());
  const std::string out = ReadAll(dir.File("third.ply"));
  char fx[32], dz[32];
  *std::to_chars(fx, fx + 32, static_cast<float>(s * static_cast<double>(0.1f))).ptr = '\0';
  *std::to_chars(dz, dz + 32, s * 0.30000000000000004).ptr = '\0';
  EXPECT_THAT(out, HasSubstr(std::string(fx) + "\t"));
  EXPECT_THAT(out, HasSubstr(std::string("\t") + dz + " 1 1 5 \r\n"));
  EXPECT_EQ(std::string(fx), "0.033333335");
}

TEST(PlyScale, VariableRecordsAcrossBufferBoundaries) {
  // 3000 vertices of 13 to 25 bytes and 1000 faces through 4 KiB buffers.
  std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3000\nproperty double x\n"
      "property list uchar uint ids\nproperty float y\nproperty float z\n"
      "element face 1000\nproperty list int uchar v\nend_header\n";
  std::string in_body, out_body;
  for (int i = 0; i < 3000; ++i) {
    const double x = 0.001 * i;
    const float y = static_cast<float>(-0.5 * i), z = static_cast<float>(i % 7);
    for (std::string* b : {&in_body, &out_body}) {
      const bool scaled = b == &out_body;
      Put<double>(b, scaled ? 3.0 * x : x, false);
      Put<uint8_t>(b, static_cast<uint8_t>(i % 4), false);
      for (int j = 0; j < i % 4; ++j) Put<uint32_t>(b, static_cast<uint32_t>(i * 10 + j), false);
      Put<float>(b, scaled ? static_cast<float>(3.0 * y) : y, false);
      Put<float>(b, scaled ? static_cast<float>(3.0 * z) : z, false);
    }
  }
  std::string faces;
  for (int i = 0; i < 1000; ++i) {
    Put<int32_t>(&faces, i % 3, false);
    for (int j = 0; j < i % 3; ++j) Put<uint8_t>(&faces, static_cast<uint8_t>(j + i), false);
  }
  TempDir dir;
  const std::string in = dir.Write("in.ply", header + in_body + faces);
  ASSERT_TRUE(Scale(in, dir.File("out.ply"), 3.0, nullptr, 4096).ok());
  EXPECT_EQ(ReadAll(dir.File("out.ply")), WithComment(header, "3") + out_body + faces);
}

TEST(PlyHeader, ParsesTypesCountsAndLists) {
  Result<PlyHeader> h = ParsePlyHeader(Header("binary_big_endian"), "h.ply");
  ASSERT_TRUE(h.ok()) << h.status().message();
  EXPECT_EQ(h->encoding, PlyEncoding::kBinaryBigEndian);
  ASSERT_EQ(h->elements.size(), 2u);
  EXPECT_EQ(h->elements[1].name, "vertex");
  EXPECT_EQ(h->elements[1].count, 2);
  EXPECT_EQ(h->elements[1].header_line, 7);
  EXPECT_EQ(h->elements[1].FixedRecordBytes(), -1);  // a list
  EXPECT_EQ(h->elements[1].properties[1].type, PlyScalarType::kFloat64);
  EXPECT_TRUE(h->elements[0].properties[0].is_list);
  EXPECT_EQ(h->elements[0].properties[0].count_type, PlyScalarType::kUint8);
  EXPECT_EQ(h->elements[0].properties[0].type, PlyScalarType::kInt32);
  EXPECT_EQ(h->FindElement("face"), 0);
  EXPECT_EQ(h->first_element_offset, Header("binary_big_endian").find("element face"));
}

// Every refusal: the message, and no output file (not even a temporary one).
class PlyErrors : public ::testing::Test {
 protected:
  std::string Refused(const std::string& contents, double s = 2.0) {
    const std::string in = dir_.Write("in.ply", contents);
    Status st = Scale(in, dir_.File("out.ply"), s);
    EXPECT_FALSE(st.ok());
    EXPECT_EQ(dir_.Entries(), std::vector<std::string>{"in.ply"});
    return st.message().substr(st.message().find(':') + 1);  // without the path
  }
  TempDir dir_;
};

TEST_F(PlyErrors, Header) {
  const std::string v = "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
  EXPECT_EQ(Refused("solid cube\n"), " not a PLY file (the first line is not 'ply')");
  EXPECT_EQ(Refused("ply\nformat binary 1.0\n" + v + "end_header\n"),
            "2: unknown format 'binary' (ascii, binary_little_endian or binary_big_endian)");
  EXPECT_EQ(Refused("ply\nformat ascii 2.0\n" + v + "end_header\n"),
            "2: unsupported PLY version '2.0' (1.0)");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\nproperty float x\n" + v + "end_header\n"),
            "3: 'property' before any 'element'");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\n" + v), " the header has no 'end_header' line");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\nelement vertex -1\nend_header\n"),
            "3: element 'vertex': not a count: '-1'");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nproperty float y\n"
                    "property float z\nend_header\n1 2 3\n"),
            "3: property 'x' of element 'vertex' is int: OPL scales float or double coordinates");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                    "end_header\n1 2\n"),
            "3: element 'vertex' has no property 'z'");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\nelement point 1\nproperty float x\nend_header\n1\n"),
            " no element 'vertex' (nothing to scale)");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\n" + v + "property list float int w\nend_header\n"),
            "7: the count of list 'w' must be an integer type, got 'float'");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\n" + v + "property float y\nend_header\n"),
            "7: a second property 'y' in element 'vertex'");
  EXPECT_EQ(Refused("ply\nformat ascii 1.0\n" + v + "propery float w\nend_header\n"),
            "7: unknown header line 'propery float w'");
  // A header that does not end within the buffer.
  std::string comments;
  while (comments.size() < 5000) comments += "comment a long story\n";
  const std::string in = dir_.Write("in.ply", "ply\nformat ascii 1.0\n" + comments + v +
                                                  "end_header\n1 2 3\n");
  EXPECT_EQ(Scale(in, dir_.File("out.ply"), 2.0, nullptr, 4096).message(),
            in + ": the header has no 'end_header' line in its first 4096 bytes (a longer header "
                 "is refused)");
  EXPECT_EQ(dir_.Entries(), std::vector<std::string>{"in.ply"});
}

TEST_F(PlyErrors, BinaryBody) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\nproperty list char int v\n"
      "end_header\n";
  std::string vertices;
  for (int i = 0; i < 9; ++i) Put<float>(&vertices, 1.0f * i, false);
  const int64_t body = static_cast<int64_t>(header.size());
  // Cut inside vertex 2 (which starts 24 bytes into the body).
  EXPECT_EQ(Refused(header + vertices.substr(0, 30)),
            " byte " + std::to_string(body + 24) +
                ": vertex 2 of 3 is cut off by the end of the file (truncated, or wrong counts "
                "in the header)");
  std::string face;
  Put<int8_t>(&face, 2, false);
  Put<int32_t>(&face, 0, false);
  EXPECT_EQ(Refused(header + vertices + face),  // one index of two
            " byte " + std::to_string(body + 36) +
                ": face 0 of 1 is cut off by the end of the file (truncated, or wrong counts in "
                "the header)");
  Put<int32_t>(&face, 1, false);
  EXPECT_EQ(Refused(header + vertices + face + "xyz"),
            " byte " + std::to_string(body + 45) +
                ": 3 bytes after the last element (wrong counts in the header?)");
  std::string negative;
  Put<int8_t>(&negative, -1, false);
  EXPECT_EQ(Refused(header + vertices + negative),
            " byte " + std::to_string(body + 36) + ": face 0 of 1: list 'v' has a negative count -1");
  std::string big = vertices;
  const float huge = 3e38f;
  std::memcpy(&big[4 * 4], &huge, 4);  // y of vertex 1
  EXPECT_EQ(Refused(header + big + face, 10.0),
            " byte " + std::to_string(body + 12) +
                ": vertex 1 of 3: property 'y': 3e+38 * s = 3e+39 is beyond the range "
                "of float");
}

TEST_F(PlyErrors, AsciiBody) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\nproperty list uchar int l\nend_header\n";
  EXPECT_EQ(Refused(header + "1 2 3 0\n4 5\n"),
            "10: vertex 1: too few values (no value for property 'z')");
  EXPECT_EQ(Refused(header + "1 2 3 0 9\n"), "9: vertex 0: more values than its 4 properties");
  EXPECT_EQ(Refused(header + "1 2 3 2 7\n"), "9: vertex 0: too few values (list 'l' has 1 of its 2)");
  EXPECT_EQ(Refused(header + "1 2 3 x\n"), "9: vertex 0: list 'l': not a count: 'x'");
  EXPECT_EQ(Refused(header + "1 2,5 3 0\n"), "9: vertex 0: property 'y': not a number: '2,5'");
  EXPECT_EQ(Refused(header + "1 2 3 0\n"),
            "10: the file ends at vertex 1 of 2 (truncated, or wrong counts in the header)");
  EXPECT_EQ(Refused(header + "1 2 3 0\n1 2 3 0\n7 7 7 0\n"),
            "11: text after the last element (wrong counts in the header?)");
}

// Every truncation and every single corrupted byte of a small binary and
// ASCII PLY: an error or a complete output, never a crash (the sanitizer
// build runs this too), never a partial file.
TEST(PlyScale, EveryTruncationAndCorruptionIsRefusedOrScaled) {
  // Hundreds of runs, each fsyncing its output: on tmpfs when there is one.
  TempDir dir(std::filesystem::is_directory("/dev/shm")
                  ? std::string("/dev/shm")
                  : std::filesystem::temp_directory_path().string());
  ASSERT_FALSE(dir.path().empty());
  for (const bool ascii : {false, true}) {
    std::string file;
    if (ascii) {
      file = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
             "property float z\nproperty list uchar int l\nelement face 1\n"
             "property list uchar int v\nend_header\n1 2 3 2 4 5\n6 7 8 0\n3 0 1 1\n";
    } else {
      file = Header("binary_little_endian") + Faces(false) +
             Vertices(false, 1.5f, -2.25, 0.3f, 3.0f, 1e-3, -4.0f);
    }
    // (An ASCII file without its last line break is complete.)
    for (size_t cut = 0; cut < file.size() - (ascii ? 1 : 0); ++cut) {
      const std::string in = dir.Write("in.ply", file.substr(0, cut));
      EXPECT_FALSE(Scale(in, dir.File("out.ply"), 2.0, nullptr, 4096).ok()) << "cut at " << cut;
      EXPECT_EQ(dir.Entries(), std::vector<std::string>{"in.ply"});
    }
    for (size_t at = 0; at < file.size(); ++at) {
      for (const char c : std::string("\n9 \xff\x80", 5)) {
        std::string bad = file;
        bad[at] = c;
        const std::string in = dir.Write("in.ply", bad);
        Status st = Scale(in, dir.File("out.ply"), 2.0, nullptr, 4096);
        if (st.ok()) {
          std::error_code ec;
          std::filesystem::remove(dir.File("out.ply"), ec);
        }
        EXPECT_EQ(dir.Entries(), std::vector<std::string>{"in.ply"});
      }
    }
  }
}

}  // namespace
}  // namespace opl
