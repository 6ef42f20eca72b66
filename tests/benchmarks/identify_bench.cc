// Benchmark of spot identification (issue 5): a scene of two calibrated
// 11 x 11 grids (equal-angle / grating designs perturbed by 2 mrad per beam)
// on a plane ~1 m away, partly overlapping, 10% spurious points (half of them
// 0.5-3 mm from a real spot), no spot missing, 0.110/0.073/0.073 mm noise,
// the module at a random pose. Target: 5 ms median on one core.
#include <benchmark/benchmark.h>

#include "opl/identify/identify_spots.h"
#include "support/identify_scene.h"

namespace {

opl::test::IdentifyScene MakeBenchScene() {
  opl::test::IdentifySceneOptions o;
  o.sources = 2;
  o.surface = 0;
  o.max_missing = 0.0;
  o.max_spurious = 0.1;
  o.min_distance_mm = 1000.0;
  o.max_distance_mm = 1000.0;
  // max_spurious is the upper end of a uniform draw; pick a seed whose draw
  // is near 10%.
  for (uint64_t seed = 1;; ++seed) {
    opl::test::IdentifyScene s = opl::test::MakeIdentifyScene(seed, o);
    if (s.spurious * 100 >= 9 * s.real) return s;
  }
}

// state.range(0): IdentifyOptions::num_threads (the seed search's threads).
void BM_IdentifyTwoGrids(benchmark::State& state) {
  const opl::test::IdentifyScene scene = MakeBenchScene();
  opl::IdentifyOptions options;
  options.num_threads = static_cast<int>(state.range(0));
  int assigned = 0;
  for (auto _ : state) {
    auto r = opl::IdentifySpots(scene.calibration, scene.spots, options);
    assigned = r.ok() ? r->num_assigned() : -1;
    benchmark::DoNotOptimize(r);
  }
  state.counters["points"] = static_cast<double>(scene.spots.size());
  state.counters["assigned"] = assigned;
}
BENCHMARK(BM_IdentifyTwoGrids)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

namespace {

// Large unassigned sets (issue 19 item 8): two sources of n x n beams over
// 29 deg at 1 m on a plane, 10 % clutter (half of it near real spots), none
// missing. The spot noise and the calibration's departure from the design
// shrink with the spacing (x 10 / (n - 1)), so that every n is the 11 x 11
// bench scene made denser, identifiable alike.
// state.range(0) = n: 71 (1.05e4 points), 121 (3.0e4). n = 201 (8.4e4
// points) finds no source yet and takes minutes: not benchmarked. Not in
// the ctest smoke run (seconds each).
void BM_IdentifyLargeUnassignedSet(benchmark::State& state) {
  opl::test::IdentifySceneOptions o;
  o.sources = 2;
  o.beams_per_side = static_cast<int>(state.range(0));
  const double denser = 10.0 / (o.beams_per_side - 1);
  o.noise_mm *= denser;
  o.perturbation_rad *= denser;
  o.surface = 0;
  o.max_missing = 0.0;
  o.max_spurious = 0.1;
  o.min_distance_mm = 1000.0;
  o.max_distance_mm = 1000.0;
  const opl::test::IdentifyScene scene = opl::test::MakeIdentifyScene(7, o);
  opl::IdentifyOptions options;
  options.num_threads = 2;
  int assigned = 0;
  for (auto _ : state) {
    auto r = opl::IdentifySpots(scene.calibration, scene.spots, options);
    assigned = r.ok() ? r->num_assigned() : -1;
    benchmark::DoNotOptimize(r);
  }
  state.counters["points"] = static_cast<double>(scene.spots.size());
  state.counters["real"] = scene.real;
  state.counters["assigned"] = assigned;
}
BENCHMARK(BM_IdentifyLargeUnassignedSet)->Arg(71)->Arg(121)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

}  // namespace
