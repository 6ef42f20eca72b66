// PLY point clouds and meshes (the Stanford "polygon file format"), as
// opl_measure --apply scales them (opl/io/scale_point_file.h; docs/formats.md,
// "Point files").
//
//   ply
//   format binary_little_endian 1.0        (or ascii 1.0, binary_big_endian 1.0)
//   comment made by a scanner
//   element vertex 2
//   property float x                       x, y, z: float or double
//   property float y
//   property float z
//   property float nx                      anything else: kept
//   property uchar red
//   element face 1
//   property list uchar int vertex_indices
//   end_header
//   <body: the elements in header order, each record its properties in order>
//
// Scaling multiplies the `x`, `y`, `z` properties of the `vertex` element by s
// (in double, then rounded to the property's type); every other byte is kept:
// the other properties of a vertex (normals nx, ny, nz stay as they are: they
// are directions; colours, scalar fields, list properties), every other element
// (faces, edges, anything), every comment and obj_info line, and the header
// text itself, into which one line `comment OPL scaled vertex x, y, z by s = <s>`
// is inserted before the first `element` line. Binary output has the input's
// byte order; ASCII numbers other than x, y, z keep their exact text, and x, y,
// z are written as the shortest text that reads back exactly as the scaled
// value of the property's type. A non-finite coordinate (NaN marks an invalid
// point in organised clouds) is kept as it is.
//
// Refused, with one line naming the file and the header line, or the element
// index and byte offset in the body:
//   "cloud.ply:5: property 'x' of element 'vertex' is int: OPL scales float or double coordinates"
//   "cloud.ply: byte 1036: vertex 84 of 100 is cut off by the end of the file (truncated, or wrong counts in the header)"
//
// Why hand-written: Debian 12 packages no PLY library (no rply, tinyply or
// happly in its archive), and the known ones read or write every value through
// a double or their own buffers: RPly reformats ASCII numbers (its output is not
// byte-faithful) and tinyply and happly read whole elements into memory (not
// streaming). The format is small; this reader streams a record at a time.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "opl/core/status.h"

namespace opl {

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

// The scalar types of PLY 1.0, with their alternative names
// (char/int8 ... double/float64).
enum class PlyScalarType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

// Size in bytes of a value of `type` in a binary PLY.
int PlyScalarBytes(PlyScalarType type);
// "char", "uchar", ... "double": the PLY 1.0 name.
const char* PlyScalarTypeName(PlyScalarType type);

struct PlyProperty {
  std::string name;
  PlyScalarType type = PlyScalarType::kFloat32;  // the value type (of the items of a list)
  bool is_list = false;
  PlyScalarType count_type = PlyScalarType::kUint8;  // a list's count (an integer type)
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> properties;
  int header_line = 0;  // 1-based line of its `element` line

  // Index of the property named `name`, or -1.
  int FindProperty(const std::string& name) const;
  // Bytes of one record in a binary PLY, or -1 when it has a list property
  // (records then differ in size).
  int64_t FixedRecordBytes() const;
};

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<PlyElement> elements;  // in file (= body) order
  // The header's bytes, "ply" to the line break of "end_header"; the body
  // starts right after.
  std::string text;
  // Offset in `text` of the first `element` line (where OPL's comment goes).
  size_t first_element_offset = 0;
  // The line break the header uses ("\n" or "\r\n").
  std::string line_break = "\n";

  // Index of the element named `name`, or -1.
  int FindElement(const std::string& name) const;
};

// Parses a PLY header: `text` is the file's first bytes up to and including
// the line break after `end_header` (more is ignored); `name` prefixes
// messages. Checks: "ply" first, one `format` line before any element (ascii,
// binary_little_endian or binary_big_endian, version 1.0), known types, counts
// >= 0, property lines after an element, no duplicate element or property
// names, integer list counts, `end_header` present. Not checked here: which
// properties exist (see CheckScalablePly).
Result<PlyHeader> ParsePlyHeader(std::string_view text, const std::string& name);

// What scaling needs of a header: an element `vertex` with scalar properties
// x, y and z of type float or double. ParseError naming the line otherwise.
Status CheckScalablePly(const PlyHeader& header, const std::string& name);

}  // namespace opl
