// Point clouds into and out of numpy: read_point_cloud / write_point_cloud
// for PLY (ASCII and binary), headerless XYZ and points CSV. The library
// streams these files to scale them (opl/io/scale_point_file.h) but has no
// call that returns their points; this reads a whole file (up to the
// library's 512 MiB input limit) with the library's PLY header parser and
// returns x, y, z. Scaling a large file is scale_point_file's job.
#include <charconv>
#include <cstring>
#include <sstream>

#include "common.h"
#include "opl/core/version.h"
#include "opl/io/atomic_file.h"
#include "opl/io/point_cloud_ply.h"
#include "opl/io/points_csv.h"
#include "opl/io/scale_point_file.h"

namespace opl_python {
namespace {

using opl::Status;

bool LittleEndianHost() {
  const uint16_t one = 1;
  unsigned char b;
  std::memcpy(&b, &one, 1);
  return b == 1;
}

// A binary scalar of `type` at p, as double.
double ReadBinary(const char* p, opl::PlyScalarType type, bool swap) {
  char buf[8];
  const int n = opl::PlyScalarBytes(type);
  for (int i = 0; i < n; ++i) buf[i] = swap ? p[n - 1 - i] : p[i];
  switch (type) {
    case opl::PlyScalarType::kInt8: { int8_t v; std::memcpy(&v, buf, 1); return v; }
    case opl::PlyScalarType::kUint8: { uint8_t v; std::memcpy(&v, buf, 1); return v; }
    case opl::PlyScalarType::kInt16: { int16_t v; std::memcpy(&v, buf, 2); return v; }
    case opl::PlyScalarType::kUint16: { uint16_t v; std::memcpy(&v, buf, 2); return v; }
    case opl::PlyScalarType::kInt32: { int32_t v; std::memcpy(&v, buf, 4); return v; }
    case opl::PlyScalarType::kUint32: { uint32_t v; std::memcpy(&v, buf, 4); return v; }
    case opl::PlyScalarType::kFloat32: { float v; std::memcpy(&v, buf, 4); return v; }
    case opl::PlyScalarType::kFloat64: { double v; std::memcpy(&v, buf, 8); return v; }
  }
  return 0.0;
}

std::vector<Eigen::Vector3d> ReadPly(const std::string& path) {
  const std::string data = Unwrap(opl::ReadFileToString(path));
  const opl::PlyHeader header = Unwrap(opl::ParsePlyHeader(data, path));
  ThrowIfError(opl::CheckScalablePly(header, path));
  const int vertex = header.FindElement("vertex");
  const opl::PlyElement& v = header.elements[static_cast<size_t>(vertex)];
  const int ix = v.FindProperty("x"), iy = v.FindProperty("y"), iz = v.FindProperty("z");
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<size_t>(v.count));
  size_t pos = header.text.size();
  auto cut_off = [&](int64_t record) {
    ThrowIfError(Status::ParseError(path + ": byte " + std::to_string(pos) + ": " + v.name + " " +
                                    std::to_string(record) + " of " + std::to_string(v.count) +
                                    " is cut off by the end of the file"));
  };
  if (header.encoding == opl::PlyEncoding::kAscii) {
    std::istringstream in(data.substr(pos));
    std::string line;
    for (int e = 0; e < vertex; ++e) {  // one line per record of the elements before
      for (int64_t k = 0; k < header.elements[static_cast<size_t>(e)].count; ++k) std::getline(in, line);
    }
    for (int64_t k = 0; k < v.count; ++k) {
      if (!std::getline(in, line)) cut_off(k);
      std::istringstream fields(line);
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (size_t i = 0; i < v.properties.size(); ++i) {
        const opl::PlyProperty& prop = v.properties[i];
        std::string token;
        int items = 1;
        if (prop.is_list) {
          if (!(fields >> items)) items = -1;
          std::string skip;
          for (int j = 0; j < items && fields >> skip; ++j) {
          }
          continue;
        }
        double value = 0.0;
        if (!(fields >> token) || items < 0) {
          ThrowIfError(Status::ParseError(path + ": " + v.name + " " + std::to_string(k) + ": property '" +
                                          prop.name + "' missing"));
        }
        const char* b = token.data();
        const auto [end, ec] = std::from_chars(b, b + token.size(), value);
        if (ec != std::errc() || end != b + token.size()) {
          ThrowIfError(Status::ParseError(path + ": " + v.name + " " + std::to_string(k) + ": property '" +
                                          prop.name + "': not a number: '" + token + "'"));
        }
        if (static_cast<int>(i) == ix) p.x() = value;
        if (static_cast<int>(i) == iy) p.y() = value;
        if (static_cast<int>(i) == iz) p.z() = value;
      }
      points.push_back(p);
    }
    return points;
  }
  const bool swap = (header.encoding == opl::PlyEncoding::kBinaryLittleEndian) != LittleEndianHost();
  auto skip_record = [&](const opl::PlyElement& element, int64_t record) {
    for (const opl::PlyProperty& prop : element.properties) {
      if (prop.is_list) {
        const size_t cb = static_cast<size_t>(opl::PlyScalarBytes(prop.count_type));
        if (pos + cb > data.size()) cut_off(record);
        const double count = ReadBinary(data.data() + pos, prop.count_type, swap);
        pos += cb + static_cast<size_t>(count) * static_cast<size_t>(opl::PlyScalarBytes(prop.type));
      } else {
        pos += static_cast<size_t>(opl::PlyScalarBytes(prop.type));
      }
    }
  };
  for (int e = 0; e < vertex; ++e) {
    const opl::PlyElement& element = header.elements[static_cast<size_t>(e)];
    for (int64_t k = 0; k < element.count; ++k) skip_record(element, k);
  }
  std::vector<size_t> offset(v.properties.size());
  for (int64_t k = 0; k < v.count; ++k) {
    const size_t start = pos;
    for (size_t i = 0; i < v.properties.size(); ++i) {
      offset[i] = pos - start;
      const opl::PlyProperty& prop = v.properties[i];
      if (prop.is_list) {
        const size_t cb = static_cast<size_t>(opl::PlyScalarBytes(prop.count_type));
        if (pos + cb > data.size()) cut_off(k);
        const double count = ReadBinary(data.data() + pos, prop.count_type, swap);
        pos += cb + static_cast<size_t>(count) * static_cast<size_t>(opl::PlyScalarBytes(prop.type));
      } else {
        pos += static_cast<size_t>(opl::PlyScalarBytes(prop.type));
      }
    }
    if (pos > data.size()) cut_off(k);
    points.emplace_back(ReadBinary(data.data() + start + offset[static_cast<size_t>(ix)], v.properties[static_cast<size_t>(ix)].type, swap),
                        ReadBinary(data.data() + start + offset[static_cast<size_t>(iy)], v.properties[static_cast<size_t>(iy)].type, swap),
                        ReadBinary(data.data() + start + offset[static_cast<size_t>(iz)], v.properties[static_cast<size_t>(iz)].type, swap));
  }
  return points;
}

// Headerless XYZ: per line x y z (blanks between), anything after ignored;
// blank lines and lines starting with '#' skipped.
std::vector<Eigen::Vector3d> ReadXyz(const std::string& path) {
  const std::string data = Unwrap(opl::ReadFileToString(path));
  std::istringstream in(data);
  std::string line;
  std::vector<Eigen::Vector3d> points;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) {
      std::string token;
      fields >> token;
      const char* b = token.data();
      const auto [end, ec] = std::from_chars(b, b + token.size(), p[k]);
      if (token.empty() || ec != std::errc() || end != b + token.size()) {
        const char* axis[] = {"x", "y", "z"};
        ThrowIfError(Status::ParseError(path + ":" + std::to_string(number) + ": field '" + axis[k] +
                                        "': not a number: '" + token + "'"));
      }
    }
    points.push_back(p);
  }
  return points;
}

