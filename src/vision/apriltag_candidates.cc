// Private to src/vision: libapriltag candidates (apriltag_candidates.h).
#include "vision/apriltag_candidates.h"

#include <cmath>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

extern "C" {
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
}

#include "opl/core/format.h"

namespace opl {
namespace tag_internal {
namespace {

// One libapriltag detector with its own tag36h11 family (a family instance
// carries the detector's decode table and must not be shared).
struct AprilTagDetector {
  apriltag_family_t* family = nullptr;
  apriltag_detector_t* detector = nullptr;
  int bits_corrected = -1;

  AprilTagDetector() = default;
  AprilTagDetector(const AprilTagDetector&) = delete;
  AprilTagDetector& operator=(const AprilTagDetector&) = delete;
  ~AprilTagDetector() {
    if (detector != nullptr) apriltag_detector_destroy(detector);  // does not free the family
    if (family != nullptr) tag36h11_destroy(family);
  }
};

Result<std::unique_ptr<AprilTagDetector>> CreateDetector(int bits_corrected) {
  auto d = std::make_unique<AprilTagDetector>();
  d->family = tag36h11_create();
  d->detector = apriltag_detector_create();
  if (d->family == nullptr || d->detector == nullptr) {
    return Status::NoSolution("libapriltag: could not create a tag36h11 detector");
  }
  apriltag_detector_add_family_bits(d->detector, d->family, bits_corrected);
  // libapriltag reports a failed decode-table allocation on stderr only: the
  // family is then missing from the detector.
  if (d->detector->tag_families == nullptr || zarray_size(d->detector->tag_families) != 1) {
    return Status::NoSolution("libapriltag: could not add the tag36h11 family (decode table for " +
                            std::to_string(bits_corrected) + " bits)");
  }
  d->bits_corrected = bits_corrected;
  return d;
}

// Detectors not in use, shared by all threads (building a detector's decode
// table takes ~20 ms; a detection must not share a detector with another).
class DetectorPool {
 public:
  Result<std::unique_ptr<AprilTagDetector>> Take(int bits_corrected) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto it = free_.begin(); it != free_.end(); ++it) {
        if ((*it)->bits_corrected == bits_corrected) {
          std::unique_ptr<AprilTagDetector> d = std::move(*it);
          free_.erase(it);
          return d;
        }
      }
    }
    return CreateDetector(bits_corrected);
  }
  void Give(std::unique_ptr<AprilTagDetector> d) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (free_.size() < kMaxPooled) free_.push_back(std::move(d));
  }

 private:
  static constexpr size_t kMaxPooled = 8;
  std::mutex mutex_;
  std::vector<std::unique_ptr<AprilTagDetector>> free_;
};

DetectorPool& Pool() {
  static DetectorPool pool;
  return pool;
}

struct DetectionsDeleter {
  void operator()(zarray_t* detections) const { apriltag_detections_destroy(detections); }
};

bool ValidDecimate(double f) {
  return f == 1.5 || (f >= 1.0 && f <= 8.0 && f == std::floor(f));
}

}  // namespace

std::array<Eigen::Vector2d, 4> OplCornersFromAprilTag(const double (&p)[4][2]) {
  std::array<Eigen::Vector2d, 4> corners;
  for (int k = 0; k < 4; ++k) {
    const int a = kAprilTagCornerOfOplCorner[static_cast<size_t>(k)];
    corners[static_cast<size_t>(k)] = Eigen::Vector2d(p[a][0] - 0.5, p[a][1] - 0.5);
  }
  return corners;
}

Result<std::vector<TagCandidate>> FindAprilTagCandidates(const cv::Mat& gray8, const AprilTagSettings& settings) {
  if (gray8.type() != CV_8UC1) {
    return Status::InvalidArgument("FindAprilTagCandidates: image type " + std::to_string(gray8.type()) +
                                   ": expected CV_8UC1");
  }
  if (!ValidDecimate(settings.quad_decimate)) {
    return Status::InvalidArgument("FindAprilTagCandidates: quad_decimate = " +
                                   FormatNumber(settings.quad_decimate, 6) + ": must be 1.5 or an integer in [1, 8]");
  }
  if (!(settings.quad_sigma >= 0.0 && settings.quad_sigma <= 10.0) || settings.nthreads < 1 ||
      settings.nthreads > 64 || !(settings.decode_sharpening >= 0.0 && settings.decode_sharpening <= 10.0) ||
      settings.max_bits_corrected < 0 || settings.max_bits_corrected > 2) {
    return Status::InvalidArgument("FindAprilTagCandidates: settings out of range");
  }
  std::vector<TagCandidate> candidates;
  // libapriltag 3.3 has no size check and crashes on tiny images
  // (AprilRobotics/apriltag#422); no tag fits in them anyway.
  const double min_side = 16.0 * settings.quad_decimate;
  if (gray8.cols < min_side || gray8.rows < min_side) return candidates;

  Result<std::unique_ptr<AprilTagDetector>> taken = Pool().Take(settings.max_bits_corrected);
  OPL_RETURN_IF_ERROR(taken.status());
  std::unique_ptr<AprilTagDetector> d = std::move(*taken);
  apriltag_detector_t* td = d->detector;
  td->quad_decimate = static_cast<float>(settings.quad_decimate);
  td->quad_sigma = static_cast<float>(settings.quad_sigma);
  td->nthreads = settings.nthreads;
  td->refine_edges = settings.refine_edges;
  td->decode_sharpening = settings.decode_sharpening;
  td->debug = false;

  // libapriltag reads the image through its stride and does not write it.
  image_u8_t image{gray8.cols, gray8.rows, static_cast<int32_t>(gray8.step[0]), const_cast<uint8_t*>(gray8.ptr<uint8_t>(0))};
  std::unique_ptr<zarray_t, DetectionsDeleter> detections(apriltag_detector_detect(td, &image));
  if (detections == nullptr) {
    Pool().Give(std::move(d));
    return Status::NoSolution("libapriltag: apriltag_detector_detect returned no list");
  }
  const int n = zarray_size(detections.get());
  candidates.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(detections.get(), i, &det);
    if (det == nullptr) continue;
    TagCandidate c;
    c.id = det->id;
    c.corners_px = OplCornersFromAprilTag(det->p);
    c.hamming = det->hamming;
    c.decision_margin = det->decision_margin;
    c.source = TagSource::kAprilTag;
    bool finite = true;
    for (const Eigen::Vector2d& p : c.corners_px) finite = finite && p.allFinite();
    if (finite) candidates.push_back(c);
  }
  detections.reset();
  Pool().Give(std::move(d));
  return candidates;
}

}  // namespace tag_internal
}  // namespace opl
