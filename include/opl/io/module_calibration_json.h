// Module calibration JSON: a module's calibrated beam patterns, source poses
// and separations. Full description: docs/formats.md, "Module calibration JSON".
//
//   {"format": "opl.module_calibration", "version": 1, "units": "mm",
//    "sources": [{"name": "A", "beams_per_side": 11,
//                 "origin_mm": [x, y, z], "rotation_xyz_rad": [a, b, c],
//                 "rotation_quaternion_wxyz": [w, x, y, z],       (optional)
//                 "beams": [{"id": 1, "az_rad": .., "el_rad": ..,
//                            "cov_azel_rad2": [[..,..],[..,..]]}]}],   (optional)
//    "separations": [{"from": "A", "to": "B", "length_mm": 55.0,
//                     "u_length_mm": 0.002}],
//    "scaling": {...}}                                              (optional)
//
// opl_calibrate also writes, per source, an optional "quality" object
// (SourceCalibrationQuality: slices, samples_used, samples_flagged,
// beams_dropped, rms_residual_urad, variance_factor, mean_point_to_ray_mm,
// max_point_to_ray_mm, origin_cov_mm2, rotation_xyz_cov_rad2) and at the top
// level the artifact "scaling" (CalibrationScaling) when one was used; both
// are read back when present and checked like every other field.
//
// The pose is calibration_from_source: origin_mm is the projection origin,
// R = Rx(a) Ry(b) Rz(c) (geometry/rotation.h). The writer also writes the
// rotation as a unit quaternion, which the reader then uses (so a written file
// reads back bit-exact); it must agree with rotation_xyz_rad within 1e-9 rad.
// Unknown keys are ignored.
//
// Errors: IoError when the file cannot be read; ParseError otherwise, one line
// naming the file and the JSON path of the field:
//   "cal.json:3:14: JSON syntax error: ..."
//   "cal.json: format: expected \"opl.module_calibration\", got \"foo\""
//   "cal.json: sources[0].beams[4].az_rad: expected a finite number, got string"
//   "cal.json: sources[1].beams[7].id: duplicate beam id 12 (also beams[3])"
//   "cal.json: separations[0].to: unknown source 'C'"
#pragma once

#include <string>

#include "opl/core/status.h"
#include "opl/model/module_calibration.h"

namespace opl {

// Parses JSON text; `name` (the file path) prefixes messages. The result is
// validated (ModuleCalibration::Validate).
Result<ModuleCalibration> ParseModuleCalibrationJson(const std::string& text,
                                                     const std::string& name);
Result<ModuleCalibration> ReadModuleCalibrationJson(const std::string& path);

// The calibration as JSON text (one beam per line; every double written with
// the shortest text that reads back exactly). InvalidArgument when the
// calibration does not validate.
Result<std::string> FormatModuleCalibrationJson(const ModuleCalibration& calibration);
// Formats and writes atomically (WriteFileAtomically). InvalidArgument as
// above, IoError when the file cannot be written.
Status WriteModuleCalibrationJson(const ModuleCalibration& calibration, const std::string& path);

}  // namespace opl
