// OPL's file formats: module calibration JSON, spots CSV, point tables,
// points CSV, cameras JSON, and the streaming scaling of PLY / XYZ / CSV
// point files. (Design and scene JSON are read in bind_sim.cc and
// bind_images.cc, next to the classes they fill; COLMAP in bind_colmap.cc.)
#include "common.h"
#include "opl/io/atomic_file.h"
#include "opl/io/cameras_json.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/points_csv.h"
#include "opl/io/point_table.h"
#include "opl/io/scale_point_file.h"
#include "opl/io/spots_csv.h"

namespace opl_python {
namespace {

SpotTable FromCsvData(opl::SpotsCsvData&& data) {
  SpotTable t;
  t.slices = data.slices.empty() ? std::vector<int>(data.spots.size(), 0) : data.slices;
  t.spots = std::move(data.spots);
  return t;
}

std::string FormatSpots(const SpotTable& t, bool write_slices) {
  std::vector<opl::SpotsCsvExtraColumn> extra;
  if (write_slices) {
    opl::SpotsCsvExtraColumn c;
    c.name = "slice";
    for (int s : t.slices) c.values.push_back(std::to_string(s));
    extra.push_back(std::move(c));
  }
  return Unwrap(opl::FormatSpotsCsv(t.spots, extra));
}

}  // namespace

void BindIo(py::module_& m) {
  // Module calibration JSON.
  m.def(
      "read_module_calibration", [](const std::string& path) { return Unwrap(opl::ReadModuleCalibrationJson(path)); },
      py::arg("path"),
      "Reads a module calibration JSON (docs/formats.md). Raises IoError / ParseError naming the "
      "file and the field.");
  m.def(
      "parse_module_calibration",
      [](const std::string& text, const std::string& name) {
        return Unwrap(opl::ParseModuleCalibrationJson(text, name));
      },
      py::arg("text"), py::arg("name") = "<string>",
      "Parses a module calibration JSON document; `name` is what error messages call it.");
  m.def(
      "format_module_calibration",
      [](const opl::ModuleCalibration& c) { return Unwrap(opl::FormatModuleCalibrationJson(c)); },
      py::arg("calibration"), "The module calibration JSON text of a calibration.");
  m.def(
      "write_module_calibration",
      [](const opl::ModuleCalibration& c, const std::string& path) {
        ThrowIfError(opl::WriteModuleCalibrationJson(c, path));
      },
      py::arg("calibration"), py::arg("path"),
      "Writes a module calibration JSON (atomically: nothing is left on failure).");

  // Spots CSV and other programs' point tables.
  m.def(
      "read_spots_csv", [](const std::string& path) { return FromCsvData(Unwrap(opl::ReadSpotsCsv(path))); },
      py::arg("path"),
      "Reads a spots CSV ([source,beam,]x,y,z[,sx,sy,sz][,slice]; docs/formats.md) into Spots. "
      "ParseError names the file, the line and the field.");
  m.def(
      "parse_spots_csv",
      [](const std::string& text, const std::string& name) {
        return FromCsvData(Unwrap(opl::ParseSpotsCsv(text, name)));
      },
      py::arg("text"), py::arg("name") = "<string>", "Parses spots CSV text.");
  m.def("format_spots_csv", &FormatSpots, py::arg("spots"), py::arg("write_slices") = false,
        "The spots CSV text of spots (with a slice column when write_slices).");
  m.def(
      "write_spots_csv",
      [](const SpotTable& t, const std::string& path, bool write_slices) {
        ThrowIfError(opl::WriteFileAtomically(path, FormatSpots(t, write_slices)));
      },
      py::arg("spots"), py::arg("path"), py::arg("write_slices") = false,
      "Writes spots as a spots CSV (atomically), readable by opl_measure --spots.");
  m.def(
      "read_point_table",
      [](const std::string& path, const std::string& columns, int skip_rows,
         const std::string& delimiter, bool allow_extra_fields) {
        opl::PointTableFormat format = Unwrap(opl::ParseColumnMapping(columns));
        format.skip_rows = skip_rows;
        format.delimiter = Unwrap(opl::ParseDelimiterName(delimiter));
        format.allow_extra_fields = allow_extra_fields;
        ThrowIfError(format.Validate());
        return FromCsvData(Unwrap(opl::ReadPointTable(path, format)));
      },
      py::arg("path"), py::arg("columns"), py::arg("skip_rows") = 0, py::arg("delimiter") = "auto",
      py::arg("allow_extra_fields") = false,
      "Reads another program's point table as Spots (as opl_measure --columns): `columns` names "
      "the file's columns in order from id, x, y, z, sx, sy, sz, source, beam, slice and - "
      "(ignored), e.g. 'id,x,y,z'; delimiter: auto, comma, semicolon, tab or whitespace.");

  // Points CSV (the scene's other points, scaled by --apply).
  py::class_<opl::PointsCsv>(m, "PointsCsv",
                             "A points CSV: a header with x, y, z columns and any others, kept "
                             "as they are; scaling multiplies x, y, z only.")
      .def_static(
          "read", [](const std::string& path) { return Unwrap(opl::PointsCsv::Read(path)); },
          py::arg("path"), "Reads a points CSV.")
      .def_static(
          "parse",
          [](const std::string& text, const std::string& name) {
            return Unwrap(opl::PointsCsv::Parse(text, name));
          },
          py::arg("text"), py::arg("name") = "<string>", "Parses points CSV text.")
      .def_property_readonly(
          "points", [](const opl::PointsCsv& p) { return ArrayFromPoints(p.points()); },
          "(N, 3) coordinates, file order.")
      .def_property_readonly("ids", &opl::PointsCsv::ids, "The id column (empty strings when none).")
      .def_property_readonly("lines", &opl::PointsCsv::lines, "1-based line of each point.")
      .def("__len__", &opl::PointsCsv::num_points)
      .def(
          "scale", [](opl::PointsCsv& p, double s) { ThrowIfError(p.Scale(s)); }, py::arg("s"),
          "Multiplies every coordinate by s (> 0, finite).")
      .def("format", &opl::PointsCsv::Format, "The CSV text (other columns as read).")
      .def(
          "write",
          [](const opl::PointsCsv& p, const std::string& path) {
            ThrowIfError(opl::WriteFileAtomically(path, p.Format()));
          },
          py::arg("path"), "Writes the CSV (atomically).");

  // Cameras JSON.
  m.def(
      "read_cameras", [](const std::string& path) { return Unwrap(opl::ReadCamerasJson(path)); },
      py::arg("path"),
      "Reads a cameras JSON (a scene JSON's `cameras` block, or a whole scene JSON) into a list "
      "of SceneCamera.");
  m.def(
      "parse_cameras",
      [](const std::string& text, const std::string& name) {
        return Unwrap(opl::ParseCamerasJson(text, name));
      },
      py::arg("text"), py::arg("name") = "<string>", "Parses cameras JSON text.");
  m.def("format_cameras", &opl::FormatCamerasJson, py::arg("cameras"),
        "The cameras JSON text of a list of SceneCamera.");
  m.def(
      "write_cameras",
      [](const std::vector<opl::SceneCamera>& cameras, const std::string& path) {
        ThrowIfError(opl::WriteFileAtomically(path, opl::FormatCamerasJson(cameras)));
      },
      py::arg("cameras"), py::arg("path"), "Writes a cameras JSON (atomically).");

  // Point files (PLY, XYZ, points CSV), streamed.
  py::enum_<opl::PointFileFormat>(m, "PointFileFormat", "A point file's format.")
      .value("AUTO", opl::PointFileFormat::kAuto, "From the extension: .ply; .xyz or .txt; .csv")
      .value("PLY", opl::PointFileFormat::kPly)
      .value("XYZ", opl::PointFileFormat::kXyz)
      .value("CSV", opl::PointFileFormat::kCsv);
  py::class_<opl::ScalePointFileSummary>(m, "ScalePointFileSummary", "What scale_point_file did.")
      .def_readonly("format", &opl::ScalePointFileSummary::format)
      .def_readonly("num_points", &opl::ScalePointFileSummary::num_points)
      .def_readonly("bytes_read", &opl::ScalePointFileSummary::bytes_read)
      .def_readonly("bytes_written", &opl::ScalePointFileSummary::bytes_written)
      .def("brief_report", &opl::ScalePointFileSummary::BriefReport);
  m.def(
      "scale_point_file",
      [](const std::string& in_path, const std::string& out_path, double s, opl::PointFileFormat format) {
        opl::ScalePointFileOptions options;
        options.format = format;
        opl::ScalePointFileSummary summary;
        RunReleased([&] { return opl::ScalePointFile(in_path, out_path, s, options, &summary); });
        return summary;
      },
      py::arg("in_path"), py::arg("out_path"), py::arg("s"),
      py::arg("format") = opl::PointFileFormat::kAuto,
      "Multiplies every point of a PLY (ASCII or binary, every other property kept), headerless "
      "XYZ or points CSV file by s, streaming (as opl_measure --apply). The output is written "
      "atomically: nothing is left when the input is bad.");
  m.def(
      "check_point_file",
      [](const std::string& in_path, opl::PointFileFormat format) {
        opl::ScalePointFileOptions options;
        options.format = format;
        ThrowIfError(opl::CheckPointFile(in_path, options));
      },
      py::arg("in_path"), py::arg("format") = opl::PointFileFormat::kAuto,
      "Raises when the point file's header (PLY) or first records could not be scaled.");
}

}  // namespace opl_python
