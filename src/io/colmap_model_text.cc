// COLMAP's text model: cameras.txt, images.txt, points3D.txt
// (https://colmap.github.io/format.html#text-format). Fields are separated by
// runs of spaces (or tabs); lines starting with '#' and blank lines are
// skipped, except that the line right after an image's line is always that
// image's POINTS2D line, which is blank for an image without 2D points (as
// COLMAP writes and reads it).
#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>

#include "io/colmap_model_internal.h"
#include "opl/core/format.h"
#include "opl/core/message_text.h"

namespace opl {
namespace colmap_internal {
namespace {

struct Line {
  int number = 0;  // 1-based
  std::string text;
};

std::vector<Line> SplitLines(const std::string& text) {
  std::vector<Line> lines;
  size_t start = 0;
  int number = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back({++number, std::move(line)});
    start = end + 1;
  }
  return lines;
}

bool IsSkipped(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t");
  return first == std::string::npos || line[first] == '#';
}

// A line cut into fields, with the byte offset where each starts.
struct Fields {
  std::vector<std::string> values;
  std::vector<size_t> starts;
};

Fields SplitFields(const std::string& line) {
  Fields f;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) break;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    f.values.push_back(line.substr(start, i - start));
    f.starts.push_back(start);
  }
  return f;
}

// Parses one line's fields, each error "<file>:<line>: field '<NAME>': ...".
class LineParser {
 public:
  LineParser(const std::string& file, const Line& line)
      : prefix_(file + ":" + std::to_string(line.number) + ": ") {}

  const std::string& prefix() const { return prefix_; }

  Status Error(const std::string& what) const { return Status::ParseError(prefix_ + what); }

  Status FieldError(const std::string& field, const std::string& what,
                    const std::string& text) const {
    return Error("field '" + field + "': " + what + ": " + QuoteForMessage(text));
  }

  Status Double(const std::string& field, const std::string& text, double* value) const {
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, *value);
    if (ec != std::errc() || ptr != end || !std::isfinite(*value)) {
      return FieldError(field, "not a finite number", text);
    }
    return Status::Ok();
  }

  // An unsigned integer in [0, max].
  Status Unsigned(const std::string& field, const std::string& text, uint64_t max,
                  uint64_t* value) const {
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, *value);
    if (ec != std::errc() || ptr != end || *value > max) {
      return FieldError(field, "not an integer in [0, " + std::to_string(max) + "]", text);
    }
    return Status::Ok();
  }

  template <typename T>
  Status Id(const std::string& field, const std::string& text, T* value) const {
    uint64_t v = 0;
    OPL_RETURN_IF_ERROR(Unsigned(field, text, std::numeric_limits<T>::max(), &v));
    *value = static_cast<T>(v);
    return Status::Ok();
  }

 private:
  std::string prefix_;
};

Status ParseCameras(const std::string& file, const std::string& text, ColmapModel* model) {
  for (const Line& line : SplitLines(text)) {
    if (IsSkipped(line.text)) continue;
    const LineParser p(file, line);
    const Fields f = SplitFields(line.text);
    if (f.values.size() < 4) {
      return p.Error("expected CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[], found " +
                     std::to_string(f.values.size()) + " fields");
    }
    ColmapCamera camera;
    OPL_RETURN_IF_ERROR(p.Id("CAMERA_ID", f.values[0], &camera.camera_id));
    camera.model_id = ColmapCameraModelIdFromName(f.values[1]);
    if (camera.model_id < 0) return p.FieldError("MODEL", "unknown camera model", f.values[1]);
    constexpr uint64_t kMaxSide = std::numeric_limits<uint32_t>::max();
    OPL_RETURN_IF_ERROR(p.Unsigned("WIDTH", f.values[2], kMaxSide, &camera.width_px));
    OPL_RETURN_IF_ERROR(p.Unsigned("HEIGHT", f.values[3], kMaxSide, &camera.height_px));
    const size_t num_params = static_cast<size_t>(ColmapCameraModelNumParams(camera.model_id));
    if (f.values.size() - 4 != num_params) {
      return p.Error("model " + f.values[1] + " has " + std::to_string(num_params) +
                     " parameters, found " + std::to_string(f.values.size() - 4));
    }
    camera.params.resize(num_params);
    for (size_t i = 0; i < num_params; ++i) {
      OPL_RETURN_IF_ERROR(
          p.Double("PARAMS[" + std::to_string(i) + "]", f.values[4 + i], &camera.params[i]));
    }
    if (!model->cameras.emplace(camera.camera_id, camera).second) {
      return p.Error("camera " + std::to_string(camera.camera_id) + " appears twice");
    }
  }
  return Status::Ok();
}

