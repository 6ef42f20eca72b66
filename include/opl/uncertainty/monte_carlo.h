// The Monte Carlo uncertainty of a measurement (JCGM 101:2008, GUM Supplement
// 1; method.md, "Uncertainty"; docs/uncertainty.md).
//
// For a module design (its sources, the design's surface as the measurement
// scene, its spot noise) and its exact calibration (ExactCalibration, so that
// s = 1 on average), every iteration i = 0 .. N-1:
//   1. adds noise to the noise-free spots of every source (SimulateSpots with
//      no missing spot and no outlier): e ~ N(0, Sigma), Sigma =
//      ModuleDesign::SpotCovarianceMm2(), each spot carrying Sigma (or each
//      spot its own Sigma_i, MonteCarloOptions::spot_covariance_mm2);
//   2. locates every source (LocateSource);
//   3. computes L_photo of every calibrated pair and s (ComputeScaleFactor).
// and records the origins, the pose angles (R = Rx Ry Rz), the L and s. The
// report gives per quantity the mean, the standard deviation (M - 1 in the
// denominator), and for every L and s the 95 % coverage intervals of JCGM 101
// 7.7 (probabilistically symmetric and shortest, coverage_interval.h), next
// to the first-order prediction: the covariances LocateSource and
// ComputeScaleFactor report for the noise-free spots carrying Sigma (with
// the unweighted locate, whose own covariance is scaled by the residuals,
// the sandwich covariance of PoseFirstOrderCovariance instead), and to the
// Cramer-Rao bound of the design (cramer_rao.h): std / bound is 1 for an
// efficient estimator.
//
// Determinism: iteration i draws its noise from std::mt19937_64 seeded with
// IterationSeed(seed, i) (the (i+1)-th output of SplitMix64(seed)); its
// RANSAC seed, when RANSAC runs, is SplitMix64(that seed).Next(); results are stored by index and reduced in index order, so
// a seed gives bit-identical reports whatever the number of threads.
//
// Pose angles are reported as differences from the design's angles wrapped to
// (-pi, pi], added back to the design's angles for the mean: no wrap-around
// problem at +-pi.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/locate/locate_source.h"
#include "opl/sim/module_design.h"
#include "opl/uncertainty/coverage_interval.h"
#include "opl/uncertainty/cramer_rao.h"

namespace opl {

// The most Monte Carlo trials a run may ask for (docs/uncertainty.md): ten
// times the 10^6 JCGM 101 (7.2.2) takes as usually enough for a 95 % coverage
// interval to two significant digits. The results of every trial are kept
// (about 120 bytes a trial: 1.2 GB at the limit), so M is bounded up front
// rather than failing on allocation.
constexpr int kMaxMonteCarloIterations = 10000000;

struct MonteCarloOptions {
  // M, in [1, kMaxMonteCarloIterations] (coverage intervals need M >= 20)
  int iterations = 1000;
  uint64_t seed = 1;
  // Worker threads, >= 0; 0 = std::thread::hardware_concurrency(). Never more
  // than the iterations. The result does not depend on it.
  int threads = 0;
  // Coverage probability of the intervals, in (0, 1).
  double coverage_probability = 0.95;
  // Options of every locate. By default MonteCarlo starts each locate from
  // the design's pose (LocateOptions::initial_scene_from_source, which skips
  // RANSAC when >= 90% of the spots agree with it, else RANSAC runs): the
  // least-squares minimum is the same as from RANSAC's start, and the run is
  // several times faster. Set start_from_design_pose = false to run every
  // locate exactly as a measurement would (RANSAC; its seed is then derived
  // from the iteration's seed).
  LocateOptions locate;
  bool start_from_design_pose = true;
  // How every locate weights its spots (cramer_rao.h): kEfficient gives each
  // spot its covariance Sigma (the angular residuals whitened by F Sigma F^T);
  // kUnweighted gives none (plain angular residuals, as for spots without
  // sx, sy, sz).
  SpotWeighting weighting = SpotWeighting::kEfficient;
  // Spot noise per spot instead of the design's one Sigma (may be empty):
  // called once per spot with its source, beam id and true point (mm, the
  // design's frame), it returns that spot's covariance (mm^2: symmetric,
  // positive semi-definite, finite), from which the spot draws its noise
  // (through the symmetric square root) and which it carries. For noise
  // that is not the same everywhere: spots triangulated by cameras are
  // uncertain mostly along the line of sight, which turns from spot to spot
  // (tests/integration/images_coverage_test.cc). The design's spot_noise_mm
  // is then not used.
  std::function<Eigen::Matrix3d(const std::string& source, int beam_id,
                                const Eigen::Vector3d& true_point_in_scene)>
      spot_covariance_mm2;
  // Called on the calling thread, about every progress_interval_s and once at
  // the end, with the number of iterations done (successful or not) and M.
  std::function<void(int done, int total)> progress;
  double progress_interval_s = 0.1;

