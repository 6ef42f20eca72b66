// The Monte Carlo uncertainty of a calibration (JCGM 101:2008, GUM Supplement
// 1; method.md, "Calibrating a source" and "Uncertainty"; docs/uncertainty.md,
// "The calibration Monte Carlo").
//
// A simulated calibration session of a module design: the design's sources
// stay fixed, a screen is placed at every depth of options.screens
// (MakeCalibrationScreens) and every grid is measured on every screen, one grid
// per slice. Once: the noise-free spots of every source on every screen
// (SimulateSlices, no noise, no missing spot, no outlier), each carrying the
// design's spot covariance Sigma = ModuleDesign::SpotCovarianceMm2(), so that
// every calibration is weighted (CalibrateSource then uses its covariance as
// is, without the chi^2/dof factor). Every iteration i = 0 .. M-1:
//   1. every spot gets true + R_n diag(sigma) z, z ~ N(0, I3), drawn in the
//      order of SimulateSlices from std::mt19937_64 seeded with
//      IterationSeed(seed, i) (opl/uncertainty/monte_carlo.h) by the portable
//      NormalGenerator (opl/sim/random.h);
//   2. the session is calibrated (CalibrateModule, options.calibrate);
//   3. every origin, every pose's angles (R = Rx Ry Rz), every beam's (az, el)
//      and every separation are recorded.
// The report gives per quantity the mean and standard deviation (M - 1 in the
// denominator), for every separation the coverage intervals of JCGM 101 7.7,
// next to the first-order prediction: the covariances CalibrateModule reports
// for the noise-free session carrying Sigma (origin, pose angles, every beam's
// cov_azel_rad2, every separation's u).
//
// The truth and the gauge. The origins and separations do not depend on the
// gauge: their truth is the design's. The pose angles and beam directions are
// those of the calibration's gauge (method.md: central beam az = el = 0, the
// central row level, docs/calibrate.md "Gauge"). Their reference ("true")
// values are those of the noise-free calibration, i.e. the design expressed
// in that gauge: for equal-angle and grating patterns (central beam along +X,
// central row at el = 0) they are the design's pose angles and pattern to
// solver precision; a pattern from a file that does not satisfy the gauge is
// compared in the gauge, with its pose turned accordingly. Angles are
// recorded as differences from the reference wrapped to (-pi, pi] (pose
// angles, azimuths), so nothing wraps at +-pi.
//
// The central beam's direction is fixed by the gauge (its spread and
// first-order std are 0); the beam summaries are over the other beams.
//
// An iteration whose calibration fails, or lacks a beam the noise-free
// calibration has (a beam dropped after flagging), is counted (failed, with
// the first failure's message) and left out; the run fails only when every
// iteration fails.
//
// Determinism: results are stored by index and reduced in index order, so a
// seed gives bit-identical reports whatever the number of threads.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/calibrate/calibrate_source.h"
#include "opl/core/status.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_slices.h"
#include "opl/uncertainty/monte_carlo.h"  // SampleSummary, Summarize, IterationSeed

namespace opl {

// The screens of `opl_simulate slices` by default: 750:65:1335 mm (10 flat
// screens normal to the module's viewing direction).
ScreenSlicesOptions DefaultCalibrationScreens();

struct CalibrationMonteCarloOptions {
  // M, in [1, kMaxMonteCarloIterations] (coverage intervals need M >= 20 at 95 %)
  int iterations = 200;
  uint64_t seed = 1;
  // Worker threads, >= 0; 0 = std::thread::hardware_concurrency(). Never more
  // than the iterations. The result does not depend on it.
  int threads = 0;
  // Coverage probability of the intervals, in (0, 1).
  double coverage_probability = 0.95;
  // The session's screens (depths along the module's viewing direction,
  // alternating tilt, curvature: opl/sim/simulate_slices.h).
  ScreenSlicesOptions screens = DefaultCalibrationScreens();
  // Options of every calibration (the noise-free one and every iteration's).
  // Every source is calibrated with its design's beams_per_side when all
  // sources have the same n, else n is inferred from its largest beam id
  // (CalibrateModuleOptions::beams_per_side).
  CalibrateOptions calibrate;
  // Called on the calling thread, about every progress_interval_s and once at
  // the end, with the number of iterations done (successful or not) and M.
  std::function<void(int done, int total)> progress;
  double progress_interval_s = 0.1;

