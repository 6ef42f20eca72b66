#include "opl/pipeline/measure.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "pipeline/synthetic_module.h"

namespace opl {
namespace {

using testing_support::SceneTransform;
using testing_support::SyntheticCalibration;
using testing_support::SyntheticSpots;
using ::testing::HasSubstr;

TEST(MeasureScale, NoiseFreeSpotsGiveTheTrueScaleAndPoses) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  SceneTransform scene;
  scene.true_scale = 2.5;
  const std::vector<Spot> spots = SyntheticSpots(cal, scene);
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->sources.size(), 2u);
  EXPECT_EQ(report->sources[0].first, "A");
  EXPECT_EQ(report->sources[1].first, "B");
  for (size_t i = 0; i < 2; ++i) {
    const LocateResult& r = report->sources[i].second;
    EXPECT_EQ(r.num_spots, 121);
    EXPECT_EQ(r.num_inliers, 121);
    const Eigen::Vector3d expected =
        scene.SceneFromCalibration(cal.sources[i].calibration_from_source.translation);
    EXPECT_LT((r.scene_from_source.translation - expected).norm(), 1e-8) << i;
  }
  ASSERT_EQ(report->scale.lengths.size(), 1u);
  EXPECT_NEAR(report->scale.lengths[0].photo, cal.separations[0].length_mm / 2.5, 1e-9);
  EXPECT_NEAR(report->scale.scale_factor, 2.5, 1e-9);
  EXPECT_TRUE(report->sources_without_spots.empty());
}

// Spots at two module placements (Spot::placement, as a spots CSV's
// `placement` column gives them): each source located at each placement,
// one length per placement, s their combination; unassigned spots are
// identified one placement at a time.
TEST(MeasureScale, SpotsAtTwoPlacements) {
  // The ideal grid is symmetric under a half turn (not identifiable): each
  // beam moved by up to 2 mrad, differently in each source, as a real
  // calibration's are.
  ModuleCalibration cal = SyntheticCalibration(2);
  double phase = 0.0;
  for (SourceCalibration& source : cal.sources) {
    std::vector<Beam> beams = source.pattern.beams();
    phase += 1.0;
    for (Beam& b : beams) {
      b.az_rad += 2e-3 * std::sin(7.0 * b.id + phase);
      b.el_rad += 2e-3 * std::cos(5.0 * b.id + 2.0 * phase);
    }
    source.pattern = BeamPattern(source.pattern.beams_per_side(), beams);
  }
  SceneTransform first, second;
  first.true_scale = second.true_scale = 2.5;
  second.translation_mm = Eigen::Vector3d(300.0, -120.0, 40.0);
  std::vector<Spot> spots;
  for (Spot s : SyntheticSpots(cal, first)) {
    s.placement = "left";
    spots.push_back(s);
  }
  for (Spot s : SyntheticSpots(cal, second)) {
    s.placement = "right";
    spots.push_back(s);
  }
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->sources.size(), 4u);
  EXPECT_EQ(report->source_placements, (std::vector<std::string>{"left", "left", "right", "right"}));
  ASSERT_EQ(report->scale.lengths.size(), 2u);
  EXPECT_EQ(report->scale.lengths[1].placement, "right");
  EXPECT_NEAR(report->scale.scale_factor, 2.5, 1e-9);
  // The right placement's origins are the left's moved by the difference of
  // the translations (in unscaled units).
  EXPECT_LT((report->sources[2].second.scene_from_source.translation -
             report->sources[0].second.scene_from_source.translation -
             (second.translation_mm - first.translation_mm) / 2.5)
                .norm(),
            1e-8);
  // Unassigned: identified one placement at a time, the same result.
  for (Spot& s : spots) {
    s.source.clear();
    s.observation.beam_id = 0;
  }
  Result<MeasureReport> identified = MeasureScale(cal, spots);
  ASSERT_TRUE(identified.ok()) << identified.status().ToString();
  ASSERT_TRUE(identified->identification.has_value());
  const IdentifyResult& id = *identified->identification;
  ASSERT_EQ(id.sources.size(), 4u);
  EXPECT_EQ(id.sources[1].name, "B");
  EXPECT_EQ(id.sources[1].placement, "left");
  EXPECT_EQ(id.sources[2].name, "A");
  EXPECT_EQ(id.sources[2].placement, "right");
  EXPECT_EQ(id.num_assigned(), static_cast<int>(spots.size()));
  EXPECT_EQ(identified->source_placements, report->source_placements);
  EXPECT_NEAR(identified->scale.scale_factor, 2.5, 1e-9);
  EXPECT_THAT(identified->ToText(), HasSubstr("B at placement right: found, 121 points"));
  EXPECT_EQ(nlohmann::json::parse(identified->ToJson())["identification"]["sources"][3]["placement"], "right");
}

