#include "opl/report/calibration_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <vector>

#include "opl/core/format.h"
#include "opl/geometry/rotation.h"

namespace opl {
namespace {

std::string Fixed(double v, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, v);
  return buffer;
}

std::string Csv(double v) { return FormatNumber(v, 10); }

// The upper p-quantile of the mean of m independent draws from the
// empirical distribution of `pool` (binned).
double MeanOfDrawsQuantile(const std::vector<double>& pool, int m, double p) {
  constexpr int kBins = 512;
  const double top = *std::max_element(pool.begin(), pool.end());
  if (!(top > 0)) return 0.0;
  const double width = top / (kBins - 1);
  std::vector<double> single(kBins, 0.0);
  for (double d : pool) single[static_cast<size_t>(std::lround(d / width))] += 1.0 / pool.size();
  std::vector<double> sum = single;  // the distribution of the sum of k draws, bin = value / width
  for (int k = 1; k < m; ++k) {
    std::vector<double> next(sum.size() + kBins - 1, 0.0);
    for (size_t i = 0; i < sum.size(); ++i) {
      if (sum[i] == 0.0) continue;
      for (size_t j = 0; j < single.size(); ++j) next[i + j] += sum[i] * single[j];
    }
    sum.swap(next);
  }
  double tail = 0.0;
  for (size_t i = sum.size(); i-- > 0;) {
    tail += sum[i];
    if (tail > p) return static_cast<double>(i) * width / m;
  }
  return 0.0;
}

}  // namespace

double PointToRayNoiseLevel(const SourceCalibrationResult& source, double alpha) {
  // The used samples' distances per beam.
  std::map<int, std::vector<double>> by_beam;
  for (const CalibrationSampleResidual& r : source.residuals) {
    if (!r.outlier && !r.beam_dropped && std::isfinite(r.point_to_ray_mm)) by_beam[r.beam_id].push_back(r.point_to_ray_mm);
  }
  std::vector<std::vector<double>> beams;
  for (const BeamCalibrationQuality& b : source.beams) {
    auto it = by_beam.find(b.beam_id);
    if (it != by_beam.end() && it->second.size() >= 2) beams.push_back(it->second);
  }
  if (beams.size() < 2 || !(alpha > 0 && alpha < 1)) return std::numeric_limits<double>::quiet_NaN();
  // m: the most common number of used samples.
  std::map<int, int> counts;
  for (const std::vector<double>& b : beams) ++counts[static_cast<int>(b.size())];
  int m = 0, most = 0;
  for (const auto& [size, count] : counts) {
    if (count > most) most = count, m = size;
  }
  const double p = -std::expm1(std::log1p(-alpha) / static_cast<double>(beams.size()));
  std::vector<double> means;
  for (const std::vector<double>& b : beams) {
    double mean = 0.0;
    for (double d : b) mean += d / b.size();
    means.push_back(mean);
  }
  std::vector<bool> in_pool(beams.size(), true);
  double level = std::numeric_limits<double>::quiet_NaN();
  for (int round = 0; round < 3; ++round) {
    std::vector<double> pool;
    double obs_sum = 0.0, obs_sum2 = 0.0;
    int obs_n = 0;
    for (size_t i = 0; i < beams.size(); ++i) {
      if (!in_pool[i]) continue;
      pool.insert(pool.end(), beams[i].begin(), beams[i].end());
      obs_sum += means[i];
      obs_sum2 += means[i] * means[i];
      ++obs_n;
    }
    double pool_mean = 0.0, pool_var = 0.0;
    for (double d : pool) pool_mean += d / pool.size();
    for (double d : pool) pool_var += (d - pool_mean) * (d - pool_mean) / (pool.size() - 1);
    const double model_sd = std::sqrt(pool_var / m);
    const double obs_mean = obs_sum / obs_n;
    const double obs_sd = std::sqrt(std::max(0.0, (obs_sum2 - obs_n * obs_mean * obs_mean) / (obs_n - 1)));
    const double q = MeanOfDrawsQuantile(pool, m, p);
    // The model's shape, the beams' own mean and spread.
    level = model_sd > 0 ? obs_mean + (q - pool_mean) * obs_sd / model_sd : q;
    bool changed = false;
    for (size_t i = 0; i < beams.size(); ++i) {
      const bool keep = means[i] <= level;
      changed |= keep != in_pool[i];
      in_pool[i] = keep;
    }
    if (!changed) break;
  }
  if (!(level > 0)) return level;
  // Rounded up to 3 significant digits.
  const double unit = std::pow(10.0, std::floor(std::log10(level)) - 2);
  return std::ceil(level / unit - 1e-9) * unit;
}

