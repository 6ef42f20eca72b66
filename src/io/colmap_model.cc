#include "opl/io/colmap_model.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "io/colmap_model_internal.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

struct ModelInfo {
  const char* name;
  int num_params;
};
constexpr ModelInfo kModels[kNumColmapCameraModels] = {
    {"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4},         {"SIMPLE_RADIAL", 4},
    {"RADIAL", 5},         {"OPENCV", 8},          {"OPENCV_FISHEYE", 8},
    {"FULL_OPENCV", 12},   {"FOV", 5},             {"SIMPLE_RADIAL_FISHEYE", 4},
    {"RADIAL_FISHEYE", 5}, {"THIN_PRISM_FISHEYE", 12},
};

constexpr const char* kSupportedModels =
    "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV with k4 = k5 = k6 = 0";

std::string CameraLabel(const ColmapCamera& camera) {
  return "COLMAP camera " + std::to_string(camera.camera_id);
}

std::string JoinPath(const std::string& dir, const std::string& name) {
  if (dir.empty()) return name;
  return dir.back() == '/' ? dir + name : dir + "/" + name;
}

bool IsFile(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec);
}

bool HasAllFiles(const std::string& dir, ColmapFormat format) {
  const colmap_internal::ColmapFileNames names = colmap_internal::FileNames(format);
  return IsFile(JoinPath(dir, names.cameras)) && IsFile(JoinPath(dir, names.images)) &&
         IsFile(JoinPath(dir, names.points3D));
}

// Which of the six model files exist, for the message of a folder that is not
// a model: "cameras.txt, images.txt" or "none of them".
std::string FilesFound(const std::string& dir) {
  std::string found;
  for (ColmapFormat format : {ColmapFormat::kText, ColmapFormat::kBinary}) {
    const colmap_internal::ColmapFileNames n = colmap_internal::FileNames(format);
    for (const std::string* name : {&n.cameras, &n.images, &n.points3D}) {
      if (IsFile(JoinPath(dir, *name))) found += (found.empty() ? "" : ", ") + *name;
    }
  }
  return found.empty() ? "none of them" : found;
}

std::string ErrnoText(int err) { return std::strerror(err); }

// fsyncs a folder (so that a rename in it is durable); 0 or errno.
int SyncDir(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return errno;
  const int rc = ::fsync(fd) == 0 ? 0 : errno;
  ::close(fd);
  return rc;
}

}  // namespace

const char* ColmapFormatName(ColmapFormat format) {
  return format == ColmapFormat::kText ? "text" : "binary";
}

// The one place where COLMAP's pixel convention meets OPL's.
Eigen::Vector2d OplPixelFromColmap(const Eigen::Vector2d& colmap_px) {
  return colmap_px - Eigen::Vector2d::Constant(kColmapPixelOffset);
}
Eigen::Vector2d ColmapPixelFromOpl(const Eigen::Vector2d& opl_px) {
  return opl_px + Eigen::Vector2d::Constant(kColmapPixelOffset);
}

const char* ColmapCameraModelName(int model_id) {
  if (model_id < 0 || model_id >= kNumColmapCameraModels) return nullptr;
  return kModels[model_id].name;
}

int ColmapCameraModelIdFromName(const std::string& name) {
  for (int id = 0; id < kNumColmapCameraModels; ++id) {
    if (name == kModels[id].name) return id;
  }
  return -1;
}

int ColmapCameraModelNumParams(int model_id) {
  if (model_id < 0 || model_id >= kNumColmapCameraModels) return -1;
  return kModels[model_id].num_params;
}

Rigid3d ColmapImage::CamFromWorld() const {
  const Eigen::Quaterniond q(qvec_wxyz[0], qvec_wxyz[1], qvec_wxyz[2], qvec_wxyz[3]);
  return Rigid3d(q, tvec);  // normalises q
}

Eigen::Vector3d ColmapImage::CenterInWorld() const { return CamFromWorld().Inverse().translation; }

const ColmapImage* ColmapModel::FindImageByName(const std::string& name) const {
  for (const auto& entry : images) {
    if (entry.second.name == name) return &entry.second;
  }
  return nullptr;
}

