// COLMAP sparse models: read and write the three files of a COLMAP (3.x)
// reconstruction, in COLMAP's text or binary format, and map its cameras to
// OPL's camera model.
//
// A sparse model is a folder holding
//   cameras.txt  images.txt  points3D.txt     (text), or
//   cameras.bin  images.bin  points3D.bin     (binary, little endian)
// as documented at https://colmap.github.io/format.html. ReadColmapModel finds
// which from the folder's files (binary first when both are complete, as
// COLMAP does); WriteColmapModel writes either. Other files in the folder
// (project.ini, the rigs.bin and frames.bin of COLMAP >= 3.12) are neither
// read nor written. Full description: docs/colmap.md.
//
// The structs keep COLMAP's own values, exactly as read, so that a text <->
// binary round trip is exact:
//   - camera parameters in COLMAP's order for the camera's model, in COLMAP's
//     pixel convention;
//   - an image's pose as COLMAP's qvec (w, x, y, z) and tvec, which is
//     cam_from_world: X_cam = R(qvec) X_world + tvec, the same direction as
//     OPL's cam_from_scene (geometry/rigid3.h, vision/camera_model.h);
//   - 2D points in COLMAP's pixel convention.
//
// Pixel conventions. COLMAP puts the CENTRE of the top-left pixel at
// (0.5, 0.5) (its image origin is the top-left CORNER); OPL, like OpenCV, at
// (0, 0). The conversion lives in one place: OplPixelFromColmap and
// ColmapPixelFromOpl below (a shift of kColmapPixelOffset = 0.5 px in u and v),
// used for 2D points and principal points alike.
//
// Camera models (COLMAP's id, name and parameters):
//   0 SIMPLE_PINHOLE  f, cx, cy                  -> fx = fy = f
//   1 PINHOLE         fx, fy, cx, cy
//   2 SIMPLE_RADIAL   f, cx, cy, k               -> k1 = k
//   3 RADIAL          f, cx, cy, k1, k2
//   4 OPENCV          fx, fy, cx, cy, k1, k2, p1, p2
//   5 OPENCV_FISHEYE  fx, fy, cx, cy, k1, k2, k3, k4            (refused)
//   6 FULL_OPENCV     fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6
//                     mapped when k4 = k5 = k6 = 0 (its rational radial term
//                     is then OPL's polynomial), else refused
//   7 FOV, 8 SIMPLE_RADIAL_FISHEYE, 9 RADIAL_FISHEYE, 10 THIN_PRISM_FISHEYE
//                     (refused)
// COLMAP's distortion of these models is OpenCV's (Brown-Conrady), which is
// OPL's (vision/camera_model.h), so the mapped models are exact. A refused
// model is read and written back faithfully; only IntrinsicsFromColmap
// refuses it, naming the camera and the model.
//
// Errors are one line. Reading: ParseError naming the file and, for text, the
// line, for binary, the record, and the field:
//   "m/cameras.txt:4: field 'WIDTH': not an integer > 0: 'abc'"
//   "m/images.bin: record 2 (image 7): field 'NAME': truncated file (needs 1
//    more byte at offset 412, file has 412)"
//   "m/points3D.txt:9: point 12: track element 2: image 5 does not exist"
// IoError for a folder that is not a model or an unreadable file.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>
#include <utility>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/vision/camera_model.h"

namespace opl {

enum class ColmapFormat { kText, kBinary };
// "text" or "binary".
const char* ColmapFormatName(ColmapFormat format);

// COLMAP's centre of the top-left pixel, in u and v [px].
inline constexpr double kColmapPixelOffset = 0.5;
// OPL (OpenCV) pixel of a COLMAP image point: (u, v) - 0.5.
Eigen::Vector2d OplPixelFromColmap(const Eigen::Vector2d& colmap_px);
// COLMAP image point of an OPL pixel: (u, v) + 0.5.
Eigen::Vector2d ColmapPixelFromOpl(const Eigen::Vector2d& opl_px);

// COLMAP's camera model ids (src/colmap/sensor/models.h).
enum ColmapCameraModelId : int {
  kColmapSimplePinhole = 0,
  kColmapPinhole = 1,
  kColmapSimpleRadial = 2,
  kColmapRadial = 3,
  kColmapOpenCv = 4,
  kColmapOpenCvFisheye = 5,
  kColmapFullOpenCv = 6,
  kColmapFov = 7,
  kColmapSimpleRadialFisheye = 8,
  kColmapRadialFisheye = 9,
  kColmapThinPrismFisheye = 10,
};
inline constexpr int kNumColmapCameraModels = 11;
// "PINHOLE" etc.; nullptr for an id that is not a COLMAP model.
const char* ColmapCameraModelName(int model_id);
// Id of a model name (exact, upper case as COLMAP writes it); -1 if unknown.
int ColmapCameraModelIdFromName(const std::string& name);
// Number of parameters of a model; -1 for an unknown id.
int ColmapCameraModelNumParams(int model_id);

struct ColmapCamera {
  uint32_t camera_id = 0;
  int model_id = kColmapPinhole;
  uint64_t width_px = 0;
  uint64_t height_px = 0;
  // COLMAP's parameters for model_id, in its order and pixel convention.
  std::vector<double> params;
};

struct ColmapPoint2D {
  Eigen::Vector2d xy_px = Eigen::Vector2d::Zero();  // COLMAP pixel convention
  // The 3D point this observation belongs to; kColmapNoPoint3D for none
  // (written -1 in text, 2^64 - 1 in binary, as COLMAP does).
  uint64_t point3D_id = 0;
};
inline constexpr uint64_t kColmapNoPoint3D = ~uint64_t{0};

struct ColmapImage {
  uint32_t image_id = 0;
  // cam_from_world as COLMAP stores it: qvec = (w, x, y, z), not necessarily
  // of unit norm in a file (CamFromWorld normalises it).
  std::array<double, 4> qvec_wxyz = {1.0, 0.0, 0.0, 0.0};
  Eigen::Vector3d tvec = Eigen::Vector3d::Zero();
  uint32_t camera_id = 0;
  // Image file name, relative to COLMAP's image folder. In text, NAME is the
  // rest of the image's line (COLMAP itself stops at the first space, so
  // names with spaces do not go through COLMAP's text reader).
  std::string name;
  std::vector<ColmapPoint2D> points2D;

