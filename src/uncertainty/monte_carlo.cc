#include "opl/uncertainty/monte_carlo.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <utility>

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "opl/geometry/spherical.h"
#include "opl/io/json_text.h"
#include "opl/geometry/rotation.h"
#include "opl/model/module_calibration.h"
#include "opl/scale/scale_factor.h"
#include "opl/sim/random.h"
#include "opl/sim/simulate_spots.h"

#include "uncertainty/parallel_iterations.h"
#include "uncertainty/report_helpers.h"

namespace opl {
namespace {

using internal::IntervalJson;
using internal::Ratio;
using internal::StdDevs;
using internal::VectorJson;

// One source as every iteration needs it.
struct SourceSetup {
  std::string name;
  BeamPattern pattern;
  Rigid3d pose;
  Eigen::Vector3d angles = Eigen::Vector3d::Zero();
  std::vector<SpotObservation> truth;  // noise-free, carrying Sigma
  // Per spot, F with F F^T its noise covariance (F z, z ~ N(0, I)).
  std::vector<Eigen::Matrix3d> noise_factor;
};

// What one iteration produced.
struct IterationResult {
  bool ok = false;
  std::string error;
  std::vector<Eigen::Vector3d> origins;        // per source
  std::vector<Eigen::Vector3d> angle_offsets;  // per source, wrapped, from the design's angles
  std::vector<double> lengths;                 // per pair
  double scale = 0.0;
};

struct Problem {
  const std::vector<SourceSetup>* sources = nullptr;
  const ModuleCalibration* calibration = nullptr;
  std::vector<std::pair<std::string, std::string>> pairs;
  LocateOptions locate;
  bool start_from_design_pose = true;
  uint64_t seed = 0;
};

// The symmetric square root of a covariance (F = V sqrt(L) V^T, F F^T = C):
// unlike a Cholesky factor it keeps every direction's noise in that
// direction, and it allows a semi-definite C.
Result<Eigen::Matrix3d> SymmetricSquareRoot(const Eigen::Matrix3d& c) {
  if (!c.allFinite()) return Status::InvalidArgument("not finite");
  if (!c.isApprox(c.transpose(), 1e-9)) return Status::InvalidArgument("not symmetric");
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (c + c.transpose()));
  const Eigen::Vector3d l = eig.eigenvalues();
  if (l.minCoeff() < -1e-12 * std::max(1.0, l.maxCoeff())) {
    return Status::InvalidArgument("not positive semi-definite (eigenvalue " +
                                   FormatNumber(l.minCoeff()) + ")");
  }
  return Eigen::Matrix3d(eig.eigenvectors() * l.cwiseMax(0.0).cwiseSqrt().asDiagonal() *
                         eig.eigenvectors().transpose());
}

IterationResult RunIteration(const Problem& problem, int iteration) {
  IterationResult result;
  const uint64_t iteration_seed = IterationSeed(problem.seed, iteration);
  std::mt19937_64 rng(iteration_seed);
  NormalGenerator normal;
  LocateOptions locate = problem.locate;
  locate.ransac_seed = SplitMix64(iteration_seed).Next();

  const std::vector<SourceSetup>& sources = *problem.sources;
  std::vector<LocatedOrigin> located;
  located.reserve(sources.size());
  std::vector<SpotObservation> spots;
  for (const SourceSetup& source : sources) {
    spots = source.truth;
    for (size_t i = 0; i < spots.size(); ++i) {
      Eigen::Vector3d z;
      for (int k = 0; k < 3; ++k) z[k] = normal(rng);
      spots[i].point_in_scene += source.noise_factor[i] * z;
    }
    if (problem.start_from_design_pose) locate.initial_scene_from_source = source.pose;
    Result<LocateResult> r = LocateSource(source.pattern, spots, locate);
    if (!r.ok()) {
      result.error = "source '" + source.name + "': " + r.status().message();
      return result;
    }
    result.origins.push_back(r->scene_from_source.translation);
    Eigen::Vector3d offset;
    for (int k = 0; k < 3; ++k) offset[k] = WrapAngleRad(r->rotation_xyz_rad[k] - source.angles[k]);
    result.angle_offsets.push_back(offset);
    located.push_back({source.name, r->scene_from_source.translation, r->origin_covariance});
  }
  Result<ScaleResult> scale = ComputeScaleFactor(*problem.calibration, located);
  if (!scale.ok()) {
    result.error = scale.status().message();
    return result;
  }
  for (const auto& [from, to] : problem.pairs) {
    for (const LengthScale& l : scale->lengths) {
      if (l.from == from && l.to == to) result.lengths.push_back(l.photo);
    }
  }
  if (result.lengths.size() != problem.pairs.size()) {
    result.error = "a calibrated separation was not measured";
    return result;
  }
  result.scale = scale->scale_factor;
  result.ok = true;
  return result;
}

}  // namespace

