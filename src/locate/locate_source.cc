#include "opl/locate/locate_source.h"

#include "opl/core/format.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "opl/locate/p3p.h"
#include "opl/locate/pose_normal_equations.h"
#include "pose_kernel.h"

namespace opl {
namespace {

// The data of one locate, in flat arrays.
struct Data {
  int n = 0;
  std::vector<int> beam_ids;
  std::vector<Eigen::Vector3d> points;    // scene
  std::vector<Eigen::Vector3d> bearings;  // unit, source frame
  std::vector<BeamAngles> angles;         // of the bearings
  std::vector<const Beam*> beams;
  bool weighted = false;                  // every spot carries a covariance
  // The same as columns of n doubles each (the loops over spots run on these):
  // points, bearings, and when weighted the spot covariance Sigma (9,
  // column-major) and the beam's cov_azel (00, 10, 11; 0 without one).
  enum Column { kPx, kPy, kPz, kFx, kFy, kFz, kSigma, kBeamCov = kSigma + 9, kNumColumns = kBeamCov + 3 };
  std::unique_ptr<double[]> columns;  // every entry written before use
  const double* col(int k) const { return columns.get() + static_cast<size_t>(k) * n; }
  double* col(int k) { return columns.get() + static_cast<size_t>(k) * n; }
};

Status CheckSpots(const BeamPattern& pattern, const std::vector<SpotObservation>& spots,
                  Data* data) {
  const int n = static_cast<int>(spots.size());
  std::vector<char> seen(static_cast<size_t>(pattern.beams_per_side()) * pattern.beams_per_side() + 1, 0);
  data->beam_ids.reserve(n);
  data->points.reserve(n);
  data->bearings.reserve(n);
  data->beams.reserve(n);
  int with_cov = 0;
  for (int i = 0; i < n; ++i) {
    const SpotObservation& s = spots[i];
    // The spot's name, built only when there is something to say.
    auto which = [&]() {
      return "spot " + std::to_string(i) + " (beam " + std::to_string(s.beam_id) + ")";
    };
    const Beam* beam = pattern.Find(s.beam_id);
    if (beam == nullptr) {
      return Status::InvalidArgument(which() + ": beam id is not in the pattern (1.." +
                                     std::to_string(pattern.beams_per_side() *
                                                    pattern.beams_per_side()) +
                                     ", calibrated beams only)");
    }
    if (seen[s.beam_id]) return Status::InvalidArgument(which() + ": duplicate beam id");
    seen[s.beam_id] = 1;
    if (!s.point_in_scene.allFinite()) {
      return Status::InvalidArgument(which() + ": point is not finite");
    }
    if (s.cov_in_scene) {
      const Eigen::Matrix3d& C = *s.cov_in_scene;
      // Finite, and symmetric to 1e-9 of 1 + |C|_F (the largest |C - C^T|
      // is off the diagonal).
      bool finite = true;
      double max_abs = 0.0, sum_sq = 0.0;
      for (int k = 0; k < 9; ++k) {
        const double c = C(k);
        finite &= std::isfinite(c);
        max_abs = std::max(max_abs, std::abs(c));
        sum_sq += c * c;
      }
      const double asymmetry = std::max({std::abs(C(0, 1) - C(1, 0)), std::abs(C(0, 2) - C(2, 0)),
                                         std::abs(C(1, 2) - C(2, 1))});
      if (!finite || asymmetry > 1e-9 * (1.0 + std::sqrt(sum_sq))) {
        return Status::InvalidArgument(which() + ": covariance is not finite and symmetric");
      }
      // Positive semi-definite: every principal minor >= 0 (to round-off).
      const double tol = -1e-12 * max_abs * max_abs;
      const bool psd = C(0, 0) >= 0.0 && C(1, 1) >= 0.0 && C(2, 2) >= 0.0 &&
                       C(0, 0) * C(1, 1) - C(0, 1) * C(0, 1) >= tol &&
                       C(0, 0) * C(2, 2) - C(0, 2) * C(0, 2) >= tol &&
                       C(1, 1) * C(2, 2) - C(1, 2) * C(1, 2) >= tol &&
                       C.determinant() >= tol * max_abs;
      if (!psd) {
        return Status::InvalidArgument(which() + ": covariance is not positive semi-definite");
      }
      ++with_cov;
    }
    data->beam_ids.push_back(s.beam_id);
    data->points.push_back(s.point_in_scene);
    data->bearings.push_back(pattern.DirectionInSource(s.beam_id));
    data->beams.push_back(beam);
  }
  if (with_cov != 0 && with_cov != n) {
    return Status::InvalidArgument("either every spot or no spot must carry a covariance (" +
                                   std::to_string(with_cov) + " of " + std::to_string(n) +
                                   " do)");
  }
  // The columns.
  data->n = n;
  data->weighted = with_cov > 0;
  data->columns.reset(
      new double[static_cast<size_t>(data->weighted ? Data::kNumColumns : Data::kSigma) * n]);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      data->col(Data::kPx + k)[i] = data->points[i](k);
      data->col(Data::kFx + k)[i] = data->bearings[i](k);
    }
    if (!data->weighted) continue;
    const Eigen::Matrix3d& S = *spots[i].cov_in_scene;
    for (int k = 0; k < 9; ++k) data->col(Data::kSigma + k)[i] = S(k);
    const auto& B = data->beams[i]->cov_azel_rad2;
    data->col(Data::kBeamCov)[i] = B ? (*B)(0, 0) : 0.0;
    data->col(Data::kBeamCov + 1)[i] = B ? (*B)(1, 0) : 0.0;
    data->col(Data::kBeamCov + 2)[i] = B ? (*B)(1, 1) : 0.0;
  }
  // The beams' angles (BeamAngles::FromDirection), vectorised.
  using CMap = Eigen::Map<const Eigen::ArrayXd>;
  const CMap fx(data->col(Data::kFx), n), fy(data->col(Data::kFy), n);
  const Eigen::ArrayXd cos_el = (fx * fx + fy * fy).sqrt();
  const Eigen::ArrayXd cos_az = fx / cos_el, sin_az = fy / cos_el;
  data->angles.resize(n);
  for (int i = 0; i < n; ++i) {
    data->angles[i] = {cos_az[i], sin_az[i], cos_el[i], data->bearings[i].z()};
  }
  return Status::Ok();
}

