#include "opl/uncertainty/calibration_monte_carlo.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <utility>

#include <nlohmann/json.hpp>

#include "opl/calibrate/calibrate_module.h"
#include "opl/core/format.h"
#include "opl/geometry/spherical.h"
#include "opl/geometry/rotation.h"
#include "opl/sim/random.h"
#include "uncertainty/parallel_iterations.h"

#include "uncertainty/report_helpers.h"

namespace opl {
namespace {

using internal::IntervalJson;
using internal::Ratio;
using internal::StdDevs;
using internal::VectorJson;

// Mean and standard deviation (M - 1), two passes in index order: the
// formulas of Summarize, without the coverage intervals.
std::pair<double, double> MeanAndStd(const std::vector<double>& values) {
  if (values.empty()) return {0.0, 0.0};
  double sum = 0.0;
  for (double v : values) sum += v;
  const double mean = sum / static_cast<double>(values.size());
  if (values.size() < 2) return {mean, 0.0};
  double ss = 0.0;
  for (double v : values) ss += (v - mean) * (v - mean);
  return {mean, std::sqrt(ss / static_cast<double>(values.size() - 1))};
}

// The median of a non-empty list (mean of the two middle values when even).
double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// One source of the session and its reference (noise-free) calibration.
struct SourceSetup {
  std::string name;
  Eigen::Vector3d true_origin = Eigen::Vector3d::Zero();   // the design's
  Eigen::Vector3d ref_angles = Eigen::Vector3d::Zero();    // noise-free calibration, R = Rx Ry Rz
  std::vector<int> beam_ids;                                // noise-free calibration's beams, by id
  std::vector<Eigen::Vector2d> ref_azel;                    // parallel to beam_ids
};

// What one iteration produced; the default value is a failure.
struct IterationResult {
  bool ok = false;
  std::string error;
  std::vector<Eigen::Vector3d> origins;                   // per source
  std::vector<Eigen::Vector3d> angle_offsets;             // per source, wrapped, from the reference
  std::vector<std::vector<Eigen::Vector2d>> beam_offsets;  // per source, per beam: (az wrapped, el)
  std::vector<int> flagged;                                // per source
  std::vector<double> lengths;                             // per pair
};

struct Problem {
  const std::vector<SourceSetup>* sources = nullptr;
  const std::vector<Spot>* truth = nullptr;  // noise-free, carrying Sigma
  const std::vector<int>* slices = nullptr;  // one grid per slice
  std::vector<std::pair<size_t, size_t>> pairs;  // source indices, design order
  Eigen::Matrix3d noise_factor = Eigen::Matrix3d::Zero();  // R_n diag(sigma)
  CalibrateModuleOptions calibrate;
  uint64_t seed = 0;
};

const SourceCalibrationResult* FindResult(const ModuleCalibrationResult& r,
                                          const std::string& name) {
  for (const SourceCalibrationResult& s : r.sources) {
    if (s.calibration.name == name) return &s;
  }
  return nullptr;
}

const Separation* FindSeparation(const ModuleCalibration& c, const std::string& a,
                                 const std::string& b) {
  for (const Separation& s : c.separations) {
    if ((s.from == a && s.to == b) || (s.from == b && s.to == a)) return &s;
  }
  return nullptr;
}

// Fills `result` from a module calibration; false (with result->error) when a
// source or beam of the reference is missing.
bool Record(const Problem& problem, const ModuleCalibrationResult& calibrated,
            IterationResult* result) {
  const std::vector<SourceSetup>& sources = *problem.sources;
  for (const SourceSetup& s : sources) {
    const SourceCalibrationResult* r = FindResult(calibrated, s.name);
    if (r == nullptr) {
      result->error = "source '" + s.name + "' was not calibrated";
      return false;
    }
    const Rigid3d& pose = r->calibration.calibration_from_source;
    result->origins.push_back(pose.translation);
    const Eigen::Vector3d angles = XyzAnglesRadFromRotation(pose.RotationMatrix());
    Eigen::Vector3d offset;
    for (int k = 0; k < 3; ++k) offset[k] = WrapAngleRad(angles[k] - s.ref_angles[k]);
    result->angle_offsets.push_back(offset);
    std::vector<Eigen::Vector2d> beams;
    beams.reserve(s.beam_ids.size());
    for (size_t b = 0; b < s.beam_ids.size(); ++b) {
      const Beam* beam = r->calibration.pattern.Find(s.beam_ids[b]);
      if (beam == nullptr) {
        result->error = "source '" + s.name + "': beam " + std::to_string(s.beam_ids[b]) +
                        " was not calibrated (dropped after flagging)";
        return false;
      }
      beams.emplace_back(WrapAngleRad(beam->az_rad - s.ref_azel[b].x()),
                         beam->el_rad - s.ref_azel[b].y());
    }
    result->beam_offsets.push_back(std::move(beams));
    result->flagged.push_back(r->calibration.quality ? r->calibration.quality->samples_flagged : 0);
  }
  for (const auto& [i, j] : problem.pairs) {
    const Separation* sep = FindSeparation(calibrated.calibration, sources[i].name, sources[j].name);
    if (sep == nullptr) {
      result->error = "no separation " + sources[i].name + "-" + sources[j].name;
      return false;
    }
    result->lengths.push_back(sep->length_mm);
  }
  return true;
}

IterationResult RunIteration(const Problem& problem, int iteration) {
  IterationResult result;
  std::mt19937_64 rng(IterationSeed(problem.seed, iteration));
  NormalGenerator normal;
  std::vector<Spot> spots = *problem.truth;
  for (Spot& spot : spots) {
    Eigen::Vector3d z;
    for (int k = 0; k < 3; ++k) z[k] = normal(rng);
    spot.observation.point_in_scene += problem.noise_factor * z;
  }
  Result<ModuleCalibrationResult> calibrated =
      CalibrateModule(spots, *problem.slices, std::nullopt, problem.calibrate);
  if (!calibrated.ok()) {
    result.error = calibrated.status().message();
    return result;
  }
  result.ok = Record(problem, *calibrated, &result);
  return result;
}

BeamSpreadSummary SummarizeBeams(const std::vector<CalibrationMonteCarloBeam>& beams) {
  BeamSpreadSummary out;
  for (int k = 0; k < 2; ++k) {
    std::vector<double> std_mc, std_fo, ratio;
    for (const CalibrationMonteCarloBeam& b : beams) {
      const double mc = k == 0 ? b.az_std_rad : b.el_std_rad;
      const double fo = k == 0 ? b.az_first_order_std_rad : b.el_first_order_std_rad;
      if (!(fo > 0.0)) continue;  // the central beam: fixed by the gauge
      std_mc.push_back(mc);
      std_fo.push_back(fo);
      ratio.push_back(mc / fo);
    }
    if (std_mc.empty()) continue;
    out.beams = static_cast<int>(std_mc.size());
    out.std_median_rad[k] = Median(std_mc);
    out.std_max_rad[k] = *std::max_element(std_mc.begin(), std_mc.end());
    out.first_order_std_median_rad[k] = Median(std_fo);
    out.ratio_median[k] = Median(ratio);
    out.ratio_min[k] = *std::min_element(ratio.begin(), ratio.end());
    out.ratio_max[k] = *std::max_element(ratio.begin(), ratio.end());
  }
  return out;
}

nlohmann::ordered_json PairJson(const Eigen::Vector2d& v) {
  return nlohmann::ordered_json::array({v.x(), v.y()});
}

}  // namespace

ScreenSlicesOptions DefaultCalibrationScreens() {
  ScreenSlicesOptions screens;
  for (int k = 0; k < 10; ++k) screens.depths_mm.push_back(750.0 + 65.0 * k);  // 750:65:1335
  return screens;
}

Status CalibrationMonteCarloOptions::Validate() const {
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
                                   FormatNumber(coverage_probability));
  }
  if (!(std::isfinite(progress_interval_s) && progress_interval_s > 0.0)) {
    return Status::InvalidArgument("progress_interval_s must be finite and > 0, got " +
                                   FormatNumber(progress_interval_s));
  }
  if (Status st = screens.Validate(); !st.ok()) {
    return Status::InvalidArgument("screens: " + st.message());
  }
  if (Status st = calibrate.Validate(); !st.ok()) {
    return Status::InvalidArgument("calibrate options: " + st.message());
  }
  return Status::Ok();
}

