// The solves: locate a source, identify spots, the scale factor, measure,
// calibrate a module.
#include "common.h"
#include "opl/calibrate/calibrate_module.h"
#include "opl/identify/identify_spots.h"
#include "opl/locate/locate_source.h"
#include "opl/pipeline/measure.h"
#include "opl/scale/scale_factor.h"

namespace opl_python {
namespace {

void BindLocate(py::module_& m) {
  py::enum_<opl::RobustLoss>(m, "RobustLoss", "Robust loss of the locate and calibrate solves.")
      .value("NONE", opl::RobustLoss::kNone)
      .value("HUBER", opl::RobustLoss::kHuber)
      .value("CAUCHY", opl::RobustLoss::kCauchy);

  using LO = opl::LocateOptions;
  py::class_<LO>(m, "LocateOptions",
                 "Options of locate_source (include/opl/locate/locate_source.h documents each).")
      .def(py::init<>())
      .def_readwrite("loss", &LO::loss)
      .def_readwrite("loss_scale", &LO::loss_scale)
      .def_readwrite("loss_scale_unweighted_rad", &LO::loss_scale_unweighted_rad)
      .def_readwrite("ransac_inlier_threshold_rad", &LO::ransac_inlier_threshold_rad)
      .def_readwrite("ransac_max_iterations", &LO::ransac_max_iterations)
      .def_readwrite("ransac_confidence", &LO::ransac_confidence)
      .def_readwrite("ransac_seed", &LO::ransac_seed)
      .def_readwrite("outlier_threshold", &LO::outlier_threshold)
      .def_readwrite("min_unweighted_sigma_rad", &LO::min_unweighted_sigma_rad)
      .def_readwrite("min_inlier_fraction", &LO::min_inlier_fraction)
      .def_readwrite("initial_scene_from_source", &LO::initial_scene_from_source)
      .def_readwrite("max_iterations", &LO::max_iterations)
      .def_readwrite("gradient_tolerance", &LO::gradient_tolerance)
      .def_readwrite("parameter_tolerance", &LO::parameter_tolerance)
      .def("validate", [](const LO& o) { ThrowIfError(o.Validate()); });

  py::class_<opl::SpotResidual>(m, "SpotResidual", "A spot's angular residual after locating.")
      .def_readonly("beam_id", &opl::SpotResidual::beam_id)
      .def_readonly("residual_rad", &opl::SpotResidual::residual_rad, "(az, el) measured - beam.")
      .def_readonly("normalized", &opl::SpotResidual::normalized)
      .def_readonly("outlier", &opl::SpotResidual::outlier);

  using LR = opl::LocateResult;
  py::class_<LR>(m, "LocateResult", "A located source: its pose in the scene and uncertainty.")
      .def_readonly("scene_from_source", &LR::scene_from_source)
      .def_property_readonly("origin", [](const LR& r) { return r.scene_from_source.translation; },
                             "The projection origin in the scene frame, (3,).")
      .def_readonly("covariance", &LR::covariance, "6x6 covariance of the pose.")
      .def_readonly("origin_covariance", &LR::origin_covariance, "3x3, scene units^2.")
      .def_readonly("rotation_xyz_rad", &LR::rotation_xyz_rad)
      .def_readonly("rotation_xyz_covariance", &LR::rotation_xyz_covariance)
      .def_readonly("rms_residual_rad", &LR::rms_residual_rad)
      .def_readonly("variance_factor", &LR::variance_factor)
      .def_readonly("weighted", &LR::weighted)
      .def_readonly("covariance_scaled", &LR::covariance_scaled)
      .def_readonly("num_spots", &LR::num_spots)
      .def_readonly("num_inliers", &LR::num_inliers)
      .def_readonly("ransac_iterations", &LR::ransac_iterations)
      .def_readonly("solver_iterations", &LR::solver_iterations)
      .def_readonly("residuals", &LR::residuals)
      .def("outlier_beam_ids", &LR::OutlierBeamIds)
      .def("brief_report", &LR::BriefReport)
      .def("__repr__", &LR::BriefReport);

  m.def(
      "locate_source",
      [](const opl::BeamPattern& pattern, const py::array_t<double, py::array::forcecast>& points,
         const std::vector<int>& beam_ids, const py::object& covariances, const LO& options) {
        const std::vector<Eigen::Vector3d> p = PointsFromArray(points, "locate_source: points");
        if (beam_ids.size() != p.size()) {
          ThrowIfError(opl::Status::InvalidArgument(
              "locate_source: beam_ids: expected " + std::to_string(p.size()) +
              " (one per point), got " + std::to_string(beam_ids.size())));
        }
        std::vector<opl::SpotObservation> spots(p.size());
        std::vector<Eigen::Matrix3d> cov;
        if (!covariances.is_none()) {
          auto c = covariances.cast<py::array_t<double, py::array::forcecast>>();
          if (c.ndim() != 3 || static_cast<size_t>(c.shape(0)) != p.size() || c.shape(1) != 3 || c.shape(2) != 3) {
            ThrowIfError(opl::Status::InvalidArgument("locate_source: covariances: expected (" +
                                                      std::to_string(p.size()) + ", 3, 3)"));
          }
          auto r = c.unchecked<3>();
          for (size_t i = 0; i < p.size(); ++i) {
            Eigen::Matrix3d mtx;
            for (int a = 0; a < 3; ++a)
              for (int b = 0; b < 3; ++b) mtx(a, b) = r(static_cast<py::ssize_t>(i), a, b);
            spots[i].cov_in_scene = mtx;
          }
        }
        for (size_t i = 0; i < p.size(); ++i) {
          spots[i].beam_id = beam_ids[i];
          spots[i].point_in_scene = p[i];
        }
        return RunReleased([&] { return opl::LocateSource(pattern, spots, options); });
      },
      py::arg("pattern"), py::arg("points"), py::arg("beam_ids"), py::arg("covariances") = py::none(),
      py::arg("options") = LO(),
      "Locates a source from its spots: points (N, 3) in the scene frame, the beam id of each, "
      "optionally their (N, 3, 3) covariances. No starting guess is needed (closed-form / RANSAC "
      "start, then a robust least-squares solve). Returns a LocateResult (pose, covariance, "
      "residuals, outliers). Raises NoSolutionError when the spots do not fix the pose.");
}

void BindScale(py::module_& m) {
  py::class_<opl::LocatedOrigin>(m, "LocatedOrigin", "A located source's origin, input of compute_scale_factor.")
      .def(py::init([](const std::string& name, const Eigen::Vector3d& o, const Eigen::Matrix3d& c) {
             return opl::LocatedOrigin{name, o, c};
           }),
           py::arg("name"), py::arg("origin_in_scene"), py::arg("origin_covariance") = Eigen::Matrix3d::Zero().eval())
      .def_readwrite("name", &opl::LocatedOrigin::name)
      .def_readwrite("origin_in_scene", &opl::LocatedOrigin::origin_in_scene)
      .def_readwrite("origin_covariance", &opl::LocatedOrigin::origin_covariance);
  py::class_<opl::LengthScale>(m, "LengthScale", "One length scale: s_ij = L_cal / L_photo.")
      .def_readonly("from_source", &opl::LengthScale::from)
      .def_readonly("to_source", &opl::LengthScale::to)
      .def_readonly("photo", &opl::LengthScale::photo, "L_photo, scene units.")
      .def_readonly("u_photo", &opl::LengthScale::u_photo)
      .def_readonly("cal_mm", &opl::LengthScale::cal_mm, "L_cal, mm.")
      .def_readonly("u_cal_mm", &opl::LengthScale::u_cal_mm)
      .def_readonly("scale", &opl::LengthScale::scale)
      .def_readonly("u_scale", &opl::LengthScale::u_scale)
      .def_readonly("placement", &opl::LengthScale::placement, "Its module placement ('' when none).");
  py::class_<opl::ScaleResult>(m, "ScaleResult", "The scale factor s (mm per scene unit) and its uncertainty.")
      .def_readonly("lengths", &opl::ScaleResult::lengths)
      .def_readonly("scale_factor", &opl::ScaleResult::scale_factor, "s, mm per scene unit.")
      .def_readonly("u_scale_factor", &opl::ScaleResult::u_scale_factor, "u(s), k = 1.")
      .def_readonly("chi2", &opl::ScaleResult::chi2)
      .def_readonly("dof", &opl::ScaleResult::dof)
      .def_readonly("max_normalized_deviation", &opl::ScaleResult::max_normalized_deviation);
  m.def(
      "compute_scale_factor",
      [](const opl::ModuleCalibration& c, const std::vector<opl::LocatedOrigin>& located) {
        return Unwrap(opl::ComputeScaleFactor(c, located));
      },
      py::arg("calibration"), py::arg("located"),
      "s from located origins: every calibrated separation whose two sources were located gives "
      "s_ij = L_cal / L_photo; s is their weighted mean.");
}

void BindIdentify(py::module_& m) {
  using IO = opl::IdentifyOptions;
  py::class_<IO>(m, "IdentifyOptions",
                 "Options of identify_spots (include/opl/identify/identify_spots.h documents each).")
      .def(py::init<>())
      .def_readwrite("assign_gate_sigma", &IO::assign_gate_sigma)
      .def_readwrite("min_sigma_rad", &IO::min_sigma_rad)
      .def_readwrite("score_gate_fraction", &IO::score_gate_fraction)
      .def_readwrite("max_sigma_fraction", &IO::max_sigma_fraction)
      .def_readwrite("directions_nominal", &IO::directions_nominal)
      .def_readwrite("nominal_tolerance_rad", &IO::nominal_tolerance_rad)
      .def_readwrite("min_spots", &IO::min_spots)
      .def_readwrite("min_fraction", &IO::min_fraction)
      .def_readwrite("conflict_margin_chi2", &IO::conflict_margin_chi2)
      .def_readwrite("ambiguity_chi2", &IO::ambiguity_chi2)
      .def_readwrite("neighbours", &IO::neighbours)
      .def_readwrite("max_seeds", &IO::max_seeds)
      .def_readwrite("max_refined", &IO::max_refined)
      .def_readwrite("expected_rotation", &IO::expected_rotation)
      .def_readwrite("expected_rotation_tolerance_deg", &IO::expected_rotation_tolerance_deg)
      .def_readwrite("expected_origin", &IO::expected_origin)
      .def_readwrite("expected_origin_tolerance", &IO::expected_origin_tolerance)
      .def_readwrite("num_threads", &IO::num_threads)
      .def_readwrite("seed", &IO::seed)
      .def("validate", [](const IO& o) { ThrowIfError(o.Validate()); });
  py::enum_<opl::IdentifyOutcome>(m, "IdentifyOutcome")
      .value("FOUND", opl::IdentifyOutcome::kFound)
      .value("NOT_FOUND", opl::IdentifyOutcome::kNotFound)
      .value("AMBIGUOUS", opl::IdentifyOutcome::kAmbiguous);
  py::class_<opl::IdentifiedSource>(m, "IdentifiedSource", "What identification found for one source.")
      .def_readonly("name", &opl::IdentifiedSource::name)
      .def_readonly("outcome", &opl::IdentifiedSource::outcome)
      .def_readonly("detail", &opl::IdentifiedSource::detail)
      .def_readonly("scene_from_source", &opl::IdentifiedSource::scene_from_source)
      .def_readonly("assigned", &opl::IdentifiedSource::assigned)
      .def_readonly("rms_residual_rad", &opl::IdentifiedSource::rms_residual_rad)
      .def_readonly("sigma_rad", &opl::IdentifiedSource::sigma_rad)
      .def_readonly("placement", &opl::IdentifiedSource::placement,
                    "The placement it was identified at ('' with one placement).");
  py::class_<opl::IdentifyResult>(m, "IdentifyResult",
                                  "Per input spot: the index of its source in the calibration "
                                  "(-1: unassigned) and its beam id (0).")
      .def_property_readonly("source_index", [](const opl::IdentifyResult& r) { return py::array_t<int>(py::cast(r.source_index)); })
      .def_property_readonly("beam_ids", [](const opl::IdentifyResult& r) { return py::array_t<int>(py::cast(r.beam_id)); })
      .def_readonly("sources", &opl::IdentifyResult::sources)
      .def_readonly("passed_through", &opl::IdentifyResult::passed_through)
      .def("num_assigned", &opl::IdentifyResult::num_assigned)
      .def("num_unassigned", &opl::IdentifyResult::num_unassigned)
      .def("to_text", &opl::IdentifyResult::ToText);
  m.def(
      "identify_spots",
      [](const opl::ModuleCalibration& c, const SpotTable& spots, const IO& options) {
        return RunReleased([&] { return opl::IdentifySpots(c, spots.spots, options); });
      },
      py::arg("calibration"), py::arg("spots"), py::arg("options") = IO(),
      "Assigns unsorted spots to their source and beam against the calibrated patterns, whatever "
      "the module's pose; grids that cannot be identified for sure are reported, not guessed.");
  m.def(
      "assigned_spots",
      [](const SpotTable& spots, const opl::IdentifyResult& r) {
        SpotTable out;
        out.spots = opl::AssignedSpots(spots.spots, r);
        out.slices = spots.slices;
        return out;
      },
      py::arg("spots"), py::arg("result"), "The spots with the sources and beams identification gave.");
}

void BindMeasure(py::module_& m) {
  py::class_<opl::MeasureOptions>(m, "MeasureOptions", "Options of measure_scale.")
      .def(py::init<>())
      .def_readwrite("locate", &opl::MeasureOptions::locate)
      .def_readwrite("identify", &opl::MeasureOptions::identify);
  py::class_<opl::MeasureReport>(m, "MeasureReport",
                                 "A measurement: every located source, the identification (when "
                                 "spots were unsorted) and the scale factor.")
      .def_readonly("sources", &opl::MeasureReport::sources, "List of (name, LocateResult).")
      .def_readonly("sources_without_spots", &opl::MeasureReport::sources_without_spots)
      .def_readonly("source_placements", &opl::MeasureReport::source_placements,
                    "The module placement of each located source ('' when the spots name none).")
      .def_readonly("identification", &opl::MeasureReport::identification)
      .def_readonly("scale", &opl::MeasureReport::scale)
      .def_property_readonly("s", [](const opl::MeasureReport& r) { return r.scale.scale_factor; },
                             "The scale factor s, mm per scene unit.")
      .def_property_readonly("u_s", [](const opl::MeasureReport& r) { return r.scale.u_scale_factor; },
                             "u(s), k = 1.")
      .def("to_text", &opl::MeasureReport::ToText, "The report opl_measure prints.")
      .def("to_json", &opl::MeasureReport::ToJson, "The report opl_measure --json writes.");
  m.def(
      "measure_scale",
      [](const opl::ModuleCalibration& c, const SpotTable& spots, const opl::MeasureOptions& options) {
        return RunReleased([&] { return opl::MeasureScale(c, spots.spots, options); });
      },
      py::arg("calibration"), py::arg("spots"), py::arg("options") = opl::MeasureOptions(),
      "Measures the scale factor of a scene from its spots (as opl_measure --spots): unassigned "
      "spots are identified first, every source is located, and s = L_cal / L_photo is computed.");
}

void BindCalibrate(py::module_& m) {
  using CO = opl::CalibrateOptions;
  py::class_<CO>(m, "CalibrateOptions",
                 "Options of a source's calibration (include/opl/calibrate/calibrate_source.h).")
      .def(py::init<>())
      .def_readwrite("loss", &CO::loss)
      .def_readwrite("loss_scale", &CO::loss_scale)
      .def_readwrite("loss_scale_unweighted_rad", &CO::loss_scale_unweighted_rad)
      .def_readwrite("max_robust_rounds", &CO::max_robust_rounds)
      .def_readwrite("outlier_threshold", &CO::outlier_threshold)
      .def_readwrite("min_unweighted_sigma_rad", &CO::min_unweighted_sigma_rad)
      .def_readwrite("max_flagging_rounds", &CO::max_flagging_rounds)
      .def_readwrite("min_samples_per_beam", &CO::min_samples_per_beam)
      .def_readwrite("init_inlier_distance_mm", &CO::init_inlier_distance_mm)
      .def_readwrite("max_iterations", &CO::max_iterations)
      .def_readwrite("parameter_tolerance", &CO::parameter_tolerance)
      .def_readwrite("function_tolerance", &CO::function_tolerance)
      .def("validate", [](const CO& o) { ThrowIfError(o.Validate()); });
  py::class_<opl::CalibrateModuleOptions>(m, "CalibrateModuleOptions")
      .def(py::init<>())
      .def_readwrite("source", &opl::CalibrateModuleOptions::source)
      .def_readwrite("beams_per_side", &opl::CalibrateModuleOptions::beams_per_side,
                     "n, or None to infer it from the largest beam id.");
  py::class_<opl::BeamCalibrationQuality>(m, "BeamCalibrationQuality")
      .def_readonly("beam_id", &opl::BeamCalibrationQuality::beam_id)
      .def_readonly("samples_used", &opl::BeamCalibrationQuality::samples_used)
      .def_readonly("samples_flagged", &opl::BeamCalibrationQuality::samples_flagged)
      .def_readonly("mean_point_to_ray_mm", &opl::BeamCalibrationQuality::mean_point_to_ray_mm)
      .def_readonly("max_point_to_ray_mm", &opl::BeamCalibrationQuality::max_point_to_ray_mm)
      .def_readonly("rms_residual_rad", &opl::BeamCalibrationQuality::rms_residual_rad);
  using SR = opl::SourceCalibrationResult;
  py::class_<SR>(m, "SourceCalibrationResult")
      .def_readonly("calibration", &SR::calibration)
      .def_readonly("pose_covariance", &SR::pose_covariance)
      .def_readonly("variance_factor", &SR::variance_factor)
      .def_readonly("weighted", &SR::weighted)
      .def_readonly("num_slices", &SR::num_slices)
      .def_readonly("beams", &SR::beams)
      .def_readonly("dropped_beam_ids", &SR::dropped_beam_ids);
  py::class_<opl::ModuleCalibrationResult>(m, "ModuleCalibrationResult")
      .def_readonly("calibration", &opl::ModuleCalibrationResult::calibration)
      .def_readonly("sources", &opl::ModuleCalibrationResult::sources);
  py::class_<opl::ArtifactMeasurement>(m, "ArtifactMeasurement",
                                       "A calibration session's scale artifact: two measured targets "
                                       "a calibrated length apart.")
      .def(py::init<>())
      .def_readwrite("from_target", &opl::ArtifactMeasurement::from_target)
      .def_readwrite("to_target", &opl::ArtifactMeasurement::to_target)
      .def_readwrite("from_point", &opl::ArtifactMeasurement::from_point)
      .def_readwrite("to_point", &opl::ArtifactMeasurement::to_point)
      .def_readwrite("from_cov", &opl::ArtifactMeasurement::from_cov)
      .def_readwrite("to_cov", &opl::ArtifactMeasurement::to_cov)
      .def_readwrite("length_mm", &opl::ArtifactMeasurement::length_mm)
      .def_readwrite("u_length_mm", &opl::ArtifactMeasurement::u_length_mm);
  m.def(
      "compute_artifact_scaling",
      [](const opl::ArtifactMeasurement& a) { return Unwrap(opl::ComputeArtifactScaling(a)); },
      py::arg("artifact"), "The scaling of a calibration session from its artifact.");
  m.def(
      "calibrate_module",
      [](const SpotTable& spots, const std::optional<opl::CalibrationScaling>& scaling,
         const opl::CalibrateModuleOptions& options) {
        return RunReleased([&] { return opl::CalibrateModule(spots.spots, spots.slices, scaling, options); });
      },
      py::arg("spots"), py::arg("scaling") = py::none(), py::arg("options") = opl::CalibrateModuleOptions(),
      "Calibrates every source of a module from assigned spots recorded on several slices "
      "(Spots.slices): each source's origin, pose and beam directions, and the separations with "
      "their uncertainty. The session is scaled by `scaling` when given (points in mm otherwise).");
}

}  // namespace

void BindSolve(py::module_& m) {
  BindLocate(m);
  BindScale(m);
  BindIdentify(m);
  BindMeasure(m);
  BindCalibrate(m);
}

}  // namespace opl_python
