#include "opl/report/calibration_report.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "opl/sim/simulate_slices.h"
#include "support/calibration_session.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

using ::testing::HasSubstr;

// A session of the prototype where source A's beam 7 is seen on one screen
// only (so it is dropped) and 1% of the spots are wrong.
ModuleCalibrationResult Calibrated() {
  const ModuleDesign design = test::Prototype();
  ScreenSlicesOptions screens;
  screens.depths_mm = *ParseDepthList("750:65:1335");
  SpotSimulationOptions options;
  options.seed = 21;
  options.outlier_fraction = 0.01;
  std::vector<SimulatedSpot> spots =
      *SimulateSlices(design, *MakeCalibrationScreens(design, screens), options);
  std::vector<SimulatedSpot> kept;
  for (const SimulatedSpot& s : spots) {
    if (s.spot.source == "A" && s.spot.observation.beam_id == 7 && s.slice > 0) continue;
    kept.push_back(s);
  }
  Result<ModuleCalibrationResult> r =
      CalibrateModule(SpotsOf(kept), test::OneGridPerSlice(kept, design), std::nullopt);
  EXPECT_TRUE(r.ok()) << r.status().message();
  return *r;
}

std::vector<std::vector<std::string>> CsvRows(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::string field;
    std::istringstream l(line);
    while (std::getline(l, field, ',')) fields.push_back(field);
    if (!line.empty() && line.back() == ',') fields.push_back("");
    rows.push_back(fields);
  }
  return rows;
}

TEST(CalibrationReport, BeamTableHasEveryBeamAndTheDroppedOne) {
  const ModuleCalibrationResult r = Calibrated();
  ASSERT_EQ(r.sources[0].dropped_beam_ids, std::vector<int>{7});
  const auto rows = CsvRows(BeamQualityCsv(r));
  ASSERT_EQ(rows.size(), 1u + 121u + 121u);
  EXPECT_EQ(rows[0].size(), 13u);
  // Row of A's beam 7 (the 7th data row: sorted by id): no direction, 1 sample.
  EXPECT_EQ(rows[7][0], "A");
  EXPECT_EQ(rows[7][1], "7");
  EXPECT_EQ(rows[7][2], "0");
  EXPECT_EQ(rows[7][3], "6");
  EXPECT_EQ(rows[7][4], "");
  EXPECT_EQ(rows[7][8], "0");
  EXPECT_EQ(rows[7][9], "1");
  // Every other row's mean distance is the mean over that beam's used samples.
  for (size_t i = 1; i < rows.size(); ++i) {
    if (rows[i][4].empty()) continue;
    const SourceCalibrationResult& s = r.sources[rows[i][0] == "A" ? 0 : 1];
    const int id = std::stoi(rows[i][1]);
    double sum = 0.0;
    int n = 0;
    for (const CalibrationSampleResidual& res : s.residuals) {
      if (res.beam_id == id && !res.outlier && !res.beam_dropped) {
        sum += res.point_to_ray_mm;
        ++n;
      }
    }
    EXPECT_EQ(std::stoi(rows[i][8]), n);
    EXPECT_NEAR(std::stod(rows[i][10]), sum / n, 1e-9 * (1.0 + sum / n)) << "row " << i;
  }
}

TEST(CalibrationReport, SampleTableAndSummaryAgreeWithTheResult) {
  const ModuleCalibrationResult r = Calibrated();
  const auto rows = CsvRows(SampleResidualsCsv(r));
  size_t samples = 0;
  int flagged = 0, dropped = 0;
  for (const SourceCalibrationResult& s : r.sources) samples += s.residuals.size();
  ASSERT_EQ(rows.size(), 1 + samples);
  for (size_t i = 1; i < rows.size(); ++i) {
    flagged += rows[i][7] == "flagged";
    dropped += rows[i][7] == "beam_dropped";
  }
  EXPECT_EQ(dropped, 1);
  EXPECT_EQ(flagged, r.sources[0].calibration.quality->samples_flagged +
                         r.sources[1].calibration.quality->samples_flagged);
  EXPECT_GT(flagged, 0);
  const std::string text = CalibrationSummaryText(r);
  EXPECT_THAT(text, HasSubstr("source A (11 x 11, 10 slices)"));
  EXPECT_THAT(text, HasSubstr("dropped (too few good samples): 7"));
  EXPECT_THAT(text, HasSubstr("separations (calibrated length scales, u at k = 1)\n  A-B  "));
  EXPECT_THAT(text, HasSubstr("scaling         none"));
}

TEST(CalibrationReport, HeatmapHoldsEachBeamsMeanDistance) {
  const ModuleCalibrationResult r = Calibrated();
  const GridHeatmap h = PointToRayHeatmap(r.sources[0]);
  ASSERT_EQ(h.beams_per_side, 11);
  ASSERT_EQ(h.values.size(), 121u);
  EXPECT_TRUE(std::isnan(h.values[6]));  // beam 7, dropped: no data
  for (const BeamCalibrationQuality& b : r.sources[0].beams) {
    EXPECT_EQ(h.values[b.beam_id - 1], b.mean_point_to_ray_mm);
  }
  EXPECT_THAT(h.title, HasSubstr("Source A"));
  EXPECT_THAT(h.value_label, HasSubstr("[mm]"));
  EXPECT_TRUE(LayoutGridHeatmap(h).ok());
}

