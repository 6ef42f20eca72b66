// The calibration Monte Carlo (JCGM 101) against the first-order uncertainty
// of CalibrateModule, its linearity in the spot noise, its determinism across
// thread counts, its JSON, its errors; and the thread pool it runs on
// (src/uncertainty/parallel_iterations.h).
//
// Statistical tolerance: with M iterations the relative standard error of a
// sample standard deviation is 1/sqrt(2 (M - 1)) (4.1 % at M = 300); MC/FO
// ratios are asserted within 3 of those standard errors (12.3 % at M = 300).
//
// Run time: a calibration of the prototype-like session (2 sources x 121 beams
// x 10 screens) takes about 12 ms in Release and about ten times more under
// AddressSanitizer (about 80 ms of CPU). The main test runs kIterations
// calibrations of the session (300; 200 under AddressSanitizer, where the
// tolerance widens by the same formula to 15 %), the others about 80 in all:
// about 6 s of CPU in Release, 25 s under AddressSanitizer.
#include "opl/uncertainty/calibration_monte_carlo.h"

#include <atomic>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../src/uncertainty/parallel_iterations.h"
#include "opl/core/format.h"
#include "opl/sim/pattern_models.h"
#include "support/prototype_design.h"

namespace opl {
namespace {

#if defined(__SANITIZE_ADDRESS__)
#define OPL_CALMC_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define OPL_CALMC_TEST_ASAN 1
#endif
#endif
#ifdef OPL_CALMC_TEST_ASAN
constexpr int kIterations = 200;
#else
constexpr int kIterations = 300;
#endif

// 3 standard errors of a standard deviation estimated from m draws.
double StdTolerance(int m) { return 3.0 / std::sqrt(2.0 * (m - 1)); }

// The prototype-like module (tests/support/prototype_design.h): two 11 x 11
// equal-angle 29 deg sources at y = +-27.5 mm looking along +X, spot noise
// 0.110 / 0.073 / 0.073 mm; the session: 10 screens 750:65:1335 mm.
const Result<CalibrationMonteCarloReport>& PrototypeReport() {
  static const Result<CalibrationMonteCarloReport> report = [] {
    CalibrationMonteCarloOptions options;
    options.iterations = kIterations;
    options.seed = 11;
    options.threads = 2;
    return RunCalibrationMonteCarlo(test::Prototype(), options);
  }();
  return report;
}

TEST(CalibrationMonteCarloTest, DefaultScreensAreThoseOfOplSimulateSlices) {
  const CalibrationMonteCarloOptions options;
  ASSERT_EQ(options.screens.depths_mm.size(), 10u);
  const Result<std::vector<double>> parsed = ParseDepthList("750:65:1335");
  ASSERT_TRUE(parsed.ok());
  EXPECT_EQ(options.screens.depths_mm, *parsed);
  EXPECT_EQ(options.screens.tilt_deg, 0.0);
  EXPECT_EQ(options.screens.curvature_per_mm, 0.0);
  EXPECT_TRUE(options.Validate().ok());
}

TEST(CalibrationMonteCarloTest, IterationsAreBoundedUpFront) {
  // Issue 19: 2e9 iterations reserved ~120 B each before the first one ran.
  CalibrationMonteCarloOptions options;
  options.iterations = 2000000000;
  EXPECT_EQ(options.Validate().message(), "iterations must be at most 10000000, got 2000000000");
  MonteCarloOptions mc;
  mc.iterations = 2000000000;
  EXPECT_EQ(mc.Validate().message(), "iterations must be at most 10000000, got 2000000000");
  mc.iterations = kMaxMonteCarloIterations;
  EXPECT_TRUE(mc.Validate().ok());
}

// The reference of the gauge-dependent quantities is the noise-free
// calibration: for equal-angle patterns (central beam along +X, central row at
// el = 0) it is the design itself.
TEST(CalibrationMonteCarloTest, ReferenceIsTheDesignInTheGauge) {
  const Result<CalibrationMonteCarloReport>& r = PrototypeReport();
  ASSERT_TRUE(r.ok()) << r.status().message();
  const BeamPattern pattern = MakeEqualAnglePattern(11, 29.0 * kPi / 180.0);
  ASSERT_EQ(r->sources.size(), 2u);
  for (const CalibrationMonteCarloSource& s : r->sources) {
    EXPECT_EQ(s.spots, 1210) << s.name;
    EXPECT_EQ(s.slices, 10) << s.name;
    EXPECT_LT(s.true_rotation_xyz_rad.norm(), 1e-9) << s.name;
    ASSERT_EQ(s.beams.size(), 121u) << s.name;
    for (const CalibrationMonteCarloBeam& b : s.beams) {
      const Beam* designed = pattern.Find(b.id);
      ASSERT_NE(designed, nullptr);
      EXPECT_NEAR(b.true_az_rad, designed->az_rad, 1e-9) << s.name << " beam " << b.id;
      EXPECT_NEAR(b.true_el_rad, designed->el_rad, 1e-9) << s.name << " beam " << b.id;
    }
    // The central beam is fixed by the gauge: no spread, no first-order std.
    const CalibrationMonteCarloBeam& central = s.beams[60];
    EXPECT_EQ(central.id, 61);
    EXPECT_EQ(central.az_std_rad, 0.0);
    EXPECT_EQ(central.el_std_rad, 0.0);
    EXPECT_EQ(central.az_first_order_std_rad, 0.0);
    EXPECT_EQ(s.beam_summary.beams, 120);
  }
  EXPECT_EQ(r->sources[0].true_origin_mm, Eigen::Vector3d(0, 27.5, 0));
  ASSERT_EQ(r->lengths.size(), 1u);
  EXPECT_EQ(r->lengths[0].true_mm, 55.0);
}

TEST(CalibrationMonteCarloTest, PrototypeSessionMatchesFirstOrder) {
  const Result<CalibrationMonteCarloReport>& r = PrototypeReport();
  ASSERT_TRUE(r.ok()) << r.status().message();
  const int m = kIterations;
  const double tol = StdTolerance(m);
  EXPECT_EQ(r->succeeded, m);
  EXPECT_EQ(r->failed, 0);
  EXPECT_EQ(r->threads, 2);
  std::printf("%s", r->ToText().c_str());

  const CalibrationMonteCarloLength& l = r->lengths[0];
  EXPECT_EQ(l.from, "A");
  EXPECT_EQ(l.to, "B");
  EXPECT_EQ(l.samples_mm.size(), static_cast<size_t>(m));
  // docs/calibrate.md: about 0.018 mm for this session (first order).
  EXPECT_GT(l.length_mm.first_order_std, 0.012);
  EXPECT_LT(l.length_mm.first_order_std, 0.025);
  EXPECT_NEAR(l.length_mm.std_dev / l.length_mm.first_order_std, 1.0, tol);
  EXPECT_NEAR(l.length_mm.mean, l.true_mm, 4.0 * l.length_mm.std_dev / std::sqrt(m));
  ASSERT_TRUE(l.length_mm.has_interval);
  EXPECT_NEAR(l.length_mm.symmetric.low, l.length_mm.mean - 1.96 * l.length_mm.std_dev,
              0.3 * l.length_mm.std_dev);
  EXPECT_NEAR(l.length_mm.symmetric.high, l.length_mm.mean + 1.96 * l.length_mm.std_dev,
              0.3 * l.length_mm.std_dev);

  for (const CalibrationMonteCarloSource& s : r->sources) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_GT(s.origin_first_order_std_mm[k], 0.0);
      EXPECT_NEAR(s.origin_std_mm[k] / s.origin_first_order_std_mm[k], 1.0, tol)
          << s.name << " origin axis " << k;
      // Across the beams (y, z) the origin is unbiased within 4 standard
      // errors. Along them (x) the ray intersection has a second-order bias
      // away from the screens: about -0.0066 mm (0.12 std) in 2000 iterations
      // (docs/uncertainty.md), common to both sources, so the separation
      // stays unbiased. Here: below a quarter of the std.
      const double bound =
          k == 0 ? 0.25 * s.origin_std_mm[k] : 4.0 * s.origin_std_mm[k] / std::sqrt(m);
      EXPECT_NEAR(s.origin_mean_mm[k], s.true_origin_mm[k], bound)
          << s.name << " origin axis " << k;
      ASSERT_GT(s.rotation_first_order_std_rad[k], 0.0);
      EXPECT_NEAR(s.rotation_std_rad[k] / s.rotation_first_order_std_rad[k], 1.0, tol)
          << s.name << " angle " << k;
    }
    // Along the beams the origin is worse determined than across them.
    EXPECT_GT(s.origin_first_order_std_mm.x(), 2.0 * s.origin_first_order_std_mm.y());
    const BeamSpreadSummary& b = s.beam_summary;
    for (int k = 0; k < 2; ++k) {
      EXPECT_NEAR(b.std_median_rad[k] / b.first_order_std_median_rad[k], 1.0, tol)
          << s.name << (k ? " el" : " az");
      EXPECT_NEAR(b.ratio_median[k], 1.0, tol) << s.name << (k ? " el" : " az");
      // Every beam's ratio, 120 beams: within 5 standard errors.
      EXPECT_GT(b.ratio_min[k], 1.0 - 5.0 * tol / 3.0) << s.name << (k ? " el" : " az");
      EXPECT_LT(b.ratio_max[k], 1.0 + 5.0 * tol / 3.0) << s.name << (k ? " el" : " az");
      EXPECT_GE(b.std_max_rad[k], b.std_median_rad[k]);
    }
    // A beam direction from 10 samples of 0.07-0.11 mm at 0.75-1.35 m: tens of urad.
    EXPECT_GT(b.first_order_std_median_rad.minCoeff(), 10e-6);
    EXPECT_LT(b.first_order_std_median_rad.maxCoeff(), 200e-6);
  }
}

