// Calibrating a module: two 11 x 11 sources from 10 slices each (the prototype-
// like design, screens 750..1335 mm, spot noise 0.110/0.073/0.073 mm, 5% of
// spots missing), the whole CalibrateModule: initialisation, solves, flagging
// and covariance. Issue target: 50 ms median on one core.
#include <benchmark/benchmark.h>

#include "opl/calibrate/calibrate_module.h"
#include "opl/sim/simulate_slices.h"
#include "support/calibration_session.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

struct Session {
  std::vector<Spot> spots;
  std::vector<int> slices;
};

Session MakeSession(double outliers) {
  const ModuleDesign design = test::Prototype();
  ScreenSlicesOptions screens;
  screens.depths_mm = *ParseDepthList("750:65:1335");
  SpotSimulationOptions options;
  options.seed = 11;
  options.missing_fraction = 0.05;
  options.outlier_fraction = outliers;
  const std::vector<SimulatedSpot> spots =
      *SimulateSlices(design, *MakeCalibrationScreens(design, screens), options);
  return {SpotsOf(spots), test::OneGridPerSlice(spots, design)};
}

// state.range(0): 0 = clean session, 1 = 1% wrong samples (robust phase runs).
void BM_CalibrateTwoSources(benchmark::State& state) {
  const Session s = MakeSession(state.range(0) ? 0.01 : 0.0);
  for (auto _ : state) {
    Result<ModuleCalibrationResult> r = CalibrateModule(s.spots, s.slices, std::nullopt);
    if (!r.ok()) state.SkipWithError(r.status().message().c_str());
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK(BM_CalibrateTwoSources)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace opl