std::string CalibrationSummaryText(const ModuleCalibrationResult& result) {
  std::string out;
  for (const SourceCalibrationResult& s : result.sources) {
    const SourceCalibration& c = s.calibration;
    const SourceCalibrationQuality& q = *c.quality;
    const Eigen::Vector3d t = c.calibration_from_source.translation;
    const Eigen::Vector3d angles = XyzAnglesRadFromRotation(c.calibration_from_source.RotationMatrix());
    const Eigen::Vector3d u_angles = q.rotation_xyz_cov_rad2.diagonal().cwiseSqrt();
    const Eigen::Vector3d u_t = q.origin_cov_mm2.diagonal().cwiseSqrt();
    out += "source " + c.name + " (" + std::to_string(c.pattern.beams_per_side()) + " x " +
           std::to_string(c.pattern.beams_per_side()) + ", " + std::to_string(q.slices) +
           " slices)\n";
    out += "  origin        [" + Fixed(t.x(), 4) + ", " + Fixed(t.y(), 4) + ", " + Fixed(t.z(), 4) +
           "] mm   u = [" + Fixed(u_t.x(), 4) + ", " + Fixed(u_t.y(), 4) + ", " +
           Fixed(u_t.z(), 4) + "] mm\n";
    const double deg = 180.0 / kPi;
    out += "  rotation xyz  [" + Fixed(angles.x() * deg, 5) + ", " + Fixed(angles.y() * deg, 5) +
           ", " + Fixed(angles.z() * deg, 5) + "] deg  u = [" + Fixed(u_angles.x() * deg, 5) +
           ", " + Fixed(u_angles.y() * deg, 5) + ", " + Fixed(u_angles.z() * deg, 5) + "] deg\n";
    out += "  residuals     RMS " + Fixed(q.rms_residual_urad, 1) + " urad, point-to-ray mean " +
           Fixed(q.mean_point_to_ray_mm, 4) + " mm, max " + Fixed(q.max_point_to_ray_mm, 4) +
           " mm, chi2/dof " + Fixed(q.variance_factor, 3) +
           (s.weighted ? " (sample sigmas given)" : " (no sample sigmas: covariance scaled)") + "\n";
    out += "  samples       " + std::to_string(q.samples_used) + " used, " +
           std::to_string(q.samples_flagged) + " flagged as wrong, " +
           std::to_string(c.pattern.beams().size()) + " beams calibrated";
    if (!s.dropped_beam_ids.empty()) {
      out += ", dropped (too few good samples):";
      for (int id : s.dropped_beam_ids) out += " " + std::to_string(id);
    }
    out += "\n";
    std::vector<BeamCalibrationQuality> worst = s.beams;
    std::sort(worst.begin(), worst.end(), [](const auto& a, const auto& b) {
      return a.mean_point_to_ray_mm > b.mean_point_to_ray_mm;
    });
    worst.resize(std::min<size_t>(worst.size(), 5));
    out += "  worst beams   ";
    for (size_t i = 0; i < worst.size(); ++i) {
      out += (i ? ", " : "") + std::to_string(worst[i].beam_id) + " (" +
             Fixed(worst[i].mean_point_to_ray_mm, 4) + " mm)";
    }
    out += "  [mean point-to-ray distance]\n";
    std::vector<std::string> flagged;
    for (const CalibrationSampleResidual& r : s.residuals) {
      if (r.outlier) {
        flagged.push_back(std::to_string(r.beam_id) + "@" + std::to_string(r.slice));
      }
    }
    if (!flagged.empty()) {
      out += "  flagged       beam@slice:";
      for (size_t i = 0; i < flagged.size() && i < 20; ++i) out += " " + flagged[i];
      if (flagged.size() > 20) out += " ... (" + std::to_string(flagged.size()) + " in all)";
      out += "\n";
    }
  }
  if (!result.calibration.separations.empty()) out += "separations (calibrated length scales, u at k = 1)\n";
  for (const Separation& sep : result.calibration.separations) {
    out += "  " + sep.from + "-" + sep.to + "  " + Fixed(sep.length_mm, 4) + " mm  u = " +
           Fixed(sep.u_length_mm, 4) + " mm  (" + Fixed(1e6 * sep.u_length_mm / sep.length_mm, 1) +
           " ppm)\n";
  }
  if (result.calibration.scaling) {
    const CalibrationScaling& sc = *result.calibration.scaling;
    out += "scaling         artifact " + sc.from_target + "-" + sc.to_target + " " +
           FormatNumber(sc.artifact_length_mm) + " mm (u " + FormatNumber(sc.u_artifact_length_mm) +
           " mm), measured " + FormatNumber(sc.measured_length) + " -> scale " +
           FormatNumber(sc.scale) + ", u_rel " + FormatNumber(sc.u_scale_relative, 3) + "\n";
  } else {
    out += "scaling         none: the samples were taken as millimetres\n";
  }
  return out;
}