  // InvalidArgument naming the field and value.
  Status Validate() const;
};

// Sample mean, standard deviation and coverage intervals of one quantity.
struct SampleSummary {
  double mean = 0.0;
  double std_dev = 0.0;              // sqrt(sum (y - mean)^2 / (M - 1)); 0 when M = 1
  CoverageInterval symmetric;        // JCGM 101 7.7.1 (zero when M is too small)
  CoverageInterval shortest;         // JCGM 101 7.7.2 (zero when M is too small)
  bool has_interval = false;         // false when M - q < 1
  double first_order_std = 0.0;      // the first-order prediction
  double cramer_rao_std = 0.0;       // the Cramer-Rao bound (cramer_rao.h); 0 when not computed
};

struct MonteCarloSource {
  std::string name;
  Eigen::Vector3d true_origin_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d true_rotation_xyz_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_mean_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_std_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_first_order_std_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_mean_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_std_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_first_order_std_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin_cramer_rao_std_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_cramer_rao_std_rad = Eigen::Vector3d::Zero();
  int spots = 0;  // spots of this source on the surface
  // Of every successful iteration, in index order (MonteCarloReport::
  // sample_iterations): the located origin (mm) and pose angles (rad, R = Rx
  // Ry Rz; the design's angles plus the wrapped difference, as the mean).
  std::vector<Eigen::Vector3d> origin_samples_mm{};
  std::vector<Eigen::Vector3d> rotation_samples_rad{};
};

struct MonteCarloLength {
  std::string from, to;
  double true_mm = 0.0;  // the design's (= calibrated) separation
  SampleSummary photo_mm;  // L_photo, mm (the design's frame)
  std::vector<double> samples_mm;  // L_photo of every successful iteration, in index order
};

struct MonteCarloReport {
  int iterations = 0;  // M asked for
  int succeeded = 0;   // iterations where every source was located
  int failed = 0;      // iterations - succeeded
  std::string first_failure;  // "iteration 17: source 'A': ..." when failed > 0
  uint64_t seed = 0;
  int threads = 0;  // worker threads used (does not change the results)
  double coverage_probability = 0.95;
  SpotWeighting weighting = SpotWeighting::kEfficient;
  Eigen::Vector3d spot_noise_mm = Eigen::Vector3d::Zero();  // the design's; zero when per spot
  bool per_spot_noise = false;  // MonteCarloOptions::spot_covariance_mm2 was given
  std::vector<MonteCarloSource> sources;  // design order
  std::vector<MonteCarloLength> lengths;  // every pair (i < j), design order
  SampleSummary scale_factor;             // s (expected 1)
  std::vector<double> scale_samples;      // s of every successful iteration
  // The index i (0 .. iterations - 1) of every successful iteration, in
  // order: sample k of every *samples* vector is iteration
  // sample_iterations[k] (its seed IterationSeed(seed, i)).
  std::vector<int> sample_iterations{};

  // Readable summary (mm, microradians, ppm of s).
  std::string ToText() const;
  // One JSON object, format "opl.monte_carlo_report" version 1 (docs/uncertainty.md).
  // The threads count is left out, so that the JSON is identical whatever it is.
  // With include_samples, the values of every successful iteration too:
  // "sample_iterations", lengths[].samples_mm, scale_factor.samples,
  // sources[].origin_samples_mm and sources[].rotation_samples_rad. Arrays
  // of numbers are written on one line each.
  std::string ToJson(bool include_samples = false) const;
};

// The (i+1)-th output of SplitMix64(seed): the seed of iteration i.
uint64_t IterationSeed(uint64_t seed, int64_t iteration);

// Mean, std and coverage intervals of `values` (first_order_std left 0).
SampleSummary Summarize(const std::vector<double>& values, double coverage_probability);

// Errors: InvalidArgument from options.Validate() or design.Validate(), or
// when the spot noise is zero on every axis; NoSolution when a source has no
// spot on the surface, the noise-free locate fails (the design does not
// determine a pose), fewer than two sources, or every iteration fails.
// Iterations whose locate fails are counted (report.failed), not fatal.
Result<MonteCarloReport> RunMeasurementMonteCarlo(const ModuleDesign& design,
                                                  const MonteCarloOptions& options);

}  // namespace opl
