// CalibrateSource's result: the covariance of the pose and the beam
// directions at the solution (Calibrator::Covariance) and the
// SourceCalibrationResult filled from the estimate (Calibrator::FillResult).
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <ceres/ceres.h>

#include "calibrate/calibrate_source_internal.h"
#include "opl/calibrate/level_row_manifold.h"
#include "opl/geometry/spherical.h"

namespace opl {
namespace calibrate_internal {

Status Calibrator::Covariance(SourceCalibrationResult* result) {
  // Rebuild the final problem (weights 1/0) and take its tangent-space
  // Jacobian at the solution.
  ceres::Problem::Options po;
  ceres::Problem problem(po);
  problem.AddParameterBlock(theta_, 3);
  problem.AddParameterBlock(t_, 3);
  const int m = RowSize();
  std::vector<double*> blocks = {theta_, t_};
  if (m >= 1) {
    problem.AddParameterBlock(row_.data(), 2 * m, new LevelRowManifold(m));
    blocks.push_back(row_.data());
  }
  const int nf = 6 + (m >= 1 ? 2 * m - 1 : 0);
  std::vector<BeamState*> active = ActiveBeams();
  std::vector<double> beam_params(2 * active.size());
  int column = nf;
  for (size_t k = 0; k < active.size(); ++k) {
    BeamState& b = *active[k];
    std::vector<BeamRayCostFunction::Sample> s;
    for (int i : b.samples) s.push_back({samples_[i].point_mm, whitening_[i], weight_[i]});
    double* p = &beam_params[2 * k];
    p[0] = b.az;
    p[1] = b.el;
    if (b.layout == Layout::kFreeBeam) {
      problem.AddResidualBlock(new BeamRayCostFunction(std::move(s), R0_, b.layout), nullptr,
                               theta_, t_, p);
      problem.AddParameterBlock(p, 2);
      blocks.push_back(p);
      b.param_offset = column;
      column += 2;
    } else if (b.layout == Layout::kCentralRowBeam) {
      problem.AddResidualBlock(
          new BeamRayCostFunction(std::move(s), R0_, b.layout, m, b.row_index), nullptr, theta_,
          t_, row_.data());
      b.param_offset = -1;  // in the row block (an f-block)
    } else {
      problem.AddResidualBlock(new BeamRayCostFunction(std::move(s), R0_, b.layout), nullptr,
                               theta_, t_);
      b.param_offset = -1;
    }
  }
  const int np = column;
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  eo.num_threads = 1;
  double cost = 0.0;
  std::vector<double> residuals;
  ceres::CRSMatrix crs;
  if (!problem.Evaluate(eo, &cost, &residuals, nullptr, &crs) || crs.num_cols != np) {
    return Error(StatusCode::kNoSolution, "could not evaluate the Jacobian at the solution");
  }
  Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor>> J(
      crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()), crs.rows.data(),
      crs.cols.data(), crs.values.data());
  const Eigen::MatrixXd N = Eigen::MatrixXd(Eigen::SparseMatrix<double>(J.transpose() * J));

  // chi^2 / dof.
  int used = 0;
  for (size_t i = 0; i < samples_.size(); ++i) used += weight_[i] > 0.0;
  const int dof = 2 * used - np;
  const double chi2 = 2.0 * cost;
  if (dof > 0) {
    result->variance_factor = chi2 / dof;
  } else if (!weighted_) {
    return Error(StatusCode::kNoSolution,
                 "too few samples (" + std::to_string(used) + ") for " + std::to_string(np) +
                     " unknowns: no redundancy to estimate the noise without sample sigmas");
  }

