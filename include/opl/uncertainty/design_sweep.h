// Design sweeps: how the uncertainty of L moves with one design parameter
// (method.md, "Uncertainty"; docs/uncertainty.md, "Design sweeps").
//
//   Result<ModuleDesign> design = ReadModuleDesignJson("examples/staggered_design.json");
//   Result<SweepParameter> p = ParseSweepParameter("full_angle_deg");
//   Result<std::vector<double>> values = ParseSweepValues(*p, "10:5:40");
//   MonteCarloOptions mc;  mc.iterations = 1000;
//   Result<DesignSweep> sweep = RunDesignSweep(*design, *p, *values, mc);
//   WriteFileAtomically("sweep.csv", sweep->ToCsv());
//   WriteLinePlot(sweep->ToPlot(), "sweep.png");  // or .svg, .pdf
//
// Every value gives a design (ApplySweepValue: the base design with one
// parameter changed, everything else kept) and a measurement Monte Carlo of it
// (RunMeasurementMonteCarlo, same seed at every value: common random numbers,
// so neighbouring points differ by the design, not by the draw), with its
// first-order prediction and Cramer-Rao bound.
//
// The parameters (every source changes alike):
//   noise_mm        the largest per-axis spot noise sigma (mm); the other
//                   axes keep their ratio to it, the noise frame is kept;
//   full_angle_deg  the full fan angle of every pattern (degrees);
//   beams_per_side  n of every pattern (odd, >= 3);
//   separation_mm   the distance between the first two origins (mm): every
//                   origin moves away from the origins' centroid by the same
//                   factor (with two sources: along the baseline, the
//                   midpoint kept);
//   distance_mm     the projection distance (mm): the surface moves along the
//                   module's mean viewing direction v (MeanViewpoint) until
//                   it is that far from the mean origin along v;
//   stagger_deg     the layout of two sources (degrees): the baseline, length
//                   and midpoint kept, is turned in the plane of its lateral
//                   direction and v to this angle from the lateral plane:
//                   0 = side by side, 45 = staggered (as far ahead as aside;
//                   examples/staggered_design.json), 90 = one behind the other.
//   layout          the same change as stagger_deg with two named values,
//                   side_by_side (0) and staggered (45): a categorical
//                   parameter (its plot has markers at 1, 2, ... only).
#pragma once

#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/report/line_plot.h"
#include "opl/sim/module_design.h"
#include "opl/uncertainty/monte_carlo.h"

namespace opl {

enum class SweepParameter {
  kNoiseMm,
  kFullAngleDeg,
  kBeamsPerSide,
  kSeparationMm,
  kDistanceMm,
  kStaggerDeg,
  kLayout,  // stagger_deg restricted to 0 (side_by_side) and 45 (staggered)
};

// Every parameter, in the order of the names above.
const std::vector<SweepParameter>& AllSweepParameters();

// "noise_mm", "full_angle_deg", ... (the names above, as --param takes them).
const char* SweepParameterName(SweepParameter parameter);
// What a reader of a plot sees (one table, src/uncertainty/design_sweep.cc):
// the quantity in words with its unit, e.g. "fan full angle (deg)" for
// full_angle_deg; for layout just "layout" (DesignSweep::ToPlot names the
// categories at the axis's ticks).
std::string SweepParameterLabel(SweepParameter parameter);
// The quantity in words without its unit, for titles: "fan full angle".
std::string SweepParameterNoun(SweepParameter parameter);
// True for a parameter whose values are named categories (layout): its plot
// puts the values at x = 1, 2, ... with markers only.
bool IsCategoricalSweep(SweepParameter parameter);
// The value as the user writes it: "side_by_side" / "staggered" for layout,
// else the number ("0.1", "45").
std::string SweepValueText(SweepParameter parameter, double value);
// Parses a name above; InvalidArgument listing the known names otherwise.
Result<SweepParameter> ParseSweepParameter(const std::string& text);
// Parses the values: "first:step:last" or "v1,v2,..." (ParseNumberList); for
// `layout` (text_parameter == "layout") the words side_by_side (0) and
// staggered (45).
Result<std::vector<double>> ParseSweepValues(const std::string& text_parameter,
                                             const std::string& values);

// The base design with the parameter set to `value`. InvalidArgument when the
// value is out of the parameter's domain (message names parameter and value)
// or the design does not allow it (separation of coincident origins,
// stagger_deg with other than two sources, full_angle_deg of a pattern file,
// a surface not hit along v).
Result<ModuleDesign> ApplySweepValue(const ModuleDesign& base, SweepParameter parameter,
                                     double value);

struct DesignSweepPoint {
  double value = 0.0;
  MonteCarloReport report;
};

struct DesignSweep {
  SweepParameter parameter = SweepParameter::kNoiseMm;
  std::vector<DesignSweepPoint> points;  // in the order of the values

  // One row per value and length (long format, docs/uncertainty.md):
  //   parameter,value,from,to,true_mm,mean_mm,std_mm,std_u_mm,first_order_std_mm,
  //   cramer_rao_std_mm,ci95_low_mm,ci95_high_mm,u_rel_ppm,s_std_ppm,
  //   s_first_order_std_ppm,s_cramer_rao_std_ppm,iterations,failed
  // std_u_mm = std / sqrt(2 (M - 1)), the standard error of the std;
  // u_rel_ppm = 1e6 std / true. Numbers round-trip.
  std::string ToCsv() const;
  // Two panels against the parameter: std of L (mm) and u(L)/L (ppm), each
  // with, per length, the first-order prediction (solid line with markers at
  // the values), the Cramer-Rao bound (dashed, drawn over the first order:
  // where they coincide the first order shows in the dashes' gaps and at its
  // markers) and the Monte Carlo (markers, +- std_u error bars). The title
  // and the x label name the parameter in words with its unit
  // (SweepParameterLabel). A categorical sweep (layout) has the values at
  // x = 1, 2, ... in sweep order, every series as markers only (the Monte
  // Carlo at x, the first order at x - 0.12 and the bound at x + 0.12, so
  // that equal values stay apart), and the x axis is categorical
  // (PlotPanel::x_categories): ticks at 1, 2, ... named by the values
  // ("side by side", "staggered"), no numeric ticks; the x label is "layout".
  LinePlot ToPlot() const;
};

// Runs the Monte Carlo at every value (options as for RunMeasurementMonteCarlo;
// options.progress sees the iterations of the whole sweep). Errors: from
// ApplySweepValue and RunMeasurementMonteCarlo, prefixed with
// "<parameter> = <value>: "; InvalidArgument when values is empty.
Result<DesignSweep> RunDesignSweep(const ModuleDesign& base, SweepParameter parameter,
                                   const std::vector<double>& values,
                                   const MonteCarloOptions& options);

}  // namespace opl