constexpr double kInf = std::numeric_limits<double>::infinity();

// Squared sine of the angle between the bearing f_k and q_k = R p_k + t, for
// k < n; 1 where q is behind (f . q <= 0). Branch-free (vectorised).
void AngleErrorsSq(int n, const double* OPL_RESTRICT px, const double* OPL_RESTRICT py,
                   const double* OPL_RESTRICT pz, const double* OPL_RESTRICT fx,
                   const double* OPL_RESTRICT fy, const double* OPL_RESTRICT fz,
                   const PoseRt& pose, double* OPL_RESTRICT e2) {
  const Eigen::Matrix3d& R = pose.R;
  const double r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
  const double r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
  const double r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
  const double tx = pose.t.x(), ty = pose.t.y(), tz = pose.t.z();
  for (int k = 0; k < n; ++k) {
    const double qx = r00 * px[k] + r01 * py[k] + r02 * pz[k] + tx;
    const double qy = r10 * px[k] + r11 * py[k] + r12 * pz[k] + ty;
    const double qz = r20 * px[k] + r21 * py[k] + r22 * pz[k] + tz;
    const double d = fx[k] * qx + fy[k] * qy + fz[k] * qz;
    const double cx = fy[k] * qz - fz[k] * qy;
    const double cy = fz[k] * qx - fx[k] * qz;
    const double cz = fx[k] * qy - fy[k] * qx;
    const double sin2 = (cx * cx + cy * cy + cz * cz) / (qx * qx + qy * qy + qz * qz);
    // sin2 where d > 0, else 1; as a max (0 <= sin2 <= 1, NaN only where
    // q = 0, d = 0) the division is always used and the loop has no branch.
    const double behind = d > 0.0 ? 0.0 : 1.0;
    e2[k] = behind < sin2 ? sin2 : behind;
  }
}

void AngleErrorsSq(const Data& data, int begin, int end, const PoseRt& pose, double* e2) {
  AngleErrorsSq(end - begin, data.col(Data::kPx) + begin, data.col(Data::kPy) + begin,
                data.col(Data::kPz) + begin, data.col(Data::kFx) + begin,
                data.col(Data::kFy) + begin, data.col(Data::kFz) + begin, pose, e2);
}

struct RansacOutcome {
  PoseRt pose;  // source_from_scene
  int num_inliers = 0;
  int iterations = 0;
};

