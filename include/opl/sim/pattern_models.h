// Designed beam patterns: the n x n grid of pointing directions of one source,
// in its source frame (method.md, "Simulation models"; docs/simulation.md).
//
// Conventions (method.md): +X along the central beam, +Z up, +Y to the left
// looking out; az = atan2(y, x), el = atan2(z, hypot(x, y)); beam id =
// row * n + col + 1, row 0 the top row (largest Z, el > 0), col 0 the column of
// smallest Y (az < 0). With m = (n - 1) / 2, a beam at (row r, col c) has
// lattice coordinates (i, j) = (c - m, m - r): i grows with +Y, j with +Z.
// For n = 11: beam 1 is (i, j) = (-5, +5) (az < 0, el > 0, "top right" seen
// from behind), beam 61 is the central beam az = el = 0, beam 121 is (+5, -5).
//
// (a) Equal neighbour angle, MakeEqualAnglePattern. theta0 = full_angle/(n-1).
//     The spots lie on a plane normal to the central beam, on a square lattice
//     in tangent space: the direction of beam (i, j) is proportional to
//         (1, tan(i theta0), tan(j theta0)).
//     So along the central row and the central column neighbours are exactly
//     theta0 apart and the outermost beams of those lines are at
//     +-full_angle / 2. Off those lines neighbour angles are slightly smaller
//     (a flat square lattice cannot keep every neighbour angle equal); this is
//     the interpretation of method.md's model (a) we adopt.
//
// (b) Grating, MakeGratingPattern. The direction cosines lie on a square
//     lattice: (k_y, k_z) = (i, j) * lambda / period, k_x = sqrt(1 - k_y^2 -
//     k_z^2), with the period chosen so that the central row's outermost beams
//     are at +-full_angle/2:  period = m * lambda / sin(full_angle / 2).
//     A grating of fixed period lit at another wavelength fans its beams
//     differently; GratingDAzElDWavelength gives that sensitivity analytically.
//     Every order must propagate: 2 sin^2(full_angle / 2) < 1 (the corner
//     beams), i.e. full_angle < 90 deg.
//
// (c) Arbitrary, from a CSV file, ReadPatternCsv (format below).
//
// Preconditions of the Make* functions (checked by CheckPatternParameters):
// beams_per_side odd and >= 3; full_angle_rad finite, > 0 and < pi for (a),
// < pi/2 for (b); wavelength_nm finite and > 0. When they are violated the
// functions return an empty pattern (beams_per_side() == 0, Validate() fails);
// use MakePattern (sim/module_design.h) to get a Result with the reason.
#pragma once

#include <string>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/model/beam_pattern.h"

namespace opl {

enum class PatternModel {
  kEqualAngle,  // (a) equal neighbour angle on the central row and column
  kGrating,     // (b) direction cosines on a square lattice
  kFile,        // (c) read from a CSV file
};

// "equal_angle", "grating", "file".
const char* PatternModelName(PatternModel model);

// OK when (beams_per_side, full_angle_rad, wavelength_nm) are valid for
// `model` (kEqualAngle and kGrating; kFile accepts anything and returns OK).
// The message names the offending parameter and its value.
Status CheckPatternParameters(PatternModel model, int beams_per_side, double full_angle_rad,
                              double wavelength_nm);

// Model (a). All n^2 beams, sorted by id.
BeamPattern MakeEqualAnglePattern(int beams_per_side, double full_angle_rad);

// Model (b) at its design wavelength. All n^2 beams, sorted by id. The angles
// do not depend on wavelength_nm (the period scales with it); it is taken so
// that the signature matches GratingPeriodNm and GratingDAzElDWavelength.
BeamPattern MakeGratingPattern(int beams_per_side, double full_angle_rad, double wavelength_nm);

// Grating period (nm) of model (b): m * lambda / sin(full_angle / 2). NaN when
// the parameters are invalid.
double GratingPeriodNm(int beams_per_side, double full_angle_rad, double wavelength_nm);

// Model (b) at wavelength `wavelength_nm + delta_nm` with the period fixed at
// its design value: the pattern a real grating gives when its diode is off its
// nominal wavelength. Empty pattern when invalid, or when a beam would become
// evanescent (k_y^2 + k_z^2 >= 1).
BeamPattern MakeGratingPatternAtWavelength(int beams_per_side, double full_angle_rad,
                                           double design_wavelength_nm,
                                           double actual_wavelength_nm);

// d(az, el) / d lambda of every beam of model (b) at its design wavelength,
// the period held fixed, rad/nm. Row b - 1 is beam id b (n^2 rows). In closed
// form, with k = (k_x, k_y, k_z) the beam's direction cosines:
//   d el / d lambda = k_z / (lambda sqrt(1 - k_z^2))
//   d az / d lambda = k_y / (lambda k_x (1 - k_z^2))
// Empty (0 rows) when the parameters are invalid.
Eigen::Matrix<double, Eigen::Dynamic, 2> GratingDAzElDWavelength(int beams_per_side,
                                                                 double full_angle_rad,
                                                                 double wavelength_nm);

// Model (c): reads a pattern from a CSV file.
//
//   # beams_per_side: 11          <- required, before the header
//   # any other line starting with '#' is a comment; blank lines are skipped
//   id,az_rad,el_rad              <- header: columns by name, any order,
//   1,-0.2531,0.2531                 extra columns ignored
//   ...
//
// Fields are separated by commas and trimmed of spaces; quoting is not
// supported. Ids are integers in 1..n^2, unique; angles finite radians with
// |az| <= pi and |el| < pi/2. Beams may be missing. Only a regular file of at
// most kMaxPatternFileBytes is read (a device such as /dev/zero never ends).
// Errors are IoError (file cannot be read, not a regular file, too large) or
// ParseError, one line naming "<path>:<line>".
constexpr long long kMaxPatternFileBytes = 16LL << 20;  // 16 MiB
Result<BeamPattern> ReadPatternCsv(const std::string& path);

// Writes `pattern` in the format ReadPatternCsv reads (17 significant digits,
// so that angles round-trip exactly). IoError when the file cannot be written.
Status WritePatternCsv(const BeamPattern& pattern, const std::string& path);

}  // namespace opl
