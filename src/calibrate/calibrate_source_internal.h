// Private to src/calibrate: the state of CalibrateSource's solve shared by
// its files (opl/calibrate/calibrate_source.h has the model and the contract).
//
//   calibrate_source.cc             CalibrateSource, CalibrateOptions::Validate,
//                                   Calibrator::Run: the flagging rounds
//   calibrate_source_init.cc        input checks; the initial pose and beam
//                                   directions from lines through each beam's
//                                   spots
//   calibrate_source_solve.cc       whitening, the Ceres solve of pose and
//                                   directions, residuals, dropping thin beams
//   calibrate_source_covariance.cc  the covariance of the estimate; the result
//
// Frames: beam directions (az, el) [rad] are in the source frame; the pose
// (Rotation(), Origin()) is scene_from_source; spot positions in the scene
// frame [mm].
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "opl/calibrate/beam_ray_cost_function.h"
#include "opl/calibrate/calibrate_source.h"
#include "opl/core/status.h"
#include "opl/geometry/rotation.h"

namespace opl {
namespace calibrate_internal {

using Layout = BeamRayCostFunction::Layout;

// One beam of the solve and its samples (indices into the input).
struct BeamState {
  int id = 0;
  int row = 0;
  int col = 0;
  Layout layout = Layout::kFreeBeam;
  std::vector<int> samples;
  double az = 0.0;  // current estimate, source frame
  double el = 0.0;
  int row_index = -1;      // kCentralRowBeam: its entry j in row_
  int param_offset = -1;   // column of its first e-parameter in the Jacobian
  bool active = true;
};

class Calibrator {
 public:
  Calibrator(std::string name, int n, const std::vector<CalibrationSample>& samples,
             const CalibrateOptions& options)
      : name_(std::move(name)), n_(n), samples_(samples), options_(options) {}

  Result<SourceCalibrationResult> Run();

 private:
  Status Error(StatusCode code, const std::string& what) const {
    return Status(code, "source '" + name_ + "': " + what);
  }
  Status CheckInput();
  Status Initialise();
  Status UpdateWhitening();
  Status Solve();
  // Normalised residual norms (and raw residuals) of every sample at the
  // current estimate.
  void EvaluateResiduals();
  double SigmaForFlagging() const;
  // Drops beams with too few unflagged samples; error when the gauge beams or
  // too many beams are lost.
  Status DropThinBeams();
  Status Covariance(SourceCalibrationResult* result);
  void FillResult(SourceCalibrationResult* result) const;

  int CentralId() const { return (n_ * n_ + 1) / 2; }
  int CentralRow() const { return (n_ - 1) / 2; }
  std::vector<BeamState*> ActiveBeams();
  Eigen::Matrix3d Rotation() const { return ExpSO3(Eigen::Map<const Eigen::Vector3d>(theta_)) * R0_; }
  Eigen::Vector3d Origin() const { return Eigen::Map<const Eigen::Vector3d>(t_); }
  // Assigns row indices to the active central-row beams and refills row_
  // from their current directions, projected onto the level constraint.
  void RebuildRow();
  int RowSize() const { return static_cast<int>(row_.size()) / 2; }

  std::string name_;
  int n_;
  const std::vector<CalibrationSample>& samples_;
  CalibrateOptions options_;

  bool weighted_ = false;
  std::vector<BeamState> beams_;       // by id
  std::vector<double> weight_;         // per sample: 0 = left out
  std::vector<char> flagged_;          // per sample
  std::vector<char> in_dropped_beam_;  // per sample
  std::vector<Eigen::Matrix2d> whitening_;
  std::vector<Eigen::Vector2d> raw_residual_;
  std::vector<double> normalized_;
  std::vector<int> dropped_beam_ids_;
  int num_slices_ = 0;
  int iterations_ = 0;

  Eigen::Matrix3d R0_ = Eigen::Matrix3d::Identity();
  double theta_[3] = {0.0, 0.0, 0.0};
  double t_[3] = {0.0, 0.0, 0.0};
  std::vector<double> row_;  // (az_1..az_m, el_1..el_m) of the central row
};

}  // namespace calibrate_internal
}  // namespace opl
