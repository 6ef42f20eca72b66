// ModuleDesign: a simulated module (its sources, each with a designed pattern
// and a pose), the surface its spots land on, and the spot noise
// (method.md, "Simulation models"; docs/simulation.md).
//
// All positions are in one "design scene" frame, millimetres. A source's pose
// is scene_from_source: p_scene = R p_source + t, t = projection origin
// (origin_mm in files), R from the file's rotation_xyz_rad (a, b, c) as
// R = Rx(a) Ry(b) Rz(c) (geometry/rotation.h). With R = I the source looks
// along +X of the scene with +Z up.
//
// Spot noise: an anisotropic Gaussian with standard deviations spot_noise_mm
// along the axes of a noise frame whose axes are the columns of
// noise_frame_rotation (in the scene frame); the spot covariance is
//   Sigma = R_n diag(sigma^2) R_n^T,   R_n = noise_frame_rotation.
// The default R_n = I puts the noise axes on the scene axes.
//
// ExactCalibration gives what a perfect calibration of the design would give:
// the same patterns, poses in a calibration frame equal to the design scene
// frame, and the exact separations between all pairs of origins (u = 0).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/model/beam_pattern.h"
#include "opl/model/module_calibration.h"
#include "opl/sim/pattern_models.h"
#include "opl/sim/surface.h"

namespace opl {

struct SourceDesign {
  std::string name;            // unique in the module, non-empty
  int beams_per_side = 11;     // n, odd >= 3 (for kFile: must match the file)
  double full_angle_deg = 29.0;  // full fan angle of the central row, degrees
  PatternModel pattern = PatternModel::kEqualAngle;
  double wavelength_nm = 658.0;  // design wavelength (used by kGrating), > 0
  // CSV pattern (sim/pattern_models.h, ReadPatternCsv) for kFile; read as given
  // (relative to the working directory). The JSON reader resolves it against
  // the JSON file's folder.
  std::string pattern_file;
  Rigid3d scene_from_source;  // translation = projection origin, mm
  // Fabrication error of the diffractive element: every beam but the central
  // one gets a fixed random error, N(0, beam_error_mrad^2) on az and on el
  // (mrad, >= 0; 0: the ideal pattern), drawn from beam_error_seed and the
  // source's name, then the central row is levelled again (docs/simulation.md,
  // "Fabrication error"): the pattern stays in the calibration gauge. An ideal
  // equal-angle or grating pattern is symmetric under a 90 deg roll, so its
  // grid alone cannot tell which way up it is; a real element's errors break
  // that symmetry, and identification (identify_spots.h) relies on them.
  double beam_error_mrad = 0.0;
  uint64_t beam_error_seed = 1;
};

struct ModuleDesign {
  std::vector<SourceDesign> sources;
  Surface surface;
  // Standard deviation of the spot noise along each noise-frame axis, mm, >= 0.
  Eigen::Vector3d spot_noise_mm = Eigen::Vector3d::Zero();
  // Columns: the noise axes in the scene frame (a proper rotation).
  Eigen::Matrix3d noise_frame_rotation = Eigen::Matrix3d::Identity();

  // At least one source; names non-empty and unique; each source's pattern
  // parameters valid (CheckPatternParameters), pattern_file non-empty for kFile;
  // poses finite; surface valid; spot_noise_mm finite and >= 0;
  // noise_frame_rotation a proper rotation (to 1e-9). Messages name the source
  // and field, e.g. "source 'B': full angle must be finite, > 0 and < 180 deg,
  // got 0 deg". Does not read pattern files (MakePattern does).
  Status Validate() const;

  // The spot noise covariance R_n diag(sigma^2) R_n^T, mm^2.
  Eigen::Matrix3d SpotCovarianceMm2() const;

  // The same physical set-up seen in another frame: every source pose, the
  // surface and the noise frame are moved by new_from_old
  // (scene_from_source <- new_from_old * scene_from_source, noise axes rotated
  // too, so that simulating the transformed design is statistically the same
  // experiment as transforming the simulated spots). To keep the noise on the
  // new scene axes instead, reset noise_frame_rotation afterwards.
  ModuleDesign Transformed(const Rigid3d& new_from_old) const;

  // nullptr when there is no source of that name.
  const SourceDesign* FindSource(const std::string& name) const;
};

// The designed pattern of a source: MakeEqualAnglePattern, MakeGratingPattern
// or ReadPatternCsv(pattern_file). For kFile, an error when the file's
// beams_per_side differs from the design's.
Result<BeamPattern> MakePattern(const SourceDesign& source);

// The noise-free calibration of a design (see the header comment). Errors:
// the design's Validate(), or a pattern file that cannot be read.
Result<ModuleCalibration> ExactCalibration(const ModuleDesign& design);

}  // namespace opl