Status ColmapModel::Validate() const {
  return colmap_internal::ValidateModel(*this, "", format);
}

namespace colmap_internal {

ColmapFileNames FileNames(ColmapFormat format) {
  const std::string ext = format == ColmapFormat::kText ? ".txt" : ".bin";
  return {"cameras" + ext, "images" + ext, "points3D" + ext};
}

Status ValidateModel(const ColmapModel& model, const std::string& dir, ColmapFormat format) {
  const ColmapFileNames names = FileNames(format);
  const auto prefix = [&](const std::string& file) {
    return dir.empty() ? file.substr(0, file.find('.')) : JoinPath(dir, file);
  };
  const std::string cameras_file = prefix(names.cameras);
  const std::string images_file = prefix(names.images);
  const std::string points_file = prefix(names.points3D);
  for (const auto& [id, camera] : model.cameras) {
    const std::string where = cameras_file + ": camera " + std::to_string(id) + ": ";
    if (camera.camera_id != id) {
      return Status::ParseError(where + "keyed under a different id " +
                                std::to_string(camera.camera_id));
    }
    const int num_params = ColmapCameraModelNumParams(camera.model_id);
    if (num_params < 0) {
      return Status::ParseError(where + "unknown model id " + std::to_string(camera.model_id));
    }
    if (static_cast<int>(camera.params.size()) != num_params) {
      return Status::ParseError(where + "model " + ColmapCameraModelName(camera.model_id) +
                                " has " + std::to_string(num_params) + " parameters, found " +
                                std::to_string(camera.params.size()));
    }
    for (double p : camera.params) {
      if (!std::isfinite(p)) return Status::ParseError(where + "a parameter is not finite");
    }
  }
  for (const auto& [id, image] : model.images) {
    const std::string where = images_file + ": image " + std::to_string(id) + ": ";
    if (image.image_id != id) {
      return Status::ParseError(where + "keyed under a different id " +
                                std::to_string(image.image_id));
    }
    if (model.cameras.count(image.camera_id) == 0) {
      return Status::ParseError(where + "camera " + std::to_string(image.camera_id) +
                                " does not exist");
    }
    const Eigen::Vector4d q(image.qvec_wxyz[0], image.qvec_wxyz[1], image.qvec_wxyz[2],
                            image.qvec_wxyz[3]);
    if (!q.allFinite() || !image.tvec.allFinite() || !(q.norm() > 0.0)) {
      return Status::ParseError(where + "qvec or tvec not finite, or qvec zero");
    }
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      const ColmapPoint2D& p = image.points2D[i];
      if (!p.xy_px.allFinite()) {
        return Status::ParseError(where + "2D point " + std::to_string(i) + " is not finite");
      }
      if (p.point3D_id != kColmapNoPoint3D && model.points3D.count(p.point3D_id) == 0) {
        return Status::ParseError(where + "2D point " + std::to_string(i) + ": 3D point " +
                                  std::to_string(p.point3D_id) + " does not exist");
      }
    }
  }
  for (const auto& [id, point] : model.points3D) {
    const std::string where = points_file + ": point " + std::to_string(id) + ": ";
    if (point.point3D_id != id) {
      return Status::ParseError(where + "keyed under a different id " +
                                std::to_string(point.point3D_id));
    }
    if (!point.xyz_in_world.allFinite() || !std::isfinite(point.error_px)) {
      return Status::ParseError(where + "XYZ or ERROR not finite");
    }
    for (size_t k = 0; k < point.track.size(); ++k) {
      const ColmapTrackElement& e = point.track[k];
      const std::string element = where + "track element " + std::to_string(k + 1) + ": ";
      const auto image = model.images.find(e.image_id);
      if (image == model.images.end()) {
        return Status::ParseError(element + "image " + std::to_string(e.image_id) +
                                  " does not exist");
      }
      if (e.point2D_idx >= image->second.points2D.size()) {
        return Status::ParseError(element + "POINT2D_IDX " + std::to_string(e.point2D_idx) +
                                  " is out of range (image " + std::to_string(e.image_id) +
                                  " has " + std::to_string(image->second.points2D.size()) +
                                  " 2D points)");
      }
    }
  }
  return Status::Ok();
}

}  // namespace colmap_internal