// method.md: "uncertainty linear in spot noise". The same seed draws the same
// standard normals, so doubling the noise doubles every deviation to first
// order; the first-order std doubles exactly (weighted: no chi^2 factor).
TEST(CalibrationMonteCarloTest, StdIsLinearInSpotNoise) {
  ModuleDesign design = test::Prototype();
  CalibrationMonteCarloOptions options;
  options.iterations = 25;
  options.seed = 3;
  Result<CalibrationMonteCarloReport> once = RunCalibrationMonteCarlo(design, options);
  design.spot_noise_mm *= 2.0;
  Result<CalibrationMonteCarloReport> twice = RunCalibrationMonteCarlo(design, options);
  ASSERT_TRUE(once.ok()) << once.status().message();
  ASSERT_TRUE(twice.ok()) << twice.status().message();
  const SampleSummary& l1 = once->lengths[0].length_mm;
  const SampleSummary& l2 = twice->lengths[0].length_mm;
  EXPECT_NEAR(l2.std_dev / l1.std_dev, 2.0, 0.02);
  EXPECT_NEAR(l2.first_order_std / l1.first_order_std, 2.0, 1e-6);
  for (size_t s = 0; s < 2; ++s) {
    const CalibrationMonteCarloSource& a = once->sources[s];
    const CalibrationMonteCarloSource& b = twice->sources[s];
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(b.origin_std_mm[k] / a.origin_std_mm[k], 2.0, 0.02);
      EXPECT_NEAR(b.origin_first_order_std_mm[k] / a.origin_first_order_std_mm[k], 2.0, 1e-6);
    }
    for (int k = 0; k < 2; ++k) {
      EXPECT_NEAR(b.beam_summary.std_median_rad[k] / a.beam_summary.std_median_rad[k], 2.0, 0.02);
    }
  }
}

