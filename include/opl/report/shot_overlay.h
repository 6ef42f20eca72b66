// An overlay of one photograph: what the image front end found in it, drawn
// over a dimmed grey copy, so that a person can check a measurement in
// seconds (`opl_measure --images ... --overlays DIR`; docs/images.md,
// "Overlays").
//
// Legend (also written in the image's caption):
//   - tags: their quadrilateral in cyan, corner 0 marked, the id beside it;
//   - spots identified: a green circle and the label (source and beam,
//     e.g. "A61");
//   - spots matched across images but not identified: a yellow circle;
//   - spots detected but not matched: an orange circle;
//   - blobs the spot gates rejected (not laser spots): a small red cross.
// Markers scale with the image (radius about 1/250 of its width, at least
// 6 px); the caption at the top names the file and counts each kind.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"

namespace opl {

struct ShotOverlay {
  struct Tag {
    int id = 0;
    std::array<Eigen::Vector2d, 4> corners_px;  // OpenCV pixel convention
  };
  enum class SpotState { kDetected, kMatched, kIdentified };
  struct Spot {
    Eigen::Vector2d center_px = Eigen::Vector2d::Zero();
    SpotState state = SpotState::kDetected;
    std::string label;  // identified: "A61"; else empty
  };
  std::string title;  // the caption's first words, e.g. the file name
  std::vector<Tag> tags;
  std::vector<Spot> spots;
  std::vector<Eigen::Vector2d> rejected_px;
};

// The overlay drawn over `image` (CV_8U or CV_16U, 1 or 3 channels: shown
// as dimmed grey): an 8-bit BGR image of the same size. InvalidArgument for
// an empty image or another type.
Result<cv::Mat> DrawShotOverlay(const cv::Mat& image, const ShotOverlay& overlay);

}  // namespace opl