Result<CalibrationMonteCarloReport> RunCalibrationMonteCarlo(
    const ModuleDesign& design, const CalibrationMonteCarloOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  {
    ModuleDesign sources_only = design;  // the design's surface is not used
    sources_only.surface = Surface();
    if (Status st = sources_only.Validate(); !st.ok()) {
      return Status::InvalidArgument("module design: " + st.message());
    }
  }
  if (!(design.spot_noise_mm.array() > 0.0).any()) {
    return Status::InvalidArgument("spot_noise_mm is zero on every axis: nothing to simulate");
  }
  Result<std::vector<Surface>> screens = MakeCalibrationScreens(design, options.screens);
  if (!screens.ok()) return screens.status();
  SpotSimulationOptions exact;
  exact.attach_covariance = false;
  Result<std::vector<SimulatedSpot>> simulated = SimulateSlices(design, *screens, exact);
  if (!simulated.ok()) return simulated.status();

  // The noise-free session, each sample carrying Sigma; slice = source index
  // * screens + screen (one grid per slice, as CalibrateModule requires).
  const Eigen::Matrix3d sigma = design.SpotCovarianceMm2();
  const int num_screens = static_cast<int>(screens->size());
  std::map<std::string, size_t> index_of;
  for (size_t s = 0; s < design.sources.size(); ++s) index_of[design.sources[s].name] = s;
  std::vector<Spot> truth;
  std::vector<int> slices;
  truth.reserve(simulated->size());
  slices.reserve(simulated->size());
  std::vector<int> spot_count(design.sources.size(), 0);
  std::vector<std::set<int>> screens_seen(design.sources.size());
  for (const SimulatedSpot& s : *simulated) {
    const size_t source = index_of.at(s.spot.source);
    Spot spot;
    spot.source = s.spot.source;
    spot.observation.beam_id = s.spot.observation.beam_id;
    spot.observation.point_in_scene = s.true_point_in_scene;
    spot.observation.cov_in_scene = sigma;
    spot.where = "screen " + std::to_string(s.slice);
    truth.push_back(std::move(spot));
    slices.push_back(static_cast<int>(source) * num_screens + s.slice);
    ++spot_count[source];
    screens_seen[source].insert(s.slice);
  }
  for (size_t s = 0; s < design.sources.size(); ++s) {
    if (spot_count[s] == 0) {
      return Status::NoSolution("source '" + design.sources[s].name +
                                "': no beam hits any of the " + std::to_string(num_screens) +
                                " screens");
    }
  }

  CalibrateModuleOptions calibrate;
  calibrate.source = options.calibrate;
  const int n0 = design.sources.front().beams_per_side;
  if (std::all_of(design.sources.begin(), design.sources.end(),
                  [&](const SourceDesign& d) { return d.beams_per_side == n0; })) {
    calibrate.beams_per_side = n0;
  }

  // First order and the reference: the noise-free session.
  Result<ModuleCalibrationResult> reference =
      CalibrateModule(truth, slices, std::nullopt, calibrate);
  if (!reference.ok()) {
    return Status::NoSolution("the noise-free session: " + reference.status().message());
  }
  CalibrationMonteCarloReport report;
  report.iterations = options.iterations;
  report.seed = options.seed;
  report.coverage_probability = options.coverage_probability;
  report.spot_noise_mm = design.spot_noise_mm;
  report.depths_mm = options.screens.depths_mm;
  report.tilt_deg = options.screens.tilt_deg;
  report.curvature_per_mm = options.screens.curvature_per_mm;

  std::vector<SourceSetup> sources;
  for (size_t s = 0; s < design.sources.size(); ++s) {
    const SourceDesign& d = design.sources[s];
    const SourceCalibrationResult* r = FindResult(*reference, d.name);
    if (r == nullptr) {
      return Status::NoSolution("the noise-free session: source '" + d.name +
                                "' was not calibrated");
    }
    SourceSetup setup;
    setup.name = d.name;
    setup.true_origin = d.scene_from_source.translation;
    setup.ref_angles =
        XyzAnglesRadFromRotation(r->calibration.calibration_from_source.RotationMatrix());
    CalibrationMonteCarloSource out;
    out.name = d.name;
    out.spots = spot_count[s];
    out.slices = static_cast<int>(screens_seen[s].size());
    out.true_origin_mm = setup.true_origin;
    out.true_rotation_xyz_rad = setup.ref_angles;
    if (r->calibration.quality) {
      out.origin_first_order_std_mm = StdDevs(r->calibration.quality->origin_cov_mm2);
      out.rotation_first_order_std_rad = StdDevs(r->calibration.quality->rotation_xyz_cov_rad2);
    } else {
      out.origin_first_order_std_mm = StdDevs(r->pose_covariance.bottomRightCorner<3, 3>());
    }
    for (const Beam& b : r->calibration.pattern.beams()) {
      setup.beam_ids.push_back(b.id);
      setup.ref_azel.emplace_back(b.az_rad, b.el_rad);
      CalibrationMonteCarloBeam mb;
      mb.id = b.id;
      mb.true_az_rad = b.az_rad;
      mb.true_el_rad = b.el_rad;
      if (b.cov_azel_rad2) {
        mb.az_first_order_std_rad = std::sqrt(std::max(0.0, (*b.cov_azel_rad2)(0, 0)));
        mb.el_first_order_std_rad = std::sqrt(std::max(0.0, (*b.cov_azel_rad2)(1, 1)));
      }
      out.beams.push_back(mb);
    }
    sources.push_back(std::move(setup));
    report.sources.push_back(std::move(out));
  }

  Problem problem;
  problem.sources = &sources;
  problem.truth = &truth;
  problem.slices = &slices;
  problem.noise_factor = design.noise_frame_rotation * design.spot_noise_mm.asDiagonal();
  problem.calibrate = calibrate;
  problem.seed = options.seed;
  for (size_t i = 0; i < sources.size(); ++i) {
    for (size_t j = i + 1; j < sources.size(); ++j) {
      const Separation* sep =
          FindSeparation(reference->calibration, sources[i].name, sources[j].name);
      if (sep == nullptr) {
        return Status::NoSolution("the noise-free session: no separation " + sources[i].name +
                                  "-" + sources[j].name);
      }
      CalibrationMonteCarloLength l;
      l.from = sources[i].name;
      l.to = sources[j].name;
      l.true_mm = (sources[j].true_origin - sources[i].true_origin).norm();
      l.length_mm.first_order_std = sep->u_length_mm;
      report.lengths.push_back(std::move(l));
      problem.pairs.emplace_back(i, j);
    }
  }

  // The iterations, on a pool of threads; results by index.
  const int m = options.iterations;
  std::vector<IterationResult> results;
  const int workers = internal::RunIterations<IterationResult>(
      m, options.threads, [&](int i) { return RunIteration(problem, i); },
      [](int, const std::string& what) {
        IterationResult failed;
        failed.error = "exception: " + what;
        return failed;
      },
      &results, options.progress, options.progress_interval_s);
  report.threads = std::max(1, workers);  // 0: the calling thread ran them all

  // Reduction, in index order.
  const size_t ns = sources.size();
  std::vector<std::vector<double>> origin(ns * 3), angle(ns * 3);
  std::vector<std::vector<std::vector<double>>> beam_az(ns), beam_el(ns);
  for (size_t s = 0; s < ns; ++s) {
    beam_az[s].resize(sources[s].beam_ids.size());
    beam_el[s].resize(sources[s].beam_ids.size());
  }
  for (int i = 0; i < m; ++i) {
    const IterationResult& r = results[static_cast<size_t>(i)];
    if (!r.ok) {
      if (report.failed++ == 0) {
        report.first_failure = "iteration " + std::to_string(i) + ": " + r.error;
      }
      continue;
    }
    ++report.succeeded;
    for (size_t s = 0; s < ns; ++s) {
      for (int k = 0; k < 3; ++k) {
        origin[s * 3 + static_cast<size_t>(k)].push_back(r.origins[s][k]);
        angle[s * 3 + static_cast<size_t>(k)].push_back(r.angle_offsets[s][k]);
      }
      for (size_t b = 0; b < beam_az[s].size(); ++b) {
        beam_az[s][b].push_back(r.beam_offsets[s][b].x());
        beam_el[s][b].push_back(r.beam_offsets[s][b].y());
      }
      report.sources[s].flagged_samples += r.flagged[s];
    }
    for (size_t l = 0; l < report.lengths.size(); ++l) {
      report.lengths[l].samples_mm.push_back(r.lengths[l]);
    }
  }
  if (report.succeeded == 0) {
    return Status::NoSolution("every one of the " + std::to_string(m) +
                              " iterations failed; first: " + report.first_failure);
  }
  for (size_t s = 0; s < ns; ++s) {
    CalibrationMonteCarloSource& out = report.sources[s];
    for (int k = 0; k < 3; ++k) {
      const auto [o_mean, o_std] = MeanAndStd(origin[s * 3 + static_cast<size_t>(k)]);
      const auto [a_mean, a_std] = MeanAndStd(angle[s * 3 + static_cast<size_t>(k)]);
      out.origin_mean_mm[k] = o_mean;
      out.origin_std_mm[k] = o_std;
      out.rotation_mean_rad[k] = out.true_rotation_xyz_rad[k] + a_mean;
      out.rotation_std_rad[k] = a_std;
    }
    for (size_t b = 0; b < out.beams.size(); ++b) {
      const auto [az_mean, az_std] = MeanAndStd(beam_az[s][b]);
      const auto [el_mean, el_std] = MeanAndStd(beam_el[s][b]);
      CalibrationMonteCarloBeam& beam = out.beams[b];
      beam.az_mean_rad = beam.true_az_rad + az_mean;
      beam.el_mean_rad = beam.true_el_rad + el_mean;
      beam.az_std_rad = az_std;
      beam.el_std_rad = el_std;
    }
    out.beam_summary = SummarizeBeams(out.beams);
  }
  const double p = options.coverage_probability;
  for (CalibrationMonteCarloLength& l : report.lengths) {
    const double first = l.length_mm.first_order_std;
    l.length_mm = Summarize(l.samples_mm, p);
    l.length_mm.first_order_std = first;
  }
  return report;
}

