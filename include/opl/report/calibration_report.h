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

// The noise level of that heat map derived from the session itself
// (opl_calibrate's default for --heatmap-noise-mm): the largest mean
// point-to-ray distance that the B beams of a source reach, when they carry
// spot noise only, with probability 1 - alpha (family-wise over the beams,
// Sidak). A map of pure noise is then labelled "all beams at the noise
// level" in about 1 - alpha of sessions, and a beam above the level is
// evidence of a defect at level alpha.
//
// A beam's value is the mean of its m used samples' distances d. The shape
// of its distribution under pure noise is that of the mean of m independent
// draws from the source's pooled used distances (their empirical
// distribution in 512 bins, convolved m times); its centre and spread are
// the beams' own (samples of one beam share the pose error and their
// geometry, so their means spread more than independent draws would):
//   level = mean_b + (q_p(G_m) - mean(d)) * sd_b / (sd(d) / sqrt(m))
// with G_m the distribution of the mean of m draws, q_p its upper
// p-quantile, p = 1 - (1 - alpha)^(1/B) (about alpha / B), mean_b and sd_b
// the mean and standard deviation of the beam values, mean(d) and sd(d)
// those of the pooled distances, m the most common number of used samples.
// Robust to a few defective beams: beams above the level are left out of
// all of these and the level is computed again (up to 3 rounds). Rounded up
// to 3 significant digits. NaN when fewer than 2 beams have 2 used samples
// or alpha is not in (0, 1).
//
// Measured (tests/report/calibration_report_test.cc, the prototype module,
// 11 x 11 beams, 10 slices, alpha = 0.05): on 600 sources of pure noise
// (300 seeds) every beam was at or below the level in 578 (96.3 %); one beam
// whose samples were moved 3 sigma off its ray (random directions) was above
// the level in 291 of 300 sessions. Samples moved further are increasingly
// flagged as outliers (5 sigma) and leave the beam's mean: at 4 sigma the
// beam was above the level in 266 of 300 sessions (7.6 of 10 samples used),
// at 6 sigma in 66 of 100 (4.6 used): such a beam shows in its flagged
// count (beams.csv), not in the map.
double PointToRayNoiseLevel(const SourceCalibrationResult& source, double alpha = 0.05);

}  // namespace opl
