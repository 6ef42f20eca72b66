// Identifying a calibration session (identify_slices.h): the prototype's two
// sources have the same ideal pattern, symmetric under a 90 deg roll, so a
// grid alone fits 8 numberings of either source. With the design's mounting
// as prior every slice is identified, every assignment checked against the
// simulation's truth; the same session in a module frame turned by a random
// rotation (the design turned with it) too; and without the prior the same
// slice is ambiguous.
#include "opl/identify/identify_slices.h"

#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "opl/sim/module_design.h"
#include "opl/sim/simulate_slices.h"
#include "support/calibration_session.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

struct Session {
  ModuleDesign design;
  std::vector<SimulatedSpot> simulated;
  std::vector<Spot> unlabelled;
  std::vector<int> slices;
};

Session MakeSession(const Rigid3d& frame, uint64_t seed) {
  Session s;
  s.design = test::Prototype().Transformed(frame);
  ScreenSlicesOptions screens;
  screens.depths_mm = {750, 900, 1050, 1200, 1335};
  screens.tilt_deg = 5.0;
  Result<std::vector<Surface>> made = MakeCalibrationScreens(s.design, screens);
  EXPECT_TRUE(made.ok()) << made.status().message();
  SpotSimulationOptions options;
  options.seed = seed;
  options.missing_fraction = 0.1;
  options.outlier_fraction = 0.01;
  Result<std::vector<SimulatedSpot>> simulated = SimulateSlices(s.design, *made, options);
  EXPECT_TRUE(simulated.ok()) << simulated.status().message();
  s.simulated = *simulated;
  s.slices = test::OneGridPerSlice(s.simulated, s.design);
  for (const SimulatedSpot& spot : s.simulated) {
    Spot u = spot.spot;
    u.source.clear();
    u.observation.beam_id = 0;
    s.unlabelled.push_back(u);
  }
  return s;
}

// Every assigned spot carries its true source and beam; at least 98 % of the
// spots that were not moved are assigned; every slice names one source.
void ExpectCorrect(const Session& s, const SessionIdentification& id) {
  size_t k = 0, right = 0, clean = 0;
  for (size_t i = 0; i < s.simulated.size(); ++i) {
    if (!s.simulated[i].outlier) ++clean;
    if (k < id.spots.size() && id.spots[k].where == s.simulated[i].spot.where &&
        id.spots[k].observation.point_in_scene == s.simulated[i].spot.observation.point_in_scene) {
      EXPECT_EQ(id.spots[k].source, s.simulated[i].spot.source) << i;
      EXPECT_EQ(id.spots[k].observation.beam_id, s.simulated[i].spot.observation.beam_id) << i;
      EXPECT_EQ(id.slices[k], s.slices[i]);
      right += id.spots[k].source == s.simulated[i].spot.source &&
               id.spots[k].observation.beam_id == s.simulated[i].spot.observation.beam_id;
      ++k;
    }
  }
  EXPECT_EQ(k, id.spots.size());  // every output spot matched an input, in order
  EXPECT_GE(right, 0.98 * clean) << right << " of " << clean;
  for (const SliceIdentification& slice : id.per_slice) {
    EXPECT_TRUE(slice.detail.empty()) << "slice " << slice.slice << ": " << slice.detail;
    EXPECT_EQ(slice.source, slice.slice >= 1000 ? "B" : "A");
  }
}

TEST(IdentifySessionSlices, SymmetricIdenticalPatternsAreNumberedAsMounted) {
  const Session s = MakeSession(Rigid3d(), 3);
  Result<ModuleCalibration> nominal = ExactCalibration(s.design);
  ASSERT_TRUE(nominal.ok());
  Result<SessionIdentification> id = IdentifySessionSlices(*nominal, s.unlabelled, s.slices);
  ASSERT_TRUE(id.ok()) << id.status().message();
  EXPECT_EQ(id->per_slice.size(), 10u);
  ExpectCorrect(s, *id);
  EXPECT_NE(id->ToText().find("spots assigned in 10 slices"), std::string::npos);
}

TEST(IdentifySessionSlices, AnyModuleFrame) {
  std::mt19937_64 rng(17);
  for (int trial = 0; trial < 3; ++trial) {
    const Session s = MakeSession(test::RandomMotion(rng, 500.0), 10 + trial);
    Result<ModuleCalibration> nominal = ExactCalibration(s.design);
    ASSERT_TRUE(nominal.ok());
    Result<SessionIdentification> id = IdentifySessionSlices(*nominal, s.unlabelled, s.slices);
    ASSERT_TRUE(id.ok()) << id.status().message();
    ExpectCorrect(s, *id);
  }
}

// Without the mounting prior a slice of this module cannot be identified.
TEST(IdentifySessionSlices, WithoutThePriorTheSliceIsAmbiguous) {
  const Session s = MakeSession(Rigid3d(), 4);
  Result<ModuleCalibration> nominal = ExactCalibration(s.design);
  ASSERT_TRUE(nominal.ok());
  std::vector<Spot> slice0;
  for (size_t i = 0; i < s.unlabelled.size(); ++i) {
    if (s.slices[i] == 0) slice0.push_back(s.unlabelled[i]);
  }
  IdentifyOptions options;
  options.directions_nominal = true;
  Result<IdentifyResult> r = IdentifySpots(*nominal, slice0, options);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->num_assigned(), 0);
  EXPECT_EQ(r->sources[0].outcome, IdentifyOutcome::kAmbiguous) << r->sources[0].detail;
}

TEST(IdentifySessionSlices, Errors) {
  const Session s = MakeSession(Rigid3d(), 5);
  Result<ModuleCalibration> nominal = ExactCalibration(s.design);
  ASSERT_TRUE(nominal.ok());
  std::vector<int> short_slices(s.slices.begin(), s.slices.end() - 1);
  EXPECT_EQ(IdentifySessionSlices(*nominal, s.unlabelled, short_slices).status().message(),
            std::to_string(s.unlabelled.size()) + " spots but " +
                std::to_string(short_slices.size()) + " slices");
  IdentifyOptions options;
  options.expected_rotation_tolerance_deg = 60.0;
  EXPECT_EQ(IdentifySessionSlices(*nominal, s.unlabelled, s.slices, options).status().code(),
            StatusCode::kInvalidArgument);
  options = IdentifyOptions();
  options.expected_origin["C"] = Eigen::Vector3d::Zero();
  options.expected_origin_tolerance = 10.0;
  EXPECT_EQ(IdentifySessionSlices(*nominal, s.unlabelled, s.slices, options).status().message(),
            "IdentifyOptions.expected_origin: unknown source 'C'");
}

}  // namespace
}  // namespace opl
