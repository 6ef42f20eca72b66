#include "opl/io/module_design_json.h"

#include <algorithm>
#include <cstdlib>
#include <iterator>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include "opl/geometry/rotation.h"
#include "opl/sim/simulate_spots.h"

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

std::string TempDir() {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("opl_sim_design_json_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir.string();
}

std::string WriteFile(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

// A valid document with one replaceable part: `sources` and `surface` JSON.
std::string Doc(const std::string& sources, const std::string& surface,
                const std::string& extra = "") {
  return R"({"format": "opl.module_design", "version": 1, "sources": )" + sources +
         R"(, "surface": )" + surface + R"(, "spot_noise_mm": [0.1, 0.07, 0.07])" + extra + "}";
}
const std::string kSourceA =
    R"({"name": "A", "pattern": "equal_angle", "beams_per_side": 11, "full_angle_deg": 29,
        "origin_mm": [0, 27.5, 0], "rotation_xyz_rad": [0, 0, 0]})";
const std::string kSourceB =
    R"({"name": "B", "pattern": "grating", "beams_per_side": 7, "full_angle_deg": 20,
        "wavelength_nm": 635, "origin_mm": [0, -27.5, 0], "rotation_xyz_rad": [0.1, -0.2, 0.3]})";
const std::string kPlane = R"({"type": "plane", "point_mm": [1000, 0, 0], "normal": [-1, 0, 0]})";
const std::string kTwo = "[" + kSourceA + ", " + kSourceB + "]";

TEST(ModuleDesignJson, ReadsThePrototypeExample) {
  const char* root = std::getenv("OPL_SOURCE_DIR");
  ASSERT_NE(root, nullptr);
  const std::string path = std::string(root) + "/examples/prototype_design.json";
  const Result<ModuleDesign> d = ReadModuleDesignJson(path);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  ASSERT_EQ(d->sources.size(), 2u);
  for (const SourceDesign& s : d->sources) {
    EXPECT_EQ(s.beams_per_side, 11);
    EXPECT_EQ(s.full_angle_deg, 29.0);
    EXPECT_EQ(s.pattern, PatternModel::kEqualAngle);
    EXPECT_EQ(s.wavelength_nm, 658.0);
    EXPECT_TRUE(s.scene_from_source.rotation.isApprox(Eigen::Quaterniond::Identity()));
  }
  EXPECT_EQ(d->sources[0].scene_from_source.translation, Vec3(0, 27.5, 0));
  EXPECT_EQ(d->sources[1].scene_from_source.translation, Vec3(0, -27.5, 0));
  ASSERT_EQ(d->surface.type(), SurfaceType::kPlane);
  EXPECT_EQ(std::get<PlaneSurface>(d->surface.shape()).point_mm, Vec3(1000, 0, 0));
  EXPECT_EQ(d->spot_noise_mm, Vec3(0.110, 0.073, 0.073));
  EXPECT_TRUE(d->noise_frame_rotation.isIdentity());
  const Result<ModuleCalibration> cal = ExactCalibration(*d);
  ASSERT_TRUE(cal.ok());
  EXPECT_EQ(cal->separations[0].length_mm, 55.0);
}

