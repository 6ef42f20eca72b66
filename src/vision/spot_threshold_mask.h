// The threshold stage of DetectSpots (opl/vision/spot_detection.h, step 2):
// the mask of "on" pixels, where the smoothed image exceeds the interpolated
// threshold, and the background blocks that hold one. Two ways to the same
// mask, to the bit:
//  - full: the threshold interpolated at every pixel and compared;
//  - coarse to fine (SpotDetectionOptions::coarse_to_fine): per cell of
//    kThresholdCellPx x kThresholdCellPx pixels the maximum of the smoothed
//    image against a lower bound of the threshold over the cell; only the
//    cells whose maximum exceeds it are thresholded pixel by pixel.
// Why the coarse pass misses no "on" pixel: the threshold at a pixel is a
// bilinear interpolation, a convex combination, of the threshold grid's
// values at the (at most) 2 x 2 block centres around it, which lie in the
// 3 x 3 blocks around the pixel's block; computed in double from floats
// and rounded to float, it is not below the smallest of those floats (the
// double arithmetic errs by a few 1e-16 relative, far below half a float's
// step). So the bound, the minimum over the 3 x 3 blocks around each block
// the cell touches, less 1e-6 of its magnitude for good measure, is at most
// the threshold at every pixel of the cell, and a pixel is "on" only if its
// smoothed value exceeds the threshold, hence the bound, hence only if the
// cell's maximum does. Saturated, faint or border-straddling spots need no
// special case: the test is per pixel value, blind to what the pixel
// belongs to, and the cells tile the image.
#pragma once

#include <opencv2/core.hpp>

#include "vision/spot_detection_internal.h"

namespace opl {
namespace spot_internal {

// Side of the coarse pass's cells [px].
constexpr int kThresholdCellPx = 8;

// `smooth` CV_32F (H x W); `thr_blocks` the threshold grid (CV_32F, one
// value per block of block_px), `thr` its interpolation. Writes *mask
// (CV_8U, H x W: 255 "on", 0 off) and *active (CV_8U, one byte per block:
// 1 when the block holds an "on" pixel). `cells_tested` (optional): the
// number of cells thresholded pixel by pixel (all of them on the full path).
void ThresholdMask(const cv::Mat& smooth, const cv::Mat& thr_blocks, BlockGrid* thr, int block_px,
                   bool coarse_to_fine, cv::Mat* mask, cv::Mat* active, int* cells_tested);

}  // namespace spot_internal
}  // namespace opl
