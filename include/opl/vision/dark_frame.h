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

// The exposure of a laser-off frame relative to its lit shot. A camera on
// automatic exposure, or lights that flicker (50/60 Hz mains under a short
// exposure), make the two frames of the same scene differ in brightness by
// a few percent: lit - dark then leaves that fraction of the scene (the
// wall's texture, tags, lamps) behind, and on a bright textured wall a 2%
// mismatch is already several DN, as much as a faint spot's peak.
//
// Model: lit = gain x dark away from the laser light (a change of exposure
// time or gain scales every pixel alike; after a gamma-encoding camera
// curve v = L^(1/gamma) it is still a common factor). Estimate, on pixels
// sampled on a grid (every s-th row and column, s = the integer root of
// pixels / 5e5, at least 1) where neither frame is at or above 90% of
// saturation:
//   1. gain0 = sum(lit) / sum(dark);
//   2. twice: sigma = 1.4826 x the median absolute residual of
//      lit - gain x dark, then gain = sum(lit) / sum(dark) over the pixels
//      whose residual is within max(5 sigma, 1 DN) (the laser spots drop
//      out; what both frames show, distractors included, stays and
//      carries the estimate).
// A ratio of sums over the same pixels has no errors-in-variables bias
// (the noise of both frames averages out); laser light in the first step
// only moves gain0. The spots' faint tails (below 5 sigma) stay in the
// sums and raise the gain by about their share of the light (8e-4 for 60
// spots on 0.26 MP in the tests): a residue of a fraction of a DN.
struct DarkFrameGain {
  double gain = 1.0;         // lit / dark, the scene without the lasers
  double residual_sigma_dn = 0.0;  // robust sigma of lit - gain x dark [DN]
  // |gain - 1| x the 95th percentile of the sampled dark pixels [DN]: the
  // scene light that subtracting the frames as they are leaves behind.
  double mismatch_dn = 0.0;
  int samples = 0;  // pixels used in the last step
};

// InvalidArgument for images that differ in size or type, or are not
// CV_8UC1 or CV_16UC1; NoSolution when fewer than 1000 sampled pixels are
// usable (saturated or black frames) or the dark frame's sum is 0.
// `saturation_dn` as SubtractDarkFrame.
Result<DarkFrameGain> EstimateDarkFrameGain(const cv::Mat& lit, const cv::Mat& dark,
                                            double saturation_dn = 0.0);

// Whether `g` is worth applying to images of `image_depth` (CV_8U or
// CV_16U): its mismatch_dn is at least
// max(0.3 residual_sigma_dn, 0.25 x full scale / 255), i.e. the scene
// light left behind would raise the difference's noise by more than ~4%
// (or a quarter of an 8-bit step). Frames of one exposure give a gain
// within ~1e-4 of 1 and are subtracted as they are.
bool DarkFrameGainMatters(const DarkFrameGain& g, int image_depth);

// lit - dark as a CV_16UC1 image for DetectSpots (vision/spot_detection.h):
// value = lit - gain x dark + offset, rounded, with offset 256 x
// max(1, ceil(gain)) for 8-bit images (no value is clipped) and 4096 for
// 16-bit ones (clipped to [0, 65534]); gain is 1 unless given (the
// exposure match above, in (0, 16]; "dark" below is then gain x dark);
// wherever `lit` is at or above `saturation_dn` (0: its type's maximum)
// and `dark` is below 90% of it, the value is 65535, so that DetectSpots
// (saturation_dn 0) flags and excludes the pixel as it would in the lit
// image; where both are saturated or nearly (a lamp, and the rim of one
// where noise tips a pixel over in one frame only) nothing can be seen:
// the value is the offset. Both images single
// channel, the same size and type (CV_8UC1 or CV_16UC1); InvalidArgument
// otherwise.
Result<cv::Mat> SubtractDarkFrame(const cv::Mat& lit, const cv::Mat& dark,
                                  double saturation_dn = 0.0, double gain = 1.0);

}  // namespace opl