  // InvalidArgument naming the field and value ("iterations must be >= 1, got
  // 0", "screens: depths_mm[2] must be ...", "calibrate options: ...").
  Status Validate() const;
};

// The spread of one beam's calibrated direction.
struct CalibrationMonteCarloBeam {
  int id = 0;
  double true_az_rad = 0.0;  // the reference (noise-free calibration), see the header comment
  double true_el_rad = 0.0;
  double az_mean_rad = 0.0;
  double el_mean_rad = 0.0;
  double az_std_rad = 0.0;   // Monte Carlo
  double el_std_rad = 0.0;
  double az_first_order_std_rad = 0.0;  // sqrt of cov_azel_rad2 of the noise-free calibration
  double el_first_order_std_rad = 0.0;
};

// Over the beams whose first-order std is > 0 (every beam but the central
// one), separately for azimuth [0] and elevation [1].
struct BeamSpreadSummary {
  int beams = 0;  // beams summarised
  Eigen::Vector2d std_median_rad = Eigen::Vector2d::Zero();  // median of the MC std
  Eigen::Vector2d std_max_rad = Eigen::Vector2d::Zero();     // largest MC std
  Eigen::Vector2d first_order_std_median_rad = Eigen::Vector2d::Zero();
  Eigen::Vector2d ratio_median = Eigen::Vector2d::Zero();    // median of MC std / FO std
  Eigen::Vector2d ratio_min = Eigen::Vector2d::Zero();
  Eigen::Vector2d ratio_max = Eigen::Vector2d::Zero();
};

struct CalibrationMonteCarloSource {
  std::string name;
  int spots = 0;   // samples of this source in the session (every screen)
  int slices = 0;  // screens on which it has spots
  Eigen::Vector3d true_origin_mm = Eigen::Vector3d::Zero();  // the design's
  Eigen::Vector3d origin_mean_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_std_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_first_order_std_mm = Eigen::Vector3d::Zero();
  // Pose angles (R = Rx Ry Rz) in the calibration's gauge; the reference is
  // the noise-free calibration's.
  Eigen::Vector3d true_rotation_xyz_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_mean_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_std_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_first_order_std_rad = Eigen::Vector3d::Zero();
  // Samples flagged as wrong, summed over the successful iterations (a
  // 5-sigma flag: about one calibration in 400 of the prototype-like
  // session flags one sample).
  int64_t flagged_samples = 0;
  std::vector<CalibrationMonteCarloBeam> beams;  // every beam of the noise-free calibration, by id
  BeamSpreadSummary beam_summary;
};

struct CalibrationMonteCarloLength {
  std::string from, to;      // design order (from before to)
  double true_mm = 0.0;      // the design's separation |t_to - t_from|
  SampleSummary length_mm;   // the calibrated separation; first_order_std = its u
  std::vector<double> samples_mm;  // of every successful iteration, in index order
};

struct CalibrationMonteCarloReport {
  int iterations = 0;  // M asked for
  int succeeded = 0;   // iterations where every source was calibrated
  int failed = 0;      // iterations - succeeded
  std::string first_failure;  // "iteration 17: source 'A': ..." when failed > 0
  uint64_t seed = 0;
  int threads = 0;  // worker threads used (does not change the results)
  double coverage_probability = 0.95;
  Eigen::Vector3d spot_noise_mm = Eigen::Vector3d::Zero();
  std::vector<double> depths_mm;  // the screens
  double tilt_deg = 0.0;
  double curvature_per_mm = 0.0;
  std::vector<CalibrationMonteCarloSource> sources;  // design order
  std::vector<CalibrationMonteCarloLength> lengths;  // every pair (i < j), design order

  // Readable summary (mm, microradians, ppm of the separations).
  std::string ToText() const;
  // One JSON object, format "opl.calibration_monte_carlo_report" version 1
  // (docs/uncertainty.md). The thread count is left out, so that the JSON is
  // identical whatever it is. Numbers round-trip.
  std::string ToJson() const;
};

// Errors: InvalidArgument from options.Validate(), from the design (its
// surface aside: it is not used) or the screens, or when the spot noise is
// zero on every axis; NoSolution when a source has no spot on any screen, a
// screen gets no spot, the noise-free calibration fails (the session does not
// determine the calibration), or every iteration fails. A design with one
// source is calibrated (origin, pose, beams) and has no lengths. Iterations
// whose calibration fails are counted (report.failed), not fatal.
Result<CalibrationMonteCarloReport> RunCalibrationMonteCarlo(
    const ModuleDesign& design, const CalibrationMonteCarloOptions& options);

}  // namespace opl