// Per-iteration seeds and an index-ordered reduction: 1 and 3 threads give
// bit-identical samples and reports; progress comes on the calling thread.
TEST(CalibrationMonteCarloTest, IdenticalWhateverTheThreadCount) {
  const ModuleDesign design = test::Prototype();
  CalibrationMonteCarloOptions options;
  options.iterations = 8;
  options.seed = 99;
  options.threads = 1;
  Result<CalibrationMonteCarloReport> one = RunCalibrationMonteCarlo(design, options);
  options.threads = 3;
  options.progress_interval_s = 0.001;
  std::vector<int> seen;
  const std::thread::id caller = std::this_thread::get_id();
  options.progress = [&](int done, int total) {
    EXPECT_EQ(total, 8);
    EXPECT_EQ(std::this_thread::get_id(), caller);
    seen.push_back(done);
  };
  Result<CalibrationMonteCarloReport> three = RunCalibrationMonteCarlo(design, options);
  ASSERT_TRUE(one.ok()) << one.status().message();
  ASSERT_TRUE(three.ok()) << three.status().message();
  EXPECT_EQ(one->threads, 1);
  EXPECT_EQ(three->threads, 3);
  EXPECT_EQ(one->lengths[0].samples_mm, three->lengths[0].samples_mm);  // exact ==
  EXPECT_EQ(one->ToJson(), three->ToJson());
  EXPECT_EQ(one->ToText(), three->ToText());
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 8);
  for (size_t i = 1; i < seen.size(); ++i) EXPECT_LE(seen[i - 1], seen[i]);

  // A different seed gives different draws.
  options.seed = 100;
  options.progress = nullptr;
  Result<CalibrationMonteCarloReport> other = RunCalibrationMonteCarlo(design, options);
  ASSERT_TRUE(other.ok());
  EXPECT_NE(other->lengths[0].samples_mm, one->lengths[0].samples_mm);
}

