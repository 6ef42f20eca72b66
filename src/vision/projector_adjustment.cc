// ProjectorAdjust: validation, the Ceres problem and the solve. The
// covariances are in projector_adjustment_covariance.cc.
#include "opl/vision/projector_adjustment.h"

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <tuple>

#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <ceres/rotation.h>
#include <Eigen/Dense>

#include "opl/core/format.h"
#include "opl/geometry/rotation.h"
#include "opl/vision/projector_spot_cost_function.h"
#include "opl/vision/scene_frame.h"
#include "vision/projector_adjustment_internal.h"

namespace opl {
namespace {

using projector_internal::Problem;

std::string SpotPrefix(size_t k) { return "projector adjustment: spots[" + std::to_string(k) + "]"; }

bool SymmetricPositiveDefinite(const Eigen::Matrix2d& S) {
  return S.allFinite() && std::abs(S(0, 1) - S(1, 0)) <= 1e-12 * S.cwiseAbs().maxCoeff() &&
         S(0, 0) > 0.0 && S.determinant() > 0.0;
}

Status ValidateData(const ProjectorAdjustmentData& data, const ProjectorAdjustmentOptions& options) {
  const BundleData& b = data.bundle;
  OPL_RETURN_IF_ERROR(data.calibration.Validate());
  if (b.cameras.empty()) return Status::InvalidArgument("projector adjustment: bundle.cameras is empty");
  if (data.placements.empty()) {
    return Status::InvalidArgument("projector adjustment: placements is empty");
  }
  if (data.spots.empty()) return Status::InvalidArgument("projector adjustment: spots is empty");
  for (size_t k = 0; k < b.intrinsics.size(); ++k) {
    const std::string where = "projector adjustment: bundle.intrinsics[" + std::to_string(k) + "]";
    if (!b.intrinsics[k].constant) {
      return Status::InvalidArgument(where + ".constant is false: the intrinsics are held "
                                             "(calibrated cameras)");
    }
    const Status s = b.intrinsics[k].intrinsics.Validate();
    if (!s.ok()) return Status::InvalidArgument(where + ": " + s.message());
  }
  for (size_t i = 0; i < b.cameras.size(); ++i) {
    const BundleCamera& c = b.cameras[i];
    const std::string where = "projector adjustment: bundle.cameras[" + std::to_string(i) + "]";
    if (c.intrinsics_index < 0 || c.intrinsics_index >= static_cast<int>(b.intrinsics.size())) {
      return Status::InvalidArgument(where + ".intrinsics_index " +
                                     std::to_string(c.intrinsics_index) + " is not in [0, " +
                                     std::to_string(b.intrinsics.size()) + ")");
    }
    if (c.pose_constant) {
      return Status::InvalidArgument(where + ".pose_constant: the datum fixes the gauge");
    }
    if (!c.cam_from_scene.rotation.coeffs().allFinite() || !c.cam_from_scene.translation.allFinite()) {
      return Status::InvalidArgument(where + ".cam_from_scene is not finite");
    }
  }
  for (size_t j = 0; j < b.points.size(); ++j) {
    if (b.points[j].constant) {
      return Status::InvalidArgument("projector adjustment: bundle.points[" + std::to_string(j) +
                                     "].constant: the datum fixes the gauge");
    }
    if (!b.points[j].point_in_scene.allFinite()) {
      return Status::InvalidArgument("projector adjustment: bundle.points[" + std::to_string(j) +
                                     "] is not finite");
    }
  }
  for (size_t o = 0; o < b.observations.size(); ++o) {
    const BundleObservation& ob = b.observations[o];
    const std::string where = "projector adjustment: bundle.observations[" + std::to_string(o) + "]";
    if (ob.camera < 0 || ob.camera >= static_cast<int>(b.cameras.size())) {
      return Status::InvalidArgument(where + ".camera " + std::to_string(ob.camera) +
                                     " is not a camera index");
    }
    if (ob.point < 0 || ob.point >= static_cast<int>(b.points.size())) {
      return Status::InvalidArgument(where + ".point " + std::to_string(ob.point) +
                                     " is not a point index");
    }
    if (!ob.pixel_px.allFinite() || !SymmetricPositiveDefinite(ob.covariance_px2)) {
      return Status::InvalidArgument(where + ": pixel not finite or covariance_px2 not symmetric "
                                             "positive definite");
    }
  }
  for (size_t m = 0; m < data.placements.size(); ++m) {
    const Rigid3d& p = data.placements[m].scene_from_module;
    if (!p.rotation.coeffs().allFinite() || !p.translation.allFinite()) {
      return Status::InvalidArgument("projector adjustment: placements[" + std::to_string(m) +
                                     "].scene_from_module is not finite");
    }
  }
  std::map<std::tuple<int, std::string, int>, size_t> first_of_beam;
  for (size_t k = 0; k < data.spots.size(); ++k) {
    const ProjectorSpot& s = data.spots[k];
    const auto [earlier, inserted] = first_of_beam.insert({{s.placement, s.source, s.beam_id}, k});
    if (!inserted) {
      return Status::InvalidArgument(SpotPrefix(k) + ": source '" + s.source + "' beam " +
                                     std::to_string(s.beam_id) + " at placement " +
                                     std::to_string(s.placement) + " again (spots[" +
                                     std::to_string(earlier->second) + "] has it)");
    }
    if (s.placement < 0 || s.placement >= static_cast<int>(data.placements.size())) {
      return Status::InvalidArgument(SpotPrefix(k) + ".placement " + std::to_string(s.placement) +
                                     " is not a placement index");
    }
    const SourceCalibration* source = data.calibration.FindSource(s.source);
    if (source == nullptr) {
      return Status::InvalidArgument(SpotPrefix(k) + ".source '" + s.source +
                                     "' is not a calibrated source");
    }
    if (source->pattern.Find(s.beam_id) == nullptr) {
      return Status::InvalidArgument(SpotPrefix(k) + ".beam_id " + std::to_string(s.beam_id) +
                                     " is not a beam of source '" + s.source + "'");
    }
    if (!(std::isfinite(s.depth_mm) && s.depth_mm > 0.0)) {
      return Status::InvalidArgument(SpotPrefix(k) + ".depth_mm = " + FormatNumber(s.depth_mm) +
                                     ": must be finite and > 0");
    }
    if (s.observations.empty()) {
      return Status::InvalidArgument(SpotPrefix(k) + ".observations is empty");
    }
    for (size_t o = 0; o < s.observations.size(); ++o) {
      const ProjectorSpotObservation& ob = s.observations[o];
      const std::string where = SpotPrefix(k) + ".observations[" + std::to_string(o) + "]";
      if (ob.camera < 0 || ob.camera >= static_cast<int>(b.cameras.size())) {
        return Status::InvalidArgument(where + ".camera " + std::to_string(ob.camera) +
                                       " is not a camera index");
      }
      if (!ob.pixel_px.allFinite() || !SymmetricPositiveDefinite(ob.covariance_px2)) {
        return Status::InvalidArgument(where + ": pixel not finite or covariance_px2 not "
                                               "symmetric positive definite");
      }
    }
  }
  for (size_t a = 0; a < 3; ++a) {
    for (int j : options.datum_point_sets[a]) {
      if (j < 0 || j >= static_cast<int>(b.points.size())) {
        return Status::InvalidArgument("ProjectorAdjustmentOptions.datum_point_sets[" +
                                       std::to_string(a) + "] names point " + std::to_string(j) +
                                       ", not a bundle point index");
      }
    }
  }
  for (size_t l = 0; l < options.length_point_sets.size(); ++l) {
    for (size_t e = 0; e < 2; ++e) {
      const std::string field = "ProjectorAdjustmentOptions.length_point_sets[" + std::to_string(l) +
                                "][" + std::to_string(e) + "]";
      if (options.length_point_sets[l][e].empty()) return Status::InvalidArgument(field + " is empty");
      for (int j : options.length_point_sets[l][e]) {
        if (j < 0 || j >= static_cast<int>(b.points.size())) {
          return Status::InvalidArgument(field + " names point " + std::to_string(j) +
                                         ", not a bundle point index");
        }
      }
    }
  }
  return Status::Ok();
}

// Source rotation prior: W Log(R_s R_cal^T) (left perturbation).
struct SourceRotationPrior {
  SourceRotationPrior(const Eigen::Quaterniond& q_cal, const Eigen::Matrix3d& whitening)
      : q_cal_inverse(q_cal.conjugate()), W(whitening) {}
  template <typename T>
  bool operator()(const T* q_source, T* residual) const {
    const Eigen::Quaternion<T> q_rel =
        Eigen::Map<const Eigen::Quaternion<T>>(q_source) * q_cal_inverse.cast<T>();
    const T wxyz[4] = {q_rel.w(), q_rel.x(), q_rel.y(), q_rel.z()};
    T aa[3];
    ceres::QuaternionToAngleAxis(wxyz, aa);
    for (int r = 0; r < 3; ++r) {
      residual[r] = T(W(r, 0)) * aa[0] + T(W(r, 1)) * aa[1] + T(W(r, 2)) * aa[2];
    }
    return true;
  }
  Eigen::Quaterniond q_cal_inverse;
  Eigen::Matrix3d W;
};

struct BeamPrior {
  BeamPrior(const Eigen::Vector2d& azel_cal, const Eigen::Matrix2d& whitening)
      : azel(azel_cal), W(whitening) {}
  template <typename T>
  bool operator()(const T* beam, T* residual) const {
    const T da = beam[0] - T(azel(0));
    const T de = beam[1] - T(azel(1));
    residual[0] = T(W(0, 0)) * da + T(W(0, 1)) * de;
    residual[1] = T(W(1, 0)) * da + T(W(1, 1)) * de;
    return true;
  }
  Eigen::Vector2d azel;
  Eigen::Matrix2d W;
};

struct SeparationPrior {
  SeparationPrior(double origin_distance, double length_mm, double u_length_mm)
      : d(origin_distance), L(length_mm), u(u_length_mm) {}
  template <typename T>
  bool operator()(const T* lambda, T* residual) const {
    residual[0] = (lambda[0] * T(d) - T(L)) / T(u);
    return true;
  }
  double d, L, u;
};

// Whitening L^-1 of a symmetric positive definite matrix; false otherwise.
template <int N>
bool WhiteningOf(const Eigen::Matrix<double, N, N>& C, Eigen::Matrix<double, N, N>* W) {
  if (!C.allFinite()) return false;
  Eigen::LLT<Eigen::Matrix<double, N, N>> llt(0.5 * (C + C.transpose()));
  if (llt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, N, N> L = llt.matrixL();
  if (!(L.diagonal().minCoeff() > 0.0)) return false;
  *W = L.inverse();
  return true;
}

}  // namespace

Eigen::Vector3d ProjectorAdjustmentData::ModuleOriginInCalibration() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  if (calibration.sources.empty()) return c;
  for (const SourceCalibration& s : calibration.sources) c += s.calibration_from_source.translation;
  return c / static_cast<double>(calibration.sources.size());
}

Status ProjectorAdjustmentOptions::Validate() const {
  if (max_iterations < 0) {
    return Status::InvalidArgument("ProjectorAdjustmentOptions.max_iterations = " +
                                   std::to_string(max_iterations) + ": must be >= 0");
  }
  const std::pair<const char*, double> tolerances[] = {{"function_tolerance", function_tolerance},
                                                       {"gradient_tolerance", gradient_tolerance},
                                                       {"parameter_tolerance", parameter_tolerance}};
  for (const auto& [name, value] : tolerances) {
    if (!(value >= 0.0 && value < 1.0)) {
      return Status::InvalidArgument(std::string("ProjectorAdjustmentOptions.") + name + " = " +
                                     FormatNumber(value) + ": must be in [0, 1)");
    }
  }
  if (num_threads < 1) {
    return Status::InvalidArgument("ProjectorAdjustmentOptions.num_threads = " +
                                   std::to_string(num_threads) + ": must be >= 1");
  }
  for (size_t a = 0; a < 3; ++a) {
    if (datum_point_sets[a].empty()) {
      return Status::InvalidArgument("ProjectorAdjustmentOptions.datum_point_sets[" +
                                     std::to_string(a) + "] is empty: the datum needs three points");
    }
  }
  if (!(std::isfinite(unscaled_datum_length) && unscaled_datum_length >= 0.0)) {
    return Status::InvalidArgument("ProjectorAdjustmentOptions.unscaled_datum_length = " +
                                   FormatNumber(unscaled_datum_length) +
                                   ": must be finite and >= 0");
  }
  return Status::Ok();
}

std::string ProjectorAdjustmentResult::Report() const {
  std::string s = "projector adjustment: " + std::to_string(bundle.cameras.size()) + " cameras, " +
                  std::to_string(bundle.points.size()) + " tag points, " +
                  std::to_string(spot_in_scene.size()) + " spots, " +
                  std::to_string(scene_from_module.size()) + " placement(s)\n";
  s += "  solver " + linear_solver + ", " + std::to_string(iterations) + " iterations: " +
       termination + "\n";
  s += "  cost " + FormatNumber(initial_cost, 6) + " -> " + FormatNumber(final_cost, 6) +
       ", variance factor " + FormatPrintf("%.4f", variance_factor) + "; RMS tags " +
       FormatPrintf("%.4f", rms_tag_px) + " px, spots " + FormatPrintf("%.4f", rms_spot_px) + " px\n";
  s += "  calibration adjusted under its prior: " + std::to_string(free_beams) + " beams, " +
       std::to_string(free_source_rotations) + " source rotations, module length " +
       (free_module_length ? "free" : "held") + " (lambda " + FormatNumber(module_length_factor, 9) +
       " +- " + FormatNumber(u_module_length_factor, 3) + ")\n";
  if (scale_factor > 0.0) {
    s += "  datum length " + FormatNumber(datum_length_mm, 9) + " +- " +
         FormatNumber(u_datum_length_mm, 3) + " mm; s = " + FormatNumber(scale_factor, 9) +
         " +- " + FormatNumber(u_scale_factor, 3) + "\n";
  }
  s += "  covariances: " + (covariance_method.empty() ? std::string("not computed") : covariance_method) +
       "\n";
  return s;
}

Result<ProjectorAdjustmentResult> ProjectorAdjust(const ProjectorAdjustmentData& data,
                                                  const ProjectorAdjustmentOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(ValidateData(data, options));
  Problem pb(data);

  // Start: every observation in front of its camera.
  for (size_t o = 0; o < data.bundle.observations.size(); ++o) {
    if (!pb.TagResidual(o, nullptr)) {
      return Status::NoSolution("projector adjustment: bundle.observations[" + std::to_string(o) +
                                "]: point behind its camera at the start");
    }
  }
  for (size_t k = 0; k < data.spots.size(); ++k) {
    for (size_t o = 0; o < data.spots[k].observations.size(); ++o) {
      if (!pb.SpotResidual(k, o, nullptr)) {
        return Status::NoSolution(SpotPrefix(k) + ".observations[" + std::to_string(o) +
                                  "]: spot behind its camera at the start");
      }
    }
  }

  ceres::Problem problem;
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (size_t i = 0; i < pb.cam_q.size(); ++i) {
    problem.AddParameterBlock(pb.cam_q[i].data(), 4, new ceres::EigenQuaternionManifold);
    problem.AddParameterBlock(pb.cam_t[i].data(), 3);
    ordering->AddElementToGroup(pb.cam_q[i].data(), 1);
    ordering->AddElementToGroup(pb.cam_t[i].data(), 1);
  }
  for (size_t k = 0; k < pb.intrinsics.size(); ++k) {
    problem.AddParameterBlock(pb.intrinsics[k].data(), kNumCameraParameters);
    problem.SetParameterBlockConstant(pb.intrinsics[k].data());
    ordering->AddElementToGroup(pb.intrinsics[k].data(), 1);
  }
  for (auto& x : pb.points) {
    problem.AddParameterBlock(x.data(), 3);
    ordering->AddElementToGroup(x.data(), 0);
  }
  for (size_t m = 0; m < pb.module_q.size(); ++m) {
    problem.AddParameterBlock(pb.module_q[m].data(), 4, new ceres::EigenQuaternionManifold);
    problem.AddParameterBlock(pb.module_t[m].data(), 3);
    ordering->AddElementToGroup(pb.module_q[m].data(), 1);
    ordering->AddElementToGroup(pb.module_t[m].data(), 1);
  }
  problem.AddParameterBlock(&pb.lambda, 1);
  ordering->AddElementToGroup(&pb.lambda, 1);
  for (size_t s = 0; s < pb.source_q.size(); ++s) {
    problem.AddParameterBlock(pb.source_q[s].data(), 4, new ceres::EigenQuaternionManifold);
    ordering->AddElementToGroup(pb.source_q[s].data(), 1);
  }
  for (auto& [key, beam] : pb.beams) {
    problem.AddParameterBlock(beam.azel.data(), 2);
    ordering->AddElementToGroup(beam.azel.data(), 1);
  }
  for (auto& d : pb.depths) {
    problem.AddParameterBlock(&d, 1);
    ordering->AddElementToGroup(&d, 0);
  }

  // Tag corners.
  for (size_t o = 0; o < data.bundle.observations.size(); ++o) {
    const BundleObservation& ob = data.bundle.observations[o];
    const size_t i = static_cast<size_t>(ob.camera);
    const size_t k = static_cast<size_t>(data.bundle.cameras[i].intrinsics_index);
    auto* cost = new ceres::AutoDiffCostFunction<ReprojectionCostFunctor, 2, 4, 3,
                                                 kNumCameraParameters, 3>(
        new ReprojectionCostFunctor(ob.pixel_px,
                                    ReprojectionCostFunctor::WhiteningOf(ob.covariance_px2)));
    problem.AddResidualBlock(cost, nullptr, pb.cam_q[i].data(), pb.cam_t[i].data(),
                             pb.intrinsics[k].data(), pb.points[static_cast<size_t>(ob.point)].data());
  }
  // Spots.
  for (size_t k = 0; k < data.spots.size(); ++k) {
    const ProjectorSpot& spot = data.spots[k];
    const size_t s = pb.SourceIndex(spot.source);
    double* beam = pb.beams.at({s, spot.beam_id}).azel.data();
    const size_t m = static_cast<size_t>(spot.placement);
    for (const ProjectorSpotObservation& ob : spot.observations) {
      const size_t i = static_cast<size_t>(ob.camera);
      auto* cost = new ProjectorSpotCostFunction(
          pb.CameraIntrinsicsOf(i), ob.pixel_px, ReprojectionCostFunctor::WhiteningOf(ob.covariance_px2),
          pb.origin_in_module[s]);
      problem.AddResidualBlock(cost, nullptr,
                               {pb.cam_q[i].data(), pb.cam_t[i].data(), pb.module_q[m].data(),
                                pb.module_t[m].data(), &pb.lambda, pb.source_q[s].data(), beam,
                                &pb.depths[k]});
    }
  }

  // The calibration as a prior, or held.
  ProjectorAdjustmentResult result;
  int prior_residuals = 0;
  for (auto& [key, beam] : pb.beams) {
    const Beam* b = data.calibration.sources[key.first].pattern.Find(key.second);
    Eigen::Matrix2d W;
    if (options.adjust_beams && b->cov_azel_rad2 && WhiteningOf<2>(*b->cov_azel_rad2, &W)) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<BeamPrior, 2, 2>(new BeamPrior(beam.azel_cal, W)), nullptr,
          beam.azel.data());
      prior_residuals += 2;
      beam.free = true;
      ++result.free_beams;
    } else {
      problem.SetParameterBlockConstant(beam.azel.data());
    }
  }
  for (size_t s = 0; s < pb.source_q.size(); ++s) {
    const SourceCalibration& src = data.calibration.sources[s];
    Eigen::Matrix3d W;
    bool free = false;
    if (options.adjust_source_rotations && src.quality && pb.source_used[s]) {
      const Eigen::Matrix3d R = src.calibration_from_source.RotationMatrix();
      const Eigen::Matrix3d J = XyzAnglesJacobianWrtLeftPerturbation(XyzAnglesRadFromRotation(R));
      const Eigen::Matrix3d Jinv = J.inverse();
      const Eigen::Matrix3d C = Jinv * src.quality->rotation_xyz_cov_rad2 * Jinv.transpose();
      free = J.allFinite() && Jinv.allFinite() && WhiteningOf<3>(C, &W);
    }
    if (free) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SourceRotationPrior, 3, 4>(
                                   new SourceRotationPrior(src.calibration_from_source.rotation, W)),
                               nullptr, pb.source_q[s].data());
      prior_residuals += 3;
      pb.source_free[s] = true;
      ++result.free_source_rotations;
    } else {
      problem.SetParameterBlockConstant(pb.source_q[s].data());
    }
  }
  if (options.adjust_module_length) {
    for (const Separation& sep : data.calibration.separations) {
      const size_t a = pb.SourceIndex(sep.from), b = pb.SourceIndex(sep.to);
      if (!(sep.u_length_mm > 0.0) || !pb.source_used[a] || !pb.source_used[b]) continue;
      const double d = (pb.origin_in_module[a] - pb.origin_in_module[b]).norm();
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SeparationPrior, 1, 1>(
                                   new SeparationPrior(d, sep.length_mm, sep.u_length_mm)),
                               nullptr, &pb.lambda);
      prior_residuals += 1;
      pb.lambda_free = true;
    }
  }
  if (!pb.lambda_free) problem.SetParameterBlockConstant(&pb.lambda);
  result.free_module_length = pb.lambda_free;

  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  so.logging_type = ceres::SILENT;
  so.linear_solver_ordering = ordering;
  if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    so.linear_solver_type = ceres::SPARSE_SCHUR;
    so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
    result.linear_solver = "SPARSE_SCHUR (SUITE_SPARSE), depths and tag points eliminated";
  } else {
    so.linear_solver_type = ceres::DENSE_SCHUR;
    result.linear_solver = "DENSE_SCHUR, depths and tag points eliminated";
  }
  std::string why;
  if (!so.IsValid(&why)) return Status::InvalidArgument("projector adjustment: Ceres options: " + why);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (!summary.IsSolutionUsable()) {
    return Status::NoSolution("projector adjustment: solver failed: " + summary.message);
  }
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.termination = std::string(ceres::TerminationTypeToString(summary.termination_type)) +
                       ": " + summary.message;

  // Residual statistics.
  double tag_sq = 0.0, spot_sq = 0.0, chi2 = 2.0 * summary.final_cost;
  size_t tag_n = 0, spot_n = 0;
  for (size_t o = 0; o < data.bundle.observations.size(); ++o) {
    Eigen::Vector2d r;
    if (!pb.TagResidual(o, &r)) {
      return Status::NoSolution("projector adjustment: bundle.observations[" + std::to_string(o) +
                                "] ended behind its camera");
    }
    tag_sq += r.squaredNorm();
    ++tag_n;
  }
  for (size_t k = 0; k < data.spots.size(); ++k) {
    for (size_t o = 0; o < data.spots[k].observations.size(); ++o) {
      Eigen::Vector2d r;
      if (!pb.SpotResidual(k, o, &r)) {
        return Status::NoSolution(SpotPrefix(k) + ".observations[" + std::to_string(o) +
                                  "]: spot ended behind its camera");
      }
      spot_sq += r.squaredNorm();
      ++spot_n;
    }
  }
  result.rms_tag_px = tag_n ? std::sqrt(tag_sq / (2.0 * static_cast<double>(tag_n))) : 0.0;
  result.rms_spot_px = spot_n ? std::sqrt(spot_sq / (2.0 * static_cast<double>(spot_n))) : 0.0;
  const int free_params = pb.NumFreeParameters();
  const double redundancy =
      2.0 * static_cast<double>(tag_n + spot_n) + prior_residuals - free_params + 6.0;
  result.variance_factor = redundancy > 0.0 ? chi2 / redundancy : 0.0;
  result.module_length_factor = pb.lambda;

  // Covariances (in the solve's frame), then everything to the datum frame.
  projector_internal::Covariances cov;
  if (options.compute_covariances) {
    cov = projector_internal::ComputeCovariances(&problem, pb, options);
    result.covariance_method = cov.method;
  }
  OPL_RETURN_IF_ERROR(projector_internal::MoveToDatum(pb, options, cov, &result));
  if (options.compute_covariances && options.scale_by_variance_factor && result.variance_factor > 1.0 &&
      !result.point_covariances_mm2.empty()) {
    const double f = result.variance_factor;
    const double sf = std::sqrt(f);
    for (auto* list : {&result.point_covariances_mm2, &result.camera_center_covariances_mm2,
                       &result.module_origin_covariances_mm2}) {
      for (Eigen::Matrix3d& c : *list) c *= f;
    }
    result.u_scale_factor *= sf;
    result.u_datum_length_mm *= sf;
    result.u_module_length_factor *= sf;
    for (double& u : result.u_lengths_mm) u *= sf;
    result.covariance_method += "; scaled by the variance factor " + FormatNumber(f, 3);
  }
  return result;
}

}  // namespace opl
