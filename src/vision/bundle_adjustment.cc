#include "opl/vision/bundle_adjustment.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <set>
#include <string>

#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <Eigen/Dense>
#include <Eigen/Sparse>

#include "opl/core/format.h"
#include "opl/vision/scene_frame.h"

namespace opl {
namespace {

using Jet12 = ceres::Jet<double, 12>;

std::string ObservationPrefix(size_t o) { return "bundle adjustment: observation " + std::to_string(o); }

Status ValidateData(const BundleData& data, const BundleOptions& options) {
  if (data.cameras.empty()) return Status::InvalidArgument("bundle adjustment: no cameras");
  if (data.points.empty()) return Status::InvalidArgument("bundle adjustment: no points");
  for (size_t k = 0; k < data.intrinsics.size(); ++k) {
    const Status s = data.intrinsics[k].intrinsics.Validate();
    if (!s.ok()) {
      return Status::InvalidArgument("bundle adjustment: intrinsics " + std::to_string(k) + " ('" +
                                     data.intrinsics[k].name + "'): " + s.message());
    }
  }
  for (size_t i = 0; i < data.cameras.size(); ++i) {
    const BundleCamera& c = data.cameras[i];
    const std::string where =
        "bundle adjustment: camera " + std::to_string(i) + " ('" + c.name + "')";
    if (c.intrinsics_index < 0 ||
        c.intrinsics_index >= static_cast<int>(data.intrinsics.size())) {
      return Status::InvalidArgument(where + ": intrinsics_index " +
                                     std::to_string(c.intrinsics_index) + " is not in [0, " +
                                     std::to_string(data.intrinsics.size()) + ")");
    }
    if (!c.cam_from_scene.rotation.coeffs().allFinite() ||
        !c.cam_from_scene.translation.allFinite() ||
        !(std::abs(c.cam_from_scene.rotation.norm() - 1.0) < 1e-6)) {
      return Status::InvalidArgument(where + ": pose is not finite or not a unit quaternion");
    }
    if (options.gauge == BundleGauge::kThreePointDatum && c.pose_constant) {
      return Status::InvalidArgument(where +
                                     ": pose_constant with gauge kThreePointDatum (the datum "
                                     "fixes the gauge; constant blocks would fix it twice)");
    }
  }
  for (size_t j = 0; j < data.points.size(); ++j) {
    if (!data.points[j].point_in_scene.allFinite()) {
      return Status::InvalidArgument("bundle adjustment: point " + std::to_string(j) +
                                     " is not finite");
    }
    if (options.gauge == BundleGauge::kThreePointDatum && data.points[j].constant) {
      return Status::InvalidArgument("bundle adjustment: point " + std::to_string(j) +
                                     ": constant with gauge kThreePointDatum");
    }
  }
  std::vector<std::set<int>> cameras_of_point(data.points.size());
  for (size_t o = 0; o < data.observations.size(); ++o) {
    const BundleObservation& ob = data.observations[o];
    if (ob.camera < 0 || ob.camera >= static_cast<int>(data.cameras.size())) {
      return Status::InvalidArgument(ObservationPrefix(o) + ": camera index " +
                                     std::to_string(ob.camera) + " is not in [0, " +
                                     std::to_string(data.cameras.size()) + ")");
    }
    if (ob.point < 0 || ob.point >= static_cast<int>(data.points.size())) {
      return Status::InvalidArgument(ObservationPrefix(o) + ": point index " +
                                     std::to_string(ob.point) + " is not in [0, " +
                                     std::to_string(data.points.size()) + ")");
    }
    if (!ob.pixel_px.allFinite()) {
      return Status::InvalidArgument(ObservationPrefix(o) + ": pixel is not finite");
    }
    const Eigen::Matrix2d& S = ob.covariance_px2;
    if (!S.allFinite() || std::abs(S(0, 1) - S(1, 0)) > 1e-12 * S.cwiseAbs().maxCoeff() ||
        !(S(0, 0) > 0.0) || !(S.determinant() > 0.0)) {
      return Status::InvalidArgument(ObservationPrefix(o) +
                                     ": covariance_px2 is not symmetric positive definite");
    }
    cameras_of_point[static_cast<size_t>(ob.point)].insert(ob.camera);
  }
  for (size_t j = 0; j < data.points.size(); ++j) {
    if (!data.points[j].constant && cameras_of_point[j].size() < 2) {
      return Status::InvalidArgument("bundle adjustment: point " + std::to_string(j) +
                                     " is free but seen by " +
                                     std::to_string(cameras_of_point[j].size()) +
                                     " camera(s); at least 2 are needed");
    }
  }
  if (options.gauge == BundleGauge::kThreePointDatum) {
    const auto& d = options.datum_points;
    for (int k = 0; k < 3; ++k) {
      if (d[static_cast<size_t>(k)] >= static_cast<int>(data.points.size())) {
        return Status::InvalidArgument("BundleOptions.datum_points[" + std::to_string(k) +
                                       "] = " + std::to_string(d[static_cast<size_t>(k)]) +
                                       ": not a point index (" +
                                       std::to_string(data.points.size()) + " points)");
      }
    }
  }
  return Status::Ok();
}

// Parameter storage for the solve.
struct Parameters {
  std::vector<std::array<double, 4>> quaternions;  // x, y, z, w
  std::vector<std::array<double, 3>> translations;
  std::vector<std::array<double, kNumCameraParameters>> intrinsics;
  std::vector<std::array<double, 3>> points;
};

Parameters Pack(const BundleData& data) {
  Parameters p;
  for (const BundleCamera& c : data.cameras) {
    const Eigen::Quaterniond q = c.cam_from_scene.rotation.normalized();
    p.quaternions.push_back({q.x(), q.y(), q.z(), q.w()});
    p.translations.push_back(
        {c.cam_from_scene.translation.x(), c.cam_from_scene.translation.y(),
         c.cam_from_scene.translation.z()});
  }
  for (const BundleIntrinsics& k : data.intrinsics) p.intrinsics.push_back(k.intrinsics.Packed());
  for (const BundlePoint& x : data.points) {
    p.points.push_back({x.point_in_scene.x(), x.point_in_scene.y(), x.point_in_scene.z()});
  }
  return p;
}

void Unpack(const Parameters& p, BundleData* data) {
  for (size_t i = 0; i < data->cameras.size(); ++i) {
    const auto& q = p.quaternions[i];
    const auto& t = p.translations[i];
    data->cameras[i].cam_from_scene =
        Rigid3d(Eigen::Quaterniond(q[3], q[0], q[1], q[2]), Eigen::Vector3d(t[0], t[1], t[2]));
  }
  for (size_t k = 0; k < data->intrinsics.size(); ++k) {
    CameraIntrinsics& c = data->intrinsics[k].intrinsics;
    c = CameraIntrinsics::FromPacked(p.intrinsics[k].data(), c.width_px, c.height_px);
  }
  for (size_t j = 0; j < data->points.size(); ++j) {
    const auto& x = p.points[j];
    data->points[j].point_in_scene = Eigen::Vector3d(x[0], x[1], x[2]);
  }
}

// Pixel residual (unwhitened) of observation `ob`; false behind the camera.
bool PixelResidual(const Parameters& p, const BundleData& data, const BundleObservation& ob,
                   Eigen::Vector2d* r) {
  const size_t i = static_cast<size_t>(ob.camera);
  const ReprojectionCostFunctor f(ob.pixel_px, Eigen::Matrix2d::Identity());
  return f(p.quaternions[i].data(), p.translations[i].data(),
           p.intrinsics[static_cast<size_t>(data.cameras[i].intrinsics_index)].data(),
           p.points[static_cast<size_t>(ob.point)].data(), r->data());
}

const char* kGaugeWarning =
    "reduced camera matrix: the constant blocks do not fix the gauge";

}  // namespace

Eigen::Matrix2d ReprojectionCostFunctor::WhiteningOf(const Eigen::Matrix2d& covariance_px2) {
  const Eigen::Matrix2d L = covariance_px2.llt().matrixL();
  return L.inverse();
}

Camera BundleData::CameraAt(int i) const {
  const BundleCamera& c = cameras[static_cast<size_t>(i)];
  Camera out;
  out.name = c.name;
  out.intrinsics = intrinsics[static_cast<size_t>(c.intrinsics_index)].intrinsics;
  out.cam_from_scene = c.cam_from_scene;
  return out;
}

Status BundleOptions::Validate() const {
  if (max_iterations < 0) {
    return Status::InvalidArgument("BundleOptions.max_iterations = " +
                                   std::to_string(max_iterations) + ": must be >= 0");
  }
  const std::pair<const char*, double> tolerances[] = {
      {"function_tolerance", function_tolerance},
      {"gradient_tolerance", gradient_tolerance},
      {"parameter_tolerance", parameter_tolerance}};
  for (const auto& [name, value] : tolerances) {
    if (!(value >= 0.0 && value < 1.0)) {
      return Status::InvalidArgument(std::string("BundleOptions.") + name + " = " +
                                     FormatNumber(value) + ": must be in [0, 1)");
    }
  }
  if (loss != BundleLoss::kNone && !(loss_scale_px > 0.0 && std::isfinite(loss_scale_px))) {
    return Status::InvalidArgument("BundleOptions.loss_scale_px = " +
                                   FormatNumber(loss_scale_px) +
                                   ": must be positive and finite with a robust loss");
  }
  if (num_threads < 1) {
    return Status::InvalidArgument("BundleOptions.num_threads = " +
                                   std::to_string(num_threads) + ": must be >= 1");
  }
  if (gauge == BundleGauge::kThreePointDatum) {
    const auto& d = datum_points;
    if (d[0] < 0 || d[1] < 0 || d[2] < 0 || d[0] == d[1] || d[0] == d[2] || d[1] == d[2]) {
      return Status::InvalidArgument(
          "BundleOptions.datum_points = (" + std::to_string(d[0]) + ", " +
          std::to_string(d[1]) + ", " + std::to_string(d[2]) +
          "): with gauge kThreePointDatum, three distinct non-negative point indices");
    }
  }
  return Status::Ok();
}

std::string BundleResult::Report() const {
  std::string s = "bundle adjustment: " + std::to_string(data.cameras.size()) + " cameras, " +
                  std::to_string(data.points.size()) + " points, " +
                  std::to_string(data.observations.size()) + " observations\n";
  s += "  solver " + linear_solver + ", " + std::to_string(iterations) + " iterations, " +
       FormatPrintf("%.3f", solve_seconds * 1e3) + " ms: " + termination + "\n";
  s += "  cost " + FormatNumber(initial_cost, 6) + " -> " + FormatNumber(final_cost, 6) +
       ", variance factor " + FormatPrintf("%.4f", variance_factor) + "\n";
  s += "  gauge: " + gauge + "\n";
  s += "  RMS reprojection " + FormatPrintf("%.4f", rms_reprojection_px) + " px per coordinate\n";
  for (size_t i = 0; i < camera_rms_px.size(); ++i) {
    s += "    camera " + std::to_string(i) + " '" + data.cameras[i].name + "': " +
         FormatPrintf("%.4f", camera_rms_px[i]) + " px\n";
  }
  s += "  point covariances: " + (covariance_method.empty() ? std::string("not computed")
                                                             : covariance_method);
  if (!point_covariances.empty()) {
    double sum = 0.0;
    double worst = 0.0;
    int n = 0;
    for (size_t j = 0; j < point_covariances.size(); ++j) {
      if (data.points[j].constant) continue;
      const double tr = point_covariances[j].trace();
      sum += tr;
      worst = std::max(worst, tr);
      ++n;
    }
    if (n > 0) {
      s += "; RMS 3D sigma " + FormatNumber(std::sqrt(sum / n), 4) + ", worst " +
           FormatNumber(std::sqrt(worst), 4) + " (scene units)";
    }
  }
  s += "\n";
  return s;
}

Result<BundleResult> BundleAdjust(const BundleData& data, const BundleOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(ValidateData(data, options));
  Parameters p = Pack(data);
  for (size_t o = 0; o < data.observations.size(); ++o) {
    Eigen::Vector2d r;
    if (!PixelResidual(p, data, data.observations[o], &r)) {
      return Status::NoSolution(ObservationPrefix(o) + ": point " +
                                std::to_string(data.observations[o].point) +
                                " is behind camera " +
                                std::to_string(data.observations[o].camera) + " at the start");
    }
  }

  // Which blocks take part.
  const size_t n_cam = data.cameras.size();
  const size_t n_intr = data.intrinsics.size();
  const size_t n_pts = data.points.size();
  std::vector<char> cam_used(n_cam, 0), intr_used(n_intr, 0), pt_used(n_pts, 0);
  for (const BundleObservation& ob : data.observations) {
    const size_t i = static_cast<size_t>(ob.camera);
    cam_used[i] = 1;
    intr_used[static_cast<size_t>(data.cameras[i].intrinsics_index)] = 1;
    pt_used[static_cast<size_t>(ob.point)] = 1;
  }

  ceres::Problem problem;
  for (size_t i = 0; i < n_cam; ++i) {
    if (!cam_used[i]) continue;
    problem.AddParameterBlock(p.quaternions[i].data(), 4, new ceres::EigenQuaternionManifold);
    problem.AddParameterBlock(p.translations[i].data(), 3);
    if (data.cameras[i].pose_constant) {
      problem.SetParameterBlockConstant(p.quaternions[i].data());
      problem.SetParameterBlockConstant(p.translations[i].data());
    }
  }
  for (size_t k = 0; k < n_intr; ++k) {
    if (!intr_used[k]) continue;
    problem.AddParameterBlock(p.intrinsics[k].data(), kNumCameraParameters);
    if (data.intrinsics[k].constant) problem.SetParameterBlockConstant(p.intrinsics[k].data());
  }
  size_t free_points = 0;
  for (size_t j = 0; j < n_pts; ++j) {
    if (!pt_used[j]) continue;
    problem.AddParameterBlock(p.points[j].data(), 3);
    if (data.points[j].constant) {
      problem.SetParameterBlockConstant(p.points[j].data());
    } else {
      ++free_points;
    }
  }
  std::vector<double> obs_sigma(data.observations.size());
  for (size_t o = 0; o < data.observations.size(); ++o) {
    const BundleObservation& ob = data.observations[o];
    const size_t i = static_cast<size_t>(ob.camera);
    const size_t k = static_cast<size_t>(data.cameras[i].intrinsics_index);
    auto* cost = new ceres::AutoDiffCostFunction<ReprojectionCostFunctor, 2, 4, 3,
                                                 kNumCameraParameters, 3>(
        new ReprojectionCostFunctor(ob.pixel_px,
                                    ReprojectionCostFunctor::WhiteningOf(ob.covariance_px2)));
    obs_sigma[o] = std::sqrt(ob.covariance_px2.trace() / 2.0);
    ceres::LossFunction* loss = nullptr;
    if (options.loss == BundleLoss::kHuber) {
      loss = new ceres::HuberLoss(options.loss_scale_px / obs_sigma[o]);
    } else if (options.loss == BundleLoss::kCauchy) {
      loss = new ceres::CauchyLoss(options.loss_scale_px / obs_sigma[o]);
    }
    problem.AddResidualBlock(cost, loss, p.quaternions[i].data(), p.translations[i].data(),
                             p.intrinsics[k].data(), p.points[static_cast<size_t>(ob.point)].data());
  }

  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  BundleResult result;
  if (free_points > 0) {
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (size_t j = 0; j < n_pts; ++j) {
      if (pt_used[j]) ordering->AddElementToGroup(p.points[j].data(), 0);
    }
    for (size_t i = 0; i < n_cam; ++i) {
      if (!cam_used[i]) continue;
      ordering->AddElementToGroup(p.quaternions[i].data(), 1);
      ordering->AddElementToGroup(p.translations[i].data(), 1);
    }
    for (size_t k = 0; k < n_intr; ++k) {
      if (intr_used[k]) ordering->AddElementToGroup(p.intrinsics[k].data(), 1);
    }
    so.linear_solver_ordering = ordering;
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
      so.linear_solver_type = ceres::SPARSE_SCHUR;
      so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
      result.linear_solver = "SPARSE_SCHUR (SUITE_SPARSE)";
    } else {
      so.linear_solver_type = ceres::DENSE_SCHUR;
      result.linear_solver = "DENSE_SCHUR";
    }
  } else {
    so.linear_solver_type = ceres::DENSE_QR;
    result.linear_solver = "DENSE_QR (no free points)";
  }
  std::string why;
  if (!so.IsValid(&why)) {
    return Status::InvalidArgument("bundle adjustment: Ceres options: " + why);
  }
  ceres::Solver::Summary summary;
  const auto t0 = std::chrono::steady_clock::now();
  ceres::Solve(so, &problem, &summary);
  result.solve_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!summary.IsSolutionUsable()) {
    return Status::NoSolution("bundle adjustment: solver failed: " + summary.message);
  }
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.termination = std::string(ceres::TerminationTypeToString(summary.termination_type)) +
                       ": " + summary.message;

  // Residual statistics.
  result.camera_rms_px.assign(n_cam, 0.0);
  std::vector<int> per_camera(n_cam, 0);
  double sum_sq = 0.0;
  double chi2 = 0.0;
  for (size_t o = 0; o < data.observations.size(); ++o) {
    const BundleObservation& ob = data.observations[o];
    Eigen::Vector2d r;
    if (!PixelResidual(p, data, ob, &r)) {
      return Status::NoSolution(ObservationPrefix(o) + ": point " + std::to_string(ob.point) +
                                " ended behind camera " + std::to_string(ob.camera));
    }
    sum_sq += r.squaredNorm();
    chi2 += (ReprojectionCostFunctor::WhiteningOf(ob.covariance_px2) * r).squaredNorm();
    result.camera_rms_px[static_cast<size_t>(ob.camera)] += r.squaredNorm();
    per_camera[static_cast<size_t>(ob.camera)] += 1;
  }
  const size_t n_obs = data.observations.size();
  result.rms_reprojection_px = n_obs > 0 ? std::sqrt(sum_sq / (2.0 * static_cast<double>(n_obs))) : 0.0;
  for (size_t i = 0; i < n_cam; ++i) {
    if (per_camera[i] > 0) {
      result.camera_rms_px[i] = std::sqrt(result.camera_rms_px[i] / (2.0 * per_camera[i]));
    }
  }

  // Free parameter blocks in Jacobian column order: cameras, intrinsics, points.
  std::vector<double*> free_blocks;
  int nc = 0;
  for (size_t i = 0; i < n_cam; ++i) {
    if (!cam_used[i] || data.cameras[i].pose_constant) continue;
    free_blocks.push_back(p.quaternions[i].data());
    free_blocks.push_back(p.translations[i].data());
    nc += 6;
  }
  for (size_t k = 0; k < n_intr; ++k) {
    if (!intr_used[k] || data.intrinsics[k].constant) continue;
    free_blocks.push_back(p.intrinsics[k].data());
    nc += kNumCameraParameters;
  }
  std::vector<int> point_column(n_pts, -1);
  int ncols = nc;
  for (size_t j = 0; j < n_pts; ++j) {
    if (!pt_used[j] || data.points[j].constant) continue;
    free_blocks.push_back(p.points[j].data());
    point_column[j] = ncols;
    ncols += 3;
  }
  const bool datum = options.gauge == BundleGauge::kThreePointDatum;
  const double dof = 2.0 * static_cast<double>(n_obs) - ncols + (datum ? 7.0 : 0.0);
  result.variance_factor = dof > 0 ? chi2 / dof : 0.0;

  if (options.compute_point_covariances) {
    ceres::Problem::EvaluateOptions eo;
    eo.parameter_blocks = free_blocks;
    eo.apply_loss_function = true;
    eo.num_threads = options.num_threads;
    ceres::CRSMatrix crs;
    problem.Evaluate(eo, nullptr, nullptr, nullptr, &crs);
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(crs.values.size());
    for (int r = 0; r < crs.num_rows; ++r) {
      for (int q = crs.rows[static_cast<size_t>(r)]; q < crs.rows[static_cast<size_t>(r) + 1]; ++q) {
        trip.emplace_back(r, crs.cols[static_cast<size_t>(q)], crs.values[static_cast<size_t>(q)]);
      }
    }
    Eigen::SparseMatrix<double> J(crs.num_rows, crs.num_cols);
    J.setFromTriplets(trip.begin(), trip.end());
    const Eigen::SparseMatrix<double> H = Eigen::SparseMatrix<double>(J.transpose()) * J;
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(nc, nc);
    std::vector<Eigen::Matrix3d> D(n_pts, Eigen::Matrix3d::Zero());
    std::vector<Eigen::MatrixXd> B(n_pts);
    std::vector<int> point_of_column(static_cast<size_t>(ncols), -1);
    for (size_t j = 0; j < n_pts; ++j) {
      if (point_column[j] < 0) continue;
      B[j] = Eigen::MatrixXd::Zero(nc, 3);
      for (int c = 0; c < 3; ++c) point_of_column[static_cast<size_t>(point_column[j] + c)] = static_cast<int>(j);
    }
    for (int col = 0; col < H.outerSize(); ++col) {
      for (Eigen::SparseMatrix<double>::InnerIterator it(H, col); it; ++it) {
        const int row = static_cast<int>(it.row());
        if (col < nc) {
          if (row < nc) A(row, col) = it.value();
          continue;
        }
        const size_t j = static_cast<size_t>(point_of_column[static_cast<size_t>(col)]);
        const int c = col - point_column[j];
        if (row < nc) {
          B[j](row, c) = it.value();
        } else if (row >= point_column[j] && row < point_column[j] + 3) {
          D[j](row - point_column[j], c) = it.value();
        }
      }
    }
    std::vector<Eigen::Matrix3d> Dinv(n_pts, Eigen::Matrix3d::Zero());
    std::vector<Eigen::MatrixXd> W(n_pts);  // D^-1 B^T, 3 x nc
    Eigen::MatrixXd S = A;
    std::string failure;
    for (size_t j = 0; j < n_pts && failure.empty(); ++j) {
      if (point_column[j] < 0) continue;
      Eigen::LLT<Eigen::Matrix3d> llt(D[j]);
      if (llt.info() != Eigen::Success) {
        failure = "unavailable: point " + std::to_string(j) + " is not determined (singular 3x3 block)";
        break;
      }
      // A block that factors but is nearly singular (rays that nearly
      // coincide: a point seen only from one position) has an inverse of
      // no digits, and the Schur complement below loses its positive
      // semi-definiteness. Its three coordinates share one unit, so the
      // condition number is meaningful.
      const Eigen::Vector3d d_eigen = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(
          D[j], Eigen::EigenvaluesOnly).eigenvalues();
      if (!(d_eigen(0) > 1e-12 * d_eigen(2))) {
        failure = "unavailable: point " + std::to_string(j) +
                  " is not determined (its 3x3 block has condition number " +
                  FormatNumber(d_eigen(2) / std::max(d_eigen(0), 1e-300), 3) +
                  ": its rays nearly coincide)";
        break;
      }
      Dinv[j] = llt.solve(Eigen::Matrix3d::Identity());
      W[j] = Dinv[j] * B[j].transpose();
      S.noalias() -= B[j] * W[j];
    }
    Eigen::MatrixXd Sg = Eigen::MatrixXd::Zero(nc, nc);
    Eigen::MatrixXd Lg = Eigen::MatrixXd::Zero(nc, nc);  // Sg = Lg Lg^T
    if (failure.empty() && nc > 0) {
      // Jacobi scaling first: S's columns mix radians and lengths in the
      // scene's unit, so its raw eigenvalues span the square of that unit's
      // ratio to a radian (a COLMAP model in units of ~0.2 m, or a scene in
      // mm, put genuine directions below the 1e-10 threshold: "26 near-zero
      // eigenvalues, 7 expected"). Ssc = D^-1 S D^-1 with D = sqrt(diag S) is
      // unit-free; D^-1 Ssc^+ D^-1 is a generalised inverse of S, which is
      // all the datum's gauge-invariant covariances need.
      Eigen::VectorXd dinv(nc);
      for (int e = 0; e < nc; ++e) dinv(e) = S(e, e) > 0.0 ? 1.0 / std::sqrt(S(e, e)) : 1.0;
      const Eigen::MatrixXd Ssym =
          dinv.asDiagonal() * (0.5 * (S + S.transpose())) * dinv.asDiagonal();
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Ssym);
      const Eigen::VectorXd& ev = es.eigenvalues();
      const double top = ev(nc - 1);
      const double tiny = 1e-10 * top;
      const int gauge_dim = datum ? 7 : 0;
      if (!(top > 0.0)) {
        failure = "unavailable: reduced camera matrix is zero";
      } else if (nc <= gauge_dim) {
        failure = "unavailable: too few free camera parameters for the datum";
      } else {
        int near_zero = 0;
        for (int e = 0; e < nc; ++e) near_zero += ev(e) <= tiny ? 1 : 0;
        if (ev(0) < -1e-6 * top) {
          failure = "unavailable: the reduced camera matrix is indefinite (smallest eigenvalue " +
                    FormatNumber(ev(0) / top, 3) +
                    " of the largest, after Jacobi scaling): ill-conditioned points";
        } else if (near_zero != gauge_dim) {
          failure = "unavailable: " +
                    std::string(datum ? "the network has " : std::string(kGaugeWarning) + " (") +
                    std::to_string(near_zero) + " near-zero eigenvalue(s) of the reduced camera matrix" +
                    (datum ? ", 7 expected (weak or degenerate geometry)" : ")");
        } else {
          Eigen::VectorXd inv = Eigen::VectorXd::Zero(nc);
          for (int e = gauge_dim; e < nc; ++e) inv(e) = 1.0 / ev(e);
          const Eigen::MatrixXd scaled_vectors = dinv.asDiagonal() * es.eigenvectors();
          Sg = scaled_vectors * inv.asDiagonal() * scaled_vectors.transpose();
          Lg = scaled_vectors * inv.cwiseSqrt().asDiagonal();
        }
      }
    }
    if (!failure.empty()) {
      result.covariance_method = failure;
    } else {
      result.point_covariances.assign(n_pts, Eigen::Matrix3d::Zero());
      auto cross = [&](size_t a, size_t b) -> Eigen::Matrix3d {
        Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
        if (nc > 0) c = W[a] * Sg * W[b].transpose();
        if (a == b) c += Dinv[a];
        return c;
      };
      result.point_own_covariances.assign(n_pts, Eigen::Matrix3d::Zero());
      if (!datum) {
        result.point_shared_factors.assign(n_pts, Eigen::MatrixXd::Zero(3, nc));
        for (size_t j = 0; j < n_pts; ++j) {
          if (point_column[j] < 0) continue;
          result.point_covariances[j] = cross(j, j);
          result.point_own_covariances[j] = Dinv[j];
          if (nc > 0) result.point_shared_factors[j] = W[j] * Lg;
        }
        result.covariance_method =
            "first order, Schur complement of J^T J (gauge held by the constant blocks)";
      } else {
        const size_t ia = static_cast<size_t>(options.datum_points[0]);
        const size_t ib = static_cast<size_t>(options.datum_points[1]);
        const size_t ic = static_cast<size_t>(options.datum_points[2]);
        const std::array<size_t, 3> abc = {ia, ib, ic};
        Eigen::Matrix<double, 9, 9> cov_abc;
        for (size_t r = 0; r < 3; ++r) {
          for (size_t c = 0; c < 3; ++c) {
            cov_abc.block<3, 3>(static_cast<Eigen::Index>(3 * r), static_cast<Eigen::Index>(3 * c)) = cross(abc[r], abc[c]);
          }
        }
        // The own / shared split: X_j = x_j + e_j - W_j Lg xi (e_j ~ D_j^-1,
        // xi ~ N(0, I) the cameras'), and F(a, b, c, x_j) shares e_a, e_b,
        // e_c (whitened by their Cholesky factors) and xi with every point.
        std::array<Eigen::Matrix3d, 3> chol_abc;
        for (size_t r = 0; r < 3; ++r) chol_abc[r] = Dinv[abc[r]].llt().matrixL();
        const Eigen::Index m = 9 + static_cast<Eigen::Index>(nc);
        result.point_shared_factors.assign(n_pts, Eigen::MatrixXd::Zero(3, m));
        const double d0 = (Eigen::Map<const Eigen::Vector3d>(p.points[ib].data()) -
                           Eigen::Map<const Eigen::Vector3d>(p.points[ia].data())).norm();
        for (size_t j = 0; j < n_pts; ++j) {
          Eigen::Matrix<double, 12, 12> cov;
          cov.topLeftCorner<9, 9>() = cov_abc;
          for (size_t r = 0; r < 3; ++r) {
            const Eigen::Matrix3d c = cross(abc[r], j);
            cov.block<3, 3>(static_cast<Eigen::Index>(3 * r), 9) = c;
            cov.block<3, 3>(9, static_cast<Eigen::Index>(3 * r)) = c.transpose();
          }
          cov.block<3, 3>(9, 9) = cross(j, j);
          // F(a, b, c, x) = (d0 / |b - a|) R(a, b, c) (x - a), by Jets.
          Jet12 v[12];
          for (int q = 0; q < 3; ++q) {
            v[q] = Jet12(p.points[ia][static_cast<size_t>(q)], q);
            v[3 + q] = Jet12(p.points[ib][static_cast<size_t>(q)], 3 + q);
            v[6 + q] = Jet12(p.points[ic][static_cast<size_t>(q)], 6 + q);
            v[9 + q] = Jet12(p.points[j][static_cast<size_t>(q)], 9 + q);
          }
          Jet12 R[9];
          ThreePointFrame(v, v + 3, v + 6, R);
          const Jet12 dx = v[3] - v[0], dy = v[4] - v[1], dz = v[5] - v[2];
          const Jet12 s = Jet12(d0) / ceres::sqrt(dx * dx + dy * dy + dz * dz);
          Eigen::Matrix<double, 3, 12> F;
          for (int r = 0; r < 3; ++r) {
            Jet12 y(0.0);
            for (int c = 0; c < 3; ++c) y += R[3 * r + c] * (v[9 + c] - v[c]);
            F.row(r) = (s * y).v.transpose();
          }
          result.point_covariances[j] = F * cov * F.transpose();
          Eigen::MatrixXd& K = result.point_shared_factors[j];
          // d F / d e_j: how the point's own error reaches it (0 for a datum
          // point, whose own error is one of the shared ones).
          Eigen::Matrix3d F_own = F.rightCols<3>();
          Eigen::MatrixXd camera_part = Eigen::MatrixXd::Zero(3, nc);
          if (nc > 0) camera_part = F.rightCols<3>() * W[j];
          for (size_t r = 0; r < 3; ++r) {
            Eigen::Matrix3d Fr = F.block<3, 3>(0, static_cast<Eigen::Index>(3 * r));
            if (abc[r] == j) {  // a datum point: its own error is the shared one
              Fr += F.rightCols<3>();
              F_own.setZero();
            }
            K.block<3, 3>(0, static_cast<Eigen::Index>(3 * r)) = Fr * chol_abc[r];
            if (nc > 0) camera_part += F.block<3, 3>(0, static_cast<Eigen::Index>(3 * r)) * W[abc[r]];
          }
          if (nc > 0) K.rightCols(nc) = camera_part * Lg;
          result.point_own_covariances[j] = F_own * Dinv[j] * F_own.transpose();
        }
        result.covariance_method =
            "first order, Schur complement of J^T J, pseudo-inverse over the 7-dof gauge, "
            "propagated to the three-point datum with |AB| held";
      }
    }
  }

  result.data = data;
  Unpack(p, &result.data);
  result.gauge = "fixed by the caller (constant blocks)";
  if (datum) {
    result.gauge = "three-point datum (points " + std::to_string(options.datum_points[0]) + ", " +
                   std::to_string(options.datum_points[1]) + ", " +
                   std::to_string(options.datum_points[2]) + "), scale of the solve";
    const auto& d = options.datum_points;
    const Result<Rigid3d> frame = SceneFromThreePoints(
        result.data.points[static_cast<size_t>(d[0])].point_in_scene,
        result.data.points[static_cast<size_t>(d[1])].point_in_scene,
        result.data.points[static_cast<size_t>(d[2])].point_in_scene);
    if (!frame.ok()) {
      return Status::NoSolution("bundle adjustment: datum points " + std::to_string(d[0]) +
                                ", " + std::to_string(d[1]) + ", " + std::to_string(d[2]) +
                                ": " + frame.status().message());
    }
    result.datum_from_solve = *frame;
    for (BundleCamera& c : result.data.cameras) {
      c.cam_from_scene = CamFromNewScene(c.cam_from_scene, *frame, 1.0);
    }
    for (BundlePoint& x : result.data.points) x.point_in_scene = *frame * x.point_in_scene;
  }
  return result;
}

}  // namespace opl