std::string Shortest(double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  return ec == std::errc() ? std::string(buf, end) : std::string("nan");
}

void WritePointCloud(const py::array_t<double, py::array::forcecast>& array, const std::string& path,
                     opl::PointFileFormat format, bool binary) {
  const std::vector<Eigen::Vector3d> points = PointsFromArray(array, "write_point_cloud: points");
  if (format == opl::PointFileFormat::kAuto) format = Unwrap(opl::PointFileFormatFromPath(path));
  std::string out;
  if (format == opl::PointFileFormat::kPly) {
    out = std::string("ply\nformat ") + (binary ? (LittleEndianHost() ? "binary_little_endian" : "binary_big_endian") : "ascii") +
          " 1.0\ncomment written by OPL " + opl::VersionNumber() + " (Python)\nelement vertex " + std::to_string(points.size()) +
          "\nproperty double x\nproperty double y\nproperty double z\nend_header\n";
    for (const Eigen::Vector3d& p : points) {
      if (binary) {
        out.append(reinterpret_cast<const char*>(p.data()), 3 * sizeof(double));
      } else {
        out += Shortest(p.x()) + " " + Shortest(p.y()) + " " + Shortest(p.z()) + "\n";
      }
    }
  } else if (format == opl::PointFileFormat::kXyz) {
    for (const Eigen::Vector3d& p : points) out += Shortest(p.x()) + " " + Shortest(p.y()) + " " + Shortest(p.z()) + "\n";
  } else {
    out = "x,y,z\n";
    for (const Eigen::Vector3d& p : points) out += Shortest(p.x()) + "," + Shortest(p.y()) + "," + Shortest(p.z()) + "\n";
  }
  ThrowIfError(opl::WriteFileAtomically(path, out));
}

}  // namespace

void BindPointCloud(py::module_& m) {
  m.def(
      "read_point_cloud",
      [](const std::string& path, opl::PointFileFormat format) {
        if (format == opl::PointFileFormat::kAuto) format = Unwrap(opl::PointFileFormatFromPath(path));
        std::vector<Eigen::Vector3d> points;
        if (format == opl::PointFileFormat::kPly) {
          points = ReadPly(path);
        } else if (format == opl::PointFileFormat::kXyz) {
          points = ReadXyz(path);
        } else {
          points = Unwrap(opl::PointsCsv::Read(path)).points();
        }
        return ArrayFromPoints(points);
      },
      py::arg("path"), py::arg("format") = opl::PointFileFormat::kAuto,
      "The x, y, z of every point of a PLY (the `vertex` element; ASCII or binary, other "
      "properties and elements skipped), headerless XYZ (x y z per line) or points CSV file, as "
      "an (N, 3) array. The whole file is read (up to 512 MiB); to scale a file of any size, use "
      "scale_point_file.");
  m.def("write_point_cloud", &WritePointCloud, py::arg("points"), py::arg("path"),
        py::arg("format") = opl::PointFileFormat::kAuto, py::arg("binary") = true,
        "Writes an (N, 3) array as a PLY (binary in the host's byte order unless binary=False; "
        "double x, y, z), XYZ or points CSV (x,y,z) file, numbers as the shortest text that reads "
        "back exactly; the format from the extension unless given. Atomic.");
}

}  // namespace opl_python
