// Private to src/vision: tag candidates (id + quad) from libapriltag 3.x,
// tag36h11, in OPL's conventions. This is the ONE place where libapriltag's
// conventions are converted (tests/vision/tag_detection_test.cc checks both
// against rendered tags with known corners):
//
//  - Pixel coordinates. libapriltag's (0, 0) is the top-left CORNER of the
//    first pixel (its centre is at (0.5, 0.5)); OPL's and OpenCV's (0, 0) is
//    the CENTRE of the first pixel. OPL = libapriltag - (0.5, 0.5).
//  - Corner order. libapriltag's p[0..3] are the images of the tag-frame
//    points (-1, 1), (1, 1), (1, -1), (-1, -1) of its homography: as the tag
//    is printed, top-right, top-left, bottom-left, bottom-right. OPL's order
//    (vision/tag_detection.h, cv::aruco's) is top-left, top-right,
//    bottom-right, bottom-left. OPL corner k = libapriltag p[kAprilTagCornerOfOplCorner[k]].
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/vision/tag_detection.h"

namespace opl {
namespace tag_internal {

inline constexpr std::array<int, 4> kAprilTagCornerOfOplCorner = {1, 0, 3, 2};

// libapriltag's corners (apriltag_detection_t::p) in OPL's order and pixel
// convention.
std::array<Eigen::Vector2d, 4> OplCornersFromAprilTag(const double (&p)[4][2]);


struct TagCandidate {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px;  // OPL order and pixel convention
  int hamming = 0;               // bits the candidate's detector corrected
  double decision_margin = 0.0;  // libapriltag's decision margin [grey levels]; 0 for aruco
  TagSource source = TagSource::kAprilTag;
};

struct AprilTagSettings {
  double quad_decimate = 1.0;      // apriltag_detector::quad_decimate (1.5 or an integer >= 1)
  double quad_sigma = 0.0;         // apriltag_detector::quad_sigma [px], >= 0
  int nthreads = 1;                // apriltag_detector::nthreads, >= 1
  bool refine_edges = true;        // apriltag_detector::refine_edges
  double decode_sharpening = 0.25; // apriltag_detector::decode_sharpening, >= 0
  int max_bits_corrected = 2;      // apriltag_detector_add_family_bits, in [0, 2]
};

// Candidates found by libapriltag in an 8-bit gray image (CV_8UC1; any
// stride). Images too small for libapriltag (fewer than 16 pixels on a side
// after quad_decimate; libapriltag 3.3 crashes on some) give no candidate.
// Errors: wrong image type, settings out of range, libapriltag failing to
// allocate its detector. Detectors (with their decode tables, ~20 ms to
// build) are kept in a pool shared by all threads and reused.
Result<std::vector<TagCandidate>> FindAprilTagCandidates(const cv::Mat& gray8, const AprilTagSettings& settings);

}  // namespace tag_internal
}  // namespace opl
