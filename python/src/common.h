// Shared by the translation units of the `opl` Python module: how a Status
// becomes a Python exception, and the numpy <-> C++ conversions every
// binding uses. Private to python/src.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/model/spot.h"

namespace opl_python {

namespace py = pybind11;

// Creates opl.Error and its subclasses, one per StatusCode (module.cc calls
// it first).
void RegisterExceptions(py::module_& m);

// Raises the exception of `status`'s code with its message (which names the
// input and the field) unless it is OK. Needs the GIL.
void ThrowIfError(const opl::Status& status);

template <typename T>
T Unwrap(opl::Result<T>&& result) {
  if (!result.ok()) ThrowIfError(result.status());
  return std::move(result).value();
}

// Runs `f` (returning a Status or a Result) with the GIL released, then
// unwraps it with the GIL held: long solves let other Python threads run.
template <typename F>
auto RunReleased(F&& f) {
  auto result = [&] {
    py::gil_scoped_release release;
    return f();
  }();
  if constexpr (std::is_same_v<decltype(result), opl::Status>) {
    ThrowIfError(result);
  } else {
    return Unwrap(std::move(result));
  }
}

// Spots as Python sees them (opl.Spots): the library's spots plus the
// calibration slice of each (0 for a measurement).
struct SpotTable {
  std::vector<opl::Spot> spots;
  std::vector<int> slices;  // one per spot
};

// (N, 3) float64 array of points; N x 3 checked, the message naming `what`.
std::vector<Eigen::Vector3d> PointsFromArray(const py::array_t<double, py::array::forcecast>& a,
                                             const std::string& what);
py::array_t<double> ArrayFromPoints(const std::vector<Eigen::Vector3d>& points);

// Binders, one per translation unit (pybind11 TUs compile slowly; they are
// split so that the build runs them in parallel and recompiles few).
void BindGeometryModel(py::module_& m);
void BindSpots(py::module_& m);
void BindIo(py::module_& m);
void BindColmap(py::module_& m);
void BindSolve(py::module_& m);
void BindSim(py::module_& m);
void BindUncertainty(py::module_& m);
void BindImages(py::module_& m);
void BindPointCloud(py::module_& m);

}  // namespace opl_python
