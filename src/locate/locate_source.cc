#include "opl/locate/locate_source.h"

#include "opl/core/format.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <sstream>

#include <ceres/tiny_solver.h>
#include <ceres/tiny_solver_cost_function_adapter.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "opl/geometry/rotation.h"
#include "opl/geometry/spherical.h"
#include "opl/locate/source_pose_cost_function.h"
#include "opl/locate/p3p.h"

namespace opl {
namespace {

// The data of one locate, in flat arrays.
struct Data {
  std::vector<int> beam_ids;
  std::vector<Eigen::Vector3d> points;    // scene
  std::vector<Eigen::Vector3d> bearings;  // unit, source frame
  std::vector<const Beam*> beams;
  std::vector<Eigen::Matrix3d> covs;      // empty when unweighted
};

Status CheckSpots(const BeamPattern& pattern, const std::vector<SpotObservation>& spots,
                  Data* data) {
  std::vector<char> seen(static_cast<size_t>(pattern.beams_per_side()) * pattern.beams_per_side() + 1, 0);
  data->beam_ids.reserve(spots.size());
  data->points.reserve(spots.size());
  data->bearings.reserve(spots.size());
  data->beams.reserve(spots.size());
  int with_cov = 0;
  for (size_t i = 0; i < spots.size(); ++i) {
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
      if (!C.allFinite() || (C - C.transpose()).cwiseAbs().maxCoeff() > 1e-9 * (1.0 + C.norm())) {
        return Status::InvalidArgument(which() + ": covariance is not finite and symmetric");
      }
      // Positive semi-definite: every principal minor >= 0 (to round-off).
      const double tol = -1e-12 * C.cwiseAbs().maxCoeff() * C.cwiseAbs().maxCoeff();
      const bool psd = C(0, 0) >= 0.0 && C(1, 1) >= 0.0 && C(2, 2) >= 0.0 &&
                       C(0, 0) * C(1, 1) - C(0, 1) * C(0, 1) >= tol &&
                       C(0, 0) * C(2, 2) - C(0, 2) * C(0, 2) >= tol &&
                       C(1, 1) * C(2, 2) - C(1, 2) * C(1, 2) >= tol &&
                       C.determinant() >= tol * C.cwiseAbs().maxCoeff();
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
  if (with_cov != 0 && with_cov != static_cast<int>(spots.size())) {
    return Status::InvalidArgument("either every spot or no spot must carry a covariance (" +
                                   std::to_string(with_cov) + " of " +
                                   std::to_string(spots.size()) + " do)");
  }
  if (with_cov > 0) {
    for (const SpotObservation& s : spots) data->covs.push_back(*s.cov_in_scene);
  }
  return Status::Ok();
}

// (az, el) of the spot seen from the pose, minus those of the beam direction
// d (unit), radians; the same relative-angle form as SourcePoseCostFunction.
Eigen::Vector2d AngularResidual(const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                const Eigen::Vector3d& p, const Eigen::Vector3d& d) {
  const Eigen::Vector3d q = R.transpose() * (p - t);
  const double cos_el = std::hypot(d.x(), d.y());
  const double cos_az = d.x() / cos_el, sin_az = d.y() / cos_el;
  const double rho = std::hypot(q.x(), q.y());
  return Eigen::Vector2d(
      SmallAngleAtan2(q.y() * cos_az - q.x() * sin_az, q.x() * cos_az + q.y() * sin_az),
      SmallAngleAtan2(q.z() * cos_el - rho * d.z(), rho * cos_el + q.z() * d.z()));
}

// Squared sine of the angle between bearing f (unit) and q; 1 when behind.
inline double AngleErrorSq(const Eigen::Vector3d& f, const Eigen::Vector3d& q) {
  const double d = f.dot(q);
  if (!(d > 0.0)) return 1.0;
  return f.cross(q).squaredNorm() / q.squaredNorm();
}

struct RansacOutcome {
  PoseRt pose;  // source_from_scene
  int num_inliers = 0;
  int iterations = 0;
};

bool Ransac(const Data& data, const LocateOptions& options, RansacOutcome* out) {
  const int n = static_cast<int>(data.points.size());
  const double th2 = std::pow(std::sin(options.ransac_inlier_threshold_rad), 2);
  std::mt19937_64 rng(options.ransac_seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  double best_cost = std::numeric_limits<double>::infinity();
  int best_inliers = 0;
  long needed = options.ransac_max_iterations;
  std::array<PoseRt, 4> solutions;
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
      for (int k = 0; k < n && cost < best_cost; ++k) {
        const double e2 = AngleErrorSq(data.bearings[k], pose.R * data.points[k] + pose.t);
        if (e2 < th2) {
          cost += e2;
          ++inliers;
        } else {
          cost += th2;
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

// W with W^T W = C^-1 for the angular covariance C of every spot at a pose.
Status Whitening(const Data& data, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                 std::vector<Eigen::Matrix2d>* W) {
  const int n = static_cast<int>(data.points.size());
  W->assign(n, Eigen::Matrix2d::Identity());
  if (data.covs.empty()) return Status::Ok();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d q = R.transpose() * (data.points[i] - t);
    const Eigen::Matrix<double, 2, 3> Jp = AzElJacobian(q) * R.transpose();
    Eigen::Matrix2d C = Jp * data.covs[i] * Jp.transpose();
    if (data.beams[i]->cov_azel_rad2) C += *data.beams[i]->cov_azel_rad2;
    // C = L L^T with L = [a 0; b c]; W = L^-1 = [1/a 0; -b/(a c) 1/c].
    const double a = C(0, 0) > 0.0 ? std::sqrt(C(0, 0)) : 0.0;
    const double b = a > 0.0 ? C(1, 0) / a : 0.0;
    const double c2 = C(1, 1) - b * b;
    if (!(a > 0.0 && c2 > 0.0) || !std::isfinite(a) || !std::isfinite(c2)) {
      return Status::InvalidArgument("spot of beam " + std::to_string(data.beam_ids[i]) +
                                     ": its covariance gives no angular uncertainty "
                                     "(zero or singular across the ray)");
    }
    const double c = std::sqrt(c2);
    (*W)[i] << 1.0 / a, 0.0, -b / (a * c), 1.0 / c;
  }
  return Status::Ok();
}

// Normalised residual norm of every spot at a pose.
std::vector<double> NormalizedResiduals(const Data& data, const std::vector<Eigen::Matrix2d>& W,
                                        const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                        std::vector<Eigen::Vector2d>* raw) {
  const int n = static_cast<int>(data.points.size());
  std::vector<double> out(n);
  raw->resize(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d q = R.transpose() * (data.points[i] - t);
    if (!(q.x() * q.x() + q.y() * q.y() > 0.0)) {
      (*raw)[i] = Eigen::Vector2d::Constant(M_PI);
      out[i] = std::numeric_limits<double>::infinity();
      continue;
    }
    (*raw)[i] = AngularResidual(R, t, data.points[i], data.bearings[i]);
    out[i] = (W[i] * (*raw)[i]).norm();
  }
  return out;
}

struct RefineOutcome {
  bool ok = false;
  int iterations = 0;
};

// One Levenberg-Marquardt solve (ceres::TinySolver) of the spots in `use`,
// each residual whitened by W_i and scaled by sqrt(robust_weight_i).
RefineOutcome RefineOnce(const Data& data, const std::vector<Eigen::Matrix2d>& W,
                         const std::vector<char>& use, const std::vector<double>& robust_weight,
                         const LocateOptions& options, Eigen::Matrix3d* R, Eigen::Vector3d* t) {
  std::vector<SourcePoseCostFunction::Spot> spots;
  spots.reserve(data.points.size());
  for (size_t i = 0; i < data.points.size(); ++i) {
    if (!use[i]) continue;
    spots.push_back({data.points[i], data.bearings[i], std::sqrt(robust_weight[i]) * W[i]});
  }
  // TinySolver stops when |dx| < parameter_tolerance * (|x| + parameter_tolerance).
  // All six parameters are lengths (the rotation as the arc it sweeps at the
  // spots, D dtheta, D the mean distance to the spots), and the origin offset
  // is counted from a reference point D away, so |x| ~ D throughout: the test
  // reads "the step moves the pose by less than parameter_tolerance * D".
  double D = 0.0;
  for (const auto& sp : spots) D += (sp.point_in_scene - *t).norm();
  D /= static_cast<double>(std::max<size_t>(1, spots.size()));
  RefineOutcome out;
  if (!(D > 0.0) || !std::isfinite(D)) return out;
  const Eigen::Vector3d reference_offset(D, 0.0, 0.0);
  const SourcePoseCostFunction cost(std::move(spots), *R, *t - reference_offset, D);
  Eigen::Matrix<double, 6, 1> x;
  x << 0.0, 0.0, 0.0, reference_offset;
  using Adapter = ceres::TinySolverCostFunctionAdapter<Eigen::Dynamic, 6>;
  const Adapter function(cost);
  ceres::TinySolver<Adapter> solver;
  solver.options.max_num_iterations = options.max_iterations;
  solver.options.function_tolerance = std::numeric_limits<double>::min();  // step test only
  solver.options.gradient_tolerance = options.gradient_tolerance;
  solver.options.parameter_tolerance = options.parameter_tolerance;
  solver.options.cost_threshold = 0.0;
  // Start close to Gauss-Newton: the RANSAC pose is near the optimum, and
  // LM damping of 1e-4 of the diagonal would stall the solve along the weak
  // rotation-translation direction. Failed steps still raise the damping.
  solver.options.initial_trust_region_radius = 1e12;
  const auto& summary = solver.Solve(function, &x);
  out.iterations = summary.iterations;
  out.ok = x.allFinite() && std::isfinite(summary.final_cost);
  if (out.ok) {
    *R = cost.Rotation(x.data());
    *t = cost.Origin(x.data());
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
                     Eigen::Matrix3d* R, Eigen::Vector3d* t) {
  const int n = static_cast<int>(data.points.size());
  std::vector<double> weight(n, 1.0);
  const double a = data.covs.empty() ? options.loss_scale_unweighted_rad : options.loss_scale;
  RefineOutcome total;
  const int rounds = options.loss == RobustLoss::kNone ? 1 : 20;
  for (int round = 0; round < rounds; ++round) {
    const RefineOutcome once = RefineOnce(data, W, use, weight, options, R, t);
    total.iterations += once.iterations;
    total.ok = once.ok;
    if (!once.ok || options.loss == RobustLoss::kNone) break;
    double change = 0.0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d r =
          AngularResidual(*R, *t, data.points[i], data.bearings[i]);
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
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const auto& p : data.points) scatter += (p - mean) * (p - mean).transpose();
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
  result.weighted = !data.covs.empty();

  // 1. Initial pose: the user's guess when it explains the data, else RANSAC.
  PoseRt init;  // source_from_scene
  bool have_init = false;
  const double th2 = std::pow(std::sin(options.ransac_inlier_threshold_rad), 2);
  if (options.initial_scene_from_source) {
    const Rigid3d sfs = options.initial_scene_from_source->Inverse();
    init.R = sfs.RotationMatrix();
    init.t = sfs.translation;
    int inliers = 0;
    for (int i = 0; i < n; ++i) {
      inliers += AngleErrorSq(data.bearings[i], init.R * data.points[i] + init.t) < th2;
    }
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
  for (int i = 0; i < n; ++i) {
    use[i] = AngleErrorSq(data.bearings[i], init.R * data.points[i] + init.t) < th2;
  }

  // Parameters: scene_from_source.
  Eigen::Matrix3d R = init.R.transpose();
  Eigen::Vector3d t = -(R * init.t);
  std::vector<Eigen::Matrix2d> W;
  OPL_RETURN_IF_ERROR(Whitening(data, R, t, &W));

  // 2. Refine; flag outliers; refine again until the inlier set is stable.
  const double sigma_floor = result.weighted ? 1.0 : options.min_unweighted_sigma_rad;
  std::vector<double> norms;
  std::vector<Eigen::Vector2d> raw;
  for (int round = 0; round < 6; ++round) {
    const int used = static_cast<int>(std::count(use.begin(), use.end(), 1));
    if (used < 4 || used < options.min_inlier_fraction * n) {
      return Status::NoSolution("no pose explains enough spots: " + std::to_string(used) +
                                " of " + std::to_string(n) + " are consistent (at least " +
                                FormatNumber(100.0 * options.min_inlier_fraction, 6) + "% needed)");
    }
    const RefineOutcome refined = Refine(data, W, use, options, &R, &t);
    if (!refined.ok) return Status::NoSolution("the pose refinement failed");
    result.solver_iterations += refined.iterations;
    OPL_RETURN_IF_ERROR(Whitening(data, R, t, &W));

    norms = NormalizedResiduals(data, W, R, t, &raw);
    std::vector<double> inlier_norms;
    for (int i = 0; i < n; ++i) {
      if (use[i]) inlier_norms.push_back(norms[i]);
    }
    std::nth_element(inlier_norms.begin(), inlier_norms.begin() + inlier_norms.size() / 2,
                     inlier_norms.end());
    // Median of a 2D Gaussian norm is sigma sqrt(2 ln 2).
    const double sigma = std::max(sigma_floor, inlier_norms[inlier_norms.size() / 2] / 1.1774100225154747);
    const double threshold = options.outlier_threshold * sigma;
    std::vector<char> next(n);
    for (int i = 0; i < n; ++i) next[i] = norms[i] <= threshold;
    if (next == use) break;  // the inlier set is stable
    use = next;
  }
  {
    const int used = static_cast<int>(std::count(use.begin(), use.end(), 1));
    if (used < 4 || used < options.min_inlier_fraction * n) {
      return Status::NoSolution("no pose explains enough spots: " + std::to_string(used) +
                                " of " + std::to_string(n) + " are consistent after refinement");
    }
  }

  // 3. Covariance in the tangent (dtheta left, scene frame; dt) at the solution.
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  double chi2 = 0.0, sum_sq_rad = 0.0;
  int used = 0;
  for (int i = 0; i < n; ++i) {
    if (!use[i]) continue;
    const Eigen::Vector3d u = data.points[i] - t;
    const Eigen::Vector3d q = R.transpose() * u;
    Eigen::Matrix<double, 3, 6> dq;
    dq.leftCols<3>() = R.transpose() * Skew(u);
    dq.rightCols<3>() = -R.transpose();
    const Eigen::Matrix<double, 2, 6> J = W[i] * AzElJacobian(q) * dq;
    H.noalias() += J.transpose() * J;
    chi2 += (W[i] * raw[i]).squaredNorm();
    sum_sq_rad += raw[i].squaredNorm();
    ++used;
  }
  const int dof = 2 * used - 6;
  Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
  const Eigen::Matrix<double, 6, 6> cov = ldlt.solve(Eigen::Matrix<double, 6, 6>::Identity());
  if (ldlt.info() != Eigen::Success || !cov.allFinite() || !(ldlt.vectorD().minCoeff() > 0.0) ||
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
    result.residuals[i] = {data.beam_ids[i], raw[i], norms[i], !use[i]};
  }
  return result;
}

}  // namespace opl
