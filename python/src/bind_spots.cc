// opl.Spots: laser spots (3D points with their source, beam and covariance)
// held as the library's std::vector<Spot>, seen from Python as numpy arrays.
#include "common.h"

namespace opl_python {
namespace {

using opl::Status;

SpotTable MakeSpots(const py::array_t<double, py::array::forcecast>& points,
                    const py::object& sources, const py::object& beam_ids,
                    const py::object& covariances, const py::object& sigmas,
                    const py::object& slices, const py::object& placements) {
  SpotTable t;
  const std::vector<Eigen::Vector3d> p = PointsFromArray(points, "Spots: points");
  const size_t n = p.size();
  auto length_error = [n](const std::string& field, size_t got) {
    ThrowIfError(Status::InvalidArgument("Spots: " + field + ": expected " + std::to_string(n) +
                                         " entries (one per point), got " + std::to_string(got)));
  };
  std::vector<std::string> src(n);
  if (py::isinstance<py::str>(sources)) {
    std::fill(src.begin(), src.end(), sources.cast<std::string>());
  } else if (!sources.is_none()) {
    src = sources.cast<std::vector<std::string>>();
    if (src.size() != n) length_error("sources", src.size());
  }
  std::vector<int> beam(n, 0);
  if (!beam_ids.is_none()) {
    beam = beam_ids.cast<std::vector<int>>();
    if (beam.size() != n) length_error("beam_ids", beam.size());
  }
  t.slices.assign(n, 0);
  if (!slices.is_none()) {
    t.slices = slices.cast<std::vector<int>>();
    if (t.slices.size() != n) length_error("slices", t.slices.size());
  }
  std::vector<std::string> placement(n);
  if (py::isinstance<py::str>(placements)) {
    std::fill(placement.begin(), placement.end(), placements.cast<std::string>());
  } else if (!placements.is_none()) {
    placement = placements.cast<std::vector<std::string>>();
    if (placement.size() != n) length_error("placements", placement.size());
  }
  if (!covariances.is_none() && !sigmas.is_none()) {
    ThrowIfError(Status::InvalidArgument("Spots: give covariances or sigmas, not both"));
  }
  std::vector<std::optional<Eigen::Matrix3d>> cov(n);
  if (!covariances.is_none()) {
    auto c = covariances.cast<py::array_t<double, py::array::forcecast>>();
    if (c.ndim() != 3 || c.shape(1) != 3 || c.shape(2) != 3) {
      ThrowIfError(Status::InvalidArgument("Spots: covariances: expected an (N, 3, 3) array"));
    }
    if (static_cast<size_t>(c.shape(0)) != n) length_error("covariances", static_cast<size_t>(c.shape(0)));
    auto r = c.unchecked<3>();
    for (size_t i = 0; i < n; ++i) {
      Eigen::Matrix3d m;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) m(a, b) = r(static_cast<py::ssize_t>(i), a, b);
      cov[i] = m;
    }
  } else if (!sigmas.is_none()) {
    const std::vector<Eigen::Vector3d> s =
        PointsFromArray(sigmas.cast<py::array_t<double, py::array::forcecast>>(), "Spots: sigmas");
    if (s.size() != n) length_error("sigmas", s.size());
    for (size_t i = 0; i < n; ++i) {
      if (!(s[i].minCoeff() > 0) || !s[i].allFinite()) {
        ThrowIfError(Status::InvalidArgument("Spots: sigmas: row " + std::to_string(i) +
                                             ": every sigma must be finite and > 0"));
      }
      cov[i] = s[i].cwiseAbs2().asDiagonal();
    }
  }
  t.spots.resize(n);
  for (size_t i = 0; i < n; ++i) {
    opl::Spot& s = t.spots[i];
    s.source = src[i];
    s.observation.beam_id = beam[i];
    s.observation.point_in_scene = p[i];
    s.observation.cov_in_scene = cov[i];
    s.placement = placement[i];
    s.where = "point " + std::to_string(i);
  }
  return t;
}

}  // namespace