TEST(ModuleDesignJson, ParsesEveryFieldAndSurface) {
  const Result<ModuleDesign> d =
      ParseModuleDesignJson(Doc(kTwo, kPlane, R"(, "noise_frame_rotation_xyz_rad": [0.2, 0, -0.1],
                                                  "description": "test")"),
                            "t.json");
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  const SourceDesign& b = d->sources[1];
  EXPECT_EQ(b.pattern, PatternModel::kGrating);
  EXPECT_EQ(b.beams_per_side, 7);
  EXPECT_EQ(b.full_angle_deg, 20.0);
  EXPECT_EQ(b.wavelength_nm, 635.0);
  EXPECT_TRUE(b.scene_from_source.RotationMatrix().isApprox(
      RotationFromXyzAnglesRad({0.1, -0.2, 0.3}), 1e-15));
  EXPECT_TRUE(d->noise_frame_rotation.isApprox(RotationFromXyzAnglesRad({0.2, 0, -0.1}), 1e-15));

  const Result<ModuleDesign> sphere = ParseModuleDesignJson(
      Doc(kTwo, R"({"type": "sphere", "center_mm": [1500, 0, 0], "radius_mm": 700})"), "t.json");
  ASSERT_TRUE(sphere.ok()) << sphere.status().ToString();
  EXPECT_EQ(std::get<SphereSurface>(sphere->surface.shape()).radius_mm, 700.0);

  const Result<ModuleDesign> box = ParseModuleDesignJson(
      Doc(kTwo, R"({"type": "box_corner", "corner_mm": [1200, -500, -400],
                    "rotation_xyz_rad": [0, 0, 0.5]})"),
      "t.json");
  ASSERT_TRUE(box.ok()) << box.status().ToString();
  EXPECT_TRUE(std::get<BoxCornerSurface>(box->surface.shape())
                  .scene_from_box.isApprox(RotationZ(0.5), 1e-15));

  const Result<ModuleDesign> para = ParseModuleDesignJson(
      Doc(kTwo, R"({"type": "paraboloid", "vertex_mm": [1000, 0, 0], "axis": [-1, 0, 0],
                    "curvature_per_mm": 0.0005})"),
      "t.json");
  ASSERT_TRUE(para.ok()) << para.status().ToString();
  EXPECT_EQ(std::get<ParaboloidSurface>(para->surface.shape()).curvature_per_mm, 0.0005);

  const Result<ModuleDesign> planes = ParseModuleDesignJson(
      Doc(kTwo, R"({"type": "planes", "planes": [
                    {"point_mm": [750, 0, 0], "normal": [-1, 0, 0]},
                    {"point_mm": [1350, 0, 0], "normal": [-1, 0, 0]}]})"),
      "t.json");
  ASSERT_TRUE(planes.ok()) << planes.status().ToString();
  EXPECT_EQ(planes->surface.num_slices(), 2);
  EXPECT_EQ(std::get<PlaneListSurface>(planes->surface.shape()).planes[1].point_mm.x(), 1350.0);
}

TEST(ModuleDesignJson, ProvenanceIsAllowedAtTheTopLevel) {
  // docs/formats.md, "Provenance": every JSON file may carry one.
  const Result<ModuleDesign> d =
      ParseModuleDesignJson(Doc(kTwo, kPlane, R"(, "provenance": {"tool": "x", "inputs": []})"), "d.json");
  ASSERT_TRUE(d.ok()) << d.status().message();
  EXPECT_EQ(d->sources.size(), 2u);
}

