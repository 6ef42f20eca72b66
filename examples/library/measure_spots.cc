// Scale factor from a module calibration and the spots of a scene: the
// library's whole measurement in one program. Build it against an installed
// OPL (examples/library/CMakeLists.txt) and run it on the bundled example:
//   measure_spots examples/prototype_calibration.json examples/prototype_spots.csv
#include <cstdio>

#include <opl/io/module_calibration_json.h>
#include <opl/io/spots_csv.h>
#include <opl/pipeline/measure.h>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s CALIBRATION.json SPOTS.csv\n", argv[0]);
    return 2;
  }
  // The module's calibration (opl_calibrate writes it) and the spots seen in
  // the scene, in its units (docs/formats.md).
  opl::Result<opl::ModuleCalibration> calibration = opl::ReadModuleCalibrationJson(argv[1]);
  if (!calibration.ok()) {
    std::fprintf(stderr, "%s\n", calibration.status().message().c_str());  // names file and field
    return 3;
  }
  opl::Result<opl::SpotsCsvData> spots = opl::ReadSpotsCsv(argv[2]);
  if (!spots.ok()) {
    std::fprintf(stderr, "%s\n", spots.status().message().c_str());  // names file, line and field
    return 3;
  }
  // Locates every source from its spots (no starting guess needed; spots
  // without a source and beam are identified first), then s = L_cal / L_photo.
  opl::Result<opl::MeasureReport> report = opl::MeasureScale(*calibration, spots->spots);
  if (!report.ok()) {
    std::fprintf(stderr, "%s\n", report.status().message().c_str());
    return 4;
  }
  std::printf("s = %.6f +- %.6f\n", report->scale.scale_factor, report->scale.u_scale_factor);
  return 0;
}