void BindSpots(py::module_& m) {
  py::class_<SpotTable>(
      m, "Spots",
      "Laser spots: 3D points in the (unscaled) scene frame, each with its source name and beam "
      "id (empty source / beam 0 when not yet identified), an optional 3x3 covariance and the "
      "calibration slice it was recorded in (0 for a measurement). Properties return numpy copies.")
      .def(py::init(&MakeSpots), py::arg("points"), py::arg("sources") = py::none(),
           py::arg("beam_ids") = py::none(), py::arg("covariances") = py::none(),
           py::arg("sigmas") = py::none(), py::arg("slices") = py::none(),
           py::arg("placements") = py::none(),
           "points: (N, 3); sources: one name for all, a list of N names, or None (unassigned); "
           "beam_ids: N ints or None (0 = unassigned); covariances: (N, 3, 3) or sigmas: (N, 3) "
           "standard deviations per coordinate (not both; None: unweighted); slices: N ints; "
           "placements: the module placement of each spot (one name for all, N names, or None: "
           "none; docs/multiview.md, 'Several placements').")
      .def("__len__", [](const SpotTable& t) { return t.spots.size(); })
      .def_property_readonly(
          "points",
          [](const SpotTable& t) {
            std::vector<Eigen::Vector3d> p;
            for (const opl::Spot& s : t.spots) p.push_back(s.observation.point_in_scene);
            return ArrayFromPoints(p);
          },
          "(N, 3) points in the scene frame.")
      .def_property_readonly(
          "sources",
          [](const SpotTable& t) {
            std::vector<std::string> v;
            for (const opl::Spot& s : t.spots) v.push_back(s.source);
            return v;
          },
          "Source name of each spot ('' when unassigned).")
      .def_property_readonly(
          "beam_ids",
          [](const SpotTable& t) {
            Eigen::VectorXi v(static_cast<Eigen::Index>(t.spots.size()));
            for (size_t i = 0; i < t.spots.size(); ++i) v[static_cast<Eigen::Index>(i)] = t.spots[i].observation.beam_id;
            return v;
          },
          "Beam id of each spot (0 when unassigned).")
      .def_property_readonly(
          "covariances",
          [](const SpotTable& t) -> py::object {
            bool any = false;
            for (const opl::Spot& s : t.spots) any = any || s.observation.cov_in_scene.has_value();
            if (!any) return py::none();
            py::array_t<double> a({static_cast<py::ssize_t>(t.spots.size()), py::ssize_t{3}, py::ssize_t{3}});
            auto w = a.mutable_unchecked<3>();
            for (size_t i = 0; i < t.spots.size(); ++i) {
              const auto& c = t.spots[i].observation.cov_in_scene;
              for (int r = 0; r < 3; ++r)
                for (int k = 0; k < 3; ++k)
                  w(static_cast<py::ssize_t>(i), r, k) = c ? (*c)(r, k) : std::nan("");
            }
            return std::move(a);
          },
          "(N, 3, 3) covariances, NaN for spots without one; None when no spot has one.")
      .def_property_readonly(
          "slices", [](const SpotTable& t) { return t.slices; },
          "Calibration slice of each spot.")
      .def_property_readonly(
          "placements",
          [](const SpotTable& t) {
            std::vector<std::string> v;
            for (const opl::Spot& s : t.spots) v.push_back(s.placement);
            return v;
          },
          "Module placement of each spot ('' when none).")
      .def_property_readonly(
          "where",
          [](const SpotTable& t) {
            std::vector<std::string> v;
            for (const opl::Spot& s : t.spots) v.push_back(s.where);
            return v;
          },
          "Where each spot came from, as error messages name it (e.g. 'spots.csv:14').")
      .def_property_readonly(
          "assigned",
          [](const SpotTable& t) {
            std::vector<bool> v;
            for (const opl::Spot& s : t.spots) v.push_back(s.assigned());
            return py::array_t<bool>(py::cast(v));
          },
          "Boolean mask: spots with a source and a beam.")
      .def(
          "select",
          [](const SpotTable& t, const py::array_t<bool, py::array::forcecast>& mask) {
            if (mask.ndim() != 1 || static_cast<size_t>(mask.shape(0)) != t.spots.size()) {
              ThrowIfError(Status::InvalidArgument("Spots.select: mask: expected " +
                                                   std::to_string(t.spots.size()) + " booleans"));
            }
            SpotTable out;
            for (size_t i = 0; i < t.spots.size(); ++i) {
              if (mask.at(static_cast<py::ssize_t>(i))) {
                out.spots.push_back(t.spots[i]);
                out.slices.push_back(t.slices[i]);
              }
            }
            return out;
          },
          py::arg("mask"), "The spots where the boolean mask is true.")
      .def("__repr__", [](const SpotTable& t) {
        int assigned = 0;
        for (const opl::Spot& s : t.spots) assigned += s.assigned() ? 1 : 0;
        return "Spots(" + std::to_string(t.spots.size()) + " points, " + std::to_string(assigned) +
               " assigned)";
      });
}

}  // namespace opl_python
