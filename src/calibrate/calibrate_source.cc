// CalibrateSource (opl/calibrate/calibrate_source.h): the options' checks and
// the run of one source's calibration (Calibrator::Run): initial estimate,
// solve, the rounds that flag outliers and drop thin beams, the covariance.
#include "opl/calibrate/calibrate_source.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "calibrate/calibrate_source_internal.h"
#include "opl/core/format.h"

namespace opl {

Status CalibrateOptions::Validate() const {
  auto bad = [](const std::string& field, double v, const std::string& rule) {
    return Status::InvalidArgument("calibrate option " + field + " = " + FormatNumber(v) +
                                   ": " + rule);
  };
  if (!(std::isfinite(loss_scale) && loss_scale > 0.0)) return bad("loss_scale", loss_scale, "must be finite and > 0");
  if (!(std::isfinite(loss_scale_unweighted_rad) && loss_scale_unweighted_rad > 0.0)) {
    return bad("loss_scale_unweighted_rad", loss_scale_unweighted_rad, "must be finite and > 0");
  }
  if (max_robust_rounds < 1) return bad("max_robust_rounds", max_robust_rounds, "must be >= 1");
  if (!(std::isfinite(outlier_threshold) && outlier_threshold > 0.0)) {
    return bad("outlier_threshold", outlier_threshold, "must be finite and > 0");
  }
  if (!(std::isfinite(min_unweighted_sigma_rad) && min_unweighted_sigma_rad > 0.0)) {
    return bad("min_unweighted_sigma_rad", min_unweighted_sigma_rad, "must be finite and > 0");
  }
  if (max_flagging_rounds < 1) return bad("max_flagging_rounds", max_flagging_rounds, "must be >= 1");
  if (min_samples_per_beam < 2) return bad("min_samples_per_beam", min_samples_per_beam, "must be >= 2");
  if (!(std::isfinite(init_inlier_distance_mm) && init_inlier_distance_mm > 0.0)) {
    return bad("init_inlier_distance_mm", init_inlier_distance_mm, "must be finite and > 0");
  }
  if (max_iterations < 1) return bad("max_iterations", max_iterations, "must be >= 1");
  if (!(std::isfinite(parameter_tolerance) && parameter_tolerance > 0.0)) {
    return bad("parameter_tolerance", parameter_tolerance, "must be finite and > 0");
  }
  if (!(std::isfinite(function_tolerance) && function_tolerance > 0.0)) {
    return bad("function_tolerance", function_tolerance, "must be finite and > 0");
  }
  return Status::Ok();
}

namespace calibrate_internal {
namespace {

double RobustWeight(RobustLoss loss, double s2, double a) {
  switch (loss) {
    case RobustLoss::kNone:
      return 1.0;
    case RobustLoss::kHuber:
      return s2 <= a * a ? 1.0 : a / std::sqrt(s2);
    case RobustLoss::kCauchy:
      return 1.0 / (1.0 + s2 / (a * a));
  }
  return 1.0;
}

}  // namespace

Result<SourceCalibrationResult> Calibrator::Run() {
  OPL_RETURN_IF_ERROR(options_.Validate());
  OPL_RETURN_IF_ERROR(CheckInput());
  OPL_RETURN_IF_ERROR(Initialise());
  int usable = static_cast<int>(ActiveBeams().size());
  auto too_few = [&](int count) {
    return Error(StatusCode::kNoSolution,
                 "only " + std::to_string(count) + " beam(s) have " +
                     std::to_string(options_.min_samples_per_beam) +
                     " or more usable samples: a calibration needs at least three");
  };
  if (usable < 3) return too_few(usable);
  bool has_row_beam = false;
  for (BeamState* b : ActiveBeams()) has_row_beam |= b->layout == Layout::kCentralRowBeam;
  if (!has_row_beam) {
    return Error(StatusCode::kNoSolution,
                 "no beam of the central row besides the central beam has usable samples: the "
                 "roll gauge (central row mean elevation 0) cannot be fixed");
  }

  // Robust phase: IRLS with the chosen loss, starting from the line-fit inliers.
  OPL_RETURN_IF_ERROR(UpdateWhitening());
  OPL_RETURN_IF_ERROR(Solve());
  // The robust phase only when the first solve used a sample beyond the
  // flagging threshold (samples the line fits already left out do not count:
  // they did not pull the solution; a clean session goes straight to flagging).
  EvaluateResiduals();
  bool suspicious = false;
  {
    const double limit = options_.outlier_threshold * SigmaForFlagging();
    for (size_t i = 0; i < samples_.size(); ++i) {
      suspicious |= weight_[i] > 0.0 && normalized_[i] > limit;
    }
  }
  if (options_.loss != RobustLoss::kNone && suspicious) {
    const double a = weighted_ ? options_.loss_scale : options_.loss_scale_unweighted_rad;
    for (int round = 0; round < options_.max_robust_rounds; ++round) {
      OPL_RETURN_IF_ERROR(UpdateWhitening());
      EvaluateResiduals();
      double change = 0.0;
      for (size_t i = 0; i < samples_.size(); ++i) {
        if (in_dropped_beam_[i]) continue;
        const double w = RobustWeight(options_.loss, normalized_[i] * normalized_[i], a);
        change = std::max(change, std::abs(w - weight_[i]));
        weight_[i] = w;
      }
      OPL_RETURN_IF_ERROR(Solve());
      if (change < 1e-2) break;
    }
  }
  // Flagging phase: plain least squares over the samples within the threshold.
  for (int round = 0; round < options_.max_flagging_rounds; ++round) {
    OPL_RETURN_IF_ERROR(UpdateWhitening());
    EvaluateResiduals();
    const double limit = options_.outlier_threshold * SigmaForFlagging();
    bool changed = false;
    for (size_t i = 0; i < samples_.size(); ++i) {
      if (in_dropped_beam_[i]) continue;
      const char flag = normalized_[i] > limit;
      changed |= flag != flagged_[i] || weight_[i] != (flag ? 0.0 : 1.0);
      flagged_[i] = flag;
      weight_[i] = flag ? 0.0 : 1.0;
    }
    const size_t dropped_before = dropped_beam_ids_.size();
    OPL_RETURN_IF_ERROR(DropThinBeams());
    changed |= dropped_beam_ids_.size() != dropped_before;
    usable = static_cast<int>(ActiveBeams().size());
    if (usable < 3) return too_few(usable);
    if (!changed) break;
    OPL_RETURN_IF_ERROR(Solve());
  }
  OPL_RETURN_IF_ERROR(UpdateWhitening());
  EvaluateResiduals();
  SourceCalibrationResult result;
  OPL_RETURN_IF_ERROR(Covariance(&result));
  FillResult(&result);
  return result;
}

}  // namespace calibrate_internal

Result<SourceCalibrationResult> CalibrateSource(const std::string& name, int beams_per_side,
                                                const std::vector<CalibrationSample>& samples,
                                                const CalibrateOptions& options) {
  calibrate_internal::Calibrator calibrator(name, beams_per_side, samples, options);
  return calibrator.Run();
}

}  // namespace opl
