#include "opl/core/message_text.h"
#include "opl/calibrate/shared_errors.h"

#include <array>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/parallel_for.h"
#include "opl/geometry/rotation.h"

namespace opl {
namespace {

// What a re-solve gives, as differences from the base: per source the pose
// (dtheta, dt) and the beams' (az, el), in the base's beam order; per
// separation its length.
struct Solution {
  std::vector<Eigen::Matrix<double, 6, 1>> poses;
  std::vector<std::vector<Eigen::Vector2d>> beams;  // per source, per beam (az, el)
  std::vector<double> separations;
};

Result<Solution> Difference(const ModuleCalibrationResult& base, const ModuleCalibrationResult& r) {
  const auto mismatch = [](const std::string& what) {
    return Status::NoSolution("the re-solve calibrated " + what + " than the base solve");
  };
  if (r.sources.size() != base.sources.size()) return mismatch("another number of sources");
  if (r.calibration.separations.size() != base.calibration.separations.size()) {
    return mismatch("other separations");
  }
  Solution s;
  for (size_t i = 0; i < base.sources.size(); ++i) {
    const SourceCalibration& b = base.sources[i].calibration;
    const SourceCalibration& c = r.sources[i].calibration;
    if (b.name != c.name) return mismatch("source '" + c.name + "' rather than '" + b.name + "'");
    const std::vector<Beam>& bb = b.pattern.beams();
    const std::vector<Beam>& cb = c.pattern.beams();
    if (bb.size() != cb.size() || b.pattern.beams_per_side() != c.pattern.beams_per_side()) {
      return mismatch("other beams of source '" + b.name + "'");
    }
    Eigen::Matrix<double, 6, 1> pose;
    pose.head<3>() = LogSO3(c.calibration_from_source.RotationMatrix() *
                            b.calibration_from_source.RotationMatrix().transpose());
    pose.tail<3>() = c.calibration_from_source.translation - b.calibration_from_source.translation;
    s.poses.push_back(pose);
    std::vector<Eigen::Vector2d> beams;
    for (size_t k = 0; k < bb.size(); ++k) {
      if (bb[k].id != cb[k].id) return mismatch("other beams of source '" + b.name + "'");
      beams.emplace_back(cb[k].az_rad - bb[k].az_rad, cb[k].el_rad - bb[k].el_rad);
    }
    s.beams.push_back(std::move(beams));
  }
  for (size_t l = 0; l < base.calibration.separations.size(); ++l) {
    s.separations.push_back(r.calibration.separations[l].length_mm -
                            base.calibration.separations[l].length_mm);
  }
  return s;
}

}  // namespace

Result<SharedErrorSummary> AddSharedErrors(const std::vector<Spot>& spots,
                                           const std::vector<int>& slices,
                                           const std::optional<CalibrationScaling>& scaling,
                                           const CalibrateModuleOptions& options,
                                           const std::vector<Eigen::MatrixXd>& shared_factors,
                                           ModuleCalibrationResult* result, int num_threads) {
  if (shared_factors.size() != spots.size() || slices.size() != spots.size()) {
    return Status::InvalidArgument("shared errors: " + std::to_string(shared_factors.size()) +
                                   " factors and " + std::to_string(slices.size()) +
                                   " slices for " + std::to_string(spots.size()) + " spots");
  }
  SharedErrorSummary summary;
  const ModuleCalibration& calibration = result->calibration;
  for (const Separation& sep : calibration.separations) {
    summary.u_separation_own_mm.push_back(sep.u_length_mm);
    summary.u_separation_shared_mm.push_back(0.0);
  }
  if (spots.empty()) return summary;
  const Eigen::Index m = shared_factors.front().cols();
  for (size_t i = 0; i < spots.size(); ++i) {
    const Eigen::MatrixXd& K = shared_factors[i];
    if (K.rows() != 3 || K.cols() != m || !K.allFinite()) {
      return Status::InvalidArgument(spots[i].where + ": shared factor is " +
                                     std::to_string(K.rows()) + " x " + std::to_string(K.cols()) +
                                     (K.allFinite() ? "" : " and not finite") + ", expected 3 x " +
                                     std::to_string(m));
    }
  }
  summary.components = static_cast<int>(m);
  if (m == 0) return summary;

  // The samples the base solve used: source by source, its spots in input
  // order are its samples (CalibrateModule), each with its residual.
  std::map<std::string, size_t> source_index;
  for (size_t s = 0; s < result->sources.size(); ++s) {
    source_index[result->sources[s].calibration.name] = s;
  }
  std::map<std::string, size_t> next_sample;
  std::vector<size_t> used;
  for (size_t i = 0; i < spots.size(); ++i) {
    const auto s = source_index.find(spots[i].source);
    if (s == source_index.end()) {
      return Status::InvalidArgument(spots[i].where + ": source " + QuoteForMessage(spots[i].source) +
                                     " is not in the calibration");
    }
    const std::vector<CalibrationSampleResidual>& residuals = result->sources[s->second].residuals;
    const size_t k = next_sample[spots[i].source]++;
    if (k >= residuals.size()) {
      return Status::InvalidArgument("shared errors: the spots are not those the calibration "
                                     "was solved from (source " + QuoteForMessage(spots[i].source) + ")");
    }
    if (!residuals[k].outlier && !residuals[k].beam_dropped) used.push_back(i);
  }
  // Plain least squares on those samples, in the base's grid size.
  CalibrateModuleOptions resolve = options;
  resolve.source.loss = RobustLoss::kNone;
  resolve.source.outlier_threshold = 1e100;
  bool one_size = true;
  for (const SourceCalibration& s : calibration.sources) {
    one_size &= s.pattern.beams_per_side() == calibration.sources.front().pattern.beams_per_side();
  }
  if (one_size && !calibration.sources.empty()) {
    resolve.beams_per_side = calibration.sources.front().pattern.beams_per_side();
  }
  std::vector<Spot> base(used.size());
  std::vector<int> base_slices(used.size());
  for (size_t j = 0; j < used.size(); ++j) {
    base[j] = spots[used[j]];
    base_slices[j] = slices[used[j]];
  }

  // g_k for every component; the 2m re-solves are independent, so they are
  // shared out over the threads (a component's pair on one thread) and
  // summed in component order.
  std::vector<std::array<Solution, 2>> sides(static_cast<size_t>(m));
  std::vector<Status> failures(static_cast<size_t>(m), Status::Ok());
  internal::ParallelFor(static_cast<int>(m), num_threads, [&](int k) {
    std::vector<Spot> moved = base;
    for (int sign = 0; sign < 2; ++sign) {
      const double f = sign == 0 ? 1.0 : -1.0;
      for (size_t j = 0; j < used.size(); ++j) {
        moved[j].observation.point_in_scene =
            base[j].observation.point_in_scene + f * shared_factors[used[j]].col(k);
      }
      const std::string which = "shared errors, component " + std::to_string(k + 1) + " of " +
                                std::to_string(m) + ": ";
      Result<ModuleCalibrationResult> r = CalibrateModule(moved, base_slices, scaling, resolve);
      Result<Solution> d = r.ok() ? Difference(*result, *r) : Result<Solution>(r.status());
      if (!d.ok()) {
        failures[static_cast<size_t>(k)] = Status(d.status().code(), which + d.status().message());
        return;
      }
      sides[static_cast<size_t>(k)][static_cast<size_t>(sign)] = std::move(*d);
    }
  });
  for (const Status& failure : failures) {
    if (!failure.ok()) return failure;
  }
  const size_t num_sources = result->sources.size();
  std::vector<Eigen::Matrix<double, 6, 6>> pose_add(num_sources,
                                                    Eigen::Matrix<double, 6, 6>::Zero());
  std::vector<std::vector<Eigen::Matrix2d>> beam_add(num_sources);  // per beam (az, el)
  for (size_t s = 0; s < num_sources; ++s) {
    beam_add[s].assign(calibration.sources[s].pattern.beams().size(), Eigen::Matrix2d::Zero());
  }
  std::vector<double> separation_add(calibration.separations.size(), 0.0);
  for (const std::array<Solution, 2>& side : sides) {
    for (size_t s = 0; s < num_sources; ++s) {
      const Eigen::Matrix<double, 6, 1> g = 0.5 * (side[0].poses[s] - side[1].poses[s]);
      pose_add[s] += g * g.transpose();
      for (size_t b = 0; b < beam_add[s].size(); ++b) {
        const Eigen::Vector2d gb = 0.5 * (side[0].beams[s][b] - side[1].beams[s][b]);
        beam_add[s][b] += gb * gb.transpose();
      }
    }
    for (size_t l = 0; l < separation_add.size(); ++l) {
      const double g = 0.5 * (side[0].separations[l] - side[1].separations[l]);
      separation_add[l] += g * g;
    }
  }

  // Apply (to a copy: `result` changes only on success): poses and their
  // quality figures, beams, separations.
  ModuleCalibrationResult updated = *result;
  for (size_t s = 0; s < num_sources; ++s) {
    SourceCalibrationResult& source = updated.sources[s];
    source.pose_covariance += pose_add[s];
    std::vector<Beam> beams = source.calibration.pattern.beams();
    for (size_t b = 0; b < beams.size(); ++b) {
      beams[b].cov_azel_rad2 =
          beams[b].cov_azel_rad2.value_or(Eigen::Matrix2d::Zero()) + beam_add[s][b];
    }
    Result<BeamPattern> pattern =
        BeamPattern::Create(source.calibration.pattern.beams_per_side(), std::move(beams));
    if (!pattern.ok()) {
      return Status(pattern.status().code(), "shared errors: " + pattern.status().message());
    }
    source.calibration.pattern = std::move(*pattern);
    if (source.calibration.quality) {
      SourceCalibrationQuality& q = *source.calibration.quality;
      q.origin_cov_mm2 = source.pose_covariance.bottomRightCorner<3, 3>();
      const Eigen::Vector3d angles =
          XyzAnglesRadFromRotation(source.calibration.calibration_from_source.RotationMatrix());
      const Eigen::Matrix3d Ja = XyzAnglesJacobianWrtLeftPerturbation(angles);
      q.rotation_xyz_cov_rad2 = Ja * source.pose_covariance.topLeftCorner<3, 3>() * Ja.transpose();
    }
    updated.calibration.sources[s] = source.calibration;
  }
  for (size_t l = 0; l < separation_add.size(); ++l) {
    Separation& sep = updated.calibration.separations[l];
    summary.u_separation_shared_mm[l] = std::sqrt(separation_add[l]);
    sep.u_length_mm = std::sqrt(sep.u_length_mm * sep.u_length_mm + separation_add[l]);
  }
  *result = std::move(updated);
  return summary;
}

}  // namespace opl
