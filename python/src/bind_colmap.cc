// COLMAP sparse models (text and binary): read, scale, write, with numpy
// arrays for the 3D points.
#include "common.h"
#include "opl/io/colmap_model.h"

namespace opl_python {

void BindColmap(py::module_& m) {
  py::enum_<opl::ColmapFormat>(m, "ColmapFormat", "A COLMAP model's file format.")
      .value("TEXT", opl::ColmapFormat::kText, "cameras.txt, images.txt, points3D.txt")
      .value("BINARY", opl::ColmapFormat::kBinary, "cameras.bin, images.bin, points3D.bin");

  py::class_<opl::ColmapCamera>(m, "ColmapCamera", "A COLMAP camera (model id and parameters).")
      .def(py::init<>())
      .def_readwrite("camera_id", &opl::ColmapCamera::camera_id)
      .def_readwrite("model_id", &opl::ColmapCamera::model_id)
      .def_property_readonly("model_name",
                             [](const opl::ColmapCamera& c) { return std::string(opl::ColmapCameraModelName(c.model_id)); })
      .def_readwrite("width_px", &opl::ColmapCamera::width_px)
      .def_readwrite("height_px", &opl::ColmapCamera::height_px)
      .def_readwrite("params", &opl::ColmapCamera::params)
      .def(
          "intrinsics",
          [](const opl::ColmapCamera& c) { return Unwrap(opl::IntrinsicsFromColmap(c)); },
          "OPL's CameraIntrinsics of this camera (PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, "
          "FULL_OPENCV; other models raise, naming the camera and its model).");

  py::class_<opl::ColmapImage>(m, "ColmapImage", "A COLMAP image: its pose cam_from_world and 2D points.")
      .def(py::init<>())
      .def_readwrite("image_id", &opl::ColmapImage::image_id)
      .def_readwrite("camera_id", &opl::ColmapImage::camera_id)
      .def_readwrite("name", &opl::ColmapImage::name)
      .def_property(
          "qvec_wxyz", [](const opl::ColmapImage& i) { return Eigen::Vector4d(i.qvec_wxyz[0], i.qvec_wxyz[1], i.qvec_wxyz[2], i.qvec_wxyz[3]); },
          [](opl::ColmapImage& i, const Eigen::Vector4d& q) { i.qvec_wxyz = {q[0], q[1], q[2], q[3]}; },
          "Rotation of cam_from_world as a quaternion (w, x, y, z).")
      .def_readwrite("tvec", &opl::ColmapImage::tvec, "Translation of cam_from_world.")
      .def("cam_from_world", &opl::ColmapImage::CamFromWorld, "The pose as a Rigid3.")
      .def("center_in_world", &opl::ColmapImage::CenterInWorld, "The camera centre, (3,).")
      .def_property_readonly(
          "points2d_px",
          [](const opl::ColmapImage& i) {
            Eigen::MatrixX2d a(static_cast<Eigen::Index>(i.points2D.size()), 2);
            for (size_t k = 0; k < i.points2D.size(); ++k) a.row(static_cast<Eigen::Index>(k)) = i.points2D[k].xy_px;
            return a;
          },
          "(K, 2) keypoints in COLMAP's pixel convention (centre of the top-left pixel at 0.5).")
      .def_property_readonly(
          "point3d_ids",
          [](const opl::ColmapImage& i) {
            std::vector<int64_t> v;
            for (const auto& p : i.points2D) {
              v.push_back(p.point3D_id == opl::kColmapNoPoint3D ? -1 : static_cast<int64_t>(p.point3D_id));
            }
            return v;
          },
          "The 3D point id of each keypoint (-1: none).");

  py::class_<opl::ColmapModel>(
      m, "ColmapModel",
      "A COLMAP sparse model. cameras and images are dicts by id (copies); the 3D points are "
      "given as arrays (point3d_ids, points3d, colors, errors).")
      .def_static(
          "read",
          [](const std::string& dir, std::optional<opl::ColmapFormat> format) {
            return format ? Unwrap(opl::ReadColmapModel(dir, *format)) : Unwrap(opl::ReadColmapModel(dir));
          },
          py::arg("dir"), py::arg("format") = py::none(),
          "Reads the model in a folder (the format found there, binary first, unless given).")
      .def(
          "write",
          [](const opl::ColmapModel& model, const std::string& dir, std::optional<opl::ColmapFormat> format) {
            ThrowIfError(opl::WriteColmapModel(model, dir, format.value_or(model.format)));
          },
          py::arg("dir"), py::arg("format") = py::none(),
          "Writes the model into a folder (the format it was read in unless given).")
      .def(
          "scaled", [](const opl::ColmapModel& model, double s) { return opl::ScaledColmapModel(model, s); },
          py::arg("s"), "A copy with every length (points, camera centres) multiplied by s.")
      .def("validate", [](const opl::ColmapModel& model) { ThrowIfError(model.Validate()); })
      .def_readonly("format", &opl::ColmapModel::format)
      .def_readonly("cameras", &opl::ColmapModel::cameras)
      .def_readonly("images", &opl::ColmapModel::images)
      .def_property_readonly(
          "point3d_ids",
          [](const opl::ColmapModel& model) {
            std::vector<uint64_t> v;
            for (const auto& [id, p] : model.points3D) v.push_back(id);
            return v;
          },
          "Ids of the 3D points, increasing (the row order of points3d).")
      .def_property_readonly(
          "points3d",
          [](const opl::ColmapModel& model) {
            std::vector<Eigen::Vector3d> v;
            for (const auto& [id, p] : model.points3D) v.push_back(p.xyz_in_world);
            return ArrayFromPoints(v);
          },
          "(N, 3) 3D points in the model's world frame.")
      .def_property_readonly(
          "colors",
          [](const opl::ColmapModel& model) {
            py::array_t<uint8_t> a({static_cast<py::ssize_t>(model.points3D.size()), py::ssize_t{3}});
            auto w = a.mutable_unchecked<2>();
            py::ssize_t i = 0;
            for (const auto& [id, p] : model.points3D) {
              for (int k = 0; k < 3; ++k) w(i, k) = p.rgb[static_cast<size_t>(k)];
              ++i;
            }
            return a;
          },
          "(N, 3) uint8 RGB of each 3D point.")
      .def_property_readonly(
          "errors_px",
          [](const opl::ColmapModel& model) {
            std::vector<double> v;
            for (const auto& [id, p] : model.points3D) v.push_back(p.error_px);
            return v;
          },
          "COLMAP's mean reprojection error of each 3D point [px] (-1: unknown).");

  m.def("is_colmap_model_dir", &opl::IsColmapModelDir, py::arg("dir"),
        "True when the folder holds a COLMAP model (text or binary).");
}

}  // namespace opl_python
