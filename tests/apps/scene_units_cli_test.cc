// Issue 19 item 4, "units must not matter": the same spots in another scene
// unit (micrometres: x 1000; metres: x 0.001; anything from 1e-6 to 1e6) or
// shifted far from the origin (up to 1e7 units) are the same measurement. The
// tools used to refuse them as degenerate (exit 4, "normal matrix singular",
// "are the slices at distinct depths?") because their tests of singularity
// were absolute. Now the scale factor s of opl_measure times the scene scale
// is the same to ~1e-9, and so is a calibrated separation divided by it.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "io/temp_dir.h"
#include "support/provenance_strip.h"

namespace opl {
namespace {

using cli_test::Calibrate;
using cli_test::Measure;
using cli_test::RunResult;
using cli_test::Simulate;
// What the tools wrote, compared without the provenance they stamp in
// (its time and command line differ by run; tests/apps/provenance_cli_test.cc
// checks it).
std::string ReadAll(const std::string& path) { return testing_support::ReadOutput(path); }
using testing_support::TempDir;

const std::string kExamples = OPL_EXAMPLES_DIR;

// `csv` (plain, unquoted fields) with every position column (x, y, z,
// true_x, true_y, true_z) mapped to v * scale + offset and every sigma (sx,
// sy, sz) to v * scale; with `unassign`, source and beam emptied.
std::string Transformed(const std::string& csv, double scale, double offset,
                        bool unassign = false) {
  std::istringstream in(csv);
  std::string line, out;
  std::vector<int> kind;  // 0 keep, 1 position, 2 sigma, 3 emptied
  bool header = true;
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::stringstream ls(line);
    std::string f;
    while (std::getline(ls, f, ',')) fields.push_back(f);
    if (!line.empty() && line.back() == ',') fields.push_back("");
    if (header) {
      for (const std::string& name : fields) {
        const bool position = name == "x" || name == "y" || name == "z" || name == "true_x" ||
                              name == "true_y" || name == "true_z";
        const bool sigma = name == "sx" || name == "sy" || name == "sz";
        const bool emptied = unassign && (name == "source" || name == "beam");
        kind.push_back(position ? 1 : sigma ? 2 : emptied ? 3 : 0);
      }
      header = false;
      out += line + "\n";
      continue;
    }
    for (size_t i = 0; i < fields.size(); ++i) {
      if (i < kind.size() && (kind[i] == 1 || kind[i] == 2)) {
        const double v = std::stod(fields[i]) * scale + (kind[i] == 1 ? offset : 0.0);
        std::ostringstream os;
        os.precision(17);
        os << v;
        fields[i] = os.str();
      } else if (i < kind.size() && kind[i] == 3) {
        fields[i].clear();
      }
      out += (i ? "," : "") + fields[i];
    }
    out += "\n";
  }
  return out;
}

// The scale factor opl_measure prints with --json (NaN when it fails).
double MeasuredScale(const std::string& calibration, const std::string& spots,
                     const std::string& what) {
  const RunResult r = Measure("--calibration " + calibration + " --spots " + spots + " --json");
  EXPECT_EQ(r.exit_code, 0) << what << "\n" << r.err;
  EXPECT_THAT(r.err, ::testing::Not(::testing::HasSubstr("degenerate"))) << what;
  if (r.exit_code != 0) return std::nan("");
  return nlohmann::json::parse(r.out).at("scale_factor").get<double>();
}

TEST(SceneUnits, MeasuredScaleDoesNotDependOnTheSceneUnitNorOrigin) {
  TempDir dir;
  const std::string calibration = kExamples + "/prototype_calibration.json";
  const std::string spots = ReadAll(kExamples + "/prototype_spots.csv");
  const double reference = MeasuredScale(calibration, kExamples + "/prototype_spots.csv", "as is");
  ASSERT_TRUE(std::isfinite(reference));
  for (const double scale : {1e-6, 1e-3, 0.25, 300.0, 500.0, 1000.0, 1e6}) {
    for (const double offset_mm : {0.0, 1e4, 1e7}) {
      // The offset in scene units; 1e7 mm at scale 1e-6 would leave the
      // spots 7 digits of the 16 a double has: kept to 1e7 units at most.
      const double offset = std::min(offset_mm * scale, 1e7);
      const std::string what = "scale " + std::to_string(scale) + ", offset " +
                               std::to_string(offset);
      dir.Write("s.csv", Transformed(spots, scale, offset));
      const double s = MeasuredScale(calibration, dir.File("s.csv"), what);
      // A far origin costs digits: 1e7 units at a 1e-16 resolution.
      const double tolerance = 1e-9 + 1e-16 * offset / (1000.0 * scale) * 1e4;
      EXPECT_NEAR(s * scale / reference, 1.0, tolerance) << what;
    }
  }
}

// Unassigned spots are identified first (the fabricated module: its sources
// differ, so that identification can tell them apart).
TEST(SceneUnits, IdentifiedSpotsDoNotDependOnTheSceneUnit) {
  TempDir dir;
  const std::string design = kExamples + "/fabricated_design.json";
  ASSERT_EQ(Simulate("calibration --design " + design + " --out " + dir.File("cal.json")).exit_code,
            0);
  ASSERT_EQ(Simulate("spots --design " + design + " --out " + dir.File("spots.csv")).exit_code, 0);
  const std::string spots = ReadAll(dir.File("spots.csv"));
  dir.Write("u.csv", Transformed(spots, 1.0, 0.0, /*unassign=*/true));
  const double reference = MeasuredScale(dir.File("cal.json"), dir.File("u.csv"), "unassigned");
  ASSERT_TRUE(std::isfinite(reference));
  for (const double scale : {1e-6, 1000.0, 1e6}) {
    const std::string what = "unassigned, scale " + std::to_string(scale);
    dir.Write("u.csv", Transformed(spots, scale, 1e4 * std::min(scale, 1.0), true));
    const double s = MeasuredScale(dir.File("cal.json"), dir.File("u.csv"), what);
    EXPECT_NEAR(s * scale / reference, 1.0, 1e-9) << what;
  }
}

TEST(SceneUnits, CalibratedSeparationDoesNotDependOnTheUnit) {
  TempDir dir;
  ASSERT_EQ(Simulate("slices --design " + kExamples + "/prototype_design.json --depths "
                     "750:65:1335 --out " + dir.File("slices.csv"))
                .exit_code,
            0);
  const std::string slices = ReadAll(dir.File("slices.csv"));
  auto separation = [&](double scale, double offset) {
    const std::string what = "scale " + std::to_string(scale) + ", offset " +
                             std::to_string(offset);
    dir.Write("t.csv", Transformed(slices, scale, offset));
    const RunResult r = Calibrate("--spots " + dir.File("t.csv") + " --out " +
                                  dir.File("cal.json"));
    EXPECT_EQ(r.exit_code, 0) << what << "\n" << r.err;
    EXPECT_THAT(r.err, ::testing::Not(::testing::HasSubstr("distinct depths"))) << what;
    if (r.exit_code != 0) return std::nan("");
    const nlohmann::json cal = nlohmann::json::parse(ReadAll(dir.File("cal.json")));
    return cal.at("separations").at(0).at("length_mm").get<double>() / scale;
  };
  const double reference = separation(1.0, 0.0);
  ASSERT_TRUE(std::isfinite(reference));
  for (const double scale : {1e-6, 1e-3, 300.0, 1000.0, 1e6}) {
    // The solver stops within ~4e-9 of the optimum (its step tolerance);
    // the separation's own uncertainty is 3e-4.
    EXPECT_NEAR(separation(scale, 0.0) / reference, 1.0, 1e-8) << scale;
  }
  EXPECT_NEAR(separation(1.0, 1e7) / reference, 1.0, 1e-6);
}

}  // namespace
}  // namespace opl
