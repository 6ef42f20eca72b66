// Monte Carlo (JCGM 101) of a measurement and of a calibration, and design
// sweeps.
#include "common.h"
#include "opl/uncertainty/calibration_monte_carlo.h"
#include "opl/uncertainty/coverage_interval.h"
#include "opl/uncertainty/cramer_rao.h"
#include "opl/uncertainty/design_sweep.h"
#include "opl/uncertainty/monte_carlo.h"

namespace opl_python {

void BindUncertainty(py::module_& m) {
  py::enum_<opl::SpotWeighting>(m, "SpotWeighting")
      .value("EFFICIENT", opl::SpotWeighting::kEfficient, "Spot covariances in the residuals.")
      .value("UNWEIGHTED", opl::SpotWeighting::kUnweighted, "Plain angular residuals.");
  py::class_<opl::CoverageInterval>(m, "CoverageInterval")
      .def_readonly("low", &opl::CoverageInterval::low)
      .def_readonly("high", &opl::CoverageInterval::high);
  py::class_<opl::SampleSummary>(m, "SampleSummary", "Mean, standard deviation and coverage intervals of samples.")
      .def_readonly("mean", &opl::SampleSummary::mean)
      .def_readonly("std_dev", &opl::SampleSummary::std_dev)
      .def_readonly("symmetric", &opl::SampleSummary::symmetric, "JCGM 101 7.7.1.")
      .def_readonly("shortest", &opl::SampleSummary::shortest, "JCGM 101 7.7.2.")
      .def_readonly("has_interval", &opl::SampleSummary::has_interval)
      .def_readonly("first_order_std", &opl::SampleSummary::first_order_std)
      .def_readonly("cramer_rao_std", &opl::SampleSummary::cramer_rao_std);
  m.def(
      "summarize",
      [](const std::vector<double>& v, double p) { return opl::Summarize(v, p); }, py::arg("values"),
      py::arg("coverage_probability") = 0.95, "SampleSummary of values (JCGM 101 coverage intervals).");

  using MO = opl::MonteCarloOptions;
  py::class_<MO>(m, "MonteCarloOptions", "Options of run_measurement_monte_carlo and run_design_sweep.")
      .def(py::init<>())
      .def_readwrite("iterations", &MO::iterations)
      .def_readwrite("seed", &MO::seed)
      .def_readwrite("threads", &MO::threads, "0: every core (results do not depend on it).")
      .def_readwrite("coverage_probability", &MO::coverage_probability)
      .def_readwrite("locate", &MO::locate)
      .def_readwrite("start_from_design_pose", &MO::start_from_design_pose)
      .def_readwrite("weighting", &MO::weighting);
  py::class_<opl::MonteCarloSource>(m, "MonteCarloSource")
      .def_readonly("name", &opl::MonteCarloSource::name)
      .def_readonly("true_origin_mm", &opl::MonteCarloSource::true_origin_mm)
      .def_readonly("origin_mean_mm", &opl::MonteCarloSource::origin_mean_mm)
      .def_readonly("origin_std_mm", &opl::MonteCarloSource::origin_std_mm)
      .def_readonly("origin_first_order_std_mm", &opl::MonteCarloSource::origin_first_order_std_mm)
      .def_readonly("origin_cramer_rao_std_mm", &opl::MonteCarloSource::origin_cramer_rao_std_mm)
      .def_readonly("rotation_mean_rad", &opl::MonteCarloSource::rotation_mean_rad)
      .def_readonly("rotation_std_rad", &opl::MonteCarloSource::rotation_std_rad)
      .def_readonly("spots", &opl::MonteCarloSource::spots);
  py::class_<opl::MonteCarloLength>(m, "MonteCarloLength")
      .def_readonly("from_source", &opl::MonteCarloLength::from)
      .def_readonly("to_source", &opl::MonteCarloLength::to)
      .def_readonly("true_mm", &opl::MonteCarloLength::true_mm)
      .def_readonly("photo_mm", &opl::MonteCarloLength::photo_mm)
      .def_property_readonly("samples_mm", [](const opl::MonteCarloLength& l) {
        return py::array_t<double>(py::cast(l.samples_mm));
      });
  using MR = opl::MonteCarloReport;
  py::class_<MR>(m, "MonteCarloReport", "A measurement Monte Carlo: spread of L_photo and of s.")
      .def_readonly("iterations", &MR::iterations)
      .def_readonly("succeeded", &MR::succeeded)
      .def_readonly("failed", &MR::failed)
      .def_readonly("first_failure", &MR::first_failure)
      .def_readonly("seed", &MR::seed)
      .def_readonly("sources", &MR::sources)
      .def_readonly("lengths", &MR::lengths)
      .def_readonly("scale_factor", &MR::scale_factor)
      .def_property_readonly("scale_samples", [](const MR& r) { return py::array_t<double>(py::cast(r.scale_samples)); })
      .def("to_text", &MR::ToText)
      .def_readonly("sample_iterations", &MR::sample_iterations,
                    "The index of every successful iteration, in the order of every sample array.")
      .def("to_json", &MR::ToJson, py::arg("include_samples") = false,
           "The opl.monte_carlo_report JSON; include_samples adds every iteration's values.");
  m.def(
      "run_measurement_monte_carlo",
      [](const opl::ModuleDesign& d, const MO& o) {
        return RunReleased([&] { return opl::RunMeasurementMonteCarlo(d, o); });
      },
      py::arg("design"), py::arg("options") = MO(),
      "JCGM 101 Monte Carlo of a measurement: the design's spots with its noise, every source "
      "located again, `iterations` times; the spread of each L_photo and of s, with first-order "
      "and Cramer-Rao predictions.");

  py::enum_<opl::SweepParameter>(m, "SweepParameter", "What a design sweep varies.")
      .value("NOISE_MM", opl::SweepParameter::kNoiseMm)
      .value("FULL_ANGLE_DEG", opl::SweepParameter::kFullAngleDeg)
      .value("BEAMS_PER_SIDE", opl::SweepParameter::kBeamsPerSide)
      .value("SEPARATION_MM", opl::SweepParameter::kSeparationMm)
      .value("DISTANCE_MM", opl::SweepParameter::kDistanceMm)
      .value("STAGGER_DEG", opl::SweepParameter::kStaggerDeg)
      .value("LAYOUT", opl::SweepParameter::kLayout);
  m.def(
      "apply_sweep_value",
      [](const opl::ModuleDesign& d, opl::SweepParameter p, double v) { return Unwrap(opl::ApplySweepValue(d, p, v)); },
      py::arg("design"), py::arg("parameter"), py::arg("value"), "The design with one parameter set.");
  py::class_<opl::DesignSweepPoint>(m, "DesignSweepPoint")
      .def_readonly("value", &opl::DesignSweepPoint::value)
      .def_readonly("report", &opl::DesignSweepPoint::report);
  py::class_<opl::DesignSweep>(m, "DesignSweep")
      .def_readonly("parameter", &opl::DesignSweep::parameter)
      .def_readonly("points", &opl::DesignSweep::points)
      .def("to_csv", &opl::DesignSweep::ToCsv, "The table opl_simulate sweep writes.");
  m.def(
      "run_design_sweep",
      [](const opl::ModuleDesign& d, opl::SweepParameter p, const std::vector<double>& values, const MO& o) {
        return RunReleased([&] { return opl::RunDesignSweep(d, p, values, o); });
      },
      py::arg("design"), py::arg("parameter"), py::arg("values"), py::arg("options") = MO(),
      "A measurement Monte Carlo at each value of one design parameter.");

  using CO = opl::CalibrationMonteCarloOptions;
  py::class_<CO>(m, "CalibrationMonteCarloOptions")
      .def(py::init<>())
      .def_readwrite("iterations", &CO::iterations)
      .def_readwrite("seed", &CO::seed)
      .def_readwrite("threads", &CO::threads)
      .def_readwrite("coverage_probability", &CO::coverage_probability)
      .def_readwrite("screens", &CO::screens)
      .def_readwrite("calibrate", &CO::calibrate);
  py::class_<opl::CalibrationMonteCarloLength>(m, "CalibrationMonteCarloLength")
      .def_readonly("from_source", &opl::CalibrationMonteCarloLength::from)
      .def_readonly("to_source", &opl::CalibrationMonteCarloLength::to)
      .def_readonly("true_mm", &opl::CalibrationMonteCarloLength::true_mm)
      .def_readonly("length_mm", &opl::CalibrationMonteCarloLength::length_mm)
      .def_property_readonly("samples_mm", [](const opl::CalibrationMonteCarloLength& l) {
        return py::array_t<double>(py::cast(l.samples_mm));
      });
  using CR = opl::CalibrationMonteCarloReport;
  py::class_<CR>(m, "CalibrationMonteCarloReport")
      .def_readonly("iterations", &CR::iterations)
      .def_readonly("succeeded", &CR::succeeded)
      .def_readonly("failed", &CR::failed)
      .def_readonly("first_failure", &CR::first_failure)
      .def_readonly("lengths", &CR::lengths)
      .def("to_text", &CR::ToText)
      .def("to_json", &CR::ToJson);
  m.def(
      "run_calibration_monte_carlo",
      [](const opl::ModuleDesign& d, const CO& o) {
        return RunReleased([&] { return opl::RunCalibrationMonteCarlo(d, o); });
      },
      py::arg("design"), py::arg("options") = CO(),
      "JCGM 101 Monte Carlo of a calibration session: spread of the calibrated separations.");
}

}  // namespace opl_python
