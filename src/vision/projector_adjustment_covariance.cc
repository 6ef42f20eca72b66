// ProjectorAdjust's parameter storage, its first-order covariances and the
// move of the solution to the datum frame (projector_adjustment.h).
#include <cmath>

#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <Eigen/Dense>
#include <Eigen/Sparse>

#include "opl/vision/projector_spot_cost_function.h"
#include "opl/vision/scene_frame.h"
#include "vision/projector_adjustment_internal.h"

namespace opl {
namespace projector_internal {
namespace {

std::array<double, 4> Packed(const Eigen::Quaterniond& q_in) {
  const Eigen::Quaterniond q = q_in.normalized();
  return {q.x(), q.y(), q.z(), q.w()};
}
std::array<double, 3> Packed(const Eigen::Vector3d& t) { return {t.x(), t.y(), t.z()}; }
Eigen::Quaterniond Quat(const std::array<double, 4>& q) { return Eigen::Quaterniond(q[3], q[0], q[1], q[2]); }
Eigen::Vector3d Vec(const std::array<double, 3>& t) { return Eigen::Vector3d(t[0], t[1], t[2]); }

using Jet12 = ceres::Jet<double, 12>;

}  // namespace

Problem::Problem(const ProjectorAdjustmentData& d) : data(d) {
  for (const BundleCamera& c : d.bundle.cameras) {
    cam_q.push_back(Packed(c.cam_from_scene.rotation));
    cam_t.push_back(Packed(c.cam_from_scene.translation));
  }
  for (const BundleIntrinsics& k : d.bundle.intrinsics) intrinsics.push_back(k.intrinsics.Packed());
  for (const BundlePoint& x : d.bundle.points) points.push_back(Packed(x.point_in_scene));
  for (const ProjectorPlacement& m : d.placements) {
    module_q.push_back(Packed(m.scene_from_module.rotation));
    module_t.push_back(Packed(m.scene_from_module.translation));
  }
  const Eigen::Vector3d centre = d.ModuleOriginInCalibration();
  for (const SourceCalibration& s : d.calibration.sources) {
    source_q.push_back(Packed(s.calibration_from_source.rotation));
    origin_in_module.push_back(s.calibration_from_source.translation - centre);
  }
  source_used.assign(source_q.size(), 0);
  source_free.assign(source_q.size(), 0);
  for (const ProjectorSpot& spot : d.spots) {
    const size_t s = SourceIndex(spot.source);
    source_used[s] = 1;
    BeamBlock& b = beams[{s, spot.beam_id}];
    const Beam* beam = d.calibration.sources[s].pattern.Find(spot.beam_id);
    b.azel = {beam->az_rad, beam->el_rad};
    b.azel_cal = Eigen::Vector2d(beam->az_rad, beam->el_rad);
    depths.push_back(spot.depth_mm);
  }
}

size_t Problem::SourceIndex(const std::string& name) const {
  for (size_t s = 0; s < data.calibration.sources.size(); ++s) {
    if (data.calibration.sources[s].name == name) return s;
  }
  return 0;
}

CameraIntrinsics Problem::CameraIntrinsicsOf(size_t camera) const {
  return data.bundle.intrinsics[static_cast<size_t>(data.bundle.cameras[camera].intrinsics_index)]
      .intrinsics;
}

bool Problem::TagResidual(size_t o, Eigen::Vector2d* r) const {
  const BundleObservation& ob = data.bundle.observations[o];
  const size_t i = static_cast<size_t>(ob.camera);
  const ReprojectionCostFunctor f(ob.pixel_px, Eigen::Matrix2d::Identity());
  Eigen::Vector2d local;
  return f(cam_q[i].data(), cam_t[i].data(),
           intrinsics[static_cast<size_t>(data.bundle.cameras[i].intrinsics_index)].data(),
           points[static_cast<size_t>(ob.point)].data(), r ? r->data() : local.data());
}

bool Problem::SpotResidual(size_t k, size_t o, Eigen::Vector2d* r) const {
  const ProjectorSpot& spot = data.spots[k];
  const ProjectorSpotObservation& ob = spot.observations[o];
  const size_t s = SourceIndex(spot.source);
  const size_t i = static_cast<size_t>(ob.camera);
  const size_t m = static_cast<size_t>(spot.placement);
  const ProjectorSpotCostFunction f(CameraIntrinsicsOf(i), ob.pixel_px, Eigen::Matrix2d::Identity(),
                                    origin_in_module[s]);
  const double* params[] = {cam_q[i].data(), cam_t[i].data(), module_q[m].data(),
                            module_t[m].data(), &lambda, source_q[s].data(),
                            beams.at({s, spot.beam_id}).azel.data(), &depths[k]};
  Eigen::Vector2d local;
  return f.Evaluate(params, r ? r->data() : local.data(), nullptr);
}

Eigen::Vector3d Problem::SpotInScene(size_t k) const {
  const ProjectorSpot& spot = data.spots[k];
  const size_t s = SourceIndex(spot.source);
  const size_t m = static_cast<size_t>(spot.placement);
  const auto& azel = beams.at({s, spot.beam_id}).azel;
  const Eigen::Vector3d d(std::cos(azel[1]) * std::cos(azel[0]),
                          std::cos(azel[1]) * std::sin(azel[0]), std::sin(azel[1]));
  const Eigen::Vector3d p_module = Quat(source_q[s]) * (depths[k] * d) + lambda * origin_in_module[s];
  return Quat(module_q[m]) * p_module + Vec(module_t[m]);
}

int Problem::NumFreeParameters() const {
  int n = 6 * static_cast<int>(cam_q.size()) + 3 * static_cast<int>(points.size()) +
          6 * static_cast<int>(module_q.size()) + static_cast<int>(depths.size()) +
          (lambda_free ? 1 : 0);
  for (char f : source_free) n += f ? 3 : 0;
  for (const auto& [key, b] : beams) n += b.free ? 2 : 0;
  return n;
}

Covariances ComputeCovariances(ceres::Problem* problem, Problem& pb,
                               const ProjectorAdjustmentOptions& options) {
  Covariances cov;
  std::vector<double*> blocks;
  int nc = 0;
  for (size_t i = 0; i < pb.cam_q.size(); ++i) {
    blocks.push_back(pb.cam_q[i].data());
    blocks.push_back(pb.cam_t[i].data());
    cov.cam_col.push_back(nc);
    nc += 6;
  }
  for (auto& x : pb.points) {
    blocks.push_back(x.data());
    cov.point_col.push_back(nc);
    nc += 3;
  }
  for (size_t m = 0; m < pb.module_q.size(); ++m) {
    blocks.push_back(pb.module_q[m].data());
    blocks.push_back(pb.module_t[m].data());
    cov.module_col.push_back(nc);
    nc += 6;
  }
  if (pb.lambda_free) {
    blocks.push_back(&pb.lambda);
    cov.lambda_col = nc;
    nc += 1;
  }
  for (size_t s = 0; s < pb.source_q.size(); ++s) {
    if (!pb.source_free[s]) continue;
    blocks.push_back(pb.source_q[s].data());
    nc += 3;
  }
  for (auto& [key, b] : pb.beams) {
    if (!b.free) continue;
    blocks.push_back(b.azel.data());
    nc += 2;
  }
  const int nd = static_cast<int>(pb.depths.size());
  for (double& d : pb.depths) blocks.push_back(&d);

  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  eo.num_threads = options.num_threads;
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(eo, nullptr, nullptr, nullptr, &crs) || crs.num_cols != nc + nd) {
    cov.method = "unavailable: the Jacobian could not be evaluated";
    return cov;
  }
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(crs.values.size());
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int q = crs.rows[static_cast<size_t>(r)]; q < crs.rows[static_cast<size_t>(r) + 1]; ++q) {
      trip.emplace_back(r, crs.cols[static_cast<size_t>(q)], crs.values[static_cast<size_t>(q)]);
    }
  }
  Eigen::SparseMatrix<double> J(crs.num_rows, crs.num_cols);
  J.setFromTriplets(trip.begin(), trip.end());
  const Eigen::SparseMatrix<double> Jc = J.leftCols(nc);
  const Eigen::SparseMatrix<double> Jd = J.rightCols(nd);
  // D is diagonal: no residual holds two depths.
  Eigen::VectorXd D = Eigen::VectorXd::Zero(nd);
  for (int k = 0; k < Jd.outerSize(); ++k) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(Jd, k); it; ++it) D(k) += it.value() * it.value();
  }
  if (nd > 0 && !(D.minCoeff() > 0.0)) {
    cov.method = "unavailable: a spot's depth is not determined";
    return cov;
  }
  const Eigen::SparseMatrix<double> B = Eigen::SparseMatrix<double>(Jc.transpose()) * Jd;  // nc x nd
  Eigen::MatrixXd S = Eigen::MatrixXd(Eigen::SparseMatrix<double>(Jc.transpose()) * Jc);
  const Eigen::SparseMatrix<double> BDinv = B * D.cwiseInverse().asDiagonal();
  S -= Eigen::MatrixXd(BDinv * Eigen::SparseMatrix<double>(B.transpose()));
  S = 0.5 * (S + S.transpose());
  // Scaled to unit diagonal first (rotations in rad and points in mm differ
  // by many orders): the gauge's null space is then told from small but
  // real eigenvalues. G = P (P S P)^+ P, P = diag(S)^-1/2, is a generalised
  // inverse of S (S G S = S), and every gauge-free quantity's covariance is
  // the same with any generalised inverse (header).
  Eigen::VectorXd P = S.diagonal();
  if (!(P.minCoeff() > 0.0)) {
    cov.method = "unavailable: a parameter is not observed (zero diagonal)";
    return cov;
  }
  P = P.cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd Ss = P.asDiagonal() * S * P.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Ss);
  const Eigen::VectorXd& ev = es.eigenvalues();
  const double top = ev(nc - 1);
  int near_zero = 0;
  for (int e = 0; e < nc; ++e) near_zero += ev(e) <= 1e-9 * top ? 1 : 0;
  if (!(top > 0.0) || near_zero != 6) {
    cov.method = "unavailable: the reduced matrix has " + std::to_string(near_zero) +
                 " near-zero eigenvalue(s), 6 expected (the rigid gauge): weak or degenerate "
                 "geometry";
    return cov;
  }
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(nc);
  for (int e = 6; e < nc; ++e) inv(e) = 1.0 / ev(e);
  cov.Sg = P.asDiagonal() * (es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose()) *
           P.asDiagonal();
  cov.ok = true;
  cov.method =
      "first order, depths eliminated (Schur complement), pseudo-inverse over the 6-dof rigid "
      "gauge, propagated to the three-point datum";
  return cov;
}