Status ParseImages(const std::string& file, const std::string& text, ColmapModel* model) {
  const std::vector<Line> lines = SplitLines(text);
  for (size_t l = 0; l < lines.size(); ++l) {
    if (IsSkipped(lines[l].text)) continue;
    const LineParser p(file, lines[l]);
    const Fields f = SplitFields(lines[l].text);
    if (f.values.size() < 10) {
      return p.Error(
          "expected IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME, found " +
          std::to_string(f.values.size()) + " fields");
    }
    ColmapImage image;
    OPL_RETURN_IF_ERROR(p.Id("IMAGE_ID", f.values[0], &image.image_id));
    static const char* kPose[] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
    for (int i = 0; i < 4; ++i) {
      OPL_RETURN_IF_ERROR(p.Double(kPose[i], f.values[1 + i], &image.qvec_wxyz[i]));
    }
    for (int i = 0; i < 3; ++i) {
      OPL_RETURN_IF_ERROR(p.Double(kPose[4 + i], f.values[5 + i], &image.tvec[i]));
    }
    OPL_RETURN_IF_ERROR(p.Id("CAMERA_ID", f.values[8], &image.camera_id));
    // NAME is the rest of the line (a name may hold spaces), trailing blanks cut.
    image.name = lines[l].text.substr(f.starts[9]);
    image.name.erase(image.name.find_last_not_of(" \t") + 1);

    if (l + 1 >= lines.size()) {
      return p.Error("image " + std::to_string(image.image_id) +
                     ": missing its POINTS2D line (the line after the image's line)");
    }
    ++l;
    const LineParser q(file, lines[l]);
    const Fields points = SplitFields(lines[l].text);
    if (points.values.size() % 3 != 0) {
      return q.Error("POINTS2D of image " + std::to_string(image.image_id) +
                     ": expected triples X, Y, POINT3D_ID, found " +
                     std::to_string(points.values.size()) + " fields");
    }
    image.points2D.resize(points.values.size() / 3);
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      ColmapPoint2D& point = image.points2D[i];
      const std::string n = "[" + std::to_string(i) + "]";
      OPL_RETURN_IF_ERROR(q.Double("X" + n, points.values[3 * i], &point.xy_px.x()));
      OPL_RETURN_IF_ERROR(q.Double("Y" + n, points.values[3 * i + 1], &point.xy_px.y()));
      const std::string& id = points.values[3 * i + 2];
      if (id == "-1") {
        point.point3D_id = kColmapNoPoint3D;
      } else {
        OPL_RETURN_IF_ERROR(q.Unsigned("POINT3D_ID" + n, id, kColmapNoPoint3D - 1,
                                       &point.point3D_id));
      }
    }
    if (!model->images.emplace(image.image_id, image).second) {
      return p.Error("image " + std::to_string(image.image_id) + " appears twice");
    }
  }
  return Status::Ok();
}

Status ParsePoints3D(const std::string& file, const std::string& text, ColmapModel* model) {
  for (const Line& line : SplitLines(text)) {
    if (IsSkipped(line.text)) continue;
    const LineParser p(file, line);
    const Fields f = SplitFields(line.text);
    if (f.values.size() < 8 || (f.values.size() - 8) % 2 != 0) {
      return p.Error(
          "expected POINT3D_ID, X, Y, Z, R, G, B, ERROR and pairs IMAGE_ID, POINT2D_IDX, found " +
          std::to_string(f.values.size()) + " fields");
    }
    ColmapPoint3D point;
    OPL_RETURN_IF_ERROR(p.Unsigned("POINT3D_ID", f.values[0], kColmapNoPoint3D - 1,
                                   &point.point3D_id));
    static const char* kXyz[] = {"X", "Y", "Z"};
    static const char* kRgb[] = {"R", "G", "B"};
    for (int i = 0; i < 3; ++i) {
      OPL_RETURN_IF_ERROR(p.Double(kXyz[i], f.values[1 + i], &point.xyz_in_world[i]));
    }
    for (int i = 0; i < 3; ++i) {
      OPL_RETURN_IF_ERROR(p.Id(kRgb[i], f.values[4 + i], &point.rgb[i]));
    }
    OPL_RETURN_IF_ERROR(p.Double("ERROR", f.values[7], &point.error_px));
    point.track.resize((f.values.size() - 8) / 2);
    for (size_t k = 0; k < point.track.size(); ++k) {
      const std::string n = "[" + std::to_string(k) + "]";
      OPL_RETURN_IF_ERROR(p.Id("IMAGE_ID" + n, f.values[8 + 2 * k], &point.track[k].image_id));
      OPL_RETURN_IF_ERROR(
          p.Id("POINT2D_IDX" + n, f.values[9 + 2 * k], &point.track[k].point2D_idx));
    }
    if (!model->points3D.emplace(point.point3D_id, point).second) {
      return p.Error("point " + std::to_string(point.point3D_id) + " appears twice");
    }
  }
  return Status::Ok();
}

