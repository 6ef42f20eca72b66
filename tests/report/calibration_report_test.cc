#include "opl/report/calibration_report.h"

#include <cmath>
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

}  // namespace
}  // namespace opl
