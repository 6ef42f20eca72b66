#include "spots_input.h"

#include "opl/io/point_table.h"

namespace opl {
namespace cli {

void AddPointTableOptions(CLI::App& app, SpotsInputArgs* args) {
  app.add_option("--columns", args->columns,
                 "Read the spots file as a point table of another program: its columns in\n"
                 "file order, from id, x, y, z, sx, sy, sz, source, beam, slice and - (ignored),\n"
                 "e.g. id,x,y,z or id,x,y,z,sx,sy,sz. Without source and beam columns every\n"
                 "point is identified against the calibration (docs/formats.md)")
      ->type_name("LIST");
  app.add_option("--skip-rows", args->skip_rows,
                 "With --columns: lines to skip at the top (a header row: 1)")
      ->capture_default_str()
      ->type_name("N");
  app.add_option("--delimiter", args->delimiter,
                 "With --columns: auto, comma, semicolon, tab or whitespace")
      ->capture_default_str()
      ->type_name("D");
  app.add_flag("--allow-extra-fields", args->allow_extra_fields,
               "With --columns: ignore fields beyond the mapped columns");
}

Result<SpotsCsvData> ReadSpotsInput(const SpotsInputArgs& args, bool* usage_error) {
  *usage_error = false;
  if (args.columns.empty()) {
    if (args.skip_rows != 0 || args.delimiter != "auto" || args.allow_extra_fields) {
      *usage_error = true;
      return Status::InvalidArgument(
          "--skip-rows, --delimiter and --allow-extra-fields need --columns (a spots CSV is "
          "read by its header)");
    }
    return ReadSpotsCsv(args.path);
  }
  Result<PointTableFormat> format = ParseColumnMapping(args.columns);
  Result<PointTableFormat::Delimiter> delimiter = ParseDelimiterName(args.delimiter);
  if (!format.ok() || !delimiter.ok()) {
    *usage_error = true;
    return !format.ok() ? format.status() : delimiter.status();
  }
  format->skip_rows = args.skip_rows;
  format->delimiter = *delimiter;
  format->allow_extra_fields = args.allow_extra_fields;
  if (Status st = format->Validate(); !st.ok()) {
    *usage_error = true;
    return st;
  }
  return ReadPointTable(args.path, *format);
}

}  // namespace cli
}  // namespace opl