TEST(MeasureScale, ThreeSourcesReportConsistency) {
  const ModuleCalibration cal = SyntheticCalibration(3);
  Result<MeasureReport> report = MeasureScale(cal, SyntheticSpots(cal));
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->scale.lengths.size(), 3u);
  EXPECT_EQ(report->scale.dof, 2);
  EXPECT_NEAR(report->scale.scale_factor, 2.0, 1e-9);
  EXPECT_THAT(report->ToText(), HasSubstr("Consistency chi2/dof = "));
}

TEST(MeasureScale, SourceWithoutSpotsIsListedAndTheOthersGiveTheScale) {
  const ModuleCalibration cal = SyntheticCalibration(3);
  std::vector<Spot> spots;
  for (const Spot& s : SyntheticSpots(cal)) {
    if (s.source != "B") spots.push_back(s);
  }
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->sources_without_spots, std::vector<std::string>{"B"});
  ASSERT_EQ(report->scale.lengths.size(), 1u);
  EXPECT_EQ(report->scale.lengths[0].from, "A");
  EXPECT_EQ(report->scale.lengths[0].to, "C");
  EXPECT_NEAR(report->scale.scale_factor, 2.0, 1e-9);
  EXPECT_THAT(report->ToText(), HasSubstr("Source B: no spots, not located"));
}

TEST(MeasureScale, OutlierIsReportedByBeamId) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots = SyntheticSpots(cal);
  // Beam 17 of source A, moved 5 mm (2.5 scene units) sideways.
  for (Spot& s : spots) {
    if (s.source == "A" && s.observation.beam_id == 17) {
      s.observation.point_in_scene += Eigen::Vector3d(0.0, 0.0, 2.5);
    }
  }
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->sources[0].second.OutlierBeamIds(), std::vector<int>{17});
  EXPECT_TRUE(report->sources[1].second.OutlierBeamIds().empty());
  EXPECT_NEAR(report->scale.scale_factor, 2.0, 1e-7);
  EXPECT_THAT(report->ToText(), HasSubstr("Source A: 121 spots, 120 used, 1 outliers (beams 17)"));
  const nlohmann::json j = nlohmann::json::parse(report->ToJson());
  EXPECT_EQ(j["sources"][0]["outliers"], nlohmann::json::array({17}));
  EXPECT_EQ(j["sources"][0]["n_spots"], 121);
}

TEST(MeasureScale, JsonHasTheDocumentedFieldsAndRoundTripsNumbers) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  Result<MeasureReport> report = MeasureScale(cal, SyntheticSpots(cal));
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  const nlohmann::json j = nlohmann::json::parse(report->ToJson());
  EXPECT_EQ(j["format"], "opl.measure_report");
  EXPECT_EQ(j["version"], 1);
  ASSERT_EQ(j["sources"].size(), 2u);
  const nlohmann::json& a = j["sources"][0];
  EXPECT_EQ(a["name"], "A");
  const LocateResult& r = report->sources[0].second;
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(a["origin"][k].get<double>(), r.scene_from_source.translation[k]);
    EXPECT_EQ(a["rotation_xyz_rad"][k].get<double>(), r.rotation_xyz_rad[k]);
    for (int l = 0; l < 3; ++l) EXPECT_EQ(a["origin_cov"][k][l].get<double>(), r.origin_covariance(k, l));
  }
  EXPECT_EQ(a["rms_residual_urad"].get<double>(), r.rms_residual_rad * 1e6);
  EXPECT_EQ(a["n_spots"], 121);
  EXPECT_TRUE(a["outliers"].is_array());
  ASSERT_EQ(j["lengths"].size(), 1u);
  EXPECT_EQ(j["lengths"][0]["from"], "A");
  EXPECT_EQ(j["lengths"][0]["to"], "B");
  EXPECT_EQ(j["lengths"][0]["cal"].get<double>(), cal.separations[0].length_mm);
  EXPECT_EQ(j["lengths"][0]["photo"].get<double>(), report->scale.lengths[0].photo);
  EXPECT_EQ(j["lengths"][0]["u_photo"].get<double>(), report->scale.lengths[0].u_photo);
  EXPECT_EQ(j["scale_factor"].get<double>(), report->scale.scale_factor);
  EXPECT_EQ(j["u_scale_factor"].get<double>(), report->scale.u_scale_factor);
  EXPECT_EQ(j["expanded_u_scale_factor"].get<double>(), 2.0 * report->scale.u_scale_factor);
  EXPECT_EQ(j["coverage_factor"].get<int>(), 2);
  EXPECT_EQ(j["units"]["scale_factor"], "mm per scene unit");
}