// The JSON: format, keys, values round-trip exactly.
TEST(CalibrationMonteCarloTest, JsonHoldsTheReport) {
  const Result<CalibrationMonteCarloReport>& r = PrototypeReport();
  ASSERT_TRUE(r.ok()) << r.status().message();
  const nlohmann::json j = nlohmann::json::parse(r->ToJson());
  EXPECT_EQ(j.at("format"), "opl.calibration_monte_carlo_report");
  EXPECT_EQ(j.at("version"), 1);
  EXPECT_EQ(j.at("iterations"), kIterations);
  EXPECT_EQ(j.at("succeeded"), kIterations);
  EXPECT_EQ(j.at("failed"), 0);
  EXPECT_FALSE(j.contains("first_failure"));
  EXPECT_FALSE(j.contains("threads"));
  EXPECT_EQ(j.at("seed"), 11u);
  EXPECT_EQ(j.at("coverage_probability"), 0.95);
  EXPECT_EQ(j.at("coverage_interval"), "probabilistically_symmetric");
  EXPECT_EQ(j.at("spot_noise_mm").get<std::vector<double>>(),
            (std::vector<double>{0.110, 0.073, 0.073}));
  EXPECT_EQ(j.at("depths_mm").get<std::vector<double>>(), r->depths_mm);

  const nlohmann::json& l = j.at("lengths").at(0);
  const CalibrationMonteCarloLength& length = r->lengths[0];
  EXPECT_EQ(l.at("from"), "A");
  EXPECT_EQ(l.at("to"), "B");
  EXPECT_EQ(l.at("true_mm").get<double>(), length.true_mm);
  EXPECT_EQ(l.at("mean_mm").get<double>(), length.length_mm.mean);
  EXPECT_EQ(l.at("std_mm").get<double>(), length.length_mm.std_dev);
  EXPECT_EQ(l.at("first_order_std_mm").get<double>(), length.length_mm.first_order_std);
  EXPECT_EQ(l.at("ci95_mm").at(0).get<double>(), length.length_mm.symmetric.low);
  EXPECT_EQ(l.at("ci95_mm").at(1).get<double>(), length.length_mm.symmetric.high);
  EXPECT_EQ(l.at("shortest_ci95_mm").at(1).get<double>(), length.length_mm.shortest.high);

  const nlohmann::json& s = j.at("sources").at(1);
  const CalibrationMonteCarloSource& source = r->sources[1];
  EXPECT_EQ(s.at("name"), "B");
  EXPECT_EQ(s.at("spots"), 1210);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(s.at("origin_mean_mm").at(k).get<double>(), source.origin_mean_mm[k]);
    EXPECT_EQ(s.at("origin_std_mm").at(k).get<double>(), source.origin_std_mm[k]);
    EXPECT_EQ(s.at("origin_first_order_std_mm").at(k).get<double>(),
              source.origin_first_order_std_mm[k]);
    EXPECT_EQ(s.at("rotation_std_rad").at(k).get<double>(), source.rotation_std_rad[k]);
    EXPECT_EQ(s.at("rotation_first_order_std_rad").at(k).get<double>(),
              source.rotation_first_order_std_rad[k]);
  }
  EXPECT_EQ(s.at("beam_std_median_rad").at(1).get<double>(), source.beam_summary.std_median_rad[1]);
  EXPECT_EQ(s.at("beam_std_max_rad").at(0).get<double>(), source.beam_summary.std_max_rad[0]);
  const nlohmann::json& beams = s.at("beams");
  ASSERT_EQ(beams.size(), 121u);
  const nlohmann::json& b = beams.at(0);
  EXPECT_EQ(b.at("id"), 1);
  EXPECT_EQ(b.at("az_std_rad").get<double>(), source.beams[0].az_std_rad);
  EXPECT_EQ(b.at("el_std_rad").get<double>(), source.beams[0].el_std_rad);
  EXPECT_EQ(b.at("az_first_order_std_rad").get<double>(), source.beams[0].az_first_order_std_rad);
  EXPECT_EQ(b.at("el_first_order_std_rad").get<double>(), source.beams[0].el_first_order_std_rad);
}