bool IsColmapModelDir(const std::string& dir) {
  return HasAllFiles(dir, ColmapFormat::kBinary) || HasAllFiles(dir, ColmapFormat::kText);
}

Result<ColmapModel> ReadColmapModel(const std::string& dir) {
  if (HasAllFiles(dir, ColmapFormat::kBinary)) return ReadColmapModel(dir, ColmapFormat::kBinary);
  if (HasAllFiles(dir, ColmapFormat::kText)) return ReadColmapModel(dir, ColmapFormat::kText);
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    return Status::IoError(dir + ": cannot read a COLMAP model: not a folder");
  }
  return Status::IoError(dir +
                         ": not a COLMAP sparse model: needs cameras, images and points3D, all "
                         ".bin or all .txt (found: " +
                         FilesFound(dir) + ")");
}

Result<ColmapModel> ReadColmapModel(const std::string& dir, ColmapFormat format) {
  const colmap_internal::ColmapFileNames names = colmap_internal::FileNames(format);
  colmap_internal::ColmapFileContents files;
  for (auto [name, contents] : {std::pair{&names.cameras, &files.cameras},
                                std::pair{&names.images, &files.images},
                                std::pair{&names.points3D, &files.points3D}}) {
    Result<std::string> text = ReadFileToString(JoinPath(dir, *name));
    if (!text.ok()) return text.status();
    *contents = std::move(text).value();
  }
  Result<ColmapModel> model = format == ColmapFormat::kText
                                  ? colmap_internal::ParseColmapText(dir, files)
                                  : colmap_internal::ParseColmapBinary(dir, files);
  if (!model.ok()) return model.status();
  model->format = format;
  OPL_RETURN_IF_ERROR(colmap_internal::ValidateModel(*model, dir, format));
  return model;
}

Status WriteColmapModel(const ColmapModel& model, const std::string& dir,
                        ColmapFormat format,
                        const std::vector<std::pair<std::string, std::string>>& extra_files) {
  namespace fs = std::filesystem;
  OPL_RETURN_IF_ERROR(model.Validate());
  const auto write_error = [&](const std::string& what) {
    return Status::IoError(dir + ": cannot write the COLMAP model: " + what);
  };
  std::string target = dir;
  while (target.size() > 1 && target.back() == '/') target.pop_back();
  if (target.empty()) return write_error("no folder name");
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(target, ec);
  if (fs::exists(status)) {
    if (!fs::is_directory(status)) return write_error("exists and is not a folder");
    if (!fs::is_empty(target, ec) || ec) {
      return Status::IoError(dir +
                             ": exists and is not empty: refusing to write a COLMAP model "
                             "among other files (give a new or empty folder)");
    }
  }
  const fs::path target_path(target);
  const std::string parent =
      target_path.has_parent_path() ? target_path.parent_path().string() : std::string(".");
  static std::atomic<int> counter{0};
  const std::string temp = JoinPath(parent, "." + target_path.filename().string() + ".tmp-" +
                                                std::to_string(::getpid()) + "-" +
                                                std::to_string(counter++));
  if (::mkdir(temp.c_str(), 0777) != 0) {
    return write_error("cannot create a temporary folder in '" + parent + "': " +
                       ErrnoText(errno));
  }
  const colmap_internal::ColmapFileNames names = colmap_internal::FileNames(format);
  const colmap_internal::ColmapFileContents files = format == ColmapFormat::kText
                                                        ? colmap_internal::FormatColmapText(model)
                                                        : colmap_internal::FormatColmapBinary(model);
  Status written;
  for (auto [name, contents] : {std::pair{&names.cameras, &files.cameras},
                                std::pair{&names.images, &files.images},
                                std::pair{&names.points3D, &files.points3D}}) {
    written = WriteFileAtomically(JoinPath(temp, *name), *contents);
    if (!written.ok()) break;
  }
  for (const auto& [name, contents] : extra_files) {
    if (!written.ok()) break;
    if (name.empty() || name.find('/') != std::string::npos || name == "." || name == ".." ||
        name == names.cameras || name == names.images || name == names.points3D) {
      written = write_error("'" + name + "' is not a plain file name beside the model's");
      break;
    }
    written = WriteFileAtomically(JoinPath(temp, name), contents);
  }
  if (written.ok() && ::rename(temp.c_str(), target.c_str()) != 0) {
    written = write_error("cannot rename the temporary folder: " + ErrnoText(errno));
  }
  if (!written.ok()) {
    fs::remove_all(temp, ec);
    return written;
  }
  const int err = SyncDir(parent);
  if (err != 0) return write_error("cannot sync '" + parent + "': " + ErrnoText(err));
  return Status::Ok();
}

