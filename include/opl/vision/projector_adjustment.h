// Projector adjustment: the bundle adjustment with the laser module as a
// calibrated projector, so that the adjusted scene comes out metric
// (docs/multiview.md, "The projector model").
//
// The two-step path (pipeline/measure_images.h) adjusts cameras and points in
// an unscaled frame, locates each grid from its triangulated spots and
// scales everything by s = L_cal / L_photo afterwards. Here the module's
// calibration enters the adjustment itself:
//
// Unknowns: every camera pose cam_from_scene (intrinsics held: calibrated
// cameras), every tag point (corner) in the scene, per placement m of the
// module its pose scene_from_module_m, per spot one depth (mm) along its
// calibrated beam, and the calibration's own parameters where it gives them
// an uncertainty: each beam's (az, el) (Beam::cov_azel_rad2), each source's
// rotation module_from_source (SourceCalibrationQuality::
// rotation_xyz_cov_rad2), and one length factor lambda of the module (the
// separations' u_length_mm). The module frame is the calibration frame moved
// to the centroid of the calibrated origins; source s's origin there is
// lambda o_s.
//
// Residuals (all whitened, so that the cost is chi^2 / 2):
//  - each tag corner observation: L^-1 (pi(K, X) - u) (ReprojectionCostFunctor);
//  - each spot observation: the same for the spot at
//      p_scene = scene_from_module_m (R_s depth d(az_b, el_b) + lambda o_s)
//    (ProjectorSpotCostFunction, analytic Jacobians);
//  - the calibration as a prior: beams L_b^-1 ((az, el) - (az, el)_cal),
//    source rotations L_s^-1 Log(R_s R_s,cal^T), separations
//    (lambda |o_a - o_b| - L_ab) / u(L_ab).
// A block the calibration gives no uncertainty for is held at its value.
//
// Gauge: the module fixes the scale; the remaining six degrees (a rigid
// motion of everything) float in the solve (Levenberg-Marquardt's damping
// holds them) and are then fixed by a three-point datum: the output frame has
// its origin at A, X towards B, XY plane through C, where A, B, C are the
// means of three sets of tag points (e.g. the four corners of three tags).
// Nothing changes scale: the output is in millimetres.
//
// Linear solver: Schur complement with the depths and the tag points in
// elimination group 0 (SPARSE_SCHUR with SuiteSparse, else DENSE_SCHUR).
//
// Covariances (first order, the observations' covariances taken as true,
// then enlarged by the variance factor when it exceeds 1, see
// ProjectorAdjustmentOptions::scale_by_variance_factor):
// H = J^T J at the solution, the depths eliminated (S = A - B D^-1 B^T, D
// diagonal), S scaled to unit diagonal (P S P, P = diag(S)^-1/2) and its
// pseudo-inverse taken with its six gauge directions dropped: G = P (P S
// P)^+ P is a generalised inverse of S, and any generalised inverse gives
// the same covariance of a gauge-free quantity,
// propagated to the datum frame through F(X) = R(A, B, C) (X - A) with A, B,
// C's errors included.
//
// The scale factor s: the factor that the unscaled solution would need, i.e.
// s = |B - A| (mm, adjusted) / options.unscaled_datum_length (|B - A| in the
// unscaled solution's units), and u(s) = u(|B - A|) / unscaled_datum_length
// from the covariance above.
//
// Several placements of the module (each a set of shots) enter one
// adjustment: one pose per placement, the calibration shared.
//
// Errors (Status, never an abort): InvalidArgument naming the field for bad
// options, a spot naming an unknown placement, source or beam, a spot
// without observations, an observation with a bad camera index, a
// non-positive-definite covariance, intrinsics not held constant, a constant
// pose or point (the datum fixes the gauge), a datum set naming a bad point;
// NoSolution when a point is behind a camera at the start or the solver
// fails. The covariance's failure (a degenerate network) is reported in
// covariance_method with the covariances left empty, not as an error.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/model/module_calibration.h"
#include "opl/vision/bundle_adjustment.h"

