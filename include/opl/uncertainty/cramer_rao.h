// The Cramer-Rao bound of a source's pose and of the lengths between origins,
// and the first-order covariance of each spot weighting (issue 4;
// docs/uncertainty.md, "The Cramer-Rao bound").
//
// The measurement model. Spot k of a source is measured at
//   y_k = p_k + e_k,   p_k = o + t_k R d_k,   e_k ~ N(0, Sigma_k),
// with R, o the pose (scene_from_source), d_k the calibrated direction of its
// beam (exact here) and t_k > 0 the unknown distance to the unknown surface.
// The unknowns are the pose x = (dtheta, do) (left rotation perturbation in the
// scene frame, rad; origin, scene units: LocateResult's convention) and one
// nuisance t_k per spot. With A_k = dp_k/dx = [ -[p_k - o]x , I ] and
// u_k = dp_k/dt_k = R d_k, the Fisher information of the pose, the t_k
// eliminated (Schur complement), is
//   I(x) = sum_k A_k^T P_k A_k,
//   P_k  = Sigma_k^-1 - Sigma_k^-1 u_k (u_k^T Sigma_k^-1 u_k)^-1 u_k^T Sigma_k^-1,
// and no unbiased estimator of the pose has a covariance below I(x)^-1. This
// bound is computed from 3D geometry only: no angle appears in it.
//
// The angular solve (LocateSource) uses the residuals r_k = azel(R^T (y_k - o))
// - azel(d_k). To first order at the truth, r_k = F_k e_k - F_k A_k dx with
// F_k = J_azel(q_k) R^T (2 x 3, F_k u_k = 0). Weighted by W_k, its estimate
// has the covariance
//   C_W = H^-1 (sum_k G_k^T W_k F_k Sigma_k F_k^T W_k G_k) H^-1,
//   G_k = F_k A_k,   H = sum_k G_k^T W_k G_k.
//  - efficient weighting, W_k = (F_k Sigma_k F_k^T)^-1 (each spot's covariance
//    carried into its angular residuals: LocateSource with cov_in_scene): then
//    F_k^T W_k F_k = P_k (F_k has rank 2 and null space u_k), so C_W = I(x)^-1:
//    the angular solve reaches the bound.
//  - unweighted, W_k = I (spots without covariance): the sandwich above, >= the
//    bound; how much above depends on how unequal the angular noise of the spots
//    is (anisotropic noise, spots at different distances or incidence angles).
//
// For a pair of independently located sources, L = |o_i - o_j| has
// var(L) = g^T (C_i + C_j) g, g = (o_i - o_j) / L, for either matrix.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"

namespace opl {

enum class SpotWeighting {
  kEfficient,   // W_k = (F_k Sigma_k F_k^T)^-1: spot covariances in the residuals
  kUnweighted,  // W_k = I: plain angular residuals
};

// "efficient" / "unweighted".
const char* SpotWeightingName(SpotWeighting weighting);
// Parses "efficient" or "unweighted"; InvalidArgument naming the text otherwise.
Result<SpotWeighting> ParseSpotWeighting(const std::string& text);

// The noise-free points of one source's spots and their covariances.
struct SourceSpotGeometry {
  Rigid3d scene_from_source;                  // the true pose
  std::vector<Eigen::Vector3d> points_in_scene;  // true spot positions p_k
  std::vector<Eigen::Matrix3d> covariances;   // Sigma_k, one per point (scene units^2)
};

// I(x)^-1, the 6 x 6 bound on the covariance of (dtheta, do). NoSolution when
// I(x) is singular (fewer than 3 spots, all spots on one line through o, ...);
// InvalidArgument when sizes differ, a point coincides with the origin or a
// covariance is not symmetric positive definite.
Result<Eigen::Matrix<double, 6, 6>> PoseCramerRaoBound(const SourceSpotGeometry& geometry);

// C_W of the angular solve with the given weighting (see above), same errors.
Result<Eigen::Matrix<double, 6, 6>> PoseFirstOrderCovariance(const SourceSpotGeometry& geometry,
                                                              SpotWeighting weighting);

// sqrt(g^T (C_i + C_j) g) for origins o_i, o_j with 3 x 3 covariances C_i, C_j.
double LengthStd(const Eigen::Vector3d& origin_i, const Eigen::Matrix3d& cov_i,
                 const Eigen::Vector3d& origin_j, const Eigen::Matrix3d& cov_j);

}  // namespace opl