std::string BeamQualityCsv(const ModuleCalibrationResult& result) {
  std::string out =
      "source,beam,row,col,az_rad,el_rad,u_az_rad,u_el_rad,samples_used,samples_flagged,"
      "mean_point_to_ray_mm,max_point_to_ray_mm,rms_residual_urad\n";
  for (const SourceCalibrationResult& s : result.sources) {
    const BeamPattern& p = s.calibration.pattern;
    const int n = p.beams_per_side();
    std::vector<std::pair<int, std::string>> rows;
    for (const BeamCalibrationQuality& q : s.beams) {
      const Beam* b = p.Find(q.beam_id);
      const Eigen::Matrix2d C = b->cov_azel_rad2.value_or(Eigen::Matrix2d::Zero());
      rows.emplace_back(q.beam_id,
                        s.calibration.name + "," + std::to_string(q.beam_id) + "," +
                            std::to_string(BeamRow(q.beam_id, n)) + "," +
                            std::to_string(BeamCol(q.beam_id, n)) + "," + Csv(b->az_rad) + "," +
                            Csv(b->el_rad) + "," + Csv(std::sqrt(C(0, 0))) + "," +
                            Csv(std::sqrt(C(1, 1))) + "," + std::to_string(q.samples_used) + "," +
                            std::to_string(q.samples_flagged) + "," +
                            Csv(q.mean_point_to_ray_mm) + "," + Csv(q.max_point_to_ray_mm) + "," +
                            Csv(1e6 * q.rms_residual_rad) + "\n");
    }
    for (int id : s.dropped_beam_ids) {
      int samples = 0;
      for (const CalibrationSampleResidual& r : s.residuals) samples += r.beam_id == id;
      rows.emplace_back(id, s.calibration.name + "," + std::to_string(id) + "," +
                                std::to_string(BeamRow(id, n)) + "," +
                                std::to_string(BeamCol(id, n)) + ",,,,,0," +
                                std::to_string(samples) + ",,,\n");
    }
    std::sort(rows.begin(), rows.end());
    for (const auto& row : rows) out += row.second;
  }
  return out;
}

std::string SampleResidualsCsv(const ModuleCalibrationResult& result) {
  std::string out =
      "source,beam,slice,residual_az_urad,residual_el_urad,normalized,point_to_ray_mm,status\n";
  for (const SourceCalibrationResult& s : result.sources) {
    for (const CalibrationSampleResidual& r : s.residuals) {
      out += s.calibration.name + "," + std::to_string(r.beam_id) + "," + std::to_string(r.slice) +
             "," + Csv(1e6 * r.residual_rad.x()) + "," + Csv(1e6 * r.residual_rad.y()) + "," +
             Csv(r.normalized) + "," + Csv(r.point_to_ray_mm) + "," +
             (r.beam_dropped ? "beam_dropped" : r.outlier ? "flagged" : "used") + "\n";
    }
  }
  return out;
}

GridHeatmap PointToRayHeatmap(const SourceCalibrationResult& source) {
  const SourceCalibration& c = source.calibration;
  const SourceCalibrationQuality& q = *c.quality;
  const int n = c.pattern.beams_per_side();
  GridHeatmap h;
  h.beams_per_side = n;
  h.values.assign(static_cast<size_t>(n) * static_cast<size_t>(n), std::numeric_limits<double>::quiet_NaN());
  for (const BeamCalibrationQuality& b : source.beams) h.values[b.beam_id - 1] = b.mean_point_to_ray_mm;
  h.title = "Source " + c.name + ": mean point-to-ray distance per beam";
  h.value_label = "mean point-to-ray distance [mm]";
  h.subtitle = std::to_string(q.slices) + " slices, " + std::to_string(q.samples_used) +
               " samples used, " + std::to_string(q.samples_flagged) + " flagged; RMS " +
               Fixed(q.rms_residual_urad, 1) + " urad, mean " + Fixed(q.mean_point_to_ray_mm, 4) +
               " mm, max " + Fixed(q.max_point_to_ray_mm, 4) + " mm";
  return h;
}

}  // namespace opl
