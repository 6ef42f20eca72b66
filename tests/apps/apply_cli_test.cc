// opl_measure --apply with point files (PLY, XYZ, CSV): run as a user would,
// the output compared value by value with s * x from the tool's own JSON, and
// every refusal checked for its exit code, its message and that nothing was
// written.
#include <cstring>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "io/temp_dir.h"
#include "support/provenance_strip.h"
#include "opl/core/format.h"

namespace opl {
namespace {

using cli_test::Measure;
using cli_test::RunResult;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }
using testing_support::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kMeasure = std::string("--calibration ") + OPL_EXAMPLES_DIR +
                             "/prototype_calibration.json --spots " + OPL_EXAMPLES_DIR +
                             "/prototype_spots.csv --json";

template <typename T>
void Put(std::string* out, T v) {  // little endian (the test hosts are)
  char bytes[sizeof(T)];
  std::memcpy(bytes, &v, sizeof(T));
  out->append(bytes, sizeof(T));
}

const char kPlyHeader[] =
    "ply\n"
    "format binary_little_endian 1.0\n"
    "comment scanner output\n"
    "element vertex 500\n"
    "property float x\n"
    "property float y\n"
    "property float z\n"
    "property float nx\n"
    "property uchar red\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "end_header\n";

// 500 vertices (x, y, z as given by `scale`, nx, red) and two faces.
std::string PlyBody(const std::function<float(float)>& scale) {
  std::string b;
  for (int i = 0; i < 500; ++i) {
    Put<float>(&b, scale(0.37f * static_cast<float>(i)));
    Put<float>(&b, scale(-1.1f * static_cast<float>(i)));
    Put<float>(&b, scale(1000.0f + 0.01f * static_cast<float>(i)));
    Put<float>(&b, 0.5f);
    Put<uint8_t>(&b, static_cast<uint8_t>(i));
  }
  for (int f = 0; f < 2; ++f) {
    Put<uint8_t>(&b, 3);
    for (int v = 0; v < 3; ++v) Put<int32_t>(&b, f + v);
  }
  return b;
}

class ApplyCli : public ::testing::Test {
 protected:
  // Runs opl_measure with --apply/--out and the extra options; on failure
  // checks that stdout is empty and nothing new is in the directory.
  RunResult Apply(const std::string& in, const std::string& out, const std::string& extra = "") {
    const std::vector<std::string> before = dir_.Entries();
    RunResult r = Measure(kMeasure + " --apply " + dir_.File(in) + " --out " + dir_.File(out) +
                          " " + extra);
    if (r.exit_code != 0) {
      EXPECT_EQ(r.out, "");
      EXPECT_EQ(dir_.Entries(), before);
    }
    return r;
  }
  static double ScaleOf(const RunResult& r) {
    return nlohmann::json::parse(r.out)["scale_factor"].get<double>();
  }
  TempDir dir_;
};

TEST_F(ApplyCli, BinaryPlyScalesVertexXyzAndKeepsEverythingElse) {
  dir_.Write("scan.ply", kPlyHeader + PlyBody([](float v) { return v; }));
  RunResult r = Apply("scan.ply", "scan_mm.ply");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double s = ScaleOf(r);
  EXPECT_NEAR(s, 1.0, 0.02);
  EXPECT_NE(s, 1.0);
  std::string header = kPlyHeader;
  header.insert(header.find("element vertex"),
                "comment OPL scaled vertex x, y, z by s = " + FormatRoundTrip(s) + "\n");
  EXPECT_EQ(ReadAll(dir_.File("scan_mm.ply")),
            header + PlyBody([s](float v) { return static_cast<float>(s * v); }));
}

TEST_F(ApplyCli, XyzAndCsvAndAnExplicitFormat) {
  dir_.Write("pts.xyz", "# id-less\n1.5 -2 1000 keep me\n");
  dir_.Write("pts.csv", "name,x,y,z,sx\nT1,1.5,-2,1000,0.1\n");
  dir_.Write("pts.asc", "1.5 -2 1000\n");
  RunResult r = Apply("pts.xyz", "out.xyz");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double s = ScaleOf(r);
  const std::string xyz = FormatRoundTrip(s * 1.5) + " " + FormatRoundTrip(s * -2.0) + " " +
                          FormatRoundTrip(s * 1000.0);
  EXPECT_EQ(ReadAll(dir_.File("out.xyz")), "# id-less\n" + xyz + " keep me\n");
  r = Apply("pts.csv", "out.csv");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(ReadAll(dir_.File("out.csv")),
            "name,x,y,z,sx\nT1," + FormatRoundTrip(s * 1.5) + "," + FormatRoundTrip(s * -2.0) +
                "," + FormatRoundTrip(s * 1000.0) + ",0.1\n");
  r = Apply("pts.asc", "out.asc", "--format xyz");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(ReadAll(dir_.File("out.asc")), xyz + "\n");
}

TEST_F(ApplyCli, RefusalsWriteNothing) {
  dir_.Write("scan.ply", kPlyHeader + PlyBody([](float v) { return v; }));
  // A truncated body: found while scaling, after the measurement; exit 3.
  const std::string full = ReadAll(dir_.File("scan.ply"));
  dir_.Write("cut.ply", full.substr(0, std::strlen(kPlyHeader) + 17 * 100 + 5));
  RunResult r = Apply("cut.ply", "o.ply");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("cut.ply") + ": byte " +
                       std::to_string(std::strlen(kPlyHeader) + 1700) +
                       ": vertex 100 of 500 is cut off by the end of the file (truncated, or "
                       "wrong counts in the header)\n");
  // A bad header: refused before the measurement.
  dir_.Write("bad.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nend_header\n");
  r = Apply("bad.ply", "o.ply");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("bad.ply") +
                       ":3: property 'x' of element 'vertex' is int: OPL scales float or double "
                       "coordinates\n");
  dir_.Write("p.xyz", "1 2 3\n4 5 six\n");
  r = Apply("p.xyz", "o.xyz");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "opl_measure: " + dir_.File("p.xyz") + ":2: field 'z': not a number: 'six'\n");
  // An extension that names no format; --format fixes it.
  dir_.Write("p.pts", "1 2 3\n");
  r = Apply("p.pts", "o.pts");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("p.pts: cannot tell the point file format from the extension "
                               "'.pts' (.ply, .xyz, .txt or .csv; or give the format)"));
  // The output has the input's format: an --out naming another is refused.
  r = Apply("scan.ply", "o.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "opl_measure: --out '" + dir_.File("o.csv") + "' names a csv file but --apply '" +
                       dir_.File("scan.ply") + "' is ply: the output has the input's format (see "
                       "--help)\n");
  r = Apply("scan.ply", "o.ply", "--format las");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, StartsWith("opl_measure: --format: "));
  EXPECT_THAT(r.err, HasSubstr("las"));
  // A failed run leaves an existing output as it was.
  dir_.Write("o.xyz", "previous\n");
  r = Apply("p.xyz", "o.xyz");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(ReadAll(dir_.File("o.xyz")), "previous\n");
  // An output directory that does not exist: exit 5.
  r = Apply("scan.ply", "missing/o.ply");
  EXPECT_EQ(r.exit_code, 5);
  EXPECT_THAT(r.err, HasSubstr("o.ply: cannot write: cannot create a temporary file"));
}

TEST(ApplyCliUsage, FormatNeedsApply) {
  RunResult r = Measure(kMeasure + " --format ply");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, StartsWith("opl_measure: --format requires --apply"));
}

}  // namespace
}  // namespace opl
