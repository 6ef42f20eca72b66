// Module design JSON: a simulated module, its surface and its spot noise, as
// a file (full format: docs/simulation.md, "Module design JSON"): read and
// written.
//
//   {
//     "format": "opl.module_design", "version": 1,
//     "sources": [
//       {"name": "A", "pattern": "equal_angle", "beams_per_side": 11,
//        "full_angle_deg": 29.0, "origin_mm": [0, 27.5, 0],
//        "rotation_xyz_rad": [0, 0, 0]}, ...],
//     "surface": {"type": "plane", "point_mm": [1000, 0, 0], "normal": [-1, 0, 0]},
//     "spot_noise_mm": [0.110, 0.073, 0.073]
//   }
//
// Errors are one line, "<file>: <field path>: <what is wrong>", e.g.
//   design.json: sources[1].full_angle_deg: expected a number, got "abc"
// with code IoError (file cannot be read), ParseError (invalid JSON, reported
// as "<file>:<line>:<column>: ...", or any field missing, of the wrong type or
// out of its domain), or the pattern file's own IoError/ParseError prefixed by
// the field path. Unknown fields are errors (typos must not pass silently).
#pragma once

#include <string>

#include "opl/core/status.h"
#include "opl/sim/module_design.h"

namespace opl {

// Reads and validates a design file. Relative pattern_file paths are resolved
// against the folder of `path`; pattern files are read to check them.
Result<ModuleDesign> ReadModuleDesignJson(const std::string& path);

// The same from text. `name_for_messages` starts every error message;
// relative pattern_file paths are resolved against `base_dir` (the working
// directory when empty).
Result<ModuleDesign> ParseModuleDesignJson(const std::string& text,
                                           const std::string& name_for_messages,
                                           const std::string& base_dir = "");

// The design as module design JSON text (the format above, keys in the
// documented order, numbers in the shortest form that reads back to the
// same double). Rotations are written as their (a, b, c) angles
// (geometry/rotation.h, XyzAnglesRadFromRotation), which read back to the
// same matrix to about 1e-15. A file pattern's pattern_file is written
// relative to `json_dir` when given (the folder the JSON will be written
// to, so that ReadModuleDesignJson finds it again), else as stored; the
// pattern file itself is not written. `description`, when not empty, is
// written as the optional free text. Errors (InvalidArgument): the design's
// Validate(), a beam_error_seed the format cannot hold (above 2^31 - 1).
Result<std::string> FormatModuleDesignJson(const ModuleDesign& design,
                                           const std::string& json_dir = "",
                                           const std::string& description = "");

// FormatModuleDesignJson(design, folder of path), written atomically (nothing
// is left on failure; io/atomic_file.h).
Status WriteModuleDesignJson(const ModuleDesign& design, const std::string& path,
                             const std::string& description = "");

}  // namespace opl