TEST(ModuleDesignJson, FilePatternRelativeToTheJsonFolder) {
  const std::string dir = TempDir() + "/design";
  std::filesystem::create_directories(dir + "/patterns");
  const BeamPattern p = MakeGratingPattern(5, 12 * kDeg, 658);
  ASSERT_TRUE(WritePatternCsv(p, dir + "/patterns/c.csv").ok());
  const std::string source_c =
      R"({"name": "C", "pattern": "file", "pattern_file": "patterns/c.csv",
          "origin_mm": [0, 0, 10], "rotation_xyz_rad": [0, 0, 0]})";
  const std::string path =
      WriteFile(dir + "/design.json", Doc("[" + kSourceA + ", " + source_c + "]", kPlane));
  const Result<ModuleDesign> d = ReadModuleDesignJson(path);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  const SourceDesign& c = d->sources[1];
  EXPECT_EQ(c.pattern, PatternModel::kFile);
  EXPECT_EQ(c.pattern_file, dir + "/patterns/c.csv");
  EXPECT_EQ(c.beams_per_side, 5);  // taken from the file
  EXPECT_NEAR(c.full_angle_deg, 12.0, 1e-12);  // central row's span, for reports
  const Result<BeamPattern> read = MakePattern(c);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->Find(15)->az_rad, p.Find(15)->az_rad);

  // beams_per_side given and wrong; missing file; full_angle_deg not allowed.
  const std::string wrong_n =
      R"({"name": "C", "pattern": "file", "pattern_file": "patterns/c.csv", "beams_per_side": 11,
          "origin_mm": [0, 0, 10], "rotation_xyz_rad": [0, 0, 0]})";
  Result<ModuleDesign> e = ParseModuleDesignJson(Doc("[" + wrong_n + "]", kPlane), "d.json", dir);
  EXPECT_EQ(e.status().message(),
            "d.json: sources[0].beams_per_side: 11 differs from the pattern file's 5");
  const std::string missing =
      R"({"name": "C", "pattern": "file", "pattern_file": "nope.csv",
          "origin_mm": [0, 0, 10], "rotation_xyz_rad": [0, 0, 0]})";
  e = ParseModuleDesignJson(Doc("[" + missing + "]", kPlane), "d.json", dir);
  EXPECT_EQ(e.status().code(), StatusCode::kIoError);
  EXPECT_EQ(e.status().message(),
            "d.json: sources[0].pattern_file: " + dir + "/nope.csv: cannot open pattern file");
  const std::string with_angle =
      R"({"name": "C", "pattern": "file", "pattern_file": "patterns/c.csv", "full_angle_deg": 29,
          "origin_mm": [0, 0, 10], "rotation_xyz_rad": [0, 0, 0]})";
  e = ParseModuleDesignJson(Doc("[" + with_angle + "]", kPlane), "d.json", dir);
  EXPECT_EQ(e.status().message(),
            "d.json: sources[0].full_angle_deg: not used with \"pattern\": \"file\" (remove it)");
  // A malformed pattern file reports its own file and line.
  WriteFile(dir + "/patterns/bad.csv", "# beams_per_side: 3\nid,az_rad,el_rad\n1,x,0\n");
  const std::string bad =
      R"({"name": "C", "pattern": "file", "pattern_file": "patterns/bad.csv",
          "origin_mm": [0, 0, 10], "rotation_xyz_rad": [0, 0, 0]})";
  e = ParseModuleDesignJson(Doc("[" + bad + "]", kPlane), "d.json", dir);
  EXPECT_EQ(e.status().code(), StatusCode::kParseError);
  EXPECT_EQ(e.status().message(), "d.json: sources[0].pattern_file: " + dir +
                                      "/patterns/bad.csv:3: field 'az_rad': not a finite number: 'x'");
}

