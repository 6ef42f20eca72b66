// Cameras, scenes (scene JSON) and the images front end: the scale factor
// from photographs.
#include "common.h"
#include "opl/io/scene_json.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/image_front_end.h"
#include "opl/pipeline/measure_images.h"
#include "opl/vision/camera_model.h"

namespace opl_python {

void BindImages(py::module_& m) {
  using CI = opl::CameraIntrinsics;
  py::class_<CI>(m, "CameraIntrinsics",
                 "Pinhole + Brown-Conrady (k1, k2, k3, p1, p2) intrinsics, pixels, OpenCV "
                 "convention (centre of the top-left pixel at 0, 0).")
      .def(py::init<>())
      .def_readwrite("width_px", &CI::width_px)
      .def_readwrite("height_px", &CI::height_px)
      .def_readwrite("fx_px", &CI::fx_px)
      .def_readwrite("fy_px", &CI::fy_px)
      .def_readwrite("cx_px", &CI::cx_px)
      .def_readwrite("cy_px", &CI::cy_px)
      .def_readwrite("k1", &CI::k1)
      .def_readwrite("k2", &CI::k2)
      .def_readwrite("k3", &CI::k3)
      .def_readwrite("p1", &CI::p1)
      .def_readwrite("p2", &CI::p2)
      .def("validate", [](const CI& c) { ThrowIfError(c.Validate()); })
      .def(
          "project",
          [](const CI& c, const Eigen::Vector3d& p) -> std::optional<Eigen::Vector2d> {
            Eigen::Vector2d px;
            if (!opl::ProjectToPixel(c, p, &px)) return std::nullopt;
            return px;
          },
          py::arg("point_in_cam"), "The pixel of a point in the camera frame (None behind it).");

  py::class_<opl::SceneCameraCalibration>(m, "SceneCameraCalibration",
                                          "How a camera was calibrated (standard deviations, RMS).")
      .def(py::init<>())
      .def_readwrite("intrinsics_std", &opl::SceneCameraCalibration::intrinsics_std,
                     "Standard deviations of fx, fy, cx, cy, k1, k2, p1, p2, k3.")
      .def_readwrite("rms_px", &opl::SceneCameraCalibration::rms_px)
      .def_readwrite("num_views", &opl::SceneCameraCalibration::num_views)
      .def_readwrite("num_corners", &opl::SceneCameraCalibration::num_corners)
      .def_readwrite("board", &opl::SceneCameraCalibration::board);
  py::class_<opl::SceneCamera>(m, "SceneCamera", "A named calibrated camera of a scene.")
      .def(py::init<>())
      .def_readwrite("name", &opl::SceneCamera::name)
      .def_readwrite("intrinsics", &opl::SceneCamera::intrinsics)
      .def_readwrite("cam_from_scene", &opl::SceneCamera::cam_from_scene, "Rigid3 or None.")
      .def_readwrite("calibration", &opl::SceneCamera::calibration, "SceneCameraCalibration or None.");
  py::class_<opl::SceneShot>(m, "SceneShot", "One photograph: camera, file, lasers on, slice, placement.")
      .def(py::init<>())
      .def_readwrite("camera", &opl::SceneShot::camera)
      .def_readwrite("file", &opl::SceneShot::file)
      .def_readwrite("lasers", &opl::SceneShot::lasers)
      .def_readwrite("slice", &opl::SceneShot::slice)
      .def_readwrite("placement", &opl::SceneShot::placement,
                     "The module placement it shows ('' when the scene lists none).");
  py::class_<opl::Scene>(m, "Scene",
                         "A scene JSON: cameras, tags, frame, artifact, module, the look of the "
                         "images and the shots (docs/formats.md). List attributes return copies.")
      .def_static(
          "read", [](const std::string& path) { return Unwrap(opl::ReadSceneJson(path)); },
          py::arg("path"), "Reads a scene JSON; errors name the file and the field.")
      .def_static(
          "parse",
          [](const std::string& text, const std::string& name, const std::string& base_dir) {
            return Unwrap(opl::ParseSceneJson(text, name, base_dir));
          },
          py::arg("text"), py::arg("name") = "<string>", py::arg("base_dir") = "")
      .def_readwrite("cameras", &opl::Scene::cameras)
      .def_readwrite("shots", &opl::Scene::shots)
      .def_readwrite("module", &opl::Scene::module, "ModuleDesign or None.")
      .def_readwrite("seed", &opl::Scene::seed)
      .def_property_readonly("tag_ids",
                             [](const opl::Scene& s) {
                               std::vector<int> ids;
                               for (const opl::SceneTag& t : s.tags.tags) ids.push_back(t.id);
                               return ids;
                             })
      .def_property_readonly("tag_size_mm", [](const opl::Scene& s) { return s.tags.size_mm; })
      .def_property_readonly(
          "module_placements",
          [](const opl::Scene& s) {
            std::vector<std::string> names;
            for (const opl::SceneModulePlacement& p : s.module_placements) names.push_back(p.name);
            return names;
          },
          "Names of the module placements (empty: one, the module as designed).")
      .def("validate", [](const opl::Scene& s) { ThrowIfError(s.Validate()); });

  using FO = opl::FrontEndOptions;
  py::class_<FO>(m, "FrontEndOptions",
                 "The main options of the images front end "
                 "(include/opl/pipeline/image_front_end.h documents them all).")
      .def(py::init<>())
      .def_readwrite("max_tag_residual_px", &FO::max_tag_residual_px)
      .def_readwrite("min_tag_triangulation_angle_deg", &FO::min_tag_triangulation_angle_deg)
      .def_readwrite("min_spot_snr", &FO::min_spot_snr)
      .def_readwrite("max_spot_center_sigma_px", &FO::max_spot_center_sigma_px)
      .def_readwrite("max_tag_rms_ratio", &FO::max_tag_rms_ratio)
      .def_readwrite("force", &FO::force)
      .def_readwrite("min_spot_sigma_px", &FO::min_spot_sigma_px)
      .def_readwrite("rescale_spot_covariances", &FO::rescale_spot_covariances)
      .def_readwrite("one_pose_per_camera", &FO::one_pose_per_camera)
      .def_readwrite("use_dark_frames", &FO::use_dark_frames)
      .def_readwrite("max_dark_frame_shift_px", &FO::max_dark_frame_shift_px)
      .def_readwrite("match_dark_frame_exposure", &FO::match_dark_frame_exposure,
                     "Scale a laser-off frame to its lit shot's exposure when they differ "
                     "(default True; docs/images.md, 'Laser-off frames').")
      .def_readwrite("min_dark_frame_gain", &FO::min_dark_frame_gain)
      .def_readwrite("max_dark_frame_gain", &FO::max_dark_frame_gain)
      .def_readwrite("scale_in_adjustment", &FO::scale_in_adjustment,
                     "The module as a calibrated projector in the adjustment, its s the "
                     "report's s (default True; docs/multiview.md).")
      .def_readwrite("num_threads", &FO::num_threads, "0: every core.");
  using IO = opl::ImageMeasureOptions;
  py::class_<IO>(m, "ImageMeasureOptions")
      .def(py::init<>())
      .def_readwrite("front_end", &IO::front_end)
      .def_readwrite("measure", &IO::measure)
      .def_readwrite("propagate_shared_errors", &IO::propagate_shared_errors);
  using IR = opl::ImageMeasureReport;
  py::class_<IR>(m, "ImageMeasureReport", "A measurement from photographs.")
      .def_property_readonly(
          "spots",
          [](const IR& r) {
            SpotTable t;
            t.spots = r.spots;
            t.slices.assign(r.spots.size(), 0);
            return t;
          },
          "The 3D spots (scene frame, unscaled) with their covariances.")
      .def_readonly("identification", &IR::identification)
      .def_readonly("measure", &IR::measure)
      .def_readonly("s", &IR::scale_factor,
                    "The reported s (what opl_measure prints last): the scale inside the "
                    "adjustment, or the two-step s (scale_method says which).")
      .def_readonly("u_s", &IR::u_scale_factor, "u(s) of the reported s.")
      .def_property_readonly("scale_method",
                             [](const IR& r) { return std::string(opl::ScaleMethodName(r.scale_method)); },
                             "'adjustment' or 'two-step'.")
      .def_readonly("scale_method_note", &IR::scale_method_note,
                    "Why the two-step s is reported (empty when it is not).")
      .def_property_readonly("two_step_s", [](const IR& r) { return r.measure.scale.scale_factor; },
                             "The two-step s (also measure.scale.scale_factor).")
      .def_property_readonly("two_step_u_s", [](const IR& r) { return r.measure.scale.u_scale_factor; },
                             "Its u(s), including the errors the spots share (cameras, frame tags).")
      .def_readonly("u_scale_factor_own", &IR::u_scale_factor_own)
      .def_readonly("u_scale_factor_shared", &IR::u_scale_factor_shared)
      .def_readonly("metadata_conflicts", &IR::metadata_conflicts)
      .def_property_readonly("front_end_text", [](const IR& r) { return r.front_end.ToText(); },
                             "Per image: tags, spots detected and matched, RMS; warnings.")
      .def_property_readonly("warnings", [](const IR& r) { return r.front_end.warnings; })
      .def("to_text", &IR::ToText)
      .def("to_json", &IR::ToJson);
  m.def(
      "measure_scale_from_images",
      [](const opl::Scene& scene, const std::string& images_dir, const opl::ModuleCalibration& c,
         const IO& options) {
        return RunReleased([&] { return opl::MeasureScaleFromImages(scene, images_dir, c, options); });
      },
      py::arg("scene"), py::arg("images_dir"), py::arg("calibration"), py::arg("options") = IO(),
      "The scale factor from photographs (as opl_measure --images --scene): tags and spots "
      "detected in every shot of the scene, cameras posed, spots triangulated and adjusted, then "
      "identified and measured.");
}

}  // namespace opl_python
