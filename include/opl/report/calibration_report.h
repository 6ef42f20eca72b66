// What opl_calibrate shows a metrologist about a calibration
// (docs/calibrate.md, "Report"): a readable summary, the per-beam quality
// table and, per source, the heat map of the mean point-to-ray distance.
#pragma once

#include <string>

#include "opl/calibrate/calibrate_module.h"
#include "opl/report/grid_heatmap.h"

namespace opl {

// Per source: origin (mm) with standard deviations, pose angles (deg), RMS
// residual (urad), mean/max point-to-ray distance, samples used/flagged, the
// worst beams and any dropped beams; then every separation with u (k = 1) and
// the artifact scaling when one was used.
std::string CalibrationSummaryText(const ModuleCalibrationResult& result);

// One row per calibrated beam of every source:
//   source,beam,row,col,az_rad,el_rad,u_az_rad,u_el_rad,samples_used,
//   samples_flagged,mean_point_to_ray_mm,max_point_to_ray_mm,rms_residual_urad
// and one row per dropped beam with empty direction and distance fields.
std::string BeamQualityCsv(const ModuleCalibrationResult& result);

// One row per sample, in input order of each source:
//   source,beam,slice,residual_az_urad,residual_el_urad,normalized,
//   point_to_ray_mm,status        (status: used | flagged | beam_dropped)
std::string SampleResidualsCsv(const ModuleCalibrationResult& result);

// The heat map of a source's mean point-to-ray distance per beam (mm); beams
// without a calibration are "no data".
GridHeatmap PointToRayHeatmap(const SourceCalibrationResult& source);

}  // namespace opl
