// The `opl` Python module: entry point, exceptions and the shared numpy
// conversions. The bindings themselves are in bind_*.cc.
#include <Python.h>

#include "common.h"
#include "opl/core/version.h"

namespace opl_python {
namespace {

// Owned for the life of the process (never decref'ed: the interpreter may be
// finalised before static destructors run).
PyObject* g_error = nullptr;
PyObject* g_invalid_argument = nullptr;
PyObject* g_io_error = nullptr;
PyObject* g_parse_error = nullptr;
PyObject* g_no_solution = nullptr;

PyObject* NewException(py::module_& m, const char* name, PyObject* bases, const char* doc) {
  const std::string qualified = std::string("opl.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
  if (type == nullptr) throw py::error_already_set();
  m.attr(name) = py::handle(type);
  return type;
}

}  // namespace

void RegisterExceptions(py::module_& m) {
  g_error = NewException(m, "Error", PyExc_RuntimeError,
                         "Base of every error an OPL call raises. The message is the library's "
                         "one-line Status message: it names the input (file and line, or "
                         "argument) and the field.");
  auto pair = [](PyObject* a, PyObject* b) { return PyTuple_Pack(2, a, b); };
  g_invalid_argument = NewException(m, "InvalidArgumentError", pair(g_error, PyExc_ValueError),
                                    "A value given by the caller is out of its domain "
                                    "(StatusCode kInvalidArgument).");
  g_io_error = NewException(m, "IoError", pair(g_error, PyExc_OSError),
                            "A file could not be read or written (StatusCode kIoError).");
  g_parse_error = NewException(m, "ParseError", pair(g_error, PyExc_ValueError),
                               "A file's content is malformed; the message names the file, the "
                               "line and the field (StatusCode kParseError).");
  g_no_solution = NewException(m, "NoSolutionError", g_error,
                               "The data are valid but do not determine an answer "
                               "(StatusCode kNoSolution).");
}

void ThrowIfError(const opl::Status& status) {
  if (status.ok()) return;
  PyObject* type = g_error;
  switch (status.code()) {
    case opl::StatusCode::kInvalidArgument: type = g_invalid_argument; break;
    case opl::StatusCode::kIoError: type = g_io_error; break;
    case opl::StatusCode::kParseError: type = g_parse_error; break;
    case opl::StatusCode::kNoSolution: type = g_no_solution; break;
    case opl::StatusCode::kOk: return;
  }
  PyErr_SetString(type, status.message().c_str());
  throw py::error_already_set();
}

std::vector<Eigen::Vector3d> PointsFromArray(const py::array_t<double, py::array::forcecast>& a,
                                             const std::string& what) {
  if (a.ndim() != 2 || a.shape(1) != 3) {
    std::string shape;
    for (py::ssize_t i = 0; i < a.ndim(); ++i) {
      shape += (i ? ", " : "") + std::to_string(a.shape(i));
    }
    ThrowIfError(opl::Status::InvalidArgument(what + ": expected an (N, 3) array of points, got shape (" +
                                              shape + ")"));
  }
  auto r = a.unchecked<2>();
  std::vector<Eigen::Vector3d> points(static_cast<size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    points[static_cast<size_t>(i)] = Eigen::Vector3d(r(i, 0), r(i, 1), r(i, 2));
  }
  return points;
}

py::array_t<double> ArrayFromPoints(const std::vector<Eigen::Vector3d>& points) {
  py::array_t<double> a({static_cast<py::ssize_t>(points.size()), py::ssize_t{3}});
  auto w = a.mutable_unchecked<2>();
  for (size_t i = 0; i < points.size(); ++i) {
    for (int k = 0; k < 3; ++k) w(static_cast<py::ssize_t>(i), k) = points[i][k];
  }
  return a;
}

}  // namespace opl_python

PYBIND11_MODULE(opl, m) {
  namespace op = opl_python;
  m.doc() =
      "OPL, the optically projected length scale: scale a photogrammetry scene from the laser "
      "spots of a calibrated module.\n\n"
      "Read and write OPL's files (module calibration and design JSON, scene and cameras JSON, "
      "spots and points CSV, PLY/XYZ point files, COLMAP models), locate sources, identify "
      "spots, measure the scale factor s (mm per scene unit), calibrate a module, simulate "
      "spots and run Monte Carlo uncertainty studies. Points are numpy arrays of shape (N, 3). "
      "Errors raise opl.Error subclasses whose message names the input and the field. "
      "See docs/python.md.";
  m.attr("__version__") = opl::VersionNumber();
  m.def("version_string", &opl::VersionString,
        "The library's version and commit, as the command-line tools print with --version.");
  op::RegisterExceptions(m);
  op::BindGeometryModel(m);
  op::BindSpots(m);
  op::BindIo(m);
  op::BindColmap(m);
  op::BindSolve(m);
  op::BindSim(m);
  op::BindUncertainty(m);
  op::BindImages(m);
  op::BindPointCloud(m);
}