Status MoveToDatum(const Problem& pb, const ProjectorAdjustmentOptions& options,
                   const Covariances& cov, ProjectorAdjustmentResult* result) {
  const ProjectorAdjustmentData& data = pb.data;
  std::array<Eigen::Vector3d, 3> abc;
  for (size_t a = 0; a < 3; ++a) {
    abc[a].setZero();
    for (int j : options.datum_point_sets[a]) abc[a] += Vec(pb.points[static_cast<size_t>(j)]);
    abc[a] /= static_cast<double>(options.datum_point_sets[a].size());
  }
  const Result<Rigid3d> frame = SceneFromThreePoints(abc[0], abc[1], abc[2]);
  if (!frame.ok()) return Status::NoSolution("projector adjustment: datum: " + frame.status().message());
  result->datum_from_solve = *frame;
  result->bundle = data.bundle;
  for (size_t i = 0; i < pb.cam_q.size(); ++i) {
    result->bundle.cameras[i].cam_from_scene =
        Rigid3d(Quat(pb.cam_q[i]), Vec(pb.cam_t[i])) * frame->Inverse();
  }
  for (size_t j = 0; j < pb.points.size(); ++j) {
    result->bundle.points[j].point_in_scene = *frame * Vec(pb.points[j]);
  }
  for (size_t m = 0; m < pb.module_q.size(); ++m) {
    result->scene_from_module.push_back(*frame * Rigid3d(Quat(pb.module_q[m]), Vec(pb.module_t[m])));
  }
  for (size_t k = 0; k < pb.depths.size(); ++k) {
    result->spot_in_scene.push_back(*frame * pb.SpotInScene(k));
    result->spot_depth_mm.push_back(pb.depths[k]);
  }
  result->datum_length_mm = (abc[1] - abc[0]).norm();
  // The requested lengths: rigid invariants, the same in the solve's frame.
  auto set_mean = [&](const std::vector<int>& set) {
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (int j : set) m += Vec(pb.points[static_cast<size_t>(j)]);
    return Eigen::Vector3d(m / static_cast<double>(set.size()));
  };
  for (const auto& ends : options.length_point_sets) {
    result->lengths_mm.push_back((set_mean(ends[1]) - set_mean(ends[0])).norm());
    result->u_lengths_mm.push_back(0.0);
  }
  if (options.unscaled_datum_length > 0.0) {
    result->scale_factor = result->datum_length_mm / options.unscaled_datum_length;
  }
  if (!cov.ok) return Status::Ok();

  // d(datum coordinates of X) / d(A, B, C, X), 3 x 12, by Jets.
  auto datum_jacobian = [&](const Eigen::Vector3d& x) {
    Jet12 v[12];
    for (int q = 0; q < 3; ++q) {
      v[q] = Jet12(abc[0](q), q);
      v[3 + q] = Jet12(abc[1](q), 3 + q);
      v[6 + q] = Jet12(abc[2](q), 6 + q);
      v[9 + q] = Jet12(x(q), 9 + q);
    }
    Jet12 R[9];
    ThreePointFrame(v, v + 3, v + 6, R);
    Eigen::Matrix<double, 3, 12> F;
    for (int r = 0; r < 3; ++r) {
      Jet12 y(0.0);
      for (int c = 0; c < 3; ++c) y += R[3 * r + c] * (v[9 + c] - v[c]);
      F.row(r) = y.v.transpose();
    }
    return F;
  };
  const Eigen::Index nc = cov.Sg.rows();
  // d(A, B, C) / d(columns), 9 x nc.
  Eigen::MatrixXd dABC = Eigen::MatrixXd::Zero(9, nc);
  for (size_t a = 0; a < 3; ++a) {
    const double w = 1.0 / static_cast<double>(options.datum_point_sets[a].size());
    for (int j : options.datum_point_sets[a]) {
      dABC.block(static_cast<Eigen::Index>(3 * a), cov.point_col[static_cast<size_t>(j)], 3, 3) +=
          w * Eigen::Matrix3d::Identity();
    }
  }
  // Covariance in the datum frame of a point x with d x / d(columns) = dX.
  auto datum_covariance = [&](const Eigen::Vector3d& x, const Eigen::MatrixXd& dX) {
    const Eigen::Matrix<double, 3, 12> F = datum_jacobian(x);
    const Eigen::MatrixXd G = F.leftCols<9>() * dABC + F.rightCols<3>() * dX;
    Eigen::Matrix3d C = G * cov.Sg * G.transpose();
    return Eigen::Matrix3d(0.5 * (C + C.transpose()));
  };
  for (size_t j = 0; j < pb.points.size(); ++j) {
    Eigen::MatrixXd dX = Eigen::MatrixXd::Zero(3, nc);
    dX.block(0, cov.point_col[j], 3, 3).setIdentity();
    result->point_covariances_mm2.push_back(datum_covariance(Vec(pb.points[j]), dX));
  }
  const ceres::EigenQuaternionManifold manifold;
  for (size_t i = 0; i < pb.cam_q.size(); ++i) {
    // c = -R^T t = -(conj(q) t); tangent of q by the manifold's PlusJacobian.
    const Eigen::Quaterniond q = Quat(pb.cam_q[i]);
    const Eigen::Vector3d t = Vec(pb.cam_t[i]);
    Eigen::Matrix<double, 3, 4> dc_dq = -RotatedVectorJacobianWrtQuaternion(q.conjugate(), t);
    dc_dq.leftCols<3>() *= -1.0;  // d conj(q) / dq = diag(-1, -1, -1, 1)
    Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus;
    manifold.PlusJacobian(pb.cam_q[i].data(), plus.data());
    Eigen::MatrixXd dX = Eigen::MatrixXd::Zero(3, nc);
    dX.block(0, cov.cam_col[i], 3, 3) = dc_dq * plus;
    dX.block(0, cov.cam_col[i] + 3, 3, 3) = -q.conjugate().toRotationMatrix();
    result->camera_center_covariances_mm2.push_back(datum_covariance(-(q.conjugate() * t), dX));
  }
  for (size_t m = 0; m < pb.module_q.size(); ++m) {
    Eigen::MatrixXd dX = Eigen::MatrixXd::Zero(3, nc);
    dX.block(0, cov.module_col[m] + 3, 3, 3).setIdentity();
    result->module_origin_covariances_mm2.push_back(datum_covariance(Vec(pb.module_t[m]), dX));
  }
  const Eigen::Vector3d e = (abc[1] - abc[0]) / result->datum_length_mm;
  const Eigen::RowVectorXd g =
      e.transpose() * (dABC.middleRows(3, 3) - dABC.topRows(3));
  result->u_datum_length_mm = std::sqrt(std::max(0.0, (g * cov.Sg * g.transpose())(0, 0)));
  if (options.unscaled_datum_length > 0.0) {
    result->u_scale_factor = result->u_datum_length_mm / options.unscaled_datum_length;
  }
  for (size_t l = 0; l < options.length_point_sets.size(); ++l) {
    const auto& ends = options.length_point_sets[l];
    const Eigen::Vector3d d = set_mean(ends[1]) - set_mean(ends[0]);
    if (!(d.norm() > 0.0)) continue;
    const Eigen::Vector3d along = d / d.norm();
    Eigen::RowVectorXd gl = Eigen::RowVectorXd::Zero(nc);
    for (size_t end = 0; end < 2; ++end) {
      const double w = (end == 0 ? -1.0 : 1.0) / static_cast<double>(ends[end].size());
      for (int j : ends[end]) {
        gl.segment(cov.point_col[static_cast<size_t>(j)], 3) += w * along.transpose();
      }
    }
    result->u_lengths_mm[l] = std::sqrt(std::max(0.0, (gl * cov.Sg * gl.transpose())(0, 0)));
  }
  if (cov.lambda_col >= 0) {
    result->u_module_length_factor = std::sqrt(std::max(0.0, cov.Sg(cov.lambda_col, cov.lambda_col)));
  }
  return Status::Ok();
}

}  // namespace projector_internal
}  // namespace opl