bool Ransac(const Data& data, const LocateOptions& options, RansacOutcome* out) {
  const int n = data.n;
  const double th2 = std::pow(std::sin(options.ransac_inlier_threshold_rad), 2);
  std::mt19937_64 rng(options.ransac_seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  double best_cost = std::numeric_limits<double>::infinity();
  int best_inliers = 0;
  long needed = options.ransac_max_iterations;
  std::array<PoseRt, 4> solutions;
  // MSAC score over blocks of spots: the errors of a block at once
  // (vectorised), summed in spot order; a pose is dropped as soon as its cost
  // reaches the best one.
  constexpr int kBlock = 32;
  double e2[kBlock];
  int it = 0;
  for (; it < needed && it < options.ransac_max_iterations; ++it) {
    int i0 = pick(rng), i1 = pick(rng), i2 = pick(rng);
    if (i0 == i1 || i0 == i2 || i1 == i2) continue;
    const Eigen::Vector3d a = data.points[i1] - data.points[i0];
    const Eigen::Vector3d b = data.points[i2] - data.points[i0];
    // Reject nearly collinear samples: sin(angle) < 0.05.
    if (a.cross(b).squaredNorm() < 0.0025 * a.squaredNorm() * b.squaredNorm()) continue;
    const int ns = SolveP3P({data.bearings[i0], data.bearings[i1], data.bearings[i2]},
                            {data.points[i0], data.points[i1], data.points[i2]}, &solutions);
    for (int s = 0; s < ns; ++s) {
      const PoseRt& pose = solutions[s];
      double cost = 0.0;
      int inliers = 0;
      for (int begin = 0; begin < n && cost < best_cost; begin += kBlock) {
        const int end = std::min(n, begin + kBlock);
        AngleErrorsSq(data, begin, end, pose, e2);
        for (int k = 0; k < end - begin && cost < best_cost; ++k) {
          if (e2[k] < th2) {
            cost += e2[k];
            ++inliers;
          } else {
            cost += th2;
          }
        }
      }
      if (cost < best_cost) {
        best_cost = cost;
        best_inliers = inliers;
        out->pose = pose;
        const double w = static_cast<double>(inliers) / n;
        const double p_good = w * w * w;
        if (p_good >= 1.0 - 1e-12) {
          needed = 0;
        } else {
          needed = static_cast<long>(
              std::ceil(std::log(1.0 - options.ransac_confidence) / std::log(1.0 - p_good)));
        }
      }
    }
  }
  out->iterations = it;
  out->num_inliers = best_inliers;
  return best_inliers >= 4;
}

// The angular covariance C = J_p Sigma J_p^T (+ the beam's cov_azel) of every
// spot at the pose (R, t) (Rt = R^T), J_p = d(az, el)/dp = G R^T,
// G = d(az, el)/dq = [-q_y / rho^2, q_x / rho^2, 0; -q_x k, -q_y k, rho / r^2],
// k = q_z / (rho r^2) (spherical.h), from q, rho^2 and rho. Vectorised.
void AngularCovariances(int n, const Data& data, const Eigen::Matrix3d& Rt,
                        const double* OPL_RESTRICT qx, const double* OPL_RESTRICT qy,
                        const double* OPL_RESTRICT qz, const double* OPL_RESTRICT rho2,
                        const double* OPL_RESTRICT rho, double* OPL_RESTRICT c00,
                        double* OPL_RESTRICT c10, double* OPL_RESTRICT c11) {
  const double* OPL_RESTRICT S[9];
  for (int k = 0; k < 9; ++k) S[k] = data.col(Data::kSigma + k);
  const double* OPL_RESTRICT b00 = data.col(Data::kBeamCov);
  const double* OPL_RESTRICT b10 = data.col(Data::kBeamCov + 1);
  const double* OPL_RESTRICT b11 = data.col(Data::kBeamCov + 2);
  const double r00 = Rt(0, 0), r01 = Rt(0, 1), r02 = Rt(0, 2);
  const double r10 = Rt(1, 0), r11 = Rt(1, 1), r12 = Rt(1, 2);
  const double r20 = Rt(2, 0), r21 = Rt(2, 1), r22 = Rt(2, 2);
  for (int i = 0; i < n; ++i) {
    const double inv_rho2 = 1.0 / rho2[i];
    const double inv_r2 = 1.0 / (rho2[i] + qz[i] * qz[i]);
    const double k = qz[i] * inv_r2 * rho[i] * inv_rho2;
    const double g00 = -qy[i] * inv_rho2, g01 = qx[i] * inv_rho2;
    const double g10 = -qx[i] * k, g11 = -qy[i] * k, g12 = rho[i] * inv_r2;
    // Rows of J_p = G R^T.
    const double a0 = g00 * r00 + g01 * r10;
    const double a1 = g00 * r01 + g01 * r11;
    const double a2 = g00 * r02 + g01 * r12;
    const double b0 = g10 * r00 + g11 * r10 + g12 * r20;
    const double b1 = g10 * r01 + g11 * r11 + g12 * r21;
    const double b2 = g10 * r02 + g11 * r12 + g12 * r22;
    // Sigma a and Sigma b (column-major Sigma: S[r + 3 c]).
    const double sa0 = S[0][i] * a0 + S[3][i] * a1 + S[6][i] * a2;
    const double sa1 = S[1][i] * a0 + S[4][i] * a1 + S[7][i] * a2;
    const double sa2 = S[2][i] * a0 + S[5][i] * a1 + S[8][i] * a2;
    const double sb0 = S[0][i] * b0 + S[3][i] * b1 + S[6][i] * b2;
    const double sb1 = S[1][i] * b0 + S[4][i] * b1 + S[7][i] * b2;
    const double sb2 = S[2][i] * b0 + S[5][i] * b1 + S[8][i] * b2;
    c00[i] = a0 * sa0 + a1 * sa1 + a2 * sa2 + b00[i];
    c10[i] = b0 * sa0 + b1 * sa1 + b2 * sa2 + b10[i];
    c11[i] = b0 * sb0 + b1 * sb1 + b2 * sb2 + b11[i];
  }
}

// The state of the spots at one pose (R, t): whitening, raw and normalised
// residuals, and the normal matrix of the whitened problem over the spots in
// use, with the scratch storage to compute them.
struct Assessment {
  std::vector<Eigen::Matrix2d> W;   // W^T W = C^-1, C the angular covariance (I when unweighted)
  std::vector<Eigen::Vector2d> raw;  // (az, el) measured - beam, rad
  std::vector<double> norms;         // |W raw|
  // Normal matrix J^T J over the spots in use, in the tangent (dtheta left,
  // scene frame; dt), and the sums of squares over those spots.
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  double chi2 = 0.0, sum_sq_rad = 0.0;
  int used = 0;
  // Scratch: 8 arrays of n doubles (uninitialised); spot indices and angle
  // differences.
  std::unique_ptr<double[]> scratch;
  std::vector<int> index;
  std::vector<double> angles;
};

// W at the pose (R, t), when the spots carry covariances: the angular
// covariance C (AngularCovariances) factored C = L L^T, W = L^-1. A spot on
// the source's Z axis has no direction, and no angular uncertainty.
Status Whiten(const Data& data, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
              Assessment* as) {
  const int n = data.n;
  as->W.resize(n);
  if (!data.weighted) {
    for (Eigen::Matrix2d& W : as->W) W.setIdentity();
    return Status::Ok();
  }
  const Eigen::Matrix3d Rt = R.transpose();
  if (!as->scratch) as->scratch.reset(new double[8 * static_cast<size_t>(n)]);
  double* const w = as->scratch.get();
  double *qx = w, *qy = w + n, *qz = w + 2 * n, *rho2 = w + 3 * n, *rho = w + 4 * n;
  double *c00 = w + 5 * n, *c10 = w + 6 * n, *c11 = w + 7 * n;
  locate_internal::SourceFramePoints(n, data.col(Data::kPx), data.col(Data::kPy),
                                     data.col(Data::kPz), Rt, t, qx, qy, qz, rho2);
  using Map = Eigen::Map<Eigen::ArrayXd>;
  Map(rho, n) = Map(rho2, n).sqrt();
  AngularCovariances(n, data, Rt, qx, qy, qz, rho2, rho, c00, c10, c11);
  // C = L L^T with L = [a 0; b c]; W = L^-1 = [1/a 0; -b/(a c) 1/c], as
  // w00 = 1/a, b = C10 w00, w11 = 1/sqrt(C11 - b^2), w10 = -b w00 w11. One
  // operation at a time over all spots (vectorised), in place.
  Map a(c00, n), b(c10, n), c2(c11, n);
  Map w00(qx, n), w10(qy, n), w11(qz, n);
  a = a.sqrt();
  w00 = a.inverse();
  b *= w00;
  c2 -= b * b;
  w11 = c2.sqrt().inverse();
  w10 = -b * w00 * w11;
  // A usable factor: a > 0, c2 > 0, both finite (checked for all spots at
  // once, then spot by spot for the message).
  const bool all_good = ((a > 0.0) && (c2 > 0.0) && (a < kInf) && (c2 < kInf)).all();
  for (int i = 0; !all_good && i < n; ++i) {
    if (!(a[i] > 0.0 && c2[i] > 0.0) || !std::isfinite(a[i]) || !std::isfinite(c2[i])) {
      return Status::InvalidArgument("spot of beam " + std::to_string(data.beam_ids[i]) +
                                     ": its covariance gives no angular uncertainty "
                                     "(zero or singular across the ray)");
    }
  }
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix2d& W = as->W[i];
    W(0, 0) = w00[i];
    W(0, 1) = 0.0;
    W(1, 0) = w10[i];
    W(1, 1) = w11[i];
  }
  return Status::Ok();
}

