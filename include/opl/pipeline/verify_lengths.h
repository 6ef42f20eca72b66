// The acceptance test of an optical 3D measuring system as VDI/VDE 2634
// Part 1 and ISO 10360-13 define it, on one measured session: calibrated
// test lengths (Scene::check_lengths, pairs of tags whose centres are a
// certified distance apart) through the measuring volume, and for each the
// length measurement error E = measured - calibrated with its expanded
// uncertainty. `opl_verify` is its CLI (docs/verify.md).
//
//   Result<ImageMeasureReport> m = MeasureScaleFromImages(scene, "images/", cal);
//   Result<VerifyReport> v = VerifyLengths(scene, *m);
//   std::cout << v->ToText();
//
// Three columns, from the same photographs:
//  - OPL: the scene scaled by the laser module alone, s = the two-step
//    measurement's (ImageMeasureReport::measure.scale): L = s d, d the
//    distance of the two tag centres in the unscaled scene;
//  - bar: the same scene scaled by the scene's artifact (Scene::artifact,
//    a conventional scale bar), s_bar = L_bar / d_bar: L = s_bar d.
//    Absent when the scene has no artifact or its tags were not adjusted;
//  - OPL in the adjustment: the scene scaled inside the bundle adjustment by
//    the module as a calibrated projector (ImageMeasureReport::projector,
//    FrontEndOptions::scale_in_adjustment), the lengths asked for by
//    ImageMeasureOptions::projector_tag_lengths = the check lengths' tags in
//    scene order (CheckLengthTags): L and u(L) straight from the metric
//    adjustment and its full covariance. Absent when the measurement ran
//    without it.
//
// Uncertainties (first order, k = 1, then U = 2 u): a length L is a function
// of s (or L_bar) and of the tag centres; its error is
//   dL = d ds + s e^T (dT_2 - dT_1)          (OPL; e the unit vector T_1 -> T_2)
//   dL = (d / d_bar) dL_bar + s_bar e^T (dT_2 - dT_1)
//        - s_bar (d / d_bar) e_bar^T (dB_2 - dB_1)   (bar)
// with each tag centre's error split as the front end gives it (FrontEndResult::
// tag_center_own_covariances, tag_center_shared_factors: own parts
// independent, shared parts K z common to every point) and s's as own (the
// spots' own errors, u_scale_factor_own) plus g^T z (scale_shared_gradient):
// the correlations between s and the tags, and between tags, through the
// cameras and the datum are kept. Without the split (a front end that gave
// none) the terms are taken as independent and the report says so.
// u(E)^2 = u(L)^2 + u(L_cal)^2; U(E) = 2 u(E).
//
// The test's own conditions (VDI/VDE 2634-1, 5.2): at least 7 positions, the
// longest length at least 2/3 of the measuring volume's space diagonal (the
// diagonal of the box around every adjusted tag centre). A session that
// does not meet them is still reported, with a warning saying which.
//
// Errors: InvalidArgument when the scene has no check lengths; NoSolution
// naming the check length when one of its tags was not adjusted (not seen
// from two camera positions), or when the measurement has no scale.
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/report/line_plot.h"

namespace opl {

// One length as one scaling measures it.
struct ScaledLength {
  double measured_mm = 0.0;  // L
  double u_measured_mm = 0.0;  // u(L), k = 1
  double error_mm = 0.0;       // E = L - L_cal
  double u_error_mm = 0.0;     // u(E) = sqrt(u(L)^2 + u(L_cal)^2)
  double expanded_u_error_mm = 0.0;  // U(E) = 2 u(E)
  // |E| <= U(E): the error is explained by the stated uncertainty.
  bool within_uncertainty() const { return std::abs(error_mm) <= expanded_u_error_mm; }
};

struct CheckLengthResult {
  std::string name;
  int tag_1 = 0, tag_2 = 0;
  double calibrated_mm = 0.0;    // L_cal
  double u_calibrated_mm = 0.0;  // its standard uncertainty
  double unscaled = 0.0;         // d, scene units
  ScaledLength opl;
  std::optional<ScaledLength> bar;
  std::optional<ScaledLength> projector;  // OPL in the adjustment
};

struct VerifyReport {
  std::vector<CheckLengthResult> lengths;  // scene order
  double scale_factor = 0.0;    // s (OPL)
  double u_scale_factor = 0.0;
  std::optional<double> bar_scale_factor;  // s_bar, when the scene has an artifact
  double u_bar_scale_factor = 0.0;
  // The test's conditions (header comment).
  double space_diagonal_mm = 0.0;  // of the box around the adjusted tag centres, scaled by s
  double longest_mm = 0.0;
  bool correlations_kept = true;  // false: the front end gave no error split
  std::vector<std::string> warnings;
  // Largest |E| and RMS E of each column (the bar's 0 when absent).
  double max_abs_error_opl_mm = 0.0, rms_error_opl_mm = 0.0;
  double max_abs_error_bar_mm = 0.0, rms_error_bar_mm = 0.0;
  // OPL in the adjustment, when the measurement ran it.
  std::optional<double> projector_scale_factor;
  double u_projector_scale_factor = 0.0;
  double max_abs_error_projector_mm = 0.0, rms_error_projector_mm = 0.0;

  // A table: one row per length (name, tags, L_cal, then per column L, E,
  // U(E)), the summary and the warnings.
  std::string ToText() const;
  // One header row then one row per length (docs/verify.md, "Files").
  std::string ToCsv() const;
  // {"format": "opl.verify_report", "version": 1, ...} (docs/verify.md).
  std::string ToJson() const;
  // E against L_cal (mm), titled with `scene_name`: each column as markers
  // with error bars +-U(E) (OPL first, then the bar), drawn apart by 1 % of
  // the lengths' span each side of L_cal so that the bars do not hide each
  // other, and the line E = 0 (dashed). With a bar column a second panel
  // shows it alone on its own scale (its E and U(E) may be far smaller).
  // RenderLinePlot (report/line_plot.h) draws it.
  LinePlot ToPlot(const std::string& scene_name) const;
};

// OK when the scene lists at least one check length; else InvalidArgument
// "check_lengths: the scene lists no check length ...". opl_verify asks it
// before reading any image; VerifyLengths refuses such a scene the same way.
Status CheckSceneHasCheckLengths(const Scene& scene);

// The check lengths' tag pairs in scene order: what
// ImageMeasureOptions::projector_tag_lengths must be for the third column.
std::vector<std::pair<int, int>> CheckLengthTags(const Scene& scene);

Result<VerifyReport> VerifyLengths(const Scene& scene, const ImageMeasureReport& measured);

}  // namespace opl
