// Private to src/io: the text and binary halves of the COLMAP model reader and
// writer (io/colmap_model.h).
#pragma once

#include <string>

#include "opl/core/status.h"
#include "opl/io/colmap_model.h"

namespace opl {
namespace colmap_internal {

// The three files of a model, as names in a folder and as contents.
struct ColmapFileNames {
  std::string cameras, images, points3D;
};
ColmapFileNames FileNames(ColmapFormat format);

struct ColmapFileContents {
  std::string cameras, images, points3D;
};

// Parse the three files; `dir` prefixes every message ("<dir>/cameras.txt:4:
// ..."). No cross-file consistency check (ColmapModel::Validate does that).
Result<ColmapModel> ParseColmapText(const std::string& dir, const ColmapFileContents& files);
Result<ColmapModel> ParseColmapBinary(const std::string& dir, const ColmapFileContents& files);

// The three files of `model` (assumed valid).
ColmapFileContents FormatColmapText(const ColmapModel& model);
ColmapFileContents FormatColmapBinary(const ColmapModel& model);

// Validate with every message prefixed by the file it concerns, e.g.
// "m/points3D.txt: point 12: track element 2: image 5 does not exist".
// Empty `dir`: "points3D: point 12: ...".
Status ValidateModel(const ColmapModel& model, const std::string& dir, ColmapFormat format);

}  // namespace colmap_internal
}  // namespace opl