std::string FormatColmapPointsPly(const ColmapModel& model) {
  std::string header = "ply\nformat binary_little_endian 1.0\n";
  if (!model.points3D.empty()) {
    header += "comment COLMAP points3D, POINT3D_ID " +
              std::to_string(model.points3D.begin()->first) + " to " +
              std::to_string(model.points3D.rbegin()->first) + " in increasing order\n";
  }
  header += "element vertex " + std::to_string(model.points3D.size()) +
            "\nproperty double x\nproperty double y\nproperty double z\n"
            "property uchar red\nproperty uchar green\nproperty uchar blue\n"
            "property double error\nproperty int track_length\nend_header\n";
  constexpr size_t kRecord = 3 * 8 + 3 + 8 + 4;
  std::string body(model.points3D.size() * kRecord, '\0');
  char* p = body.data();
  const uint16_t one = 1;
  const bool little = *reinterpret_cast<const unsigned char*>(&one) == 1;
  const auto put = [&p, little](const void* value, size_t bytes) {  // little endian
    std::memcpy(p, value, bytes);
    if (!little) std::reverse(p, p + bytes);
    p += bytes;
  };
  for (const auto& entry : model.points3D) {
    const ColmapPoint3D& point = entry.second;
    for (int k = 0; k < 3; ++k) put(&point.xyz_in_world[k], 8);
    put(point.rgb.data(), 3);
    put(&point.error_px, 8);
    const int32_t track = static_cast<int32_t>(point.track.size());
    put(&track, 4);
  }
  return header + body;
}

ColmapModel ScaledColmapModel(const ColmapModel& model, double scale) {
  ColmapModel scaled = model;
  for (auto& entry : scaled.images) entry.second.tvec *= scale;
  for (auto& entry : scaled.points3D) entry.second.xyz_in_world *= scale;
  return scaled;
}

Result<CameraIntrinsics> IntrinsicsFromColmap(const ColmapCamera& camera) {
  const int model = camera.model_id;
  const char* name = ColmapCameraModelName(model);
  if (name == nullptr) {
    return Status::InvalidArgument(CameraLabel(camera) + ": unknown model id " +
                                   std::to_string(model));
  }
  if (static_cast<int>(camera.params.size()) != ColmapCameraModelNumParams(model)) {
    return Status::InvalidArgument(CameraLabel(camera) + ": model " + name + " has " +
                                   std::to_string(ColmapCameraModelNumParams(model)) +
                                   " parameters, found " + std::to_string(camera.params.size()));
  }
  const std::vector<double>& p = camera.params;
  CameraIntrinsics in;
  double cx = 0.0, cy = 0.0;
  switch (model) {
    case kColmapSimplePinhole:
    case kColmapSimpleRadial:
    case kColmapRadial:
      in.fx_px = in.fy_px = p[0];
      cx = p[1];
      cy = p[2];
      if (model == kColmapSimpleRadial) in.k1 = p[3];
      if (model == kColmapRadial) {
        in.k1 = p[3];
        in.k2 = p[4];
      }
      break;
    case kColmapPinhole:
    case kColmapOpenCv:
    case kColmapFullOpenCv:
      in.fx_px = p[0];
      in.fy_px = p[1];
      cx = p[2];
      cy = p[3];
      if (model != kColmapPinhole) {
        in.k1 = p[4];
        in.k2 = p[5];
        in.p1 = p[6];
        in.p2 = p[7];
      }
      if (model == kColmapFullOpenCv) {
        in.k3 = p[8];
        static const char* kRational[] = {"k4", "k5", "k6"};
        for (int i = 0; i < 3; ++i) {
          if (p[9 + i] != 0.0) {
            return Status::InvalidArgument(
                CameraLabel(camera) + ": FULL_OPENCV parameter " + kRational[i] + " = " +
                FormatNumber(p[9 + i]) +
                " is not 0: OPL's camera model has no rational radial term (k4, k5, k6)");
          }
        }
      }
      break;
    default:
      return Status::InvalidArgument(CameraLabel(camera) + ": model " + name +
                                     " is not supported (supported: " + kSupportedModels + ")");
  }
  const Eigen::Vector2d c = OplPixelFromColmap(Eigen::Vector2d(cx, cy));
  in.cx_px = c.x();
  in.cy_px = c.y();
  constexpr uint64_t kMaxSide = 1u << 30;
  if (camera.width_px > kMaxSide || camera.height_px > kMaxSide) {
    return Status::InvalidArgument(CameraLabel(camera) + ": image size " +
                                   std::to_string(camera.width_px) + " x " +
                                   std::to_string(camera.height_px) + " is too large");
  }
  in.width_px = static_cast<int>(camera.width_px);
  in.height_px = static_cast<int>(camera.height_px);
  const Status valid = in.Validate();
  if (!valid.ok()) return Status::InvalidArgument(CameraLabel(camera) + ": " + valid.message());
  return in;
}