Status MonteCarloOptions::Validate() const {
  if (iterations < 1) {
    return Status::InvalidArgument("iterations must be >= 1, got " + std::to_string(iterations));
  }
  if (iterations > kMaxMonteCarloIterations) {
    return Status::InvalidArgument("iterations must be at most " +
                                   std::to_string(kMaxMonteCarloIterations) + ", got " +
                                   std::to_string(iterations));
  }
  if (threads < 0) {
    return Status::InvalidArgument("threads must be >= 0 (0: every core), got " +
                                   std::to_string(threads));
  }
  if (!(coverage_probability > 0.0 && coverage_probability < 1.0)) {
    return Status::InvalidArgument("coverage_probability must be in (0, 1), got " +
                                   std::to_string(coverage_probability));
  }
  if (!(std::isfinite(progress_interval_s) && progress_interval_s > 0.0)) {
    return Status::InvalidArgument("progress_interval_s must be finite and > 0, got " +
                                   std::to_string(progress_interval_s));
  }
  if (Status st = locate.Validate(); !st.ok()) {
    return Status::InvalidArgument("locate options: " + st.message());
  }
  return Status::Ok();
}

uint64_t IterationSeed(uint64_t seed, int64_t iteration) {
  // SplitMix64's k-th output only depends on seed + k * gamma: jump there.
  return SplitMix64(seed + static_cast<uint64_t>(iteration) * 0x9E3779B97F4A7C15ull).Next();
}

SampleSummary Summarize(const std::vector<double>& values, double coverage_probability) {
  SampleSummary s;
  if (values.empty()) return s;
  double sum = 0.0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(values.size());
  if (values.size() > 1) {
    double ss = 0.0;
    for (double v : values) ss += (v - s.mean) * (v - s.mean);
    s.std_dev = std::sqrt(ss / static_cast<double>(values.size() - 1));
  }
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  Result<CoverageInterval> symmetric = CoverageIntervalOfSorted(
      sorted, coverage_probability, CoverageIntervalKind::kProbabilisticallySymmetric);
  Result<CoverageInterval> shortest =
      CoverageIntervalOfSorted(sorted, coverage_probability, CoverageIntervalKind::kShortest);
  if (symmetric.ok() && shortest.ok()) {
    s.symmetric = *symmetric;
    s.shortest = *shortest;
    s.has_interval = true;
  }
  return s;
}

