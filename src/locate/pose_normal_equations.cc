#include "opl/locate/pose_normal_equations.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "opl/geometry/rotation.h"
#include "opl/locate/source_pose_cost_function.h"
#include "pose_kernel.h"

namespace opl {

using locate_internal::SmallAngleApplies;

namespace {
// Arrays of one evaluation, each of (spots rounded up to even) doubles: q (3),
// rho^2, rho, a flag, the angle differences (2), the whitened residuals (2)
// and the six columns of whitened rows (2 each).
constexpr size_t kWorkArrays = 22;
}  // namespace

BeamAngles BeamAngles::FromDirection(const Eigen::Vector3d& d) {
  // d is a unit vector: no overflow to guard against (std::hypot is slow).
  const double cos_el = std::sqrt(d.x() * d.x() + d.y() * d.y());
  return {d.x() / cos_el, d.y() / cos_el, cos_el, d.z()};
}

PoseNormalEquations::PoseNormalEquations(const std::vector<Eigen::Vector3d>& points_in_scene,
                                         const std::vector<Eigen::Vector3d>& beam_directions_in_source,
                                         const std::vector<Eigen::Matrix2d>& whitening,
                                         const Eigen::Matrix3d& R0, const Eigen::Vector3d& t0,
                                         double length_per_radian) {
  Reset(R0, t0, length_per_radian);
  Reserve(static_cast<int>(points_in_scene.size()));
  for (size_t i = 0; i < points_in_scene.size(); ++i) {
    AddSpot(points_in_scene[i], BeamAngles::FromDirection(beam_directions_in_source[i]),
            whitening[i]);
  }
}

void PoseNormalEquations::Reset(const Eigen::Matrix3d& R0, const Eigen::Vector3d& t0,
                                double length_per_radian) {
  n_ = 0;
  any_w01_ = false;
  R0_ = R0;
  t0_ = t0;
  length_per_radian_ = length_per_radian;
}

void PoseNormalEquations::Reserve(int num_spots) {
  if (num_spots <= capacity_) return;
  std::unique_ptr<double[]> grown(new double[static_cast<size_t>(kFields) * num_spots]);
  for (int f = 0; f < kFields; ++f) {
    std::copy(field(f), field(f) + n_, grown.get() + static_cast<size_t>(f) * num_spots);
  }
  spots_ = std::move(grown);
  capacity_ = num_spots;
}

Eigen::Matrix3d PoseNormalEquations::Rotation(const double* x) const {
  return ExpSO3(Eigen::Vector3d(x[0], x[1], x[2]) / length_per_radian_) * R0_;
}

Eigen::Vector3d PoseNormalEquations::Origin(const double* x) const {
  return t0_ + Eigen::Vector3d(x[3], x[4], x[5]);
}

bool PoseNormalEquations::Residuals(const double* x, double* residuals) const {
  const int n = num_spots();
  std::vector<double> angles(2 * static_cast<size_t>(n));
  double cost = 0.0;
  if (!Evaluate(x, &cost, nullptr, nullptr, angles.data())) return false;
  for (int i = 0; i < n; ++i) {
    const double daz = angles[2 * i], del = angles[2 * i + 1];
    residuals[2 * i] = field(kW00)[i] * daz + field(kW01)[i] * del;
    residuals[2 * i + 1] = field(kW10)[i] * daz + field(kW11)[i] * del;
  }
  return true;
}

namespace {

using Pair = Eigen::Array2d;
using PairMap = Eigen::Map<const Eigen::Array2d>;

// The loops of one evaluation, one pass over the spots each (vectorised; see
// pose_kernel.h).

// Angles of q relative to the beam: (x, y) rotated by -az, (rho, z) by -el,
// as tangents t = sin / cos (the arctangents follow); `outside` is 1 where a
// spot needs more (on the Z axis, or an angle outside the small-angle range of
// SmallAngleApplies), else 0.
void AngleTangents(int n, const double* OPL_RESTRICT qx, const double* OPL_RESTRICT qy,
                   const double* OPL_RESTRICT qz, const double* OPL_RESTRICT rho2,
                   const double* OPL_RESTRICT rho, const double* OPL_RESTRICT ca,
                   const double* OPL_RESTRICT sa, const double* OPL_RESTRICT ce,
                   const double* OPL_RESTRICT se, double* OPL_RESTRICT t_az,
                   double* OPL_RESTRICT t_el, double* OPL_RESTRICT outside) {
  for (int i = 0; i < n; ++i) {
    const double sa_i = qy[i] * ca[i] - qx[i] * sa[i];
    const double ca_i = qx[i] * ca[i] + qy[i] * sa[i];
    const double se_i = qz[i] * ce[i] - rho[i] * se[i];
    const double ce_i = rho[i] * ce[i] + qz[i] * se[i];
    t_az[i] = sa_i / ca_i;
    t_el[i] = se_i / ce_i;
    // SmallAngleApplies for both, and rho^2 > 0, without branches.
    const bool ok = (rho2[i] > 0.0) & (ca_i > 0.0) & (std::abs(sa_i) <= 0.125 * ca_i) &
                    (ce_i > 0.0) & (std::abs(se_i) <= 0.125 * ce_i);
    outside[i] = ok ? 0.0 : 1.0;
  }
}

// atan t in place, |t| <= 0.125: the series of SmallAngleAtan2
// (geometry/spherical.h; Horner, the same coefficients) from the t^(2K-2) term
// down. K = 10 is all of it, the same operations as SmallAngleAtan2; fewer
// terms are used only where the first one left out is below 1e-18 of the sum
// (see Evaluate), which changes the result by at most an ulp or so.
template <int K>
void SmallAtan(int n, double* OPL_RESTRICT t) {
  static constexpr double c[10] = {1.0,        -1.0 / 3.0,  1.0 / 5.0,   -1.0 / 7.0,
                                   1.0 / 9.0,  -1.0 / 11.0, 1.0 / 13.0,  -1.0 / 15.0,
                                   1.0 / 17.0, -1.0 / 19.0};
  for (int i = 0; i < n; ++i) {
    const double ti = t[i];
    const double t2 = ti * ti;
    double p = c[K - 1];
    for (int k = K - 2; k >= 0; --k) p = p * t2 + c[k];
    t[i] = ti * p;
  }
}

// r = W (daz, del): az components to r0, el components to r1.
void Whiten(int n, const double* OPL_RESTRICT w00, const double* OPL_RESTRICT w01,
            const double* OPL_RESTRICT w10, const double* OPL_RESTRICT w11,
            const double* OPL_RESTRICT daz, const double* OPL_RESTRICT del,
            double* OPL_RESTRICT r0, double* OPL_RESTRICT r1) {
  for (int i = 0; i < n; ++i) {
    r0[i] = w00[i] * daz[i] + w01[i] * del[i];
    r1[i] = w10[i] * daz[i] + w11[i] * del[i];
  }
}

// Whitened rows of dr/d(dphi, dt') (pose_normal_equations.h): column k of
// the az rows to c[k][i], of the el rows to c[k][m + i].
void PoseRowsAll(int n, int m, const double* OPL_RESTRICT qx, const double* OPL_RESTRICT qy,
                 const double* OPL_RESTRICT qz, const double* OPL_RESTRICT rho2,
                 const double* OPL_RESTRICT rho, const double* OPL_RESTRICT w00,
                 const double* OPL_RESTRICT w01, const double* OPL_RESTRICT w10,
                 const double* OPL_RESTRICT w11, double* OPL_RESTRICT c0,
                 double* OPL_RESTRICT c1, double* OPL_RESTRICT c2, double* OPL_RESTRICT c3,
                 double* OPL_RESTRICT c4, double* OPL_RESTRICT c5) {
  for (int i = 0; i < n; ++i) {
    const double X = qx[i], Y = qy[i], Z = qz[i];
    // 1 / rho^2 and 1 / r^2 from one division.
    const double r2 = rho2[i] + Z * Z;
    const double inv_both = 1.0 / (rho2[i] * r2);
    const double inv_rho2 = r2 * inv_both;
    const double inv_r2 = rho2[i] * inv_both;
    const double inv_rho = rho[i] * inv_rho2;
    const double k = Z * inv_r2 * inv_rho;
    const double z_rho2 = Z * inv_rho2;
    // az row u0 = [X z_rho2, Y z_rho2, -1, Y inv_rho2, -X inv_rho2, 0],
    // el row u1 = [-Y inv_rho, X inv_rho, 0, X k, Y k, -rho inv_r2].
    const double u00 = X * z_rho2, u01 = Y * z_rho2, u03 = Y * inv_rho2, u04 = -X * inv_rho2;
    const double u10 = -Y * inv_rho, u11 = X * inv_rho, u13 = X * k, u14 = Y * k;
    const double u15 = -rho[i] * inv_r2;
    const double a = w00[i], b = w01[i], c = w10[i], d = w11[i];
    c0[i] = a * u00 + b * u10;
    c1[i] = a * u01 + b * u11;
    c2[i] = -a;
    c3[i] = a * u03 + b * u13;
    c4[i] = a * u04 + b * u14;
    c5[i] = b * u15;
    c0[m + i] = c * u00 + d * u10;
    c1[m + i] = c * u01 + d * u11;
    c2[m + i] = -c;
    c3[m + i] = c * u03 + d * u13;
    c4[m + i] = c * u04 + d * u14;
    c5[m + i] = d * u15;
  }
}

// Sums over rows [begin, end) (an even count) of products of columns:
// h[e.out] = sum_i col[e.a][i] col[e.b][i] for each listed entry e, two rows at
// a time (one SIMD register per sum; few enough sums per pass to stay in
// registers).
struct Entry {
  int a, b, out;
};
// The entries are compile-time constants, so that every column a pass needs is
// loaded once per pair of rows.
template <int K, const Entry (&entries)[K]>
void SumProducts(const double* const* col, int begin, int end, double* h) {
  Pair acc[K];
  for (int e = 0; e < K; ++e) acc[e].setZero();
  for (int i = begin; i < end; i += 2) {
    Pair c[7];
    for (int k = 0; k < 7; ++k) c[k] = PairMap(col[k] + i);
    for (int e = 0; e < K; ++e) acc[e] += c[entries[e].a] * c[entries[e].b];
  }
  for (int e = 0; e < K; ++e) h[entries[e].out] = acc[e].sum();
}

// Index of (i, j), i <= j < 6, in the row-major upper triangle; J^T r at 21 + i,
// r^T r at 27 (column 6 is r).
constexpr int U(int i, int j) {
  return j == 6 ? (i == 6 ? 27 : 21 + i) : i * 6 - i * (i - 1) / 2 + (j - i);
}
constexpr Entry E(int i, int j) { return {i, j, U(i, j)}; }

// All 28 sums over all rows.
constexpr Entry kAll0[7] = {E(0, 0), E(0, 1), E(0, 2), E(0, 3), E(0, 4), E(0, 5), E(1, 1)};
constexpr Entry kAll1[7] = {E(1, 2), E(1, 3), E(1, 4), E(1, 5), E(2, 2), E(2, 3), E(2, 4)};
constexpr Entry kAll2[7] = {E(2, 5), E(3, 3), E(3, 4), E(3, 5), E(4, 4), E(4, 5), E(5, 5)};
constexpr Entry kAll3[7] = {E(0, 6), E(1, 6), E(2, 6), E(3, 6), E(4, 6), E(5, 6), E(6, 6)};
// When W is lower triangular (w01 = 0), column 5 is zero on the az rows: the
// 21 sums without column 5 over all rows, the 7 with it over the el rows.
constexpr Entry kNoCol5_0[7] = {E(0, 0), E(0, 1), E(0, 2), E(0, 3), E(0, 4), E(1, 1), E(1, 2)};
constexpr Entry kNoCol5_1[7] = {E(1, 3), E(1, 4), E(2, 2), E(2, 3), E(2, 4), E(3, 3), E(3, 4)};
constexpr Entry kNoCol5_2[7] = {E(4, 4), E(0, 6), E(1, 6), E(2, 6), E(3, 6), E(4, 6), E(6, 6)};
constexpr Entry kCol5[7] = {E(0, 5), E(1, 5), E(2, 5), E(3, 5), E(4, 5), E(5, 5), E(5, 6)};

}  // namespace

bool PoseNormalEquations::Evaluate(const double* x, double* cost, Matrix6* JtJ, Vector6* Jtr,
                                   double* angle_differences) const {
  const int n = num_spots();
  const int m = n + (n & 1);  // rows per residual component, even
  const Eigen::Vector3d dtheta = Eigen::Vector3d(x[0], x[1], x[2]) / length_per_radian_;
  const Eigen::Matrix3d Rt = (ExpSO3(dtheta) * R0_).transpose();
  const Eigen::Vector3d t = Origin(x);
  const bool normal = JtJ != nullptr && Jtr != nullptr;

  const size_t work_size = kWorkArrays * static_cast<size_t>(m);
  if (work_size > work_size_) {
    work_.reset(new double[work_size]);
    work_size_ = work_size;
  }
  double* const w = work_.get();
  double* const qx = w;
  double* const qy = w + m;
  double* const qz = w + 2 * m;
  double* const rho2 = w + 3 * m;
  double* const rho = w + 4 * m;
  double* const outside = w + 5 * m;
  double* const daz = w + 6 * m;
  double* const del = w + 7 * m;
  // Whitened residuals and rows: 2m rows, az rows then el rows (zero padded).
  double* const res = w + 8 * m;
  double* cols[7];
  for (int k = 0; k < 6; ++k) cols[k] = w + (10 + 2 * k) * m;
  cols[6] = res;

  locate_internal::SourceFramePoints(n, field(kPx), field(kPy), field(kPz), Rt, t, qx, qy, qz, rho2);
  Eigen::Map<Eigen::ArrayXd>(rho, n) = Eigen::Map<const Eigen::ArrayXd>(rho2, n).sqrt();
  AngleTangents(n, qx, qy, qz, rho2, rho, field(kCosAz), field(kSinAz), field(kCosEl),
                field(kSinEl), daz, del, outside);
  using ArrayMap = Eigen::Map<Eigen::ArrayXd>;
  const bool any_outside = n > 0 && ArrayMap(outside, n).maxCoeff() > 0.0;
  // How many terms of the arctangent series: the first term left out,
  // t^(2K) / (2K + 1) relative, must stay below 1e-18 for every spot. Near a
  // solution the angles are small (residuals), and 3 or 5 terms do.
  const double tau = (n == 0 || any_outside) ? 1.0
                                             : std::max(ArrayMap(daz, n).abs().maxCoeff(),
                                                        ArrayMap(del, n).abs().maxCoeff());
  if (tau <= 0x1p-10) {
    SmallAtan<3>(n, daz);  // t^6 / 7 < 1.2e-19
    SmallAtan<3>(n, del);
  } else if (tau <= 0x1p-6) {
    SmallAtan<5>(n, daz);  // t^10 / 11 < 8e-20
    SmallAtan<5>(n, del);
  } else {
    SmallAtan<10>(n, daz);
    SmallAtan<10>(n, del);
  }
  if (any_outside) {
    const double* ca = field(kCosAz);
    const double* sa = field(kSinAz);
    const double* ce = field(kCosEl);
    const double* se = field(kSinEl);
    for (int i = 0; i < n; ++i) {
      if (!(rho2[i] > 0.0)) return false;
      const double sa_i = qy[i] * ca[i] - qx[i] * sa[i];
      const double ca_i = qx[i] * ca[i] + qy[i] * sa[i];
      const double se_i = qz[i] * ce[i] - rho[i] * se[i];
      const double ce_i = rho[i] * ce[i] + qz[i] * se[i];
      if (!SmallAngleApplies(sa_i, ca_i)) daz[i] = std::atan2(sa_i, ca_i);
      if (!SmallAngleApplies(se_i, ce_i)) del[i] = std::atan2(se_i, ce_i);
    }
  }
  if (angle_differences != nullptr) {
    for (int i = 0; i < n; ++i) {
      angle_differences[2 * i] = daz[i];
      angle_differences[2 * i + 1] = del[i];
    }
  }
  Whiten(n, field(kW00), field(kW01), field(kW10), field(kW11), daz, del, res, res + m);
  if (m != n) {
    res[n] = 0.0;
    res[m + n] = 0.0;
  }
  if (!normal) {
    *cost = 0.5 * Eigen::Map<const Eigen::VectorXd>(res, 2 * m).squaredNorm();
    return true;
  }
  PoseRowsAll(n, m, qx, qy, qz, rho2, rho, field(kW00), field(kW01), field(kW10), field(kW11),
              cols[0], cols[1], cols[2], cols[3], cols[4], cols[5]);
  if (m != n) {
    for (int k = 0; k < 6; ++k) {
      cols[k][n] = 0.0;
      cols[k][m + n] = 0.0;
    }
  }
  // J^T J (upper triangle), J^T r and r^T r in the source-frame perturbation.
  double h[28];
  if (!any_w01_) {
    SumProducts<7, kNoCol5_0>(cols, 0, 2 * m, h);
    SumProducts<7, kNoCol5_1>(cols, 0, 2 * m, h);
    SumProducts<7, kNoCol5_2>(cols, 0, 2 * m, h);
    SumProducts<7, kCol5>(cols, m, 2 * m, h);
  } else {
    SumProducts<7, kAll0>(cols, 0, 2 * m, h);
    SumProducts<7, kAll1>(cols, 0, 2 * m, h);
    SumProducts<7, kAll2>(cols, 0, 2 * m, h);
    SumProducts<7, kAll3>(cols, 0, 2 * m, h);
  }
  Matrix6 H;
  int e = 0;
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j, ++e) {
      H(i, j) = h[e];
      H(j, i) = h[e];
    }
  }
  *cost = 0.5 * h[27];
  // To x = (D dtheta, dt): d(dphi)/dx_rot = R0^T J_l(-dtheta) / D, d(dt')/dt = R^T.
  const Eigen::Matrix3d M = R0_.transpose() * LeftJacobianSO3(-dtheta) / length_per_radian_;
  *JtJ = locate_internal::CongruenceBlockDiagonal(H, M, Rt);
  const Eigen::Map<const Eigen::Vector3d> g_rot(h + 21), g_t(h + 24);
  Jtr->head<3>() = M.transpose() * g_rot;
  Jtr->tail<3>() = Rt.transpose() * g_t;
  return true;
}

