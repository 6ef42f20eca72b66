// Laser-off (dark) frames. Structured-light systems suppress a cluttered
// scene by differencing: a shot with the lasers on minus the same camera's
// shot with them off leaves the laser light and the noise; the wall's
// texture, lamps, highlights and reflective dots cancel.
//
// A dark frame is only valid for a lit image taken from the same place:
// the tags both show must sit on the same pixels (TagShiftPx). The front
// end (pipeline/image_front_end.h) pairs each lit shot with the laser-off
// shot of its camera and slice whose tags moved least, if they moved no
// more than a pixel (a calibration screen moves between slices; the tags
// do not).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "opl/vision/tag_detection.h"

namespace opl {

// The median distance [px] between the corners of the tags (same id) two
// images both show; `common_tags` receives their number (may be null).
// +infinity when they share no tag.
double TagShiftPx(const std::vector<TagDetection>& a, const std::vector<TagDetection>& b,
                  int* common_tags);

// lit - dark as a CV_16UC1 image for DetectSpots (vision/spot_detection.h):
// value = lit - dark + offset, offset 256 for 8-bit images (no value is
// clipped: 1..511) and 4096 for 16-bit ones (clipped to [0, 65534]);
// wherever `lit` is at or above `saturation_dn` (0: its type's maximum)
// and `dark` is below 90% of it, the value is 65535, so that DetectSpots
// (saturation_dn 0) flags and excludes the pixel as it would in the lit
// image; where both are saturated or nearly (a lamp, and the rim of one
// where noise tips a pixel over in one frame only) nothing can be seen:
// the value is the offset. Both images single
// channel, the same size and type (CV_8UC1 or CV_16UC1); InvalidArgument
// otherwise.
Result<cv::Mat> SubtractDarkFrame(const cv::Mat& lit, const cv::Mat& dark,
                                  double saturation_dn = 0.0);

}  // namespace opl