// Expects a ParseError with exactly this message.
void ExpectError(const std::string& text, const std::string& message,
                 StatusCode code = StatusCode::kParseError) {
  const Result<ModuleDesign> d = ParseModuleDesignJson(text, "design.json");
  ASSERT_FALSE(d.ok()) << text;
  EXPECT_EQ(d.status().code(), code) << d.status().ToString();
  EXPECT_EQ(d.status().message(), message);
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

TEST(ModuleDesignJson, EveryErrorNamesFileFieldAndProblem) {
  const std::string ok = Doc(kTwo, kPlane);
  ASSERT_TRUE(ParseModuleDesignJson(ok, "design.json").ok());

  // The example from the brief.
  ExpectError(Replace(ok, R"("full_angle_deg": 20)", R"("full_angle_deg": "abc")"),
              R"(design.json: sources[1].full_angle_deg: expected a number, got "abc")");
  // Format and version.
  ExpectError(Replace(ok, R"("opl.module_design")", R"("opl.module_calibration")"),
              R"(design.json: format: expected "opl.module_design", got "opl.module_calibration")");
  ExpectError(Replace(ok, R"("version": 1)", R"("version": 2)"),
              "design.json: version: unsupported version 2 (this reader reads version 1)");
  ExpectError(Replace(ok, R"("version": 1)", R"("version": "1")"),
              R"(design.json: version: expected an integer, got "1")");
  ExpectError(Replace(ok, R"("version": 1, )", ""), "design.json: version: missing field");
  ExpectError("[1, 2]", "design.json: expected a JSON object at the top level, got [1,2]");
  // Missing fields.
  ExpectError(Replace(ok, R"("origin_mm": [0, -27.5, 0], )", ""),
              "design.json: sources[1].origin_mm: missing field");
  ExpectError(Replace(ok, R"("pattern": "equal_angle", )", ""),
              "design.json: sources[0].pattern: missing field");
  ExpectError(Replace(ok, R"("beams_per_side": 11, )", ""),
              "design.json: sources[0].beams_per_side: missing field");
  ExpectError(Replace(ok, R"(, "spot_noise_mm": [0.1, 0.07, 0.07])", ""),
              "design.json: spot_noise_mm: missing field");
  // Types and domains.
  ExpectError(Replace(ok, R"("origin_mm": [0, 27.5, 0])", R"("origin_mm": [0, 27.5])"),
              "design.json: sources[0].origin_mm: expected an array of 3 numbers, got [0,27.5]");
  ExpectError(Replace(ok, R"("origin_mm": [0, 27.5, 0])", R"("origin_mm": [0, null, 0])"),
              "design.json: sources[0].origin_mm[1]: expected a number, got null");
  ExpectError(Replace(ok, R"("beams_per_side": 11)", R"("beams_per_side": 10)"),
              "design.json: sources[0].beams_per_side: must be odd and in [3, 201], got 10");
  ExpectError(Replace(ok, R"("beams_per_side": 11)", R"("beams_per_side": 46341)"),
              "design.json: sources[0].beams_per_side: must be odd and in [3, 201], got 46341");
  ExpectError(Replace(ok, R"("beams_per_side": 11)", R"("beams_per_side": 100001)"),
              "design.json: sources[0].beams_per_side: must be odd and in [3, 201], got 100001");
  ExpectError(Replace(ok, R"("beams_per_side": 11)", R"("beams_per_side": 11.5)"),
              "design.json: sources[0].beams_per_side: expected an integer, got 11.5");
  ExpectError(Replace(ok, R"("full_angle_deg": 20)", R"("full_angle_deg": 95)"),
              "design.json: sources[1].full_angle_deg: must be > 0 and < 90 for a grating "
              "(corner orders must propagate), got 95");
  ExpectError(Replace(ok, R"("full_angle_deg": 29)", R"("full_angle_deg": 0)"),
              "design.json: sources[0].full_angle_deg: must be > 0 and < 180, got 0");
  ExpectError(Replace(ok, R"("wavelength_nm": 635)", R"("wavelength_nm": -635)"),
              "design.json: sources[1].wavelength_nm: must be > 0, got -635");
  ExpectError(Replace(ok, R"("pattern": "grating")", R"("pattern": "hologram")"),
              R"(design.json: sources[1].pattern: expected "equal_angle", "grating" or "file", got "hologram")");
  ExpectError(Replace(ok, R"("name": "B")", R"("name": "")"),
              "design.json: sources[1].name: must not be empty");
  ExpectError(Replace(ok, R"("name": "B")", R"("name": "A")"),
              R"(design.json: sources[1].name: duplicate source name "A" (also sources[0]))");
  ExpectError(Replace(ok, R"("name": "B", )", R"("name": "B", "pattern_file": "x.csv", )"),
              R"(design.json: sources[1].pattern_file: only used with "pattern": "file")");
  ExpectError(Replace(ok, R"("spot_noise_mm": [0.1, 0.07, 0.07])", R"("spot_noise_mm": [0.1, -0.07, 0.07])"),
              "design.json: spot_noise_mm[1]: standard deviation must be >= 0, got -0.07");
  ExpectError(Doc("[]", kPlane), "design.json: sources: must hold at least one source");
  ExpectError(Doc("{}", kPlane), "design.json: sources: expected an array, got {}");
  ExpectError(Doc("[3]", kPlane), "design.json: sources[0]: expected an object, got 3");
  // Unknown fields (typos) are errors.
  ExpectError(Replace(ok, R"("wavelength_nm": 635)", R"("wavelenght_nm": 635)"),
              "design.json: sources[1].wavelenght_nm: unknown field (allowed here: beam_error_mrad, "
              "beam_error_seed, beams_per_side, "
              "description, full_angle_deg, name, origin_mm, pattern, pattern_file, "
              "rotation_xyz_rad, wavelength_nm)");
  // Surfaces.
  ExpectError(Doc(kTwo, R"({"type": "plane", "point_mm": [1000, 0, 0], "normal": [0, 0, 0]})"),
              "design.json: surface.normal: must not be the zero vector");
  ExpectError(Doc(kTwo, R"({"type": "cube"})"),
              R"(design.json: surface.type: unknown surface type "cube" (expected "plane", "sphere", "box_corner", "paraboloid" or "planes"))");
  ExpectError(Doc(kTwo, R"({"point_mm": [1000, 0, 0]})"), "design.json: surface.type: missing field");
  ExpectError(Doc(kTwo, R"({"type": "sphere", "center_mm": [0, 0, 0], "radius_mm": 0})"),
              "design.json: surface.radius_mm: must be > 0, got 0");
  ExpectError(Doc(kTwo, R"({"type": "sphere", "center_mm": [0, 0, 0], "radius": 5})"),
              "design.json: surface.radius: unknown field (allowed here: center_mm, radius_mm, type)");
  ExpectError(Doc(kTwo, R"({"type": "paraboloid", "vertex_mm": [0, 0, 0], "axis": [0, 0, 0],
                             "curvature_per_mm": 0.001})"),
              "design.json: surface.axis: must not be the zero vector");
  ExpectError(Doc(kTwo, R"({"type": "planes", "planes": []})"),
              "design.json: surface.planes: must hold at least one plane");
  ExpectError(Doc(kTwo, R"({"type": "planes", "planes": [
                             {"point_mm": [750, 0, 0], "normal": [-1, 0, 0]},
                             {"point_mm": [1350, 0, 0], "normal": [0, 0, 0]}]})"),
              "design.json: surface.planes[1].normal: must not be the zero vector");
  ExpectError(Doc(kTwo, R"({"type": "box_corner", "corner_mm": [0, 0, 0]})"),
              "design.json: surface.rotation_xyz_rad: missing field");
}