std::string CalibrationMonteCarloReport::ToText() const {
  std::string out;
  out += "Calibration Monte Carlo (JCGM 101): " + std::to_string(iterations) + " iterations, " +
         std::to_string(succeeded) + " calibrated, " + std::to_string(failed) + " failed; seed " +
         std::to_string(seed) + "; spot noise " + FormatTriple("%.4g", spot_noise_mm) + " mm\n";
  if (failed > 0) out += "  first failure: " + first_failure + "\n";
  out += "Session: " + std::to_string(depths_mm.size()) + " screen(s) at ";
  if (depths_mm.size() <= 12) {
    for (size_t k = 0; k < depths_mm.size(); ++k) {
      out += (k ? ", " : "") + FormatPrintf("%g", depths_mm[k]);
    }
  } else {
    out += FormatPrintf("%g", depths_mm.front()) + ", " + FormatPrintf("%g", depths_mm[1]) +
           ", ..., " + FormatPrintf("%g", depths_mm.back());
  }
  out += " mm; tilt " + FormatPrintf("%g", tilt_deg) + " deg, curvature " +
         FormatPrintf("%g", curvature_per_mm) + " /mm\n";
  const std::string pct = FormatPrintf("%g", coverage_probability * 100.0);
  out += pct + " % coverage intervals: probabilistically symmetric (JCGM 101 7.7.1);"
               " shortest (7.7.2) in the JSON\n";
  if (lengths.empty()) {
    out += "Separations: none (one source)\n";
  } else {
    out += "Separations between calibrated origins (mm; MC = Monte Carlo, FO = first order):\n";
  }
  for (const CalibrationMonteCarloLength& l : lengths) {
    const SampleSummary& s = l.length_mm;
    const double ppm = l.true_mm > 0.0 ? 1e6 / l.true_mm : 0.0;
    out += "  " + l.from + "-" + l.to + ": true " + FormatPrintf("%.4f", l.true_mm) + ", mean " +
           FormatPrintf("%.5f", s.mean) + " (bias " + FormatPrintf("%+.1f", (s.mean - l.true_mm) * ppm) +
           " ppm), std MC " + FormatPrintf("%.5f", s.std_dev) + " (" +
           FormatPrintf("%.1f", s.std_dev * ppm) + " ppm) FO " +
           FormatPrintf("%.5f", s.first_order_std) + " (MC/FO " +
           FormatPrintf("%.3f", Ratio(s.std_dev, s.first_order_std)) + ")";
    if (s.has_interval) {
      out += ", " + pct + " % [" + FormatPrintf("%.5f", s.symmetric.low) + ", " +
             FormatPrintf("%.5f", s.symmetric.high) + "]";
    }
    out += "\n";
  }
  out += "Sources (std MC / FO; origin in mm; pose angles R = Rx Ry Rz and beam directions in "
         "urad, in the calibration's gauge):\n";
  for (const CalibrationMonteCarloSource& src : sources) {
    out += "  " + src.name + " (" + std::to_string(src.spots) + " spots on " +
           std::to_string(src.slices) + " screens): origin true " +
           FormatTriple("%.4f", src.true_origin_mm) + " mean " + FormatTriple("%.4f", src.origin_mean_mm) +
           "\n";
    const Eigen::Vector3d origin_ratio(Ratio(src.origin_std_mm.x(), src.origin_first_order_std_mm.x()),
                                       Ratio(src.origin_std_mm.y(), src.origin_first_order_std_mm.y()),
                                       Ratio(src.origin_std_mm.z(), src.origin_first_order_std_mm.z()));
    out += "    origin std   MC " + FormatTriple("%.5f", src.origin_std_mm) + "  FO " +
           FormatTriple("%.5f", src.origin_first_order_std_mm) + "  MC/FO " +
           FormatTriple("%.3f", origin_ratio) + "\n";
    const Eigen::Vector3d rotation_ratio(
        Ratio(src.rotation_std_rad.x(), src.rotation_first_order_std_rad.x()),
        Ratio(src.rotation_std_rad.y(), src.rotation_first_order_std_rad.y()),
        Ratio(src.rotation_std_rad.z(), src.rotation_first_order_std_rad.z()));
    out += "    rotation std MC " + FormatTriple("%.2f", src.rotation_std_rad * 1e6) + "  FO " +
           FormatTriple("%.2f", src.rotation_first_order_std_rad * 1e6) + "  MC/FO " +
           FormatTriple("%.3f", rotation_ratio) + "\n";
    const BeamSpreadSummary& b = src.beam_summary;
    for (int k = 0; k < 2; ++k) {
      out += std::string("    beam ") + (k == 0 ? "az" : "el") + " std over " +
             std::to_string(b.beams) + " beams: median MC " +
             FormatPrintf("%.2f", b.std_median_rad[k] * 1e6) + " FO " +
             FormatPrintf("%.2f", b.first_order_std_median_rad[k] * 1e6) + ", max MC " +
             FormatPrintf("%.2f", b.std_max_rad[k] * 1e6) + "; MC/FO median " +
             FormatPrintf("%.3f", b.ratio_median[k]) + " (" + FormatPrintf("%.3f", b.ratio_min[k]) +
             " .. " + FormatPrintf("%.3f", b.ratio_max[k]) + ")\n";
    }
    out += "    samples flagged: " + std::to_string(src.flagged_samples) + " in " +
           std::to_string(succeeded) + " calibrations\n";
  }
  return out;
}

