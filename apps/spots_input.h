// The spots input shared by opl_measure and opl_calibrate: a spots CSV read
// by its header names (docs/formats.md, "Spots CSV"), or, with --columns, a
// point table exported by other photogrammetry software (docs/formats.md,
// "Point tables from other software").
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "opl/core/status.h"
#include "opl/io/spots_csv.h"

namespace opl {
namespace cli {

struct SpotsInputArgs {
  std::string path;
  std::string columns;  // empty: a spots CSV with a header
  int skip_rows = 0;
  std::string delimiter = "auto";
  bool allow_extra_fields = false;
};

// Adds --columns, --skip-rows, --delimiter and --allow-extra-fields (the file
// option itself is the tool's own).
void AddPointTableOptions(CLI::App& app, SpotsInputArgs* args);

// Reads args.path. Usage errors (a bad --columns or --delimiter, --skip-rows
// without --columns) come back as InvalidArgument starting with the option's
// name; file errors as ReadSpotsCsv / ReadPointTable give them.
Result<SpotsCsvData> ReadSpotsInput(const SpotsInputArgs& args, bool* usage_error);

}  // namespace cli
}  // namespace opl
