// opl.Rigid3, the beam pattern and the module calibration model.
#include "common.h"
#include "opl/geometry/rigid3.h"
#include "opl/geometry/rotation.h"
#include "opl/model/beam_pattern.h"
#include "opl/model/module_calibration.h"

namespace opl_python {

void BindGeometryModel(py::module_& m) {
  using opl::Rigid3d;
  py::class_<Rigid3d>(m, "Rigid3",
                      "A rigid transform b_from_a: x_in_b = R x_in_a + t (R a rotation matrix, t "
                      "a translation). A source's pose is scene_from_source: its translation is "
                      "the projection origin in the scene frame.")
      .def(py::init<>(), "The identity.")
      .def(py::init([](const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
             const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
             if (!(err < 1e-6) || !(R.determinant() > 0)) {
               ThrowIfError(opl::Status::InvalidArgument(
                   "Rigid3: rotation: not a rotation matrix (|R^T R - I| = " +
                   std::to_string(err) + ", det = " + std::to_string(R.determinant()) + ")"));
             }
             return Rigid3d(R, t);
           }),
           py::arg("rotation"), py::arg("translation"),
           "From a 3x3 rotation matrix and a translation (3,).")
      .def_static(
          "from_xyz_angles",
          [](const Eigen::Vector3d& xyz_rad, const Eigen::Vector3d& t) {
            return Rigid3d(opl::RotationFromXyzAnglesRad(xyz_rad), t);
          },
          py::arg("xyz_rad"), py::arg("translation"),
          "From angles (alpha, beta, gamma) [rad] with R = Rx(alpha) Ry(beta) Rz(gamma) (the "
          "convention of OPL's files and reports) and a translation.")
      .def_static(
          "from_quaternion",
          [](const Eigen::Vector4d& wxyz, const Eigen::Vector3d& t) {
            if (!(wxyz.norm() > 0)) {
              ThrowIfError(opl::Status::InvalidArgument("Rigid3: quaternion: zero"));
            }
            return Rigid3d(Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]), t);
          },
          py::arg("wxyz"), py::arg("translation"),
          "From a quaternion (w, x, y, z) (normalised) and a translation.")
      .def_property_readonly("rotation", &Rigid3d::RotationMatrix, "R, 3x3.")
      .def_property(
          "translation", [](const Rigid3d& r) { return r.translation; },
          [](Rigid3d& r, const Eigen::Vector3d& t) { r.translation = t; }, "t, (3,).")
      .def_property_readonly(
          "quaternion_wxyz",
          [](const Rigid3d& r) {
            return Eigen::Vector4d(r.rotation.w(), r.rotation.x(), r.rotation.y(), r.rotation.z());
          },
          "The rotation as a unit quaternion (w, x, y, z).")
      .def_property_readonly(
          "xyz_angles_rad",
          [](const Rigid3d& r) { return opl::XyzAnglesRadFromRotation(r.RotationMatrix()); },
          "(alpha, beta, gamma) [rad] with R = Rx(alpha) Ry(beta) Rz(gamma).")
      .def("inverse", &Rigid3d::Inverse, "a_from_b.")
      .def(
          "__mul__", [](const Rigid3d& c_from_b, const Rigid3d& b_from_a) { return c_from_b * b_from_a; },
          py::is_operator(), "Composition: (c_from_b * b_from_a) = c_from_a.")
      .def(
          "apply",
          [](const Rigid3d& r, const py::array_t<double, py::array::forcecast>& points) -> py::object {
            if (points.ndim() == 1) {
              if (points.shape(0) != 3) {
                ThrowIfError(opl::Status::InvalidArgument("Rigid3.apply: points: expected (3,) or (N, 3)"));
              }
              Eigen::Vector3d p(points.at(0), points.at(1), points.at(2));
              return py::cast(Eigen::Vector3d(r * p));
            }
            std::vector<Eigen::Vector3d> p = PointsFromArray(points, "Rigid3.apply: points");
            for (auto& x : p) x = r * x;
            return ArrayFromPoints(p);
          },
          py::arg("points"), "x_in_b for points x_in_a, (3,) or (N, 3).")
      .def("__repr__", [](const Rigid3d& r) {
        const Eigen::Vector3d a = opl::XyzAnglesRadFromRotation(r.RotationMatrix());
        return "Rigid3(xyz_angles_rad=[" + std::to_string(a[0]) + ", " + std::to_string(a[1]) +
               ", " + std::to_string(a[2]) + "], translation=[" + std::to_string(r.translation[0]) +
               ", " + std::to_string(r.translation[1]) + ", " + std::to_string(r.translation[2]) + "])";
      });

  py::class_<opl::BeamPattern>(
      m, "BeamPattern",
      "The calibrated (or designed) pointing directions of a source's n x n beams, in the source "
      "frame: azimuth atan2(y, x), elevation atan2(z, hypot(x, y)), radians. Beam id = row * n + "
      "col + 1, row 0 the top row, col 0 the rightmost seen from behind (docs/method).")
      .def(py::init([](int beams_per_side, const Eigen::VectorXi& ids, const Eigen::VectorXd& az_rad,
                       const Eigen::VectorXd& el_rad) {
             if (ids.size() != az_rad.size() || ids.size() != el_rad.size()) {
               ThrowIfError(opl::Status::InvalidArgument(
                   "BeamPattern: ids, az_rad, el_rad: lengths differ (" + std::to_string(ids.size()) +
                   ", " + std::to_string(az_rad.size()) + ", " + std::to_string(el_rad.size()) + ")"));
             }
             std::vector<opl::Beam> beams(static_cast<size_t>(ids.size()));
             for (Eigen::Index i = 0; i < ids.size(); ++i) {
               beams[static_cast<size_t>(i)].id = ids[i];
               beams[static_cast<size_t>(i)].az_rad = az_rad[i];
               beams[static_cast<size_t>(i)].el_rad = el_rad[i];
             }
             return Unwrap(opl::BeamPattern::Create(beams_per_side, std::move(beams)));
           }),
           py::arg("beams_per_side"), py::arg("ids"), py::arg("az_rad"), py::arg("el_rad"),
           "From n and the beams' ids and directions (arrays of equal length).")
      .def_property_readonly("beams_per_side", &opl::BeamPattern::beams_per_side, "n.")
      .def_property_readonly("central_beam_id", &opl::BeamPattern::central_beam_id,
                             "(n^2 + 1) / 2.")
      .def_property_readonly(
          "ids",
          [](const opl::BeamPattern& p) {
            Eigen::VectorXi v(static_cast<Eigen::Index>(p.beams().size()));
            for (size_t i = 0; i < p.beams().size(); ++i) v[static_cast<Eigen::Index>(i)] = p.beams()[i].id;
            return v;
          },
          "Beam ids, increasing.")
      .def_property_readonly(
          "az_rad",
          [](const opl::BeamPattern& p) {
            Eigen::VectorXd v(static_cast<Eigen::Index>(p.beams().size()));
            for (size_t i = 0; i < p.beams().size(); ++i) v[static_cast<Eigen::Index>(i)] = p.beams()[i].az_rad;
            return v;
          },
          "Azimuth of each beam (same order as ids) [rad].")
      .def_property_readonly(
          "el_rad",
          [](const opl::BeamPattern& p) {
            Eigen::VectorXd v(static_cast<Eigen::Index>(p.beams().size()));
            for (size_t i = 0; i < p.beams().size(); ++i) v[static_cast<Eigen::Index>(i)] = p.beams()[i].el_rad;
            return v;
          },
          "Elevation of each beam (same order as ids) [rad].")
      .def_property_readonly(
          "directions",
          [](const opl::BeamPattern& p) {
            std::vector<Eigen::Vector3d> d;
            for (const opl::Beam& b : p.beams()) d.push_back(b.DirectionInSource());
            return ArrayFromPoints(d);
          },
          "Unit direction of each beam in the source frame, (N, 3).")
      .def("__len__", [](const opl::BeamPattern& p) { return p.beams().size(); });

  py::class_<opl::SourceCalibrationQuality>(m, "SourceCalibrationQuality",
                                            "How well a source's calibration fitted its samples.")
      .def(py::init<>())
      .def_readwrite("slices", &opl::SourceCalibrationQuality::slices)
      .def_readwrite("samples_used", &opl::SourceCalibrationQuality::samples_used)
      .def_readwrite("samples_flagged", &opl::SourceCalibrationQuality::samples_flagged)
      .def_readwrite("beams_dropped", &opl::SourceCalibrationQuality::beams_dropped)
      .def_readwrite("rms_residual_urad", &opl::SourceCalibrationQuality::rms_residual_urad)
      .def_readwrite("variance_factor", &opl::SourceCalibrationQuality::variance_factor)
      .def_readwrite("mean_point_to_ray_mm", &opl::SourceCalibrationQuality::mean_point_to_ray_mm)
      .def_readwrite("max_point_to_ray_mm", &opl::SourceCalibrationQuality::max_point_to_ray_mm)
      .def_readwrite("origin_cov_mm2", &opl::SourceCalibrationQuality::origin_cov_mm2)
      .def_readwrite("rotation_xyz_cov_rad2", &opl::SourceCalibrationQuality::rotation_xyz_cov_rad2);

  py::class_<opl::SourceCalibration>(m, "SourceCalibration",
                                     "One calibrated source: its beam pattern and its pose in the "
                                     "calibration frame (mm).")
      .def(py::init<>())
      .def_readwrite("name", &opl::SourceCalibration::name)
      .def_readwrite("pattern", &opl::SourceCalibration::pattern)
      .def_readwrite("calibration_from_source", &opl::SourceCalibration::calibration_from_source)
      .def_readwrite("quality", &opl::SourceCalibration::quality, "SourceCalibrationQuality or None.");

  py::class_<opl::Separation>(m, "Separation",
                              "A calibrated length scale: the distance between two origins [mm].")
      .def(py::init<>())
      .def_readwrite("from_source", &opl::Separation::from)
      .def_readwrite("to_source", &opl::Separation::to)
      .def_readwrite("length_mm", &opl::Separation::length_mm)
      .def_readwrite("u_length_mm", &opl::Separation::u_length_mm, "Standard uncertainty (k = 1).");

  py::class_<opl::CalibrationScaling>(m, "CalibrationScaling",
                                      "How a calibration session was scaled by an artifact.")
      .def(py::init<>())
      .def_readwrite("from_target", &opl::CalibrationScaling::from_target)
      .def_readwrite("to_target", &opl::CalibrationScaling::to_target)
      .def_readwrite("artifact_length_mm", &opl::CalibrationScaling::artifact_length_mm)
      .def_readwrite("u_artifact_length_mm", &opl::CalibrationScaling::u_artifact_length_mm)
      .def_readwrite("measured_length", &opl::CalibrationScaling::measured_length)
      .def_readwrite("u_measured_length", &opl::CalibrationScaling::u_measured_length)
      .def_readwrite("scale", &opl::CalibrationScaling::scale)
      .def_readwrite("u_scale_relative", &opl::CalibrationScaling::u_scale_relative);

  py::class_<opl::ModuleCalibration>(
      m, "ModuleCalibration",
      "A calibrated module: its sources and the separations between their origins (the length "
      "scales). Attributes holding lists return copies: assign the whole list to change it.")
      .def(py::init<>())
      .def_readwrite("sources", &opl::ModuleCalibration::sources)
      .def_readwrite("separations", &opl::ModuleCalibration::separations)
      .def_readwrite("scaling", &opl::ModuleCalibration::scaling, "CalibrationScaling or None.")
      .def(
          "validate", [](const opl::ModuleCalibration& c) { ThrowIfError(c.Validate()); },
          "Raises when the calibration is inconsistent (the message names the field).")
      .def(
          "find_source",
          [](const opl::ModuleCalibration& c, const std::string& name) -> opl::SourceCalibration {
            const opl::SourceCalibration* s = c.FindSource(name);
            if (s == nullptr) {
              throw py::key_error("ModuleCalibration: no source named '" + name + "'");
            }
            return *s;
          },
          py::arg("name"), "The source of that name (a copy); KeyError when none.")
      .def_static("separations_from_origins", &opl::ModuleCalibration::SeparationsFromOrigins,
                  py::arg("sources"),
                  "The separations between every pair of the sources' origins (no uncertainty).");
}

}  // namespace opl_python