std::string CalibrationMonteCarloReport::ToJson() const {
  using nlohmann::ordered_json;
  ordered_json doc = internal::RunHeaderJson("opl.calibration_monte_carlo_report", iterations, succeeded, failed,
                                              first_failure, seed, coverage_probability);
  doc["spot_noise_mm"] = VectorJson(spot_noise_mm);
  doc["depths_mm"] = depths_mm;
  doc["tilt_deg"] = tilt_deg;
  doc["curvature_per_mm"] = curvature_per_mm;
  ordered_json length_array = ordered_json::array();
  for (const CalibrationMonteCarloLength& l : lengths) {
    ordered_json j;
    j["from"] = l.from;
    j["to"] = l.to;
    j["true_mm"] = l.true_mm;
    j["mean_mm"] = l.length_mm.mean;
    j["std_mm"] = l.length_mm.std_dev;
    j["ci95_mm"] = IntervalJson(l.length_mm, l.length_mm.symmetric);
    j["shortest_ci95_mm"] = IntervalJson(l.length_mm, l.length_mm.shortest);
    j["first_order_std_mm"] = l.length_mm.first_order_std;
    length_array.push_back(j);
  }
  doc["lengths"] = length_array;
  ordered_json source_array = ordered_json::array();
  for (const CalibrationMonteCarloSource& s : sources) {
    ordered_json j;
    j["name"] = s.name;
    j["spots"] = s.spots;
    j["slices"] = s.slices;
    j["true_origin_mm"] = VectorJson(s.true_origin_mm);
    j["origin_mean_mm"] = VectorJson(s.origin_mean_mm);
    j["origin_std_mm"] = VectorJson(s.origin_std_mm);
    j["origin_first_order_std_mm"] = VectorJson(s.origin_first_order_std_mm);
    j["true_rotation_rad"] = VectorJson(s.true_rotation_xyz_rad);
    j["rotation_mean_rad"] = VectorJson(s.rotation_mean_rad);
    j["rotation_std_rad"] = VectorJson(s.rotation_std_rad);
    j["rotation_first_order_std_rad"] = VectorJson(s.rotation_first_order_std_rad);
    j["flagged_samples"] = s.flagged_samples;
    const BeamSpreadSummary& b = s.beam_summary;
    j["beams_summarized"] = b.beams;
    j["beam_std_median_rad"] = PairJson(b.std_median_rad);
    j["beam_std_max_rad"] = PairJson(b.std_max_rad);
    j["beam_first_order_std_median_rad"] = PairJson(b.first_order_std_median_rad);
    j["beam_std_ratio_median"] = PairJson(b.ratio_median);
    j["beam_std_ratio_min"] = PairJson(b.ratio_min);
    j["beam_std_ratio_max"] = PairJson(b.ratio_max);
    ordered_json beams = ordered_json::array();
    for (const CalibrationMonteCarloBeam& beam : s.beams) {
      ordered_json jb;
      jb["id"] = beam.id;
      jb["true_az_rad"] = beam.true_az_rad;
      jb["true_el_rad"] = beam.true_el_rad;
      jb["az_mean_rad"] = beam.az_mean_rad;
      jb["el_mean_rad"] = beam.el_mean_rad;
      jb["az_std_rad"] = beam.az_std_rad;
      jb["el_std_rad"] = beam.el_std_rad;
      jb["az_first_order_std_rad"] = beam.az_first_order_std_rad;
      jb["el_first_order_std_rad"] = beam.el_first_order_std_rad;
      beams.push_back(jb);
    }
    j["beams"] = beams;
    source_array.push_back(j);
  }
  doc["sources"] = source_array;
  return doc.dump(2) + "\n";
}

}  // namespace opl