// Fills `as` at the pose (R, t): whitening, residuals of every spot (a spot on
// the source's Z axis: raw (pi, pi), norm infinity), and the normal matrix of
// the spots in use, from PoseNormalEquations at x = 0 around (R, t) with D = 1
// (its rotation parameters are then the left perturbation in the scene frame).
Status Assess(const Data& data, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
              const std::vector<char>& use, PoseNormalEquations* problem, Assessment* as) {
  OPL_RETURN_IF_ERROR(Whiten(data, R, t, as));
  const int n = data.n;
  as->raw.assign(n, Eigen::Vector2d::Constant(M_PI));
  as->norms.assign(n, std::numeric_limits<double>::infinity());
  const Eigen::Matrix2d zero = Eigen::Matrix2d::Zero();
  // Every spot, except (rarely) those on the Z axis, which the evaluation
  // refuses; spots not in use count with zero weight.
  const Eigen::Matrix<double, 6, 1> x0 = Eigen::Matrix<double, 6, 1>::Zero();
  double cost = 0.0;
  Eigen::Matrix<double, 6, 1> g;
  for (int pass = 0; pass < 2; ++pass) {
    problem->Reset(R, t, 1.0);
    as->index.clear();
    const Eigen::Matrix3d Rt = R.transpose();
    for (int i = 0; i < n; ++i) {
      if (pass == 1) {
        const Eigen::Vector3d q = Rt * (data.points[i] - t);
        if (!(q.x() * q.x() + q.y() * q.y() > 0.0)) continue;
      }
      problem->AddSpot(data.points[i], data.angles[i], use[i] ? as->W[i] : zero);
      as->index.push_back(i);
    }
    as->angles.resize(2 * as->index.size());
    if (problem->Evaluate(x0.data(), &cost, &as->H, &g, as->angles.data())) break;
    if (pass == 1) return Status::NoSolution("the pose refinement failed");
  }
  as->chi2 = 2.0 * cost;
  as->sum_sq_rad = 0.0;
  as->used = 0;
  for (size_t j = 0; j < as->index.size(); ++j) {
    const int i = as->index[j];
    const Eigen::Vector2d r(as->angles[2 * j], as->angles[2 * j + 1]);
    as->raw[i] = r;
    as->norms[i] = (as->W[i] * r).norm();
    if (use[i]) {
      as->sum_sq_rad += r.squaredNorm();
      ++as->used;
    }
  }
  return Status::Ok();
}