  // X_cam = R X_world + t.
  Rigid3d CamFromWorld() const;
  // Camera centre in the model's world frame: -R^T t.
  Eigen::Vector3d CenterInWorld() const;
};

struct ColmapTrackElement {
  uint32_t image_id = 0;
  uint32_t point2D_idx = 0;  // index into that image's points2D
};

struct ColmapPoint3D {
  uint64_t point3D_id = 0;
  Eigen::Vector3d xyz_in_world = Eigen::Vector3d::Zero();
  std::array<uint8_t, 3> rgb = {0, 0, 0};
  double error_px = 0.0;  // COLMAP's mean reprojection error; -1 when unknown
  std::vector<ColmapTrackElement> track;
};

struct ColmapModel {
  ColmapFormat format = ColmapFormat::kBinary;  // what it was read from
  std::map<uint32_t, ColmapCamera> cameras;
  std::map<uint32_t, ColmapImage> images;
  std::map<uint64_t, ColmapPoint3D> points3D;

  // The image of that file name, or nullptr.
  const ColmapImage* FindImageByName(const std::string& name) const;
  // OK, or the first inconsistency: an image's camera that does not exist, a
  // 2D point naming a missing 3D point, a track element naming a missing image
  // or a 2D point index out of range, a camera whose parameter count does not
  // fit its model, a non-finite value. Read calls it; call it before writing
  // a model built by hand.
  Status Validate() const;
};

// True when `dir` holds the three files of a text or binary model.
bool IsColmapModelDir(const std::string& dir);

// Reads the model in `dir` (format found from the files present).
Result<ColmapModel> ReadColmapModel(const std::string& dir);
// Reads the model in `dir` in the given format.
Result<ColmapModel> ReadColmapModel(const std::string& dir, ColmapFormat format);

// Writes `model` to the folder `dir` in `format`, all three files or none:
// they are written to a fresh temporary folder beside `dir`, synced, and the
// folder renamed to `dir`. `dir` must not exist or be an empty folder (it is
// then replaced); a folder with files in it is refused (IoError
// "<dir>: exists and is not empty: ..."). Numbers in text are written as the
// shortest decimal that reads back as exactly the same double. Records are
// written in increasing id order.
// `extra_files` (name, bytes) are written into the folder with the model and
// appear with it (opl_measure --colmap-out: the points as PLY, the run's
// provenance); a name must be a plain file name other than the model's.
Status WriteColmapModel(const ColmapModel& model, const std::string& dir,
                        ColmapFormat format,
                        const std::vector<std::pair<std::string, std::string>>& extra_files = {});

// The model's 3D points as a binary little-endian PLY: element vertex with
// double x, y, z, uchar red, green, blue, double error (px, COLMAP's mean
// reprojection error) and int track_length, in increasing point id order;
// a comment line names the point ids' range. For viewers and point tools.
std::string FormatColmapPointsPly(const ColmapModel& model);

// The model with every length multiplied by `scale`: the points' XYZ and the
// images' tvec (so every camera centre -R^T tvec is multiplied too).
// Rotations, cameras, 2D points, colours, errors (pixels) and tracks are
// unchanged: every pixel projects where it did.
ColmapModel ScaledColmapModel(const ColmapModel& model, double scale);

// The camera as OPL intrinsics (OpenCV pixel convention). InvalidArgument,
// naming the camera id, for a model without an exact counterpart:
//   "COLMAP camera 3: model OPENCV_FISHEYE is not supported (supported:
//    SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV with
//    k4 = k5 = k6 = 0)"
//   "COLMAP camera 2: FULL_OPENCV parameter k5 = 0.01 is not 0: OPL's model
//    has no rational radial term (k4, k5, k6)"
// or for sizes or parameters out of OPL's domain (CameraIntrinsics::Validate).
Result<CameraIntrinsics> IntrinsicsFromColmap(const ColmapCamera& camera);

// Writes `intrinsics` into `camera`'s parameters, keeping its model (the model
// the camera was read as). InvalidArgument, naming the camera, the model and
// the term, when the model cannot hold them exactly (e.g. p1 != 0 for RADIAL,
// fx != fy for SIMPLE_PINHOLE) or for a refused model.
Status SetColmapIntrinsics(const CameraIntrinsics& intrinsics, ColmapCamera* camera);

}  // namespace opl