std::string Num(double value) { return FormatRoundTrip(value); }

}  // namespace

Result<ColmapModel> ParseColmapText(const std::string& dir, const ColmapFileContents& files) {
  const ColmapFileNames names = FileNames(ColmapFormat::kText);
  const auto path = [&](const std::string& name) {
    return dir.empty() ? name : (dir.back() == '/' ? dir + name : dir + "/" + name);
  };
  ColmapModel model;
  model.format = ColmapFormat::kText;
  OPL_RETURN_IF_ERROR(ParseCameras(path(names.cameras), files.cameras, &model));
  OPL_RETURN_IF_ERROR(ParseImages(path(names.images), files.images, &model));
  OPL_RETURN_IF_ERROR(ParsePoints3D(path(names.points3D), files.points3D, &model));
  return model;
}

ColmapFileContents FormatColmapText(const ColmapModel& model) {
  ColmapFileContents out;
  std::ostringstream cameras;
  cameras << "# Camera list with one line of data per camera:\n"
          << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
          << "# Number of cameras: " << model.cameras.size() << "\n";
  for (const auto& [id, camera] : model.cameras) {
    cameras << id << " " << ColmapCameraModelName(camera.model_id) << " " << camera.width_px
            << " " << camera.height_px;
    for (double p : camera.params) cameras << " " << Num(p);
    cameras << "\n";
  }
  out.cameras = cameras.str();

  size_t observations = 0;
  for (const auto& entry : model.images) {
    for (const ColmapPoint2D& p : entry.second.points2D) {
      observations += p.point3D_id != kColmapNoPoint3D ? 1 : 0;
    }
  }
  std::ostringstream images;
  images << "# Image list with two lines of data per image:\n"
         << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
         << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
         << "# Number of images: " << model.images.size() << ", mean observations per image: "
         << (model.images.empty() ? 0.0
                                  : static_cast<double>(observations) / model.images.size())
         << "\n";
  for (const auto& [id, image] : model.images) {
    images << id;
    for (double q : image.qvec_wxyz) images << " " << Num(q);
    for (int i = 0; i < 3; ++i) images << " " << Num(image.tvec[i]);
    images << " " << image.camera_id << " " << image.name << "\n";
    bool first = true;
    for (const ColmapPoint2D& p : image.points2D) {
      images << (first ? "" : " ") << Num(p.xy_px.x()) << " " << Num(p.xy_px.y()) << " ";
      if (p.point3D_id == kColmapNoPoint3D) {
        images << "-1";
      } else {
        images << p.point3D_id;
      }
      first = false;
    }
    images << "\n";
  }
  out.images = images.str();

  size_t track_total = 0;
  for (const auto& entry : model.points3D) track_total += entry.second.track.size();
  std::ostringstream points;
  points << "# 3D point list with one line of data per point:\n"
         << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
         << "# Number of points: " << model.points3D.size() << ", mean track length: "
         << (model.points3D.empty()
                 ? 0.0
                 : static_cast<double>(track_total) / model.points3D.size())
         << "\n";
  for (const auto& [id, point] : model.points3D) {
    points << id;
    for (int i = 0; i < 3; ++i) points << " " << Num(point.xyz_in_world[i]);
    for (uint8_t c : point.rgb) points << " " << static_cast<int>(c);
    points << " " << Num(point.error_px);
    for (const ColmapTrackElement& e : point.track) {
      points << " " << e.image_id << " " << e.point2D_idx;
    }
    points << "\n";
  }
  out.points3D = points.str();
  return out;
}

}  // namespace colmap_internal
}  // namespace opl