TEST(ModuleDesignJson, InvalidJsonNonFiniteDuplicateKeysAndIo) {
  // Syntax error on line 3, column 8 (the ']' where a value should be).
  ExpectError("{\n  \"format\": \"opl.module_design\",\n  \"x\": ]\n}",
              "design.json:3:8: invalid JSON: syntax error while parsing value - unexpected ']'; "
              "expected '[', '{', or a literal");
  ExpectError("", "design.json:1:1: invalid JSON: syntax error while parsing value - unexpected "
                  "end of input; expected '[', '{', or a literal");
  // A number that overflows a double is not finite: reported with its position.
  ExpectError("{\"format\": \"opl.module_design\",\n \"version\": 1e999}",
              "design.json:2:13: invalid JSON: number overflow parsing '1e999' (numbers must be "
              "finite doubles)");
  // Duplicate keys would silently keep the last value: an error.
  ExpectError(Replace(Doc(kTwo, kPlane), R"("origin_mm": [0, -27.5, 0])",
                      R"("origin_mm": [0, -27.5, 0], "origin_mm": [0, 27.5, 0])"),
              "design.json: sources[1].origin_mm: duplicate key (each field may appear once)");
  ExpectError(Replace(Doc(kTwo, kPlane), R"("version": 1)", R"("version": 1, "version": 1)"),
              "design.json: version: duplicate key (each field may appear once)");
  // Issue 19: nesting is capped at 64 levels (80 KB of '[' took 2.4 GB), refused
  // at the bracket opening level 65; brackets inside strings do not count.
  ExpectError(std::string(80000, '['),
              "design.json:1:65: invalid JSON: nested deeper than 64 levels");
  ExpectError(R"({"format": "opl.module_design", "version": 1, "x": )" + std::string(63, '[') +
                  std::string(63, ']') + "}",
              "design.json: x: unknown field (allowed here: description, format, "
              "noise_frame_rotation_xyz_rad, provenance, sources, spot_noise_mm, surface, version)");  // 64 levels: parsed
  ExpectError("{\"format\": \"" + std::string(100, '[') + "\\\"\",\n\"a\": " +
                  std::string(64, '{') + "\"b\": 1" + std::string(64, '}') + "}",
              "design.json:2:69: invalid JSON: nested deeper than 64 levels");

  const Result<ModuleDesign> missing = ReadModuleDesignJson("/nonexistent/design.json");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_EQ(missing.status().message(),
            "/nonexistent/design.json: cannot open: No such file or directory");
  const Result<ModuleDesign> directory = ReadModuleDesignJson(TempDir());
  EXPECT_EQ(directory.status().code(), StatusCode::kIoError);
  EXPECT_EQ(directory.status().message(), TempDir() + ": cannot read: is a directory");
  // The file name starts file-level messages.
  const std::string path = WriteFile(TempDir() + "/v2.json",
                                     Replace(Doc(kTwo, kPlane), R"("version": 1)", R"("version": 3)"));
  EXPECT_EQ(ReadModuleDesignJson(path).status().message(),
            path + ": version: unsupported version 3 (this reader reads version 1)");
}


