// Simulation: module designs (and their JSON), surfaces, patterns, simulated
// spots and calibration slices.
#include "common.h"
#include "opl/io/module_design_json.h"
#include "opl/sim/module_design.h"
#include "opl/sim/pattern_models.h"
#include "opl/sim/simulate_slices.h"
#include "opl/sim/simulate_spots.h"
#include "opl/sim/surface.h"

namespace opl_python {
namespace {

// (Spots, true points (N, 3), outlier mask) of simulated spots.
py::tuple SimulatedTuple(const std::vector<opl::SimulatedSpot>& simulated) {
  SpotTable t;
  std::vector<Eigen::Vector3d> truth;
  std::vector<bool> outlier;
  for (const opl::SimulatedSpot& s : simulated) {
    t.spots.push_back(s.spot);
    t.slices.push_back(s.slice);
    truth.push_back(s.true_point_in_scene);
    outlier.push_back(s.outlier);
  }
  return py::make_tuple(t, ArrayFromPoints(truth), py::array_t<bool>(py::cast(outlier)));
}

void BindSurface(py::module_& m) {
  py::enum_<opl::SurfaceType>(m, "SurfaceType")
      .value("PLANE", opl::SurfaceType::kPlane)
      .value("SPHERE", opl::SurfaceType::kSphere)
      .value("BOX_CORNER", opl::SurfaceType::kBoxCorner)
      .value("PARABOLOID", opl::SurfaceType::kParaboloid)
      .value("PLANES", opl::SurfaceType::kPlanes);
  py::class_<opl::Surface>(m, "Surface",
                           "The surface spots land on (scene frame, mm): plane, sphere, box "
                           "corner, paraboloid, or a list of planes (calibration slices).")
      .def(py::init<>(), "The default: the plane x = 1000 mm.")
      .def_static(
          "plane", [](const Eigen::Vector3d& p, const Eigen::Vector3d& n) { return opl::Surface(opl::PlaneSurface{p, n}); },
          py::arg("point_mm"), py::arg("normal"), "A plane through a point with a normal.")
      .def_static(
          "sphere", [](const Eigen::Vector3d& c, double r) { return opl::Surface(opl::SphereSurface{c, r}); },
          py::arg("center_mm"), py::arg("radius_mm"))
      .def_static(
          "box_corner",
          [](const Eigen::Vector3d& c, const Eigen::Matrix3d& R) { return opl::Surface(opl::BoxCornerSurface{c, R}); },
          py::arg("corner_mm"), py::arg("scene_from_box") = Eigen::Matrix3d::Identity().eval(),
          "The inside of a box corner (three faces of a box frame meeting at `corner_mm`).")
      .def_static(
          "paraboloid",
          [](const Eigen::Vector3d& v, const Eigen::Vector3d& a, double c) {
            return opl::Surface(opl::ParaboloidSurface{v, a, c});
          },
          py::arg("vertex_mm"), py::arg("axis"), py::arg("curvature_per_mm"))
      .def_static(
          "planes",
          [](const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& planes) {
            opl::PlaneListSurface list;
            for (const auto& [p, n] : planes) list.planes.push_back(opl::PlaneSurface{p, n});
            return opl::Surface(list);
          },
          py::arg("planes"), "A list of planes, one per slice: [(point_mm, normal), ...].")
      .def_property_readonly("type", &opl::Surface::type)
      .def_property_readonly("type_name", [](const opl::Surface& s) { return std::string(s.TypeName()); })
      .def_property_readonly("num_slices", &opl::Surface::num_slices)
      .def("validate", [](const opl::Surface& s) { ThrowIfError(s.Validate()); })
      .def("intersect_ray", &opl::Surface::IntersectRay, py::arg("origin"), py::arg("unit_direction"),
           "The first hit of a ray (mm), or None.")
      .def("transformed", &opl::Surface::Transformed, py::arg("new_from_old"));
}

void BindDesign(py::module_& m) {
  py::enum_<opl::PatternModel>(m, "PatternModel", "How a designed source's beam directions are made.")
      .value("EQUAL_ANGLE", opl::PatternModel::kEqualAngle)
      .value("GRATING", opl::PatternModel::kGrating)
      .value("FILE", opl::PatternModel::kFile);
  using SD = opl::SourceDesign;
  py::class_<SD>(m, "SourceDesign", "A designed source: its pattern and pose (mm).")
      .def(py::init<>())
      .def_readwrite("name", &SD::name)
      .def_readwrite("beams_per_side", &SD::beams_per_side, "n, odd >= 3.")
      .def_readwrite("full_angle_deg", &SD::full_angle_deg)
      .def_readwrite("pattern", &SD::pattern)
      .def_readwrite("wavelength_nm", &SD::wavelength_nm)
      .def_readwrite("pattern_file", &SD::pattern_file)
      .def_readwrite("scene_from_source", &SD::scene_from_source, "Translation = projection origin, mm.")
      .def_readwrite("beam_error_mrad", &SD::beam_error_mrad)
      .def_readwrite("beam_error_seed", &SD::beam_error_seed);
  using MD = opl::ModuleDesign;
  py::class_<MD>(m, "ModuleDesign",
                 "A designed module in a scene: sources, the surface their spots land on and the "
                 "spot noise (standard deviations per axis, mm, in the noise frame). List "
                 "attributes return copies: assign the whole list to change it.")
      .def(py::init<>())
      .def_static(
          "read", [](const std::string& path) { return Unwrap(opl::ReadModuleDesignJson(path)); },
          py::arg("path"), "Reads a module design JSON (docs/formats.md).")
      .def_static(
          "parse",
          [](const std::string& text, const std::string& name, const std::string& base_dir) {
            return Unwrap(opl::ParseModuleDesignJson(text, name, base_dir));
          },
          py::arg("text"), py::arg("name") = "<string>", py::arg("base_dir") = "",
          "Parses design JSON text (pattern files relative to base_dir).")
      .def(
          "write",
          [](const MD& d, const std::string& path, const std::string& description) {
            ThrowIfError(opl::WriteModuleDesignJson(d, path, description));
          },
          py::arg("path"), py::arg("description") = "",
          "Writes the design as module design JSON (atomically: nothing is left on failure); a "
          "file pattern's pattern_file is written relative to the JSON's folder.")
      .def(
          "format",
          [](const MD& d, const std::string& json_dir, const std::string& description) {
            return Unwrap(opl::FormatModuleDesignJson(d, json_dir, description));
          },
          py::arg("json_dir") = "", py::arg("description") = "",
          "The design as module design JSON text (pattern_file relative to json_dir when given).")
      .def_readwrite("sources", &MD::sources)
      .def_readwrite("surface", &MD::surface)
      .def_readwrite("spot_noise_mm", &MD::spot_noise_mm)
      .def_readwrite("noise_frame_rotation", &MD::noise_frame_rotation)
      .def("validate", [](const MD& d) { ThrowIfError(d.Validate()); })
      .def("spot_covariance_mm2", &MD::SpotCovarianceMm2)
      .def("transformed", &MD::Transformed, py::arg("new_from_old"))
      .def("exact_calibration", [](const MD& d) { return Unwrap(opl::ExactCalibration(d)); },
           "The calibration the design stands for (exact directions and separations).");
  m.def(
      "make_pattern", [](const SD& s) { return Unwrap(opl::MakePattern(s)); }, py::arg("source"),
      "The beam pattern of a designed source.");
  m.def("make_equal_angle_pattern", &opl::MakeEqualAnglePattern, py::arg("beams_per_side"),
        py::arg("full_angle_rad"), "Equal neighbour angle pattern (model a).");
  m.def("make_grating_pattern", &opl::MakeGratingPattern, py::arg("beams_per_side"),
        py::arg("full_angle_rad"), py::arg("wavelength_nm"), "Grating pattern (model b).");
  m.def(
      "read_pattern_csv", [](const std::string& path) { return Unwrap(opl::ReadPatternCsv(path)); },
      py::arg("path"), "Reads a pattern CSV (id, az, el).");
  m.def(
      "write_pattern_csv",
      [](const opl::BeamPattern& p, const std::string& path) { ThrowIfError(opl::WritePatternCsv(p, path)); },
      py::arg("pattern"), py::arg("path"), "Writes a pattern CSV.");
}

void BindSimulate(py::module_& m) {
  using SO = opl::SpotSimulationOptions;
  py::class_<SO>(m, "SpotSimulationOptions")
      .def(py::init<>())
      .def_readwrite("seed", &SO::seed)
      .def_readwrite("missing_fraction", &SO::missing_fraction)
      .def_readwrite("outlier_fraction", &SO::outlier_fraction)
      .def_readwrite("outlier_distance_mm", &SO::outlier_distance_mm)
      .def_readwrite("attach_covariance", &SO::attach_covariance);
  m.def(
      "simulate_spots",
      [](const opl::ModuleDesign& d, const SO& options) {
        return SimulatedTuple(Unwrap(opl::SimulateSpots(d, options)));
      },
      py::arg("design"), py::arg("options") = SO(),
      "Casts every beam of the design onto its surface and adds the design's noise. Returns "
      "(spots, true_points (N, 3), outlier mask (N,)); spots carry source and beam.");
  py::class_<opl::ScreenSlicesOptions>(m, "ScreenSlicesOptions", "Calibration screens in front of a module.")
      .def(py::init<>())
      .def_readwrite("depths_mm", &opl::ScreenSlicesOptions::depths_mm)
      .def_readwrite("tilt_deg", &opl::ScreenSlicesOptions::tilt_deg)
      .def_readwrite("curvature_per_mm", &opl::ScreenSlicesOptions::curvature_per_mm);
  m.def(
      "make_calibration_screens",
      [](const opl::ModuleDesign& d, const opl::ScreenSlicesOptions& o) {
        return Unwrap(opl::MakeCalibrationScreens(d, o));
      },
      py::arg("design"), py::arg("options"), "The screens (one Surface per depth) of a calibration session.");
  m.def(
      "simulate_slices",
      [](const opl::ModuleDesign& d, const std::vector<opl::Surface>& screens, const SO& options) {
        std::vector<opl::SimulatedSpot> simulated = Unwrap(opl::SimulateSlices(d, screens, options));
        // A calibration slice is one grid on one screen (calibrate_module
        // refuses a slice holding two sources): as opl_simulate slices,
        // source i (design order) on screen k is slice i * K + k.
        const int num_screens = static_cast<int>(screens.size());
        for (opl::SimulatedSpot& s : simulated) {
          int source_index = 0;
          while (source_index < static_cast<int>(d.sources.size()) &&
                 d.sources[static_cast<size_t>(source_index)].name != s.spot.source) {
            ++source_index;
          }
          s.slice = source_index * num_screens + s.slice;
        }
        return SimulatedTuple(simulated);
      },
      py::arg("design"), py::arg("screens"), py::arg("options") = SO(),
      "Simulates a calibration session: the spots of every source on every screen. A slice is "
      "one grid on one screen, so Spots.slices is i * K + k for source i (design order) on "
      "screen k of K, ready for calibrate_module. Returns (spots, true_points, outlier mask).");
}

}  // namespace

void BindSim(py::module_& m) {
  BindSurface(m);
  BindDesign(m);
  BindSimulate(m);
}

}  // namespace opl_python