Status SetColmapIntrinsics(const CameraIntrinsics& in, ColmapCamera* camera) {
  const int model = camera->model_id;
  const char* name = ColmapCameraModelName(model);
  const std::string where =
      CameraLabel(*camera) + ": model " + (name ? name : std::to_string(model).c_str());
  const auto cannot_hold = [&](const char* term, double value) {
    return Status::InvalidArgument(where + " cannot hold " + term + " = " + FormatNumber(value));
  };
  const Eigen::Vector2d c = ColmapPixelFromOpl(Eigen::Vector2d(in.cx_px, in.cy_px));
  const bool single_focal = model == kColmapSimplePinhole || model == kColmapSimpleRadial ||
                            model == kColmapRadial;
  const bool full = model == kColmapOpenCv || model == kColmapFullOpenCv;
  switch (model) {
    case kColmapSimplePinhole:
    case kColmapSimpleRadial:
    case kColmapRadial:
    case kColmapPinhole:
    case kColmapOpenCv:
    case kColmapFullOpenCv:
      break;
    default:
      return Status::InvalidArgument(where + " is not supported (supported: " +
                                     kSupportedModels + ")");
  }
  if (single_focal && in.fy_px != in.fx_px) {
    return Status::InvalidArgument(where + " cannot hold fy = " + FormatNumber(in.fy_px) +
                                   " != fx = " + FormatNumber(in.fx_px) + " (one focal length)");
  }
  if (model == kColmapSimplePinhole || model == kColmapPinhole) {
    if (in.k1 != 0.0) return cannot_hold("k1", in.k1);
  }
  if (model != kColmapRadial && !full && in.k2 != 0.0) return cannot_hold("k2", in.k2);
  if (!full) {
    if (in.p1 != 0.0) return cannot_hold("p1", in.p1);
    if (in.p2 != 0.0) return cannot_hold("p2", in.p2);
  }
  if (model != kColmapFullOpenCv && in.k3 != 0.0) return cannot_hold("k3", in.k3);

  std::vector<double> p;
  if (single_focal) {
    p = {in.fx_px, c.x(), c.y()};
    if (model == kColmapSimpleRadial) p.push_back(in.k1);
    if (model == kColmapRadial) p.insert(p.end(), {in.k1, in.k2});
  } else {
    p = {in.fx_px, in.fy_px, c.x(), c.y()};
    if (full) p.insert(p.end(), {in.k1, in.k2, in.p1, in.p2});
    if (model == kColmapFullOpenCv) p.insert(p.end(), {in.k3, 0.0, 0.0, 0.0});
  }
  camera->params = std::move(p);
  camera->width_px = static_cast<uint64_t>(in.width_px);
  camera->height_px = static_cast<uint64_t>(in.height_px);
  return Status::Ok();
}

}  // namespace opl