struct RefineOutcome {
  bool ok = false;
  int iterations = 0;
};

// One Levenberg-Marquardt solve of the spots in `use`, each residual whitened
// by W_i and scaled by sqrt(robust_weight_i): SourcePoseCostFunction's problem,
// solved by SolvePoseLevenbergMarquardt (ceres::TinySolver's steps and
// stopping rules on the fused normal equations, pose_normal_equations.h).
RefineOutcome RefineOnce(const Data& data, const std::vector<Eigen::Matrix2d>& W,
                         const std::vector<char>& use, const std::vector<double>& robust_weight,
                         const LocateOptions& options, PoseNormalEquations* problem,
                         Eigen::Matrix3d* R, Eigen::Vector3d* t) {
  const int n = static_cast<int>(data.points.size());
  // TinySolver's rule: stop when |dx| < parameter_tolerance * (|x| + parameter_tolerance).
  // All six parameters are lengths (the rotation as the arc it sweeps at the
  // spots, D dtheta, D the mean distance to the spots), and the origin offset
  // is counted from a reference point D away, so |x| ~ D throughout: the test
  // reads "the step moves the pose by less than parameter_tolerance * D".
  double D = 0.0;
  int used = 0;
  for (int i = 0; i < n; ++i) {
    if (!use[i]) continue;
    D += (data.points[i] - *t).norm();
    ++used;
  }
  D /= static_cast<double>(std::max(1, used));
  RefineOutcome out;
  if (!(D > 0.0) || !std::isfinite(D)) return out;
  const Eigen::Vector3d reference_offset(D, 0.0, 0.0);
  problem->Reset(*R, *t - reference_offset, D);
  for (int i = 0; i < n; ++i) {
    if (!use[i]) continue;
    problem->AddSpot(data.points[i], data.angles[i], std::sqrt(robust_weight[i]) * W[i]);
  }
  Eigen::Matrix<double, 6, 1> x;
  x << 0.0, 0.0, 0.0, reference_offset;
  PoseSolverOptions solver_options;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = std::numeric_limits<double>::min();  // step test only
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.cost_threshold = 0.0;
  // Start close to Gauss-Newton: the RANSAC pose is near the optimum, and
  // LM damping of 1e-4 of the diagonal would stall the solve along the weak
  // rotation-translation direction. Failed steps still raise the damping.
  solver_options.initial_trust_region_radius = 1e12;
  const PoseSolverSummary summary = SolvePoseLevenbergMarquardt(*problem, solver_options, &x);
  out.iterations = summary.iterations;
  out.ok = !summary.evaluation_failed && x.allFinite() && std::isfinite(summary.final_cost);
  if (out.ok) {
    *R = problem->Rotation(x.data());
    *t = problem->Origin(x.data());
  }
  return out;
}

