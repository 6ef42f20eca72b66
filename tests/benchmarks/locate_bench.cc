// Benchmarks of the measurement solve. The target of the foundation issue:
// locating one 11 x 11 grid with no starting guess, initialisation included,
// at most 50 us median on one core. BM_LocateWithGuess and BM_P3P are the
// references in the same run (the cost of refinement alone, of one minimal
// solve); BM_PoseNormalEquations is one evaluation of the refinement's normal
// equations over the 121 spots (a noisy locate makes five: four
// Levenberg-Marquardt iterations and one for the covariance).
#include <random>

#include <benchmark/benchmark.h>

#include "opl/locate/locate_source.h"
#include "opl/locate/p3p.h"
#include "opl/locate/pose_normal_equations.h"
#include "support/synthetic_source.h"

namespace {

struct Scene {
  opl::BeamPattern pattern;
  std::vector<opl::SpotObservation> spots;
  opl::Rigid3d truth;
};

Scene MakeScene(bool noisy) {
  std::mt19937_64 rng(7);
  Scene s;
  s.pattern = opl::test::TangentLatticePattern(11, 29.0 * M_PI / 180.0);
  s.truth = opl::Rigid3d(opl::test::RandomRotation(rng), Eigen::Vector3d(120.0, -40.0, 300.0));
  s.spots = opl::test::SpotsOnPlane(s.pattern, s.truth, 1000.0, 0.2, noisy ? 0.1 : 0.0, rng);
  return s;
}

void BM_LocateNoGuess(benchmark::State& state) {
  const Scene s = MakeScene(state.range(0) != 0);
  for (auto _ : state) {
    auto r = opl::LocateSource(s.pattern, s.spots);
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK(BM_LocateNoGuess)->Arg(0)->Arg(1)->ArgName("noisy")->Unit(benchmark::kMicrosecond);

void BM_LocateWithGuess(benchmark::State& state) {
  const Scene s = MakeScene(true);
  opl::LocateOptions options;
  options.initial_scene_from_source = s.truth;
  for (auto _ : state) {
    auto r = opl::LocateSource(s.pattern, s.spots, options);
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK(BM_LocateWithGuess)->Unit(benchmark::kMicrosecond);

void BM_P3P(benchmark::State& state) {
  const Scene s = MakeScene(false);
  const auto& b = s.pattern.beams();
  std::array<opl::PoseRt, 4> out;
  const std::array<Eigen::Vector3d, 3> f = {b[0].DirectionInSource(), b[60].DirectionInSource(),
                                            b[110].DirectionInSource()};
  const std::array<Eigen::Vector3d, 3> X = {s.spots[0].point_in_scene, s.spots[60].point_in_scene,
                                            s.spots[110].point_in_scene};
  for (auto _ : state) benchmark::DoNotOptimize(opl::SolveP3P(f, X, &out));
}
BENCHMARK(BM_P3P)->Unit(benchmark::kMicrosecond);

void BM_PoseNormalEquations(benchmark::State& state) {
  const Scene s = MakeScene(true);
  const Eigen::Matrix3d R = s.truth.RotationMatrix();
  const double D = 1000.0;
  opl::PoseNormalEquations problem;
  problem.Reset(R, s.truth.translation - Eigen::Vector3d(D, 0.0, 0.0), D);
  Eigen::Matrix2d W;  // ~ 1 / (0.1 mm at 1 m), lower triangular as LocateSource's
  W << 1e4, 0.0, 1e3, 1.2e4;
  for (const auto& spot : s.spots) {
    problem.AddSpot(spot.point_in_scene,
                    opl::BeamAngles::FromDirection(s.pattern.DirectionInSource(spot.beam_id)), W);
  }
  Eigen::Matrix<double, 6, 1> x;
  x << 0.1, -0.2, 0.1, D + 0.1, 0.2, -0.1;  // ~0.1 mm off
  double cost = 0.0;
  Eigen::Matrix<double, 6, 6> JtJ;
  Eigen::Matrix<double, 6, 1> Jtr;
  for (auto _ : state) {
    benchmark::DoNotOptimize(problem.Evaluate(x.data(), &cost, &JtJ, &Jtr));
    benchmark::DoNotOptimize(JtJ);
  }
}
BENCHMARK(BM_PoseNormalEquations)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