// One source: calibrated, no lengths. Sources share no parameter, so its
// first-order figures are those it has in the two-source module (the screens
// are the same planes: x = 750 .. 1335 mm).
TEST(CalibrationMonteCarloTest, OneSourceHasNoLengths) {
  ModuleDesign design = test::Prototype();
  const Result<CalibrationMonteCarloReport>& both = PrototypeReport();
  ASSERT_TRUE(both.ok());
  design.sources.resize(1);
  CalibrationMonteCarloOptions options;
  options.iterations = 3;
  Result<CalibrationMonteCarloReport> r = RunCalibrationMonteCarlo(design, options);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_TRUE(r->lengths.empty());
  ASSERT_EQ(r->sources.size(), 1u);
  EXPECT_EQ(r->succeeded, 3);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(r->sources[0].origin_first_order_std_mm[k],
                both->sources[0].origin_first_order_std_mm[k],
                1e-6 * both->sources[0].origin_first_order_std_mm[k]);
  }
  EXPECT_NE(r->ToText().find("Separations: none (one source)"), std::string::npos);
  const nlohmann::json j = nlohmann::json::parse(r->ToJson());
  EXPECT_TRUE(j.at("lengths").empty());
}

TEST(CalibrationMonteCarloTest, Errors) {
  const ModuleDesign design = test::Prototype();
  auto code_and_message = [&](const CalibrationMonteCarloOptions& o, const ModuleDesign& d,
                              StatusCode code, const std::string& word) {
    Result<CalibrationMonteCarloReport> r = RunCalibrationMonteCarlo(d, o);
    ASSERT_FALSE(r.ok()) << word;
    EXPECT_EQ(r.status().code(), code) << r.status().message();
    EXPECT_NE(r.status().message().find(word), std::string::npos) << r.status().message();
  };
  const CalibrationMonteCarloOptions good;
  CalibrationMonteCarloOptions o = good;
  o.iterations = 0;
  code_and_message(o, design, StatusCode::kInvalidArgument, "iterations");
  o = good;
  o.threads = -1;
  code_and_message(o, design, StatusCode::kInvalidArgument, "threads");
  for (double p : {0.0, 1.0, std::nan("")}) {
    o = good;
    o.coverage_probability = p;
    code_and_message(o, design, StatusCode::kInvalidArgument, "coverage_probability");
  }
  for (double s : {0.0, -1.0, std::nan("")}) {
    o = good;
    o.progress_interval_s = s;
    code_and_message(o, design, StatusCode::kInvalidArgument, "progress_interval_s");
  }
  o = good;
  o.screens.depths_mm.clear();
  code_and_message(o, design, StatusCode::kInvalidArgument, "screens: ");
  o = good;
  o.screens.depths_mm[2] = -5.0;
  code_and_message(o, design, StatusCode::kInvalidArgument, "depths_mm[2]");
  o = good;
  o.screens.tilt_deg = 90.0;
  code_and_message(o, design, StatusCode::kInvalidArgument, "tilt");
  o = good;
  o.screens.curvature_per_mm = std::nan("");
  code_and_message(o, design, StatusCode::kInvalidArgument, "curvature");
  o = good;
  o.calibrate.min_samples_per_beam = 1;
  code_and_message(o, design, StatusCode::kInvalidArgument, "calibrate options: ");

  o = good;
  o.iterations = 2;
  ModuleDesign quiet = design;
  quiet.spot_noise_mm.setZero();
  code_and_message(o, quiet, StatusCode::kInvalidArgument, "spot_noise_mm");
  ModuleDesign negative = design;
  negative.spot_noise_mm.x() = -0.1;
  code_and_message(o, negative, StatusCode::kInvalidArgument, "module design: ");
  ModuleDesign twins = design;
  twins.sources[1].name = "A";
  code_and_message(o, twins, StatusCode::kInvalidArgument, "module design: ");
  ModuleDesign none = design;
  none.sources.clear();
  code_and_message(o, none, StatusCode::kInvalidArgument, "module design: ");

  // One screen: the session does not determine the calibration.
  o.screens.depths_mm = {1000.0};
  code_and_message(o, design, StatusCode::kNoSolution, "the noise-free session: ");

  // A third source looking backwards (the mean viewing direction stays +X):
  // it hits no screen.
  o = good;
  o.iterations = 2;
  ModuleDesign backwards = design;
  backwards.sources.push_back(
      test::Source("C", Eigen::Vector3d(0, 0, 40), Eigen::Vector3d(0, 0, kPi)));
  code_and_message(o, backwards, StatusCode::kNoSolution, "source 'C': no beam hits any");
}