// The writer: every surface, every pattern, a rotated noise frame and a
// fabrication error written, read back, and compared field by field with
// the original, and through what the design is for (its exact calibration:
// every beam direction; its simulated spots), not with the writer's text.
void ExpectSameDesign(const ModuleDesign& a, const ModuleDesign& b) {
  ASSERT_EQ(a.sources.size(), b.sources.size());
  for (size_t k = 0; k < a.sources.size(); ++k) {
    const SourceDesign& x = a.sources[k];
    const SourceDesign& y = b.sources[k];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.pattern, y.pattern);
    EXPECT_EQ(x.beams_per_side, y.beams_per_side);
    // A file pattern's full angle is the reader's report of the file.
    if (x.pattern != PatternModel::kFile) {
      EXPECT_EQ(x.full_angle_deg, y.full_angle_deg);
    }
    EXPECT_EQ(x.wavelength_nm, y.wavelength_nm);
    EXPECT_EQ(x.beam_error_mrad, y.beam_error_mrad);
    if (x.beam_error_mrad != 0.0) {
      EXPECT_EQ(x.beam_error_seed, y.beam_error_seed);
    }
    EXPECT_EQ(x.scene_from_source.translation, y.scene_from_source.translation);
    EXPECT_LT((x.scene_from_source.RotationMatrix() - y.scene_from_source.RotationMatrix()).norm(), 1e-14);
  }
  EXPECT_EQ(a.spot_noise_mm, b.spot_noise_mm);
  EXPECT_LT((a.noise_frame_rotation - b.noise_frame_rotation).norm(), 1e-14);
  EXPECT_EQ(a.surface.type(), b.surface.type());
  const Result<ModuleCalibration> ca = ExactCalibration(a);
  const Result<ModuleCalibration> cb = ExactCalibration(b);
  ASSERT_TRUE(ca.ok() && cb.ok());
  for (size_t k = 0; k < ca->sources.size(); ++k) {
    for (const Beam& beam : ca->sources[k].pattern.beams()) {
      const Beam* other = cb->sources[k].pattern.Find(beam.id);
      ASSERT_NE(other, nullptr);
      EXPECT_LT((beam.DirectionInSource() - other->DirectionInSource()).norm(), 1e-14);
    }
  }
  // Noise-free spots on the surface: the same to 1e-9 mm.
  ModuleDesign qa = a, qb = b;
  qa.spot_noise_mm.setZero();
  qb.spot_noise_mm.setZero();
  const Result<std::vector<SimulatedSpot>> sa = SimulateSpots(qa, SpotSimulationOptions());
  const Result<std::vector<SimulatedSpot>> sb = SimulateSpots(qb, SpotSimulationOptions());
  ASSERT_TRUE(sa.ok() && sb.ok()) << sa.status().ToString() << sb.status().ToString();
  ASSERT_EQ(sa->size(), sb->size());
  ASSERT_GT(sa->size(), 0u);
  double worst = 0.0;
  for (size_t k = 0; k < sa->size(); ++k) worst = std::max(worst, ((*sa)[k].true_point_in_scene - (*sb)[k].true_point_in_scene).norm());
  EXPECT_LT(worst, 1e-9);
}