PoseSolverSummary SolvePoseLevenbergMarquardt(const PoseNormalEquations& problem,
                                              const PoseSolverOptions& options,
                                              Eigen::Matrix<double, 6, 1>* x_and_min) {
  using Matrix6 = PoseNormalEquations::Matrix6;
  using Vector6 = PoseNormalEquations::Vector6;
  PoseSolverSummary summary;
  summary.iterations = 0;
  Vector6& x = *x_and_min;

  Matrix6 JtJ, jtj;
  Vector6 Jtr, g;
  double cost = 0.0;
  if (!problem.Evaluate(x.data(), &cost, &JtJ, &Jtr)) {
    summary.evaluation_failed = true;
    summary.initial_cost = summary.final_cost = std::numeric_limits<double>::quiet_NaN();
    return summary;
  }
  // TinySolver: J_s = J diag(s), s = 1 / (1 + column norms of J) at the start;
  // its jtj_ = J_s^T J_s and g_ = -J_s^T r.
  const Vector6 scaling = (1.0 + JtJ.diagonal().array().sqrt()).inverse().matrix();
  auto scale = [&](const Matrix6& A, const Vector6& b) {
    jtj = scaling.asDiagonal() * A * scaling.asDiagonal();
    g = -scaling.cwiseProduct(b);
    summary.gradient_max_norm = g.cwiseAbs().maxCoeff();
  };
  scale(JtJ, Jtr);
  summary.initial_cost = cost;
  summary.final_cost = cost;
  if (summary.gradient_max_norm < options.gradient_tolerance) {
    summary.status = PoseSolverSummary::kGradientTooSmall;
    return summary;
  }
  if (cost < options.cost_threshold) {
    summary.status = PoseSolverSummary::kCostTooSmall;
    return summary;
  }

  double u = 1.0 / options.initial_trust_region_radius;
  double v = 2.0;
  Eigen::LDLT<Matrix6> solver;
  Matrix6 JtJ_new;
  Vector6 Jtr_new;
  for (summary.iterations = 1; summary.iterations < options.max_num_iterations;
       summary.iterations++) {
    Matrix6 jtj_regularized = jtj;
    const double min_diagonal = 1e-6;
    const double max_diagonal = 1e32;
    for (int i = 0; i < 6; ++i) {
      const double lm = std::sqrt(u * std::min(std::max(jtj(i, i), min_diagonal), max_diagonal));
      jtj_regularized(i, i) += lm * lm;
    }
    solver.compute(jtj_regularized);
    const Vector6 lm_step = solver.solve(g);
    const Vector6 dx = scaling.asDiagonal() * lm_step;
    const double parameter_tolerance =
        options.parameter_tolerance * (x.norm() + options.parameter_tolerance);
    if (dx.norm() < parameter_tolerance) {
      summary.status = PoseSolverSummary::kRelativeStepSizeTooSmall;
      break;
    }
    const Vector6 x_new = x + dx;
    // Residuals and normal equations together: near the optimum (where this
    // runs) steps are accepted, and the normal equations are then ready.
    double cost_new = 0.0;
    const bool evaluated = problem.Evaluate(x_new.data(), &cost_new, &JtJ_new, &Jtr_new);
    const double cost_change =
        evaluated ? 2.0 * cost - 2.0 * cost_new : -std::numeric_limits<double>::infinity();
    const double model_cost_change = lm_step.dot(2.0 * g - jtj * lm_step);
    const double rho = cost_change / model_cost_change;
    if (rho > 0.0) {
      x = x_new;
      if (std::abs(cost_change) < options.function_tolerance) {
        cost = cost_new;
        summary.status = PoseSolverSummary::kCostChangeTooSmall;
        break;
      }
      cost = cost_new;
      scale(JtJ_new, Jtr_new);
      if (summary.gradient_max_norm < options.gradient_tolerance) {
        summary.status = PoseSolverSummary::kGradientTooSmall;
        break;
      }
      if (cost < options.cost_threshold) {
        summary.status = PoseSolverSummary::kCostTooSmall;
        break;
      }
      const double tmp = 2.0 * rho - 1.0;
      u = u * std::max(1.0 / 3.0, 1.0 - tmp * tmp * tmp);
      v = 2.0;
    } else {
      if (std::abs(cost_change) < options.function_tolerance) {
        summary.status = PoseSolverSummary::kCostChangeTooSmall;
        break;
      }
      u *= v;
      v *= 2.0;
      ++summary.rejected_steps;
    }
  }
  summary.final_cost = cost;
  return summary;
}

}  // namespace opl