Result<MonteCarloReport> RunMeasurementMonteCarlo(const ModuleDesign& design,
                                                  const MonteCarloOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (Status st = design.Validate(); !st.ok()) {
    return Status::InvalidArgument("module design: " + st.message());
  }
  if (design.sources.size() < 2) {
    return Status::NoSolution("the design has " + std::to_string(design.sources.size()) +
                              " source: a length needs two");
  }
  const bool per_spot = static_cast<bool>(options.spot_covariance_mm2);
  const Eigen::Matrix3d design_sigma = design.SpotCovarianceMm2();
  const Eigen::Matrix3d design_factor = design.noise_frame_rotation * design.spot_noise_mm.asDiagonal();
  if (!per_spot && !(design.spot_noise_mm.array() > 0.0).any()) {
    return Status::InvalidArgument("spot_noise_mm is zero on every axis: nothing to simulate");
  }
  Result<ModuleCalibration> calibration = ExactCalibration(design);
  if (!calibration.ok()) return calibration.status();

  // The noise-free spots, each carrying Sigma.
  SpotSimulationOptions exact;
  exact.attach_covariance = false;
  Result<std::vector<SimulatedSpot>> simulated = SimulateSpots(design, exact);
  if (!simulated.ok()) return simulated.status();
  std::vector<SourceSetup> sources;
  for (const SourceDesign& d : design.sources) {
    SourceSetup s;
    s.name = d.name;
    const SourceCalibration* c = calibration->FindSource(d.name);
    s.pattern = c->pattern;
    s.pose = d.scene_from_source;
    s.angles = XyzAnglesRadFromRotation(d.scene_from_source.RotationMatrix());
    for (const SimulatedSpot& spot : *simulated) {
      if (spot.spot.source != d.name) continue;
      SpotObservation o;
      o.beam_id = spot.spot.observation.beam_id;
      o.point_in_scene = spot.true_point_in_scene;
      Eigen::Matrix3d sigma = design_sigma;
      Eigen::Matrix3d factor = design_factor;
      if (per_spot) {
        sigma = options.spot_covariance_mm2(d.name, o.beam_id, o.point_in_scene);
        Result<Eigen::Matrix3d> root = SymmetricSquareRoot(sigma);
        if (!root.ok()) {
          return Status::InvalidArgument("spot_covariance_mm2 of source '" + d.name + "' beam " +
                                         std::to_string(o.beam_id) + ": " +
                                         root.status().message());
        }
        factor = *root;
      }
      if (options.weighting == SpotWeighting::kEfficient) o.cov_in_scene = sigma;
      s.truth.push_back(o);
      s.noise_factor.push_back(factor);
    }
    if (s.truth.empty()) {
      return Status::NoSolution("source '" + d.name + "': no beam hits the surface (" +
                                design.surface.TypeName() + ")");
    }
    sources.push_back(std::move(s));
  }

  MonteCarloReport report;
  report.iterations = options.iterations;
  report.seed = options.seed;
  report.coverage_probability = options.coverage_probability;
  report.spot_noise_mm = per_spot ? Eigen::Vector3d::Zero() : Eigen::Vector3d(design.spot_noise_mm);
  report.per_spot_noise = per_spot;
  report.weighting = options.weighting;

  // First order: the noise-free spots with Sigma attached.
  Problem problem;
  problem.sources = &sources;
  problem.calibration = &*calibration;
  problem.locate = options.locate;
  problem.start_from_design_pose = options.start_from_design_pose;
  problem.seed = options.seed;
  std::vector<LocatedOrigin> located;
  std::vector<LocatedOrigin> bound;
  for (const SourceSetup& s : sources) {
    LocateOptions locate = options.locate;
    locate.initial_scene_from_source = s.pose;
    Result<LocateResult> r = LocateSource(s.pattern, s.truth, locate);
    if (!r.ok()) {
      return Status::NoSolution("source '" + s.name + "', noise-free spots: " +
                                r.status().message());
    }
    SourceSpotGeometry geometry;
    geometry.scene_from_source = s.pose;
    for (size_t i = 0; i < s.truth.size(); ++i) {
      geometry.points_in_scene.push_back(s.truth[i].point_in_scene);
      geometry.covariances.push_back(s.noise_factor[i] * s.noise_factor[i].transpose());
    }
    Result<Eigen::Matrix<double, 6, 6>> crb = PoseCramerRaoBound(geometry);
    if (!crb.ok()) return Status::NoSolution("source '" + s.name + "': " + crb.status().message());
    Eigen::Matrix<double, 6, 6> first_order = r->covariance;
    if (options.weighting == SpotWeighting::kUnweighted) {
      Result<Eigen::Matrix<double, 6, 6>> sandwich =
          PoseFirstOrderCovariance(geometry, SpotWeighting::kUnweighted);
      if (!sandwich.ok()) {
        return Status::NoSolution("source '" + s.name + "': " + sandwich.status().message());
      }
      first_order = *sandwich;
    }
    const Eigen::Matrix3d angles_jacobian = XyzAnglesJacobianWrtLeftPerturbation(s.angles);
    MonteCarloSource m;
    m.name = s.name;
    m.spots = static_cast<int>(s.truth.size());
    m.true_origin_mm = s.pose.translation;
    m.true_rotation_xyz_rad = s.angles;
    m.origin_first_order_std_mm = StdDevs(first_order.bottomRightCorner<3, 3>());
    m.rotation_first_order_std_rad = StdDevs(
        angles_jacobian * first_order.topLeftCorner<3, 3>() * angles_jacobian.transpose());
    m.origin_cramer_rao_std_mm = StdDevs(crb->bottomRightCorner<3, 3>());
    m.rotation_cramer_rao_std_rad =
        StdDevs(angles_jacobian * crb->topLeftCorner<3, 3>() * angles_jacobian.transpose());
    report.sources.push_back(m);
    located.push_back({s.name, s.pose.translation, first_order.bottomRightCorner<3, 3>()});
    bound.push_back({s.name, s.pose.translation, crb->bottomRightCorner<3, 3>()});
  }
  Result<ScaleResult> first_order = ComputeScaleFactor(*calibration, located);
  if (!first_order.ok()) return first_order.status();
  Result<ScaleResult> cramer_rao = ComputeScaleFactor(*calibration, bound);
  if (!cramer_rao.ok()) return cramer_rao.status();
  for (const Separation& sep : calibration->separations) {
    MonteCarloLength l;
    l.from = sep.from;
    l.to = sep.to;
    l.true_mm = sep.length_mm;
    for (const LengthScale& ls : first_order->lengths) {
      if (ls.from == sep.from && ls.to == sep.to) l.photo_mm.first_order_std = ls.u_photo;
    }
    for (const LengthScale& ls : cramer_rao->lengths) {
      if (ls.from == sep.from && ls.to == sep.to) l.photo_mm.cramer_rao_std = ls.u_photo;
    }
    report.lengths.push_back(l);
    problem.pairs.emplace_back(sep.from, sep.to);
  }

  // The iterations, on a pool of threads (parallel_iterations.h); results by index.
  const int m = options.iterations;
  std::vector<IterationResult> results;
  report.threads = internal::IterationThreads(options.threads, m);
  internal::RunIterations<IterationResult>(
      m, report.threads, [&problem](int i) { return RunIteration(problem, i); },
      [](int, const std::string& what) {
        IterationResult failed;
        failed.error = "exception: " + what;
        return failed;
      },
      &results, options.progress, options.progress_interval_s);

  // Reduction, in index order.
  const size_t ns = sources.size();
  for (int i = 0; i < m; ++i) {
    const IterationResult& r = results[static_cast<size_t>(i)];
    if (!r.ok) {
      if (report.failed++ == 0) report.first_failure = "iteration " + std::to_string(i) + ": " + r.error;
      continue;
    }
    ++report.succeeded;
    report.sample_iterations.push_back(i);
    for (size_t s = 0; s < ns; ++s) {
      MonteCarloSource& out = report.sources[s];
      out.origin_samples_mm.push_back(r.origins[s]);
      out.rotation_samples_rad.push_back(out.true_rotation_xyz_rad + r.angle_offsets[s]);
    }
    for (size_t l = 0; l < report.lengths.size(); ++l) {
      report.lengths[l].samples_mm.push_back(r.lengths[l]);
    }
    report.scale_samples.push_back(r.scale);
  }
  if (report.succeeded == 0) {
    return Status::NoSolution("every one of the " + std::to_string(m) +
                              " iterations failed; first: " + report.first_failure);
  }
  const double p = options.coverage_probability;
  // One coordinate at a time, from the iterations' results (the angles as
  // the wrapped offsets from the design's, which the samples add back).
  std::vector<double> values;
  values.reserve(static_cast<size_t>(report.succeeded));
  const auto coordinate = [&results, &values](auto get) -> const std::vector<double>& {
    values.clear();
    for (const IterationResult& r : results) {
      if (r.ok) values.push_back(get(r));
    }
    return values;
  };
  for (size_t s = 0; s < ns; ++s) {
    MonteCarloSource& out = report.sources[s];
    for (int k = 0; k < 3; ++k) {
      const SampleSummary o =
          Summarize(coordinate([s, k](const IterationResult& r) { return r.origins[s][k]; }), p);
      const SampleSummary a = Summarize(
          coordinate([s, k](const IterationResult& r) { return r.angle_offsets[s][k]; }), p);
      out.origin_mean_mm[k] = o.mean;
      out.origin_std_mm[k] = o.std_dev;
      out.rotation_mean_rad[k] = out.true_rotation_xyz_rad[k] + a.mean;
      out.rotation_std_rad[k] = a.std_dev;
    }
  }
  for (MonteCarloLength& l : report.lengths) {
    const double first = l.photo_mm.first_order_std;
    const double crb = l.photo_mm.cramer_rao_std;
    l.photo_mm = Summarize(l.samples_mm, p);
    l.photo_mm.first_order_std = first;
    l.photo_mm.cramer_rao_std = crb;
  }
  report.scale_factor = Summarize(report.scale_samples, p);
  report.scale_factor.first_order_std = first_order->u_scale_factor;
  report.scale_factor.cramer_rao_std = cramer_rao->u_scale_factor;
  return report;
}

