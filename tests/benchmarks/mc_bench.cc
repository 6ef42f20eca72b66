// Benchmark of the measurement Monte Carlo (docs/uncertainty.md): 5000
// iterations of the staggered prototype-like design (two 11 x 11 sources, 29
// deg, origins 39 mm apart across and in depth, screen at 1 m, spot noise
// 0.110 / 0.073 / 0.073 mm) on 2 threads, wall time. Target: <= 1 s median on
// 2 cores.
#include <benchmark/benchmark.h>

#include "opl/sim/module_design.h"
#include "opl/uncertainty/monte_carlo.h"

namespace {

opl::ModuleDesign StaggeredDesign() {
  opl::ModuleDesign design;
  for (int i = 0; i < 2; ++i) {
    opl::SourceDesign s;
    s.name = i == 0 ? "A" : "B";
    s.beams_per_side = 11;
    s.full_angle_deg = 29.0;
    s.scene_from_source.translation =
        i == 0 ? Eigen::Vector3d(0.0, 19.5, 0.0) : Eigen::Vector3d(-39.0, -19.5, 0.0);
    design.sources.push_back(s);
  }
  design.spot_noise_mm = Eigen::Vector3d(0.110, 0.073, 0.073);  // surface: x = 1000 (default)
  return design;
}

void BM_MonteCarloStaggered(benchmark::State& state) {
  const opl::ModuleDesign design = StaggeredDesign();
  opl::MonteCarloOptions options;
  options.iterations = static_cast<int>(state.range(0));
  options.threads = static_cast<int>(state.range(1));
  for (auto _ : state) {
    auto report = opl::RunMeasurementMonteCarlo(design, options);
    if (!report.ok()) state.SkipWithError(report.status().message().c_str());
    benchmark::DoNotOptimize(report);
  }
}
BENCHMARK(BM_MonteCarloStaggered)
    ->Args({5000, 2})
    ->ArgNames({"iterations", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