  // Schur complement on the beam parameters: only the pose/row block and each
  // beam's own block (and its cross terms with the pose) are needed.
  Eigen::MatrixXd S = N.topLeftCorner(nf, nf);
  struct BeamBlock {
    BeamState* beam;
    int offset, size;
    Eigen::MatrixXd Nbb_inv, Nfb;
  };
  std::vector<BeamBlock> bb;
  for (BeamState* b : active) {
    if (b->param_offset < 0) continue;
    const int size = 2;
    BeamBlock blk{b, b->param_offset, size, {}, {}};
    const Eigen::MatrixXd Nbb = N.block(blk.offset, blk.offset, size, size);
    Eigen::LLT<Eigen::MatrixXd> llt(Nbb);
    if (llt.info() != Eigen::Success) {
      return Error(StatusCode::kNoSolution,
                   "beam " + std::to_string(b->id) + ": its direction is undetermined");
    }
    blk.Nbb_inv = llt.solve(Eigen::MatrixXd::Identity(size, size));
    blk.Nfb = N.block(0, blk.offset, nf, size);
    S -= blk.Nfb * blk.Nbb_inv * blk.Nfb.transpose();
    bb.push_back(std::move(blk));
  }
  // The pose and row parameters mix radians and millimetres: the test of
  // singularity is made on S scaled to a unit diagonal, which does not change
  // with the unit of the samples (a session in micrometres, issue 19 item 4).
  Eigen::VectorXd equilibrate(nf);
  for (int i = 0; i < nf; ++i) {
    equilibrate(i) = S(i, i) > 0.0 && std::isfinite(S(i, i)) ? 1.0 / std::sqrt(S(i, i)) : 0.0;
  }
  const Eigen::MatrixXd Ss = equilibrate.asDiagonal() * S * equilibrate.asDiagonal();
  Eigen::LDLT<Eigen::MatrixXd> ldlt(Ss);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Ss);
  if (!(equilibrate.minCoeff() > 0.0) || ldlt.info() != Eigen::Success ||
      !(eig.eigenvalues()(0) > 1e-12 * eig.eigenvalues()(nf - 1))) {
    return Error(StatusCode::kNoSolution,
                 "the pose is undetermined by these samples (singular normal equations): are the "
                 "slices at distinct depths?");
  }
  const double scale = (!weighted_ && dof > 0) ? result->variance_factor : 1.0;
  result->covariance_scaled = !weighted_;
  const Eigen::MatrixXd Cff = scale * (equilibrate.asDiagonal() *
                                       ldlt.solve(Eigen::MatrixXd::Identity(nf, nf)) *
                                       equilibrate.asDiagonal());
  result->pose_covariance = Cff.topLeftCorner(6, 6);

  std::map<int, Eigen::Matrix2d> beam_cov;
  for (const BeamBlock& blk : bb) {
    // C_bb = s Nbb^-1 + Nbb^-1 Nbf Cff Nfb Nbb^-1.
    const Eigen::MatrixXd K = blk.Nfb * blk.Nbb_inv;  // nf x 2
    const Eigen::Matrix2d C = scale * blk.Nbb_inv + K.transpose() * Cff * K;
    beam_cov[blk.beam->id] = 0.5 * (C + C.transpose());
  }
  // The central row, from the tangent covariance of its block:
  // (az, el) = row0 + P delta, P = d Plus / d delta.
  if (m >= 1) {
    const Eigen::MatrixXd P = LevelRowManifold(m).PlusJacobianAt(row_.data());
    const Eigen::MatrixXd Crow = P * Cff.block(6, 6, 2 * m - 1, 2 * m - 1) * P.transpose();
    for (BeamState* b : active) {
      if (b->layout != Layout::kCentralRowBeam) continue;
      const int j = b->row_index;
      Eigen::Matrix2d C;
      C << Crow(j, j), Crow(j, m + j), Crow(m + j, j), Crow(m + j, m + j);
      beam_cov[b->id] = 0.5 * (C + C.transpose());
    }
  }
  for (BeamState* b : active) {
    if (!beam_cov.count(b->id)) beam_cov[b->id] = Eigen::Matrix2d::Zero();
  }
  // Fill the pattern.
  std::vector<Beam> beams;
  for (BeamState* b : active) {
    Beam beam;
    beam.id = b->id;
    beam.az_rad = b->az;
    beam.el_rad = b->el;
    beam.cov_azel_rad2 = beam_cov[b->id];
    beams.push_back(beam);
  }
  Result<BeamPattern> pattern = BeamPattern::Create(n_, std::move(beams));
  if (!pattern.ok()) return Error(StatusCode::kNoSolution, pattern.status().message());
  result->calibration.pattern = std::move(*pattern);
  return Status::Ok();
}