// The automatic noise level, checked by simulation with known truth: on
// sessions of pure noise every beam of a source is at or below it in about
// 95 % of sessions (alpha = 0.05, family-wise over the 121 beams); with one
// beam's samples moved off its ray by k sigma (each in a random direction
// perpendicular to the ray; k = 3 by default: further off, the samples are
// flagged as outliers and leave the beam's mean) that beam is above it.
// ctest runs 20 seeds; OPL_NOISE_LEVEL_SEEDS=N (and OPL_NOISE_LEVEL_K=k) runs
// N and prints the counts (the header quotes them).
struct LevelTrial {
  int sources = 0, all_below = 0;  // pure noise
  int displaced = 0, displaced_seen = 0;  // the displaced beam above the level
  int displaced_used = 0;                 // its used samples, summed
};

ModuleCalibrationResult CalibrateSpots(const ModuleDesign& design, const std::vector<SimulatedSpot>& spots) {
  Result<ModuleCalibrationResult> r =
      CalibrateModule(SpotsOf(spots), test::OneGridPerSlice(spots, design), std::nullopt);
  EXPECT_TRUE(r.ok()) << r.status().message();
  return r.ok() ? *r : ModuleCalibrationResult{};
}

bool AllBelow(const SourceCalibrationResult& s, double level) {
  for (const BeamCalibrationQuality& b : s.beams) {
    if (b.mean_point_to_ray_mm > level) return false;
  }
  return true;
}

TEST(CalibrationReport, AutomaticNoiseLevelHoldsOnPureNoiseAndSeesADisplacedBeam) {
  const char* env = std::getenv("OPL_NOISE_LEVEL_SEEDS");
  const int seeds = env != nullptr ? std::atoi(env) : 20;
  const char* k_env = std::getenv("OPL_NOISE_LEVEL_K");
  const double k = k_env != nullptr ? std::atof(k_env) : 3.0;
  const ModuleDesign design = test::Prototype();
  ScreenSlicesOptions screens;
  screens.depths_mm = *ParseDepthList("750:65:1335");
  const std::vector<Surface> surfaces = *MakeCalibrationScreens(design, screens);
  const double sigma_perp = 0.073;  // the noise across the beams (Y, Z)
  const int displaced_beam = 40;
  LevelTrial t;
  for (int seed = 1; seed <= seeds; ++seed) {
    SpotSimulationOptions options;
    options.seed = static_cast<uint64_t>(seed);
    std::vector<SimulatedSpot> spots = *SimulateSlices(design, surfaces, options);
    const ModuleCalibrationResult pure = CalibrateSpots(design, spots);
    for (const SourceCalibrationResult& s : pure.sources) {
      const double level = PointToRayNoiseLevel(s);
      ASSERT_TRUE(std::isfinite(level));
      ++t.sources;
      t.all_below += AllBelow(s, level);
    }
    // Source A's beam 40 moved off its ray.
    std::mt19937_64 rng(1000 + seed);
    std::uniform_real_distribution<double> angle(0.0, 2 * M_PI);
    const Eigen::Vector3d origin = design.sources[0].scene_from_source.translation;
    for (SimulatedSpot& s : spots) {
      if (s.spot.source != "A" || s.spot.observation.beam_id != displaced_beam) continue;
      const Eigen::Vector3d ray = (s.true_point_in_scene - origin).normalized();
      const Eigen::Vector3d u = ray.unitOrthogonal(), v = ray.cross(u);
      const double a = angle(rng);
      s.spot.observation.point_in_scene += k * sigma_perp * (std::cos(a) * u + std::sin(a) * v);
    }
    const ModuleCalibrationResult moved = CalibrateSpots(design, spots);
    const SourceCalibrationResult& a = moved.sources[0];
    const double level = PointToRayNoiseLevel(a);
    ++t.displaced;
    for (const BeamCalibrationQuality& b : a.beams) {
      if (b.beam_id != displaced_beam) continue;
      t.displaced_seen += b.mean_point_to_ray_mm > level;
      t.displaced_used += b.samples_used;
    }
    if (env != nullptr) {
      std::printf("seed %d: level A %.4f B %.4f mm (max A %.4f, B %.4f); displaced: level %.4f\n", seed,
                  PointToRayNoiseLevel(pure.sources[0]), PointToRayNoiseLevel(pure.sources[1]),
                  pure.sources[0].calibration.quality->max_point_to_ray_mm,
                  pure.sources[1].calibration.quality->max_point_to_ray_mm, level);
    }
  }
  std::printf("pure noise: all beams at or below the level in %d of %d sources; displaced beam (k = %.1f) "
              "above it in %d of %d sessions, %.1f used samples on average\n",
              t.all_below, t.sources, k, t.displaced_seen, t.displaced,
              static_cast<double>(t.displaced_used) / t.displaced);
  if (env == nullptr) {
    // 40 sources at 95 %: 38 expected; fewer than 36 has probability 0.05
    // (binomial) with an honest level, 0.74 with one at 85 % (the pooled
    // model without the beams' own spread gave 88.5 %). The seeds are fixed.
    EXPECT_GE(t.all_below, 36) << "of " << t.sources;
    EXPECT_GE(t.displaced_seen, 18) << "of " << t.displaced;
  }
}

}  // namespace
}  // namespace opl