// The thread pool: results by index, exceptions turned into results, every
// iteration run once, progress at the end.
TEST(ParallelIterationsTest, ResultsByIndexAndExceptionsCaught) {
  for (int threads : {0, 1, 3, 64}) {
    std::vector<int> out;
    std::atomic<int> calls{0};
    int last_done = -1;
    const int workers = internal::RunIterations<int>(
        50, threads,
        [&](int i) {
          ++calls;
          if (i % 7 == 3) throw std::runtime_error("seven");
          return i * i;
        },
        [](int i, const std::string& what) { return what == "seven" ? -i : -1000; }, &out,
        [&](int done, int total) {
          EXPECT_EQ(total, 50);
          last_done = done;
        },
        0.001);
    EXPECT_EQ(calls.load(), 50);
    EXPECT_EQ(last_done, 50);
    EXPECT_EQ(workers, internal::IterationThreads(threads, 50));
    ASSERT_EQ(out.size(), 50u);
    for (int i = 0; i < 50; ++i) EXPECT_EQ(out[i], i % 7 == 3 ? -i : i * i) << i;
  }
  EXPECT_EQ(internal::IterationThreads(64, 50), 50);
  EXPECT_EQ(internal::IterationThreads(2, 0), 0);
  EXPECT_GE(internal::IterationThreads(0, 50), 1);
  // A progress callback that throws is not called again; nothing escapes.
  std::vector<int> out;
  int progress_calls = 0;
  internal::RunIterations<int>(
      5, 2, [](int i) { return i; }, [](int, const std::string&) { return -1; }, &out,
      [&](int, int) {
        ++progress_calls;
        throw std::runtime_error("progress");
      },
      0.001);
  EXPECT_EQ(progress_calls, 1);
  EXPECT_EQ(out, (std::vector<int>{0, 1, 2, 3, 4}));
  // No iteration: nothing runs.
  EXPECT_EQ(internal::RunIterations<int>(
                0, 2, [](int) { return 1; }, [](int, const std::string&) { return -1; }, &out,
                nullptr, 0.1),
            0);
  EXPECT_TRUE(out.empty());
}

}  // namespace
}  // namespace opl
