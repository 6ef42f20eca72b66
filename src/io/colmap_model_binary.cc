// COLMAP's binary model (https://colmap.github.io/format.html#binary-file-format),
// little endian:
//   cameras.bin   uint64 count; per camera: uint32 CAMERA_ID, int32 MODEL_ID,
//                 uint64 WIDTH, uint64 HEIGHT, double PARAMS[model's count]
//   images.bin    uint64 count; per image: uint32 IMAGE_ID, double QW QX QY QZ,
//                 double TX TY TZ, uint32 CAMERA_ID, NAME (chars ending in '\0'),
//                 uint64 POINTS2D count, per 2D point: double X, double Y,
//                 uint64 POINT3D_ID (2^64 - 1: none)
//   points3D.bin  uint64 count; per point: uint64 POINT3D_ID, double X Y Z,
//                 uint8 R G B, double ERROR, uint64 TRACK count, per element:
//                 uint32 IMAGE_ID, uint32 POINT2D_IDX
// A file that ends inside a record, or has bytes after the last one, is refused.
#include <cstring>
#include <limits>
#include <type_traits>

#include "io/colmap_model_internal.h"

namespace opl {
namespace colmap_internal {
namespace {

static_assert(std::numeric_limits<double>::is_iec559, "COLMAP binary files hold IEEE doubles");

bool HostIsLittleEndian() {
  const uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

template <typename T>
T FromLittleEndian(const unsigned char* bytes) {
  unsigned char buffer[sizeof(T)];
  for (size_t i = 0; i < sizeof(T); ++i) {
    buffer[i] = HostIsLittleEndian() ? bytes[i] : bytes[sizeof(T) - 1 - i];
  }
  T value;
  std::memcpy(&value, buffer, sizeof(T));
  return value;
}

template <typename T>
void AppendLittleEndian(T value, std::string* out) {
  unsigned char buffer[sizeof(T)];
  std::memcpy(buffer, &value, sizeof(T));
  for (size_t i = 0; i < sizeof(T); ++i) {
    out->push_back(static_cast<char>(HostIsLittleEndian() ? buffer[i] : buffer[sizeof(T) - 1 - i]));
  }
}

// Reads a binary file front to back; every error names the file, the record
// and the field: "<file>: record 3 (camera 7): field 'PARAMS': truncated file
// (needs 8 bytes at offset 120, file has 124)".
class Reader {
 public:
  Reader(std::string file, const std::string& data, const char* noun)
      : file_(std::move(file)), data_(data), noun_(noun) {}

  // Starts record `index` (1-based); its id is not known yet.
  void BeginRecord(uint64_t index) {
    record_ = index;
    id_.clear();
  }
  void SetRecordId(uint64_t id) { id_ = std::to_string(id); }

  Status Error(const std::string& field, const std::string& what) const {
    std::string where = file_ + ": ";
    if (record_ > 0) {
      where += "record " + std::to_string(record_) + " (" + noun_ +
               (id_.empty() ? std::string() : " " + id_) + "): ";
    }
    return Status::ParseError(where + "field '" + field + "': " + what);
  }

  template <typename T>
  Status Read(const char* field, T* value) {
    if (data_.size() - offset_ < sizeof(T)) return Truncated(field, sizeof(T));
    *value = FromLittleEndian<T>(reinterpret_cast<const unsigned char*>(data_.data()) + offset_);
    offset_ += sizeof(T);
    return Status::Ok();
  }

  // A count of records or elements, each at least `min_bytes` long, which must
  // fit in what is left of the file (a corrupt count must not allocate 2^64).
  Status ReadCount(const char* field, size_t min_bytes, uint64_t* count) {
    OPL_RETURN_IF_ERROR(Read(field, count));
    const size_t left = data_.size() - offset_;
    if (*count > left / min_bytes) {
      return Error(field, std::to_string(*count) + " entries of at least " +
                              std::to_string(min_bytes) + " bytes cannot fit in the " +
                              std::to_string(left) + " bytes left (truncated or corrupt file)");
    }
    return Status::Ok();
  }

  Status ReadString(const char* field, std::string* value) {
    const size_t end = data_.find('\0', offset_);
    if (end == std::string::npos) {
      return Error(field, "truncated file (no terminating '\\0' before the end, offset " +
                              std::to_string(offset_) + ", file has " +
                              std::to_string(data_.size()) + " bytes)");
    }
    *value = data_.substr(offset_, end - offset_);
    offset_ = end + 1;
    return Status::Ok();
  }

  Status ExpectEnd() {
    record_ = 0;
    if (offset_ != data_.size()) {
      return Status::ParseError(file_ + ": " + std::to_string(data_.size() - offset_) +
                                " bytes after the last record (corrupt file, or not a " +
                                "COLMAP model of this layout)");
    }
    return Status::Ok();
  }

 private:
  Status Truncated(const char* field, size_t bytes) const {
    return Error(field, "truncated file (needs " + std::to_string(bytes) + " bytes at offset " +
                            std::to_string(offset_) + ", file has " +
                            std::to_string(data_.size()) + ")");
  }

  std::string file_;
  const std::string& data_;
  std::string noun_;
  size_t offset_ = 0;
  uint64_t record_ = 0;
  std::string id_;
};

Status ParseCameras(Reader* r, ColmapModel* model) {
  uint64_t count = 0;
  OPL_RETURN_IF_ERROR(r->ReadCount("number of cameras", 24, &count));
  for (uint64_t k = 1; k <= count; ++k) {
    r->BeginRecord(k);
    ColmapCamera camera;
    int32_t model_id = 0;
    OPL_RETURN_IF_ERROR(r->Read("CAMERA_ID", &camera.camera_id));
    r->SetRecordId(camera.camera_id);
    OPL_RETURN_IF_ERROR(r->Read("MODEL_ID", &model_id));
    if (ColmapCameraModelName(model_id) == nullptr) {
      return r->Error("MODEL_ID", "unknown camera model id " + std::to_string(model_id));
    }
    camera.model_id = model_id;
    OPL_RETURN_IF_ERROR(r->Read("WIDTH", &camera.width_px));
    OPL_RETURN_IF_ERROR(r->Read("HEIGHT", &camera.height_px));
    camera.params.resize(static_cast<size_t>(ColmapCameraModelNumParams(model_id)));
    for (double& p : camera.params) OPL_RETURN_IF_ERROR(r->Read("PARAMS", &p));
    if (!model->cameras.emplace(camera.camera_id, camera).second) {
      return r->Error("CAMERA_ID", "camera " + std::to_string(camera.camera_id) + " appears twice");
    }
  }
  return r->ExpectEnd();
}

Status ParseImages(Reader* r, ColmapModel* model) {
  uint64_t count = 0;
  OPL_RETURN_IF_ERROR(r->ReadCount("number of images", 73, &count));
  for (uint64_t k = 1; k <= count; ++k) {
    r->BeginRecord(k);
    ColmapImage image;
    OPL_RETURN_IF_ERROR(r->Read("IMAGE_ID", &image.image_id));
    r->SetRecordId(image.image_id);
    static const char* kPose[] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
    for (int i = 0; i < 4; ++i) OPL_RETURN_IF_ERROR(r->Read(kPose[i], &image.qvec_wxyz[i]));
    for (int i = 0; i < 3; ++i) OPL_RETURN_IF_ERROR(r->Read(kPose[4 + i], &image.tvec[i]));
    OPL_RETURN_IF_ERROR(r->Read("CAMERA_ID", &image.camera_id));
    OPL_RETURN_IF_ERROR(r->ReadString("NAME", &image.name));
    uint64_t num_points = 0;
    OPL_RETURN_IF_ERROR(r->ReadCount("POINTS2D count", 24, &num_points));
    image.points2D.resize(num_points);
    for (ColmapPoint2D& p : image.points2D) {
      OPL_RETURN_IF_ERROR(r->Read("X", &p.xy_px.x()));
      OPL_RETURN_IF_ERROR(r->Read("Y", &p.xy_px.y()));
      OPL_RETURN_IF_ERROR(r->Read("POINT3D_ID", &p.point3D_id));
    }
    if (!model->images.emplace(image.image_id, image).second) {
      return r->Error("IMAGE_ID", "image " + std::to_string(image.image_id) + " appears twice");
    }
  }
  return r->ExpectEnd();
}

Status ParsePoints3D(Reader* r, ColmapModel* model) {
  uint64_t count = 0;
  OPL_RETURN_IF_ERROR(r->ReadCount("number of points", 51, &count));
  for (uint64_t k = 1; k <= count; ++k) {
    r->BeginRecord(k);
    ColmapPoint3D point;
    OPL_RETURN_IF_ERROR(r->Read("POINT3D_ID", &point.point3D_id));
    r->SetRecordId(point.point3D_id);
    static const char* kXyz[] = {"X", "Y", "Z"};
    static const char* kRgb[] = {"R", "G", "B"};
    for (int i = 0; i < 3; ++i) OPL_RETURN_IF_ERROR(r->Read(kXyz[i], &point.xyz_in_world[i]));
    for (int i = 0; i < 3; ++i) OPL_RETURN_IF_ERROR(r->Read(kRgb[i], &point.rgb[i]));
    OPL_RETURN_IF_ERROR(r->Read("ERROR", &point.error_px));
    uint64_t track_length = 0;
    OPL_RETURN_IF_ERROR(r->ReadCount("TRACK length", 8, &track_length));
    point.track.resize(track_length);
    for (ColmapTrackElement& e : point.track) {
      OPL_RETURN_IF_ERROR(r->Read("IMAGE_ID", &e.image_id));
      OPL_RETURN_IF_ERROR(r->Read("POINT2D_IDX", &e.point2D_idx));
    }
    if (!model->points3D.emplace(point.point3D_id, point).second) {
      return r->Error("POINT3D_ID",
                      "point " + std::to_string(point.point3D_id) + " appears twice");
    }
  }
  return r->ExpectEnd();
}

}  // namespace

Result<ColmapModel> ParseColmapBinary(const std::string& dir, const ColmapFileContents& files) {
  const ColmapFileNames names = FileNames(ColmapFormat::kBinary);
  const auto path = [&](const std::string& name) {
    return dir.empty() ? name : (dir.back() == '/' ? dir + name : dir + "/" + name);
  };
  ColmapModel model;
  model.format = ColmapFormat::kBinary;
  Reader cameras(path(names.cameras), files.cameras, "camera");
  OPL_RETURN_IF_ERROR(ParseCameras(&cameras, &model));
  Reader images(path(names.images), files.images, "image");
  OPL_RETURN_IF_ERROR(ParseImages(&images, &model));
  Reader points(path(names.points3D), files.points3D, "point");
  OPL_RETURN_IF_ERROR(ParsePoints3D(&points, &model));
  return model;
}

ColmapFileContents FormatColmapBinary(const ColmapModel& model) {
  ColmapFileContents out;
  AppendLittleEndian<uint64_t>(model.cameras.size(), &out.cameras);
  for (const auto& [id, camera] : model.cameras) {
    AppendLittleEndian<uint32_t>(id, &out.cameras);
    AppendLittleEndian<int32_t>(camera.model_id, &out.cameras);
    AppendLittleEndian<uint64_t>(camera.width_px, &out.cameras);
    AppendLittleEndian<uint64_t>(camera.height_px, &out.cameras);
    for (double p : camera.params) AppendLittleEndian(p, &out.cameras);
  }
  AppendLittleEndian<uint64_t>(model.images.size(), &out.images);
  for (const auto& [id, image] : model.images) {
    AppendLittleEndian<uint32_t>(id, &out.images);
    for (double q : image.qvec_wxyz) AppendLittleEndian(q, &out.images);
    for (int i = 0; i < 3; ++i) AppendLittleEndian(image.tvec[i], &out.images);
    AppendLittleEndian<uint32_t>(image.camera_id, &out.images);
    out.images += image.name;
    out.images.push_back('\0');
    AppendLittleEndian<uint64_t>(image.points2D.size(), &out.images);
    for (const ColmapPoint2D& p : image.points2D) {
      AppendLittleEndian(p.xy_px.x(), &out.images);
      AppendLittleEndian(p.xy_px.y(), &out.images);
      AppendLittleEndian<uint64_t>(p.point3D_id, &out.images);
    }
  }
  AppendLittleEndian<uint64_t>(model.points3D.size(), &out.points3D);
  for (const auto& [id, point] : model.points3D) {
    AppendLittleEndian<uint64_t>(id, &out.points3D);
    for (int i = 0; i < 3; ++i) AppendLittleEndian(point.xyz_in_world[i], &out.points3D);
    for (uint8_t c : point.rgb) AppendLittleEndian(c, &out.points3D);
    AppendLittleEndian(point.error_px, &out.points3D);
    AppendLittleEndian<uint64_t>(point.track.size(), &out.points3D);
    for (const ColmapTrackElement& e : point.track) {
      AppendLittleEndian<uint32_t>(e.image_id, &out.points3D);
      AppendLittleEndian<uint32_t>(e.point2D_idx, &out.points3D);
    }
  }
  return out;
}

}  // namespace colmap_internal
}  // namespace opl