void Calibrator::FillResult(SourceCalibrationResult* result) const {
  const Eigen::Matrix3d R = Rotation();
  const Eigen::Vector3d t = Origin();
  result->calibration.name = name_;
  result->calibration.calibration_from_source = Rigid3d(R, t);
  result->weighted = weighted_;
  result->num_slices = num_slices_;
  result->solver_iterations = iterations_;
  result->dropped_beam_ids = dropped_beam_ids_;
  result->residuals.resize(samples_.size());
  SourceCalibrationQuality quality;
  quality.slices = num_slices_;
  quality.beams_dropped = static_cast<int>(dropped_beam_ids_.size());
  double sum_dist = 0.0, sum_r2 = 0.0;
  for (const BeamState& b : beams_) {
    const Eigen::Vector3d d = R * DirectionFromAzElRad(b.az, b.el);
    BeamCalibrationQuality bq;
    bq.beam_id = b.id;
    double beam_r2 = 0.0;
    for (int i : b.samples) {
      CalibrationSampleResidual& r = result->residuals[i];
      r.beam_id = b.id;
      r.slice = samples_[i].slice;
      r.residual_rad = raw_residual_[i];
      r.normalized = normalized_[i];
      const Eigen::Vector3d v = samples_[i].point_mm - t;
      r.point_to_ray_mm = (v - v.dot(d) * d).norm();
      r.outlier = flagged_[i] != 0;
      r.beam_dropped = in_dropped_beam_[i] != 0;
      if (r.beam_dropped) continue;
      if (r.outlier) {
        ++bq.samples_flagged;
        ++quality.samples_flagged;
        continue;
      }
      ++bq.samples_used;
      bq.mean_point_to_ray_mm += r.point_to_ray_mm;
      bq.max_point_to_ray_mm = std::max(bq.max_point_to_ray_mm, r.point_to_ray_mm);
      beam_r2 += r.residual_rad.squaredNorm();
      sum_dist += r.point_to_ray_mm;
      quality.max_point_to_ray_mm = std::max(quality.max_point_to_ray_mm, r.point_to_ray_mm);
    }
    if (!b.active) continue;
    quality.samples_used += bq.samples_used;
    sum_r2 += beam_r2;
    bq.mean_point_to_ray_mm /= bq.samples_used;
    bq.rms_residual_rad = std::sqrt(beam_r2 / (2.0 * bq.samples_used));
    result->beams.push_back(bq);
  }
  quality.mean_point_to_ray_mm = quality.samples_used > 0 ? sum_dist / quality.samples_used : 0.0;
  quality.rms_residual_urad =
      quality.samples_used > 0 ? 1e6 * std::sqrt(sum_r2 / (2.0 * quality.samples_used)) : 0.0;
  quality.variance_factor = result->variance_factor;
  quality.origin_cov_mm2 = result->pose_covariance.bottomRightCorner<3, 3>();
  const Eigen::Vector3d angles = XyzAnglesRadFromRotation(R);
  const Eigen::Matrix3d Ja = XyzAnglesJacobianWrtLeftPerturbation(angles);
  quality.rotation_xyz_cov_rad2 = Ja * result->pose_covariance.topLeftCorner<3, 3>() * Ja.transpose();
  result->calibration.quality = quality;
}

}  // namespace calibrate_internal
}  // namespace opl
