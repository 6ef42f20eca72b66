// A simulated calibration session (method.md, "Calibrating a source";
// docs/simulation.md, "Simulating a calibration session"): the module stays
// fixed, a screen is placed at several depths and every grid's spots are
// measured on every screen. Screen k gives "slice" k.
//
// The frame of the depths (ModuleViewpoint): o = the mean of the sources'
// projection origins, v = the module's mean viewing direction, the normalised
// mean of the sources' central-beam directions R_i e_x in the scene, and
// u = the module's "up", the mean of R_i e_z made perpendicular to v. For
// the prototype design (two sources at y = +-27.5 mm looking along +X) that is
// o = 0, v = +X, u = +Z, so a depth is the scene x of the screen.
//
// MakeCalibrationScreens: screen k passes through p_k = o + depths_mm[k] v.
// Its normal n_k is v turned about u by tilt_k (right-handed, so a positive
// tilt turns the normal from v towards u x v), with tilt_k = +tilt_deg for even
// k and -tilt_deg for odd k: neighbouring screens are not parallel. With
// curvature_per_mm = 0 the screen is the plane through p_k normal to n_k
// (PlaneSurface); otherwise the paraboloid with vertex p_k, axis -n_k
// (pointing back at the module) and that curvature (ParaboloidSurface,
// z' = c/2 r'^2): c > 0 bends the screen's edges towards the module (concave
// seen from the module), c < 0 away from it. Either way the point p_k is on
// screen k, so a source at o looking along v sees its central spot at exactly
// depths_mm[k] along v. (A source at o + s looking along v sees it on a flat
// screen at depths_mm[k] - (n_k . s) / (n_k . v) along v.)
//
// SimulateSlices: slice k is SimulateSpots of a copy of the design whose
// surface is screens[k], with seed SliceSeed(options.seed, k); every spot
// gets slice = k. So missing spots, noise and outliers are those of
// SimulateSpots applied to each slice on its own (exactly round(fraction * N_k)
// missing of the N_k hits of slice k, and so on), and a slice can be
// reproduced alone from its seed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_spots.h"
#include "opl/sim/surface.h"

namespace opl {

// The frame in which a calibration session's depths are given (see above),
// scene frame.
struct ModuleViewpoint {
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();           // o, mean projection origin
  Eigen::Vector3d viewing_direction = Eigen::Vector3d::UnitX();  // v, unit
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();                 // u, unit, _|_ v
};

// InvalidArgument from design.Validate() (the design's surface aside: it is
// not used), or when the central beams cancel out (sources looking in opposite directions: no mean viewing direction).
// When the mean up is parallel to v, u is some unit vector perpendicular to v.
Result<ModuleViewpoint> MeanViewpoint(const ModuleDesign& design);

struct ScreenSlicesOptions {
  // Distance of screen k from o along v, mm; each finite and > 0; at least one.
  std::vector<double> depths_mm;
  // Tilt of the screens about u, degrees, |tilt_deg| < 90; alternating sign
  // (+ for even k, - for odd k). 0: every screen normal to v.
  double tilt_deg = 0.0;
  // Curvature of every screen, 1/mm, finite; 0: flat screens (planes).
  double curvature_per_mm = 0.0;

  // OK, or InvalidArgument naming the field and value, e.g.
  // "depths_mm[2] must be finite and > 0, got -5".
  Status Validate() const;
};

// One screen per depth (see the header comment). Errors: InvalidArgument from
// options.Validate() or MeanViewpoint.
Result<std::vector<Surface>> MakeCalibrationScreens(const ModuleDesign& design,
                                                    const ScreenSlicesOptions& options);

// The slices of a surface as separate screens: the planes of a list of planes,
// else the surface itself.
std::vector<Surface> SlicesOf(const Surface& surface);

// The seed of slice k: the (k + 1)-th output of SplitMix64(seed) (opl/sim/random.h).
// Slice k of SimulateSlices equals SimulateSpots(design with surface
// screens[k], options with seed SliceSeed(options.seed, k)), slice set to k.
uint64_t SliceSeed(uint64_t seed, int slice);

// Every source's spots on every screen, slice = screen index; order: slice 0
// (in SimulateSpots order: source, then beam id), then slice 1, ...
// design.surface is not used (pass SlicesOf(design.surface) to use its
// planes). Deterministic for a seed. Errors: InvalidArgument when screens is
// empty, a screen is invalid ("screens[2]: normal is zero") or is itself a
// list of several planes (pass SlicesOf(it)), and from design.Validate() or
// options.Validate(); a pattern file's IoError/ParseError; NoSolution
// "screen 3: no beam of any source hits the surface (plane)" when a screen
// gets no spot at all.
Result<std::vector<SimulatedSpot>> SimulateSlices(const ModuleDesign& design,
                                                  const std::vector<Surface>& screens,
                                                  const SpotSimulationOptions& options);

// Parses a list of depths, mm:
//   "first:step:last"  first, first + step, ... up to last (included when it is
//                      reached within 1e-9 relative; the last value is then
//                      exactly `last`); step > 0, first <= last. E.g.
//                      "750:65:1335" = 750, 815, ..., 1335 (10 depths).
//   "d1,d2,..."        the numbers as given (any order); a single number is a
//                      list of one.
// Numbers are decimal (locale-independent), finite; spaces around them are
// allowed. At most 10000 depths. Does not check the sign of the depths
// (ScreenSlicesOptions::Validate does). Errors: InvalidArgument, one line
// naming the text, e.g. "depth list '750:x:1335': 'x' is not a number".
Result<std::vector<double>> ParseDepthList(const std::string& text);

}  // namespace opl