TEST(MeasureScale, TextSummaryShowsEverySection) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  Result<MeasureReport> report = MeasureScale(cal, SyntheticSpots(cal));
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  const std::string text = report->ToText();
  EXPECT_THAT(text, HasSubstr("Source A: 121 spots, 121 used, 0 outliers\n"));
  EXPECT_THAT(text, HasSubstr("  origin std dev  ("));
  EXPECT_THAT(text, HasSubstr("urad"));
  EXPECT_THAT(text, HasSubstr("  A-B: photo 27.501420 +- "));  // 55.002841 mm / 2
  EXPECT_THAT(text, HasSubstr("Scale factor s = 2.000000000 +- "));
  EXPECT_THAT(text, HasSubstr("Expanded uncertainty U = " +
                              FormatPrintf("%.9f", 2.0 * report->scale.u_scale_factor) + " (k = 2"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("Consistency")));  // one length only
}

TEST(MeasureScale, UnknownSourceNamesTheSpotAndTheSource) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots = SyntheticSpots(cal);
  spots[3].source = "Z";
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(report.status().message(),
            "spots.csv:5: unknown source 'Z' (the calibration has A, B)");
}

TEST(MeasureScale, DuplicateSourceBeamNamesBothLines) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots = SyntheticSpots(cal);
  spots[10].observation.beam_id = spots[4].observation.beam_id;  // both A, beam 5
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(report.status().message(),
            "spots.csv:12: duplicate spot of source 'A' beam 5 (also at spots.csv:6)");
}

TEST(MeasureScale, SameBeamIdOfTwoSourcesIsNotADuplicate) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  // Every beam id appears once for A and once for B.
  EXPECT_TRUE(MeasureScale(cal, SyntheticSpots(cal)).ok());
}

TEST(MeasureScale, BeamUnknownToThePattern) {
  ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots = SyntheticSpots(cal);
  spots[0].observation.beam_id = 122;
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(report.status().message(),
            "spots.csv:2: source 'A' has no beam 122 in the calibration (11 x 11 grid, 121 "
            "beams calibrated)");
}

TEST(MeasureScale, TooFewSpotsIsNoSolutionNamingTheSource) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots;
  int kept_b = 0;
  for (const Spot& s : SyntheticSpots(cal)) {
    if (s.source == "A" || (kept_b < 3 && (s.observation.beam_id % 13 == 0) && ++kept_b)) {
      spots.push_back(s);
    }
  }
  ASSERT_EQ(kept_b, 3);
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNoSolution);
  EXPECT_THAT(report.status().message(), ::testing::StartsWith("source 'B': "));
}

TEST(MeasureScale, CollinearSpotsAreNoSolutionNamingTheSource) {
  const ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots;
  for (const Spot& s : SyntheticSpots(cal)) {
    // Source A keeps only its central row: on the wall plane, a straight line.
    const bool central_row = (s.observation.beam_id - 1) / 11 == 5;
    if (s.source == "B" || central_row) spots.push_back(s);
  }
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNoSolution);
  EXPECT_THAT(report.status().message(), ::testing::StartsWith("source 'A': "));
}

TEST(MeasureScale, NoSeparationBetweenLocatedSourcesIsNoSolution) {
  ModuleCalibration cal = SyntheticCalibration(2);
  std::vector<Spot> spots;
  for (const Spot& s : SyntheticSpots(cal)) {
    if (s.source == "A") spots.push_back(s);
  }
  Result<MeasureReport> report = MeasureScale(cal, spots);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNoSolution);
  EXPECT_THAT(report.status().message(), HasSubstr("(located: A)"));
}

TEST(MeasureScale, NoSpotsAtAllIsNoSolution) {
  Result<MeasureReport> report = MeasureScale(SyntheticCalibration(2), {});
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNoSolution);
}

TEST(MeasureScale, InvalidOptionsAreRejected) {
  MeasureOptions options;
  options.locate.outlier_threshold = -1.0;
  const ModuleCalibration cal = SyntheticCalibration(2);
  Result<MeasureReport> report = MeasureScale(cal, SyntheticSpots(cal), options);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(report.status().message(), ::testing::StartsWith("locate options: "));
}

}  // namespace
}  // namespace opl