TEST(ModuleDesignJson, WrittenDesignsReadBackTheSame) {
  const std::string dir = TempDir() + "/written";
  std::filesystem::create_directories(dir + "/patterns");
  ASSERT_TRUE(WritePatternCsv(MakeGratingPattern(5, 12 * kDeg, 658), dir + "/patterns/c.csv").ok());
  ModuleDesign design;
  SourceDesign a;
  a.name = "A";
  a.beams_per_side = 11;
  a.full_angle_deg = 29.0;
  a.scene_from_source = Rigid3d(RotationFromXyzAnglesRad({0.01, -0.02, 0.03}), Vec3(0.1, 27.5, -0.2));
  a.beam_error_mrad = 0.3;
  a.beam_error_seed = 77;
  SourceDesign b;
  b.name = "B";
  b.pattern = PatternModel::kGrating;
  b.beams_per_side = 7;
  b.full_angle_deg = 20.0;
  b.wavelength_nm = 635.0;
  b.scene_from_source = Rigid3d(RotationFromXyzAnglesRad({0.1, -0.2, 0.3}), Vec3(0, -27.5, 0));
  SourceDesign c;
  c.name = "C";
  c.pattern = PatternModel::kFile;
  c.beams_per_side = 5;
  c.pattern_file = dir + "/patterns/c.csv";
  c.scene_from_source = Rigid3d(RotationFromXyzAnglesRad({0.0, 0.05, 0.0}), Vec3(0, 0, 10));
  design.sources = {a, b, c};
  design.spot_noise_mm = Vec3(0.11, 0.073, 0.07);
  design.noise_frame_rotation = RotationFromXyzAnglesRad({0.2, 0.0, -0.1});

  const std::vector<Surface> surfaces = {
      PlaneSurface{Vec3(1000, 3, -2), Vec3(-1, 0.1, 0.05)},
      SphereSurface{Vec3(1500, 0, 0), 700.0},
      BoxCornerSurface{Vec3(1200, -500, -400), RotationFromXyzAnglesRad({0.0, 0.0, 0.5})},
      ParaboloidSurface{Vec3(1000, 0, 0), Vec3(-1, 0, 0), 0.0005},
      PlaneListSurface{{PlaneSurface{Vec3(750, 0, 0), Vec3(-1, 0, 0)},
                        PlaneSurface{Vec3(1350, 0, 0), Vec3(-1, 0.01, 0)}}}};
  for (const Surface& surface : surfaces) {
    SCOPED_TRACE(surface.TypeName());
    design.surface = surface;
    const std::string path = dir + "/design.json";
    ASSERT_TRUE(WriteModuleDesignJson(design, path, "written by the test").ok());
    const Result<ModuleDesign> read = ReadModuleDesignJson(path);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    ExpectSameDesign(design, *read);
    // The pattern file is named relative to the JSON's folder.
    std::ifstream in(path);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\"pattern_file\": \"patterns/c.csv\""), std::string::npos) << text;
  }
  // The bundled designs: read, written elsewhere, read again.
  const char* root = std::getenv("OPL_SOURCE_DIR");
  ASSERT_NE(root, nullptr);
  for (const char* name : {"prototype_design.json", "anisotropic_design.json", "staggered_design.json",
                           "fabricated_design.json", "scene_small_module.json",
                           "calibration_session_small_module.json"}) {
    SCOPED_TRACE(name);
    const Result<ModuleDesign> original = ReadModuleDesignJson(std::string(root) + "/examples/" + name);
    ASSERT_TRUE(original.ok()) << original.status().ToString();
    ASSERT_TRUE(WriteModuleDesignJson(*original, dir + "/copy.json").ok());
    const Result<ModuleDesign> copy = ReadModuleDesignJson(dir + "/copy.json");
    ASSERT_TRUE(copy.ok()) << copy.status().ToString();
    ExpectSameDesign(*original, *copy);
  }
}

TEST(ModuleDesignJson, WriterRefusesWhatTheFormatCannotHold) {
  ModuleDesign design;
  SourceDesign a;
  a.name = "A";
  a.beam_error_mrad = 0.1;
  a.beam_error_seed = 1ull << 40;
  design.sources = {a};
  Result<std::string> text = FormatModuleDesignJson(design);
  ASSERT_FALSE(text.ok());
  EXPECT_EQ(text.status().message(),
            "module design: source 'A': beam_error_seed 1099511627776 cannot be written (the format "
            "holds 0 to 2147483647)");
  design.sources[0].beams_per_side = 4;  // even: invalid
  text = FormatModuleDesignJson(design);
  ASSERT_FALSE(text.ok());
  EXPECT_EQ(text.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(text.status().message().rfind("module design: source 'A'", 0), 0u) << text.status().message();
  // Nothing is written on failure.
  const std::string path = TempDir() + "/refused.json";
  std::filesystem::remove(path);
  EXPECT_FALSE(WriteModuleDesignJson(design, path).ok());
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace opl
