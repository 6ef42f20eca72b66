// Internal to ProjectorAdjust (projector_adjustment.cc and
// projector_adjustment_covariance.cc): the parameter storage of one solve,
// its covariances and the move to the datum frame.
#pragma once

#include <array>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <ceres/problem.h>
#include <Eigen/Core>

#include "opl/vision/projector_adjustment.h"

namespace opl {
namespace projector_internal {

struct BeamBlock {
  std::array<double, 2> azel = {0.0, 0.0};  // (az, el) rad, adjusted
  Eigen::Vector2d azel_cal = Eigen::Vector2d::Zero();
  bool free = false;
};

// The parameters of one solve, packed from the data (mm). Vectors are sized
// once: Ceres holds pointers into them.
struct Problem {
  explicit Problem(const ProjectorAdjustmentData& data);

  const ProjectorAdjustmentData& data;
  std::vector<std::array<double, 4>> cam_q;  // x, y, z, w
  std::vector<std::array<double, 3>> cam_t;
  std::vector<std::array<double, kNumCameraParameters>> intrinsics;
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<double, 4>> module_q;  // scene_from_module
  std::vector<std::array<double, 3>> module_t;
  double lambda = 1.0;
  bool lambda_free = false;
  std::vector<std::array<double, 4>> source_q;  // module_from_source, per calibrated source
  std::vector<Eigen::Vector3d> origin_in_module;  // o_s
  std::vector<char> source_used;  // has a spot
  std::vector<char> source_free;
  std::map<std::pair<size_t, int>, BeamBlock> beams;  // (source index, beam id) with a spot
  std::vector<double> depths;  // per spot

  size_t SourceIndex(const std::string& name) const;  // precondition: calibrated
  CameraIntrinsics CameraIntrinsicsOf(size_t camera) const;
  // Unwhitened pixel residuals (nullptr: only the in-front test).
  bool TagResidual(size_t observation, Eigen::Vector2d* r) const;
  bool SpotResidual(size_t spot, size_t observation, Eigen::Vector2d* r) const;
  Eigen::Vector3d SpotInScene(size_t spot) const;  // solve frame
  int NumFreeParameters() const;                    // tangent dimensions
};

// The covariance of the non-depth parameters (depths eliminated), with the
// six gauge directions dropped. Columns: per camera 6 (rotation tangent,
// translation), per point 3, per placement 6, lambda 1 when free, then free
// source rotations (3) and beams (2).
struct Covariances {
  bool ok = false;
  std::string method;
  Eigen::MatrixXd Sg;
  std::vector<int> cam_col;
  std::vector<int> point_col;
  std::vector<int> module_col;
  int lambda_col = -1;
};

Covariances ComputeCovariances(ceres::Problem* problem, Problem& pb,
                               const ProjectorAdjustmentOptions& options);

// Fills the result's poses, points, spots, s and the datum-frame covariances.
Status MoveToDatum(const Problem& pb, const ProjectorAdjustmentOptions& options,
                   const Covariances& cov, ProjectorAdjustmentResult* result);

}  // namespace projector_internal
}  // namespace opl