// d rho / d s of the robust loss at s = |W r|^2 (IRLS weight).
double RobustWeight(RobustLoss loss, double a, double s) {
  switch (loss) {
    case RobustLoss::kNone: return 1.0;
    case RobustLoss::kHuber: return s <= a * a ? 1.0 : a / std::sqrt(s);
    case RobustLoss::kCauchy: return 1.0 / (1.0 + s / (a * a));
  }
  return 1.0;
}

// Least squares, or with a robust loss, iteratively reweighted least squares
// (the fixed point is the M-estimate of that loss).
RefineOutcome Refine(const Data& data, const std::vector<Eigen::Matrix2d>& W,
                     const std::vector<char>& use, const LocateOptions& options,
                     PoseNormalEquations* problem, Eigen::Matrix3d* R, Eigen::Vector3d* t) {
  const int n = static_cast<int>(data.points.size());
  std::vector<double> weight(n, 1.0);
  const double a = !data.weighted ? options.loss_scale_unweighted_rad : options.loss_scale;
  RefineOutcome total;
  const int rounds = options.loss == RobustLoss::kNone ? 1 : 20;
  for (int round = 0; round < rounds; ++round) {
    const RefineOutcome once = RefineOnce(data, W, use, weight, options, problem, R, t);
    total.iterations += once.iterations;
    total.ok = once.ok;
    if (!once.ok || options.loss == RobustLoss::kNone) break;
    double change = 0.0;
    const Eigen::Matrix3d Rt = R->transpose();
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d r =
          locate_internal::AngleDifference(Rt * (data.points[i] - *t), data.angles[i]);
      const double w = RobustWeight(options.loss, a, (W[i] * r).squaredNorm());
      change = std::max(change, std::abs(w - weight[i]));
      weight[i] = w;
    }
    if (change < 1e-9) break;
  }
  return total;
}

}  // namespace

Status LocateOptions::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("LocateOptions." + field + " = " + FormatNumber(value, 6) + ": " + rule);
  };
  if (!(loss_scale > 0.0 && std::isfinite(loss_scale))) return bad("loss_scale", loss_scale, "must be > 0");
  if (!(loss_scale_unweighted_rad > 0.0 && std::isfinite(loss_scale_unweighted_rad))) {
    return bad("loss_scale_unweighted_rad", loss_scale_unweighted_rad, "must be > 0");
  }
  if (!(ransac_inlier_threshold_rad > 0.0 && ransac_inlier_threshold_rad < 0.5)) {
    return bad("ransac_inlier_threshold_rad", ransac_inlier_threshold_rad, "must be in (0, 0.5)");
  }
  if (ransac_max_iterations < 1) return bad("ransac_max_iterations", ransac_max_iterations, "must be >= 1");
  if (!(ransac_confidence > 0.0 && ransac_confidence < 1.0)) {
    return bad("ransac_confidence", ransac_confidence, "must be in (0, 1)");
  }
  if (!(outlier_threshold > 0.0 && std::isfinite(outlier_threshold))) {
    return bad("outlier_threshold", outlier_threshold, "must be > 0");
  }
  if (!(min_unweighted_sigma_rad > 0.0 && std::isfinite(min_unweighted_sigma_rad))) {
    return bad("min_unweighted_sigma_rad", min_unweighted_sigma_rad, "must be > 0");
  }
  if (!(min_inlier_fraction > 0.0 && min_inlier_fraction <= 1.0)) {
    return bad("min_inlier_fraction", min_inlier_fraction, "must be in (0, 1]");
  }
  if (max_iterations < 1) return bad("max_iterations", max_iterations, "must be >= 1");
  if (!(gradient_tolerance >= 0.0)) return bad("gradient_tolerance", gradient_tolerance, "must be >= 0");
  if (!(parameter_tolerance > 0.0 && parameter_tolerance < 1e-2)) {
    return bad("parameter_tolerance", parameter_tolerance, "must be in (0, 0.01)");
  }
  if (initial_scene_from_source &&
      (!initial_scene_from_source->translation.allFinite() ||
       !initial_scene_from_source->rotation.coeffs().allFinite())) {
    return Status::InvalidArgument("LocateOptions.initial_scene_from_source is not finite");
  }
  return Status::Ok();
}

std::vector<int> LocateResult::OutlierBeamIds() const {
  std::vector<int> ids;
  for (const SpotResidual& r : residuals) {
    if (r.outlier) ids.push_back(r.beam_id);
  }
  return ids;
}