namespace opl {

// One placement of the module: a set of shots in which it stood still.
struct ProjectorPlacement {
  std::string name;
  Rigid3d scene_from_module;  // start, mm; module frame: header comment
};

struct ProjectorSpotObservation {
  int camera = -1;  // into bundle.cameras
  Eigen::Vector2d pixel_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Identity();  // symmetric positive definite
};

// One identified laser spot: its beam, its placement and where it was seen.
struct ProjectorSpot {
  int placement = 0;   // into ProjectorAdjustmentData::placements
  std::string source;  // a calibrated source
  int beam_id = 0;     // a beam of that source's pattern
  double depth_mm = 0.0;  // start: distance from the origin along the beam, > 0
  std::vector<ProjectorSpotObservation> observations;  // at least one
};

struct ProjectorAdjustmentData {
  // Intrinsics (held constant), camera poses (start, mm), the tag points
  // (start, mm) and their observations. Poses and points must not be
  // constant (the datum fixes the gauge).
  BundleData bundle;
  ModuleCalibration calibration;  // in millimetres
  std::vector<ProjectorPlacement> placements;
  std::vector<ProjectorSpot> spots;

  // The module frame's origin in the calibration frame: the centroid of the
  // calibrated origins (module_from_calibration = translation by minus it).
  Eigen::Vector3d ModuleOriginInCalibration() const;
};

struct ProjectorAdjustmentOptions {
  int max_iterations = 100;  // Levenberg-Marquardt iterations at most, >= 0
  // Ceres tolerances, each in [0, 1).
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-14;
  double parameter_tolerance = 1e-12;
  int num_threads = 1;  // >= 1
  // The output frame (header comment): A, B, C are the means of the bundle
  // points listed in each set; every set non-empty, indices valid.
  std::array<std::vector<int>, 3> datum_point_sets;
  // |B - A| of the unscaled solution (its units); > 0 gives s and u(s),
  // 0 leaves them 0.
  double unscaled_datum_length = 0.0;
  // Lengths to report with their uncertainty (e.g. check lengths between
  // tag centres, opl_verify): each the distance between the means of two
  // sets of bundle points (every set non-empty, indices valid), in mm, with
  // u from the full covariance (the two ends' correlation kept; a length
  // does not depend on the datum).
  std::vector<std::array<std::vector<int>, 2>> length_point_sets;
  // Which parts of the calibration are adjusted under their prior (when the
  // calibration gives their uncertainty); false holds them.
  bool adjust_beams = true;
  bool adjust_source_rotations = true;
  bool adjust_module_length = true;
  bool compute_covariances = true;
  // When the a-posteriori variance factor (chi^2 / redundancy) exceeds 1,
  // the observations scatter more than their covariances say: every
  // covariance of the result is multiplied by it and every u by its square
  // root (as the two-step path enlarges its spots' covariances). Below 1 the
  // covariances are kept (a lucky sample never shrinks them). On the harder
  // virtual lab (JPEG, texture, distractors) the factor is about 1.8.
  bool scale_by_variance_factor = true;

  Status Validate() const;
};

struct ProjectorAdjustmentResult {
  // Cameras and tag points in the datum frame, millimetres.
  BundleData bundle;
  std::vector<Rigid3d> scene_from_module;  // per placement, datum frame
  std::vector<Eigen::Vector3d> spot_in_scene;  // per spot, datum frame, mm
  std::vector<double> spot_depth_mm;
  double module_length_factor = 1.0;  // lambda
  double u_module_length_factor = 0.0;
  Rigid3d datum_from_solve;

  // s and u(s) (header comment); the datum length |B - A| in mm and its u.
  double scale_factor = 0.0;
  double u_scale_factor = 0.0;
  double datum_length_mm = 0.0;
  double u_datum_length_mm = 0.0;
  // Per options.length_point_sets: the length (mm) and its standard
  // uncertainty (0 when the covariances were not computed).
  std::vector<double> lengths_mm;
  std::vector<double> u_lengths_mm;

  // First-order covariances in the datum frame (mm^2), when computed: per
  // bundle point, per camera (its centre), per placement (the module
  // frame's origin). covariance_method says how, or why not.
  std::vector<Eigen::Matrix3d> point_covariances_mm2;
  std::vector<Eigen::Matrix3d> camera_center_covariances_mm2;
  std::vector<Eigen::Matrix3d> module_origin_covariances_mm2;
  std::string covariance_method;

  // Solve.
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
  std::string termination;
  std::string linear_solver;
  // RMS pixel residual per coordinate of the tag corners and of the spots;
  // chi^2 / redundancy (observations + priors - free parameters + 6).
  double rms_tag_px = 0.0;
  double rms_spot_px = 0.0;
  double variance_factor = 0.0;
  // Free parameters of each kind.
  int free_beams = 0;
  int free_source_rotations = 0;
  bool free_module_length = false;

  std::string Report() const;
};

Result<ProjectorAdjustmentResult> ProjectorAdjust(
    const ProjectorAdjustmentData& data,
    const ProjectorAdjustmentOptions& options = ProjectorAdjustmentOptions());

}  // namespace opl
