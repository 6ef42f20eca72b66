#include "opl/scale/scale_factor.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

namespace opl {

Result<ScaleResult> ComputeScaleFactor(const ModuleCalibration& calibration,
                                       const std::vector<LocatedOrigin>& located) {
  auto find = [&](const std::string& name, const std::string& placement) -> int {
    for (size_t i = 0; i < located.size(); ++i) {
      if (located[i].name == name && located[i].placement == placement) return static_cast<int>(i);
    }
    return -1;
  };
  std::vector<std::string> placements;  // order of first appearance
  for (const LocatedOrigin& o : located) {
    if (std::find(placements.begin(), placements.end(), o.placement) == placements.end()) {
      placements.push_back(o.placement);
    }
  }
  for (const LocatedOrigin& o : located) {
    if (!o.origin_in_scene.allFinite() || !o.origin_covariance.allFinite()) {
      return Status::InvalidArgument("located source '" + o.name + "': origin is not finite");
    }
  }
  // Usable pairs.
  struct Pair {
    int i, j;
    const Separation* sep;
  };
  std::vector<Pair> pairs;
  for (const std::string& placement : placements) {
    for (const Separation& sep : calibration.separations) {
      const int i = find(sep.from, placement), j = find(sep.to, placement);
      if (i >= 0 && j >= 0) pairs.push_back({i, j, &sep});
    }
  }
  if (pairs.empty()) {
    return Status::NoSolution("no calibrated separation joins two located sources");
  }
  const int m = static_cast<int>(pairs.size());
  const int k = static_cast<int>(located.size());

  ScaleResult result;
  // Jacobian of every L_photo with respect to every origin (3k).
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(m, 3 * k);
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(3 * k, 3 * k);
  for (int s = 0; s < k; ++s) C.block<3, 3>(3 * s, 3 * s) = located[s].origin_covariance;
  Eigen::VectorXd s_vec(m);
  for (int p = 0; p < m; ++p) {
    const Eigen::Vector3d d = located[pairs[p].i].origin_in_scene - located[pairs[p].j].origin_in_scene;
    const double L = d.norm();
    if (!(L > 0.0)) {
      return Status::NoSolution("sources '" + pairs[p].sep->from + "' and '" + pairs[p].sep->to +
                                "' were located at the same point");
    }
    const Eigen::Vector3d e = d / L;
    J.block<1, 3>(p, 3 * pairs[p].i) = e.transpose();
    J.block<1, 3>(p, 3 * pairs[p].j) = -e.transpose();
    LengthScale ls;
    ls.from = pairs[p].sep->from;
    ls.to = pairs[p].sep->to;
    ls.placement = located[pairs[p].i].placement;
    ls.photo = L;
    ls.cal_mm = pairs[p].sep->length_mm;
    ls.u_cal_mm = pairs[p].sep->u_length_mm;
    ls.scale = ls.cal_mm / L;
    result.lengths.push_back(ls);
    s_vec(p) = ls.scale;
  }
  const Eigen::MatrixXd cov_L = J * C * J.transpose();
  // s_p = cal_p / L_p:  ds/dL = -s/L, ds/dcal = 1/L; calibrated lengths
  // independent of each other, one separation's error shared by its pairs
  // at every placement.
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(m, m);
  Eigen::MatrixXd V_cal = Eigen::MatrixXd::Zero(m, m);
  for (int p = 0; p < m; ++p) {
    LengthScale& ls = result.lengths[p];
    ls.u_photo = std::sqrt(std::max(0.0, cov_L(p, p)));
    D(p, p) = -ls.scale / ls.photo;
    for (int q = 0; q < m; ++q) {
      if (pairs[q].sep != pairs[p].sep) continue;
      V_cal(p, q) = ls.u_cal_mm * ls.u_cal_mm / (ls.photo * result.lengths[q].photo);
    }
  }
  const Eigen::MatrixXd V = D * cov_L * D + V_cal;
  for (int p = 0; p < m; ++p) result.lengths[p].u_scale = std::sqrt(std::max(0.0, V(p, p)));

  if (m == 1) {
    result.scale_factor = s_vec(0);
    result.u_scale_factor = result.lengths[0].u_scale;
    return result;
  }
  // Generalised least squares for the common s; fall back to the plain mean
  // when V is singular (e.g. every uncertainty zero).
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(m);
  Eigen::LDLT<Eigen::MatrixXd> ldlt(V);
  const bool gls = ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 1e-300 &&
                   ldlt.vectorD().minCoeff() > 1e-14 * ldlt.vectorD().maxCoeff();
  if (gls) {
    const Eigen::VectorXd Vinv1 = ldlt.solve(ones);
    const double info = ones.dot(Vinv1);
    result.scale_factor = Vinv1.dot(s_vec) / info;
    result.u_scale_factor = std::sqrt(1.0 / info);
    const Eigen::VectorXd r = s_vec - result.scale_factor * ones;
    result.chi2 = r.dot(ldlt.solve(r));
    result.dof = m - 1;
    for (int p = 0; p < m; ++p) {
      const double var = V(p, p) - 1.0 / info;
      if (var > 0.0) {
        result.max_normalized_deviation =
            std::max(result.max_normalized_deviation, std::abs(r(p)) / std::sqrt(var));
      }
    }
  } else {
    result.scale_factor = s_vec.mean();
    result.u_scale_factor = std::sqrt(std::max(0.0, ones.dot(V * ones))) / m;
    result.dof = m - 1;
  }
  return result;
}

}  // namespace opl