std::string LocateResult::BriefReport() const {
  std::ostringstream os;
  const Eigen::Vector3d& o = scene_from_source.translation;
  os << "origin (" << FormatNumber(o.x(), 6) << ", " << FormatNumber(o.y(), 6) << ", " << FormatNumber(o.z(), 6) << ")"
     << " +- (" << FormatNumber(std::sqrt(origin_covariance(0, 0)), 6) << ", "
     << FormatNumber(std::sqrt(origin_covariance(1, 1)), 6) << ", " << FormatNumber(std::sqrt(origin_covariance(2, 2)), 6)
     << "), rms " << FormatNumber(rms_residual_rad * 1e6, 6) << " urad, " << num_inliers << "/" << num_spots
     << " spots used, " << (num_spots - num_inliers) << " outliers";
  return os.str();
}

Result<LocateResult> LocateSource(const BeamPattern& pattern,
                                  const std::vector<SpotObservation>& spots,
                                  const LocateOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  OPL_RETURN_IF_ERROR(pattern.Validate());
  Data data;
  OPL_RETURN_IF_ERROR(CheckSpots(pattern, spots, &data));
  const int n = static_cast<int>(data.points.size());
  if (n < 4) {
    return Status::NoSolution("too few spots: " + std::to_string(n) +
                              " given, at least 4 are needed to fix the 6 pose parameters");
  }
  // Degenerate geometry: spots (nearly) on one line leave a rotation free.
  {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : data.points) mean += p;
    mean /= n;
    double sxx = 0.0, sxy = 0.0, sxz = 0.0, syy = 0.0, syz = 0.0, szz = 0.0;
    for (const auto& p : data.points) {
      const double x = p.x() - mean.x(), y = p.y() - mean.y(), z = p.z() - mean.z();
      sxx += x * x;
      sxy += x * y;
      sxz += x * z;
      syy += y * y;
      syz += y * z;
      szz += z * z;
    }
    Eigen::Matrix3d scatter;
    scatter << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter, Eigen::EigenvaluesOnly);
    const Eigen::Vector3d ev = eig.eigenvalues().cwiseMax(0.0);
    if (!(std::sqrt(ev(1)) > 1e-3 * std::sqrt(ev(2)))) {
      return Status::NoSolution("degenerate spots: all " + std::to_string(n) +
                                " spots lie on one line (within 0.1% of their extent); "
                                "the rotation about that line is undetermined");
    }
  }

  LocateResult result;
  result.num_spots = n;
  result.weighted = data.weighted;

  // 1. Initial pose: the user's guess when it explains the data, else RANSAC.
  PoseRt init;  // source_from_scene
  bool have_init = false;
  const double th2 = std::pow(std::sin(options.ransac_inlier_threshold_rad), 2);
  std::vector<double> e2(n);
  if (options.initial_scene_from_source) {
    const Rigid3d sfs = options.initial_scene_from_source->Inverse();
    init.R = sfs.RotationMatrix();
    init.t = sfs.translation;
    AngleErrorsSq(data, 0, n, init, e2.data());
    int inliers = 0;
    for (int i = 0; i < n; ++i) inliers += e2[i] < th2;
    have_init = inliers >= 0.9 * n;
  }
  std::vector<char> use(n, 1);
  if (!have_init) {
    RansacOutcome ransac;
    if (!Ransac(data, options, &ransac)) {
      return Status::NoSolution("no pose explains the spots: RANSAC found at most " +
                                std::to_string(ransac.num_inliers) + " consistent spots of " +
                                std::to_string(n) + " (threshold " +
                                FormatNumber(options.ransac_inlier_threshold_rad, 6) + " rad)");
    }
    init = ransac.pose;
    result.ransac_iterations = ransac.iterations;
  }
  AngleErrorsSq(data, 0, n, init, e2.data());
  for (int i = 0; i < n; ++i) use[i] = e2[i] < th2;

  // Parameters: scene_from_source.
  Eigen::Matrix3d R = init.R.transpose();
  Eigen::Vector3d t = -(R * init.t);
  PoseNormalEquations problem;
  problem.Reserve(n);
  Assessment assessed;
  OPL_RETURN_IF_ERROR(Whiten(data, R, t, &assessed));

  // 2. Refine; flag outliers; refine again until the inlier set is stable.
  const double sigma_floor = result.weighted ? 1.0 : options.min_unweighted_sigma_rad;
  std::vector<double> inlier_norms;
  inlier_norms.reserve(n);
  std::vector<char> next(n);
  bool stable = false;
  for (int round = 0; round < 6; ++round) {
    const int used = static_cast<int>(std::count(use.begin(), use.end(), 1));
    if (used < 4 || used < options.min_inlier_fraction * n) {
      return Status::NoSolution("no pose explains enough spots: " + std::to_string(used) +
                                " of " + std::to_string(n) + " are consistent (at least " +
                                FormatNumber(100.0 * options.min_inlier_fraction, 6) + "% needed)");
    }
    const RefineOutcome refined = Refine(data, assessed.W, use, options, &problem, &R, &t);
    if (!refined.ok) return Status::NoSolution("the pose refinement failed");
    result.solver_iterations += refined.iterations;
    OPL_RETURN_IF_ERROR(Assess(data, R, t, use, &problem, &assessed));

    inlier_norms.clear();
    for (int i = 0; i < n; ++i) {
      if (use[i]) inlier_norms.push_back(assessed.norms[i]);
    }
    std::nth_element(inlier_norms.begin(), inlier_norms.begin() + inlier_norms.size() / 2,
                     inlier_norms.end());
    // Median of a 2D Gaussian norm is sigma sqrt(2 ln 2).
    const double sigma = std::max(sigma_floor, inlier_norms[inlier_norms.size() / 2] / 1.1774100225154747);
    const double threshold = options.outlier_threshold * sigma;
    for (int i = 0; i < n; ++i) next[i] = assessed.norms[i] <= threshold;
    if (next == use) {  // the inlier set is stable
      stable = true;
      break;
    }
    use = next;
  }
  {
    const int used = static_cast<int>(std::count(use.begin(), use.end(), 1));
    if (used < 4 || used < options.min_inlier_fraction * n) {
      return Status::NoSolution("no pose explains enough spots: " + std::to_string(used) +
                                " of " + std::to_string(n) + " are consistent after refinement");
    }
  }
  // The normal matrix and sums over the final inlier set (already there when
  // the set came out stable).
  if (!stable) OPL_RETURN_IF_ERROR(Assess(data, R, t, use, &problem, &assessed));

  // 3. Covariance in the tangent (dtheta left, scene frame; dt) at the solution.
  const Eigen::Matrix<double, 6, 6>& H = assessed.H;
  const double chi2 = assessed.chi2, sum_sq_rad = assessed.sum_sq_rad;
  const int used = assessed.used;
  const int dof = 2 * used - 6;
  // Rotations are in radians, the origin in scene units: the test of
  // singularity is made on H scaled to a unit diagonal (D H D, D_ii =
  // 1 / sqrt(H_ii)), which does not change when the scene unit does (the same
  // spots in micrometres or in metres, issue 19 item 4).
  Eigen::Matrix<double, 6, 1> equilibrate;
  for (int i = 0; i < 6; ++i) {
    equilibrate(i) = H(i, i) > 0.0 && std::isfinite(H(i, i)) ? 1.0 / std::sqrt(H(i, i)) : 0.0;
  }
  const Eigen::Matrix<double, 6, 6> Hs = equilibrate.asDiagonal() * H * equilibrate.asDiagonal();
  Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(Hs);
  const Eigen::Matrix<double, 6, 6> cov = equilibrate.asDiagonal() *
                                          ldlt.solve(Eigen::Matrix<double, 6, 6>::Identity()) *
                                          equilibrate.asDiagonal();
  if (!(equilibrate.minCoeff() > 0.0) || ldlt.info() != Eigen::Success || !cov.allFinite() ||
      !(ldlt.vectorD().minCoeff() > 0.0) ||
      ldlt.vectorD().minCoeff() < 1e-14 * ldlt.vectorD().maxCoeff()) {
    return Status::NoSolution("degenerate spots: the pose is not determined by them "
                              "(normal matrix singular)");
  }
  result.variance_factor = dof > 0 ? chi2 / dof : 0.0;
  result.covariance = cov;
  if (!result.weighted) {
    result.covariance *= result.variance_factor;
    result.covariance_scaled = true;
  }
  result.scene_from_source = Rigid3d(R, t);
  result.origin_covariance = result.covariance.bottomRightCorner<3, 3>();
  result.rotation_xyz_rad = XyzAnglesRadFromRotation(R);
  const Eigen::Matrix3d J_xyz = XyzAnglesJacobianWrtLeftPerturbation(result.rotation_xyz_rad);
  result.rotation_xyz_covariance = J_xyz * result.covariance.topLeftCorner<3, 3>() * J_xyz.transpose();
  result.num_inliers = used;
  result.rms_residual_rad = std::sqrt(sum_sq_rad / (2.0 * used));
  result.residuals.resize(n);
  for (int i = 0; i < n; ++i) {
    result.residuals[i] = {data.beam_ids[i], assessed.raw[i], assessed.norms[i], !use[i]};
  }
  return result;
}

}  // namespace opl