std::string MonteCarloReport::ToText() const {
  std::string out;
  out += "Monte Carlo (JCGM 101): " + std::to_string(iterations) + " iterations, " +
         std::to_string(succeeded) + " located, " + std::to_string(failed) + " failed; seed " +
         std::to_string(seed) + "; spot noise " +
         (per_spot_noise ? std::string("per spot") : FormatTriple("%.4g", spot_noise_mm) + " mm") + "; " +
         SpotWeightingName(weighting) + " weighting\n";
  if (failed > 0) out += "  first failure: " + first_failure + "\n";
  const std::string pct = FormatPrintf("%g", coverage_probability * 100.0);
  out += pct + " % coverage intervals: probabilistically symmetric (JCGM 101 7.7.1);"
               " shortest (7.7.2) in the JSON\n";
  out += "Lengths L_photo between origins (mm, design frame; MC = Monte Carlo, FO = first order,"
         " CRB = Cramer-Rao bound):\n";
  for (const MonteCarloLength& l : lengths) {
    const SampleSummary& s = l.photo_mm;
    out += "  " + l.from + "-" + l.to + ": true " + FormatPrintf("%.4f", l.true_mm) + ", mean " +
           FormatPrintf("%.5f", s.mean) + ", std MC " + FormatPrintf("%.5f", s.std_dev) + " FO " +
           FormatPrintf("%.5f", s.first_order_std) + " (MC/FO " +
           FormatPrintf("%.3f", Ratio(s.std_dev, s.first_order_std)) + ") CRB " +
           FormatPrintf("%.5f", s.cramer_rao_std) + " (MC/CRB " +
           FormatPrintf("%.3f", Ratio(s.std_dev, s.cramer_rao_std)) + ")";
    if (s.has_interval) {
      out += ", " + pct + " % [" + FormatPrintf("%.5f", s.symmetric.low) + ", " +
             FormatPrintf("%.5f", s.symmetric.high) + "]";
    }
    out += "\n";
  }
  const SampleSummary& s = scale_factor;
  out += "Scale factor s: mean " + FormatPrintf("%.7f", s.mean) + " (bias " +
         FormatPrintf("%+.1f", (s.mean - 1.0) * 1e6) + " ppm), std MC " + FormatPrintf("%.1f", s.std_dev * 1e6) +
         " ppm FO " + FormatPrintf("%.1f", s.first_order_std * 1e6) + " ppm CRB " +
         FormatPrintf("%.1f", s.cramer_rao_std * 1e6) + " ppm";
  if (s.has_interval) {
    out += ", " + pct + " % [" + FormatPrintf("%.7f", s.symmetric.low) + ", " +
           FormatPrintf("%.7f", s.symmetric.high) + "]";
  }
  out += "\n";
  out += "Sources (std MC / FO / CRB; origin in mm, rotation angles R = Rx Ry Rz in urad):\n";
  for (const MonteCarloSource& src : sources) {
    out += "  " + src.name + " (" + std::to_string(src.spots) + " spots): origin mean " +
           FormatTriple("%.4f", src.origin_mean_mm) + "\n";
    out += "    origin std   MC " + FormatTriple("%.5f", src.origin_std_mm) + "  FO " +
           FormatTriple("%.5f", src.origin_first_order_std_mm) + "  CRB " +
           FormatTriple("%.5f", src.origin_cramer_rao_std_mm) + "\n";
    out += "    rotation std MC " + FormatTriple("%.2f", src.rotation_std_rad * 1e6) + "  FO " +
           FormatTriple("%.2f", src.rotation_first_order_std_rad * 1e6) + "  CRB " +
           FormatTriple("%.2f", src.rotation_cramer_rao_std_rad * 1e6) + "\n";
  }
  return out;
}

std::string MonteCarloReport::ToJson(bool include_samples) const {
  using nlohmann::ordered_json;
  ordered_json doc = internal::RunHeaderJson("opl.monte_carlo_report", iterations, succeeded, failed,
                                              first_failure, seed, coverage_probability);
  doc["weighting"] = SpotWeightingName(weighting);
  doc["spot_noise_mm"] = VectorJson(spot_noise_mm);
  doc["per_spot_noise"] = per_spot_noise;
  if (include_samples) doc["sample_iterations"] = sample_iterations;
  ordered_json length_array = ordered_json::array();
  for (const MonteCarloLength& l : lengths) {
    ordered_json j;
    j["from"] = l.from;
    j["to"] = l.to;
    j["true_mm"] = l.true_mm;
    j["mean_mm"] = l.photo_mm.mean;
    j["std_mm"] = l.photo_mm.std_dev;
    j["ci95_mm"] = IntervalJson(l.photo_mm, l.photo_mm.symmetric);
    j["shortest_ci95_mm"] = IntervalJson(l.photo_mm, l.photo_mm.shortest);
    j["first_order_std_mm"] = l.photo_mm.first_order_std;
    j["cramer_rao_std_mm"] = l.photo_mm.cramer_rao_std;
    j["std_over_cramer_rao"] = Ratio(l.photo_mm.std_dev, l.photo_mm.cramer_rao_std);
    if (include_samples) j["samples_mm"] = l.samples_mm;
    length_array.push_back(j);
  }
  doc["lengths"] = length_array;
  ordered_json source_array = ordered_json::array();
  for (const MonteCarloSource& s : sources) {
    ordered_json j;
    j["name"] = s.name;
    j["spots"] = s.spots;
    j["true_origin_mm"] = VectorJson(s.true_origin_mm);
    j["origin_mean_mm"] = VectorJson(s.origin_mean_mm);
    j["origin_std_mm"] = VectorJson(s.origin_std_mm);
    j["origin_first_order_std_mm"] = VectorJson(s.origin_first_order_std_mm);
    j["origin_cramer_rao_std_mm"] = VectorJson(s.origin_cramer_rao_std_mm);
    j["true_rotation_rad"] = VectorJson(s.true_rotation_xyz_rad);
    j["rotation_mean_rad"] = VectorJson(s.rotation_mean_rad);
    j["rotation_std_rad"] = VectorJson(s.rotation_std_rad);
    j["rotation_first_order_std_rad"] = VectorJson(s.rotation_first_order_std_rad);
    j["rotation_cramer_rao_std_rad"] = VectorJson(s.rotation_cramer_rao_std_rad);
    if (include_samples) {
      ordered_json origins = ordered_json::array(), rotations = ordered_json::array();
      for (const Eigen::Vector3d& v : s.origin_samples_mm) origins.push_back(VectorJson(v));
      for (const Eigen::Vector3d& v : s.rotation_samples_rad) rotations.push_back(VectorJson(v));
      j["origin_samples_mm"] = std::move(origins);
      j["rotation_samples_rad"] = std::move(rotations);
    }
    source_array.push_back(j);
  }
  doc["sources"] = source_array;
  ordered_json scale;
  scale["mean"] = scale_factor.mean;
  scale["std"] = scale_factor.std_dev;
  scale["ci95"] = IntervalJson(scale_factor, scale_factor.symmetric);
  scale["shortest_ci95"] = IntervalJson(scale_factor, scale_factor.shortest);
  scale["first_order_std"] = scale_factor.first_order_std;
  scale["cramer_rao_std"] = scale_factor.cramer_rao_std;
  scale["std_over_cramer_rao"] = Ratio(scale_factor.std_dev, scale_factor.cramer_rao_std);
  if (include_samples) scale["samples"] = scale_samples;
  doc["scale_factor"] = scale;
  return CompactNumberArrays(doc.dump(2)) + "\n";
}

}  // namespace opl
