// ThresholdMask (vision/spot_threshold_mask.h): the "on" pixels of
// DetectSpots, by every pixel or coarse to fine.
#include "vision/spot_threshold_mask.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace opl {
namespace spot_internal {
namespace {

// Marks the blocks of row `m` (a mask row of width w) that hold an "on"
// pixel in [x0, x1) (an OR over the bytes, vectorised by the compiler).
void MarkActive(const uint8_t* m, int x0, int x1, int block_px, uint8_t* a) {
  for (int x = x0; x < x1;) {
    const int bx = x / block_px;
    const int end = std::min(x1, (bx + 1) * block_px);
    if (a[bx] == 0) {
      uint8_t any = 0;
      for (int k = x; k < end; ++k) any |= m[k];
      if (any != 0) a[bx] = 1;
    }
    x = end;
  }
}

void FullMask(const cv::Mat& smooth, BlockGrid* thr, int block_px, cv::Mat* mask, cv::Mat* active) {
  const int W = smooth.cols, H = smooth.rows;
  // Row by row: the mask by OpenCV's vectorised comparison (255 where
  // smooth > threshold, else 0), then the row's blocks that hold an "on"
  // pixel.
  std::vector<float> thr_row;
  for (int y = 0; y < H; ++y) {
    thr->Row(y, &thr_row);
    uint8_t* m = mask->ptr<uint8_t>(y);
    cv::Mat mask_row(1, W, CV_8U, m);
    cv::compare(smooth.row(y), cv::Mat(1, W, CV_32F, thr_row.data()), mask_row, cv::CMP_GT);
    MarkActive(m, 0, W, block_px, active->ptr<uint8_t>(y / block_px));
  }
}

void CoarseToFineMask(const cv::Mat& smooth, const cv::Mat& thr_blocks, BlockGrid* thr,
                      int block_px, cv::Mat* mask, cv::Mat* active, int* cells_tested) {
  const int W = smooth.cols, H = smooth.rows, C = kThresholdCellPx;
  const int nbx = thr_blocks.cols, nby = thr_blocks.rows;
  // The smallest threshold of the 3 x 3 blocks around each block (the
  // blocks whose centres the interpolation can use; erode's default border
  // leaves the blocks outside the grid out of the minimum).
  cv::Mat lower;
  cv::erode(thr_blocks, lower, cv::Mat::ones(3, 3, CV_8U));
  const int ncx = (W + C - 1) / C;
  // Per cell column: the smallest `lower` over the blocks the cell's
  // columns touch, for the current block row range.
  std::vector<float> col_max(static_cast<size_t>(W)), thr_span(static_cast<size_t>(C));
  std::vector<float> cell_bound(static_cast<size_t>(ncx));
  int tested = 0;
  for (int y0 = 0; y0 < H; y0 += C) {
    const int y1 = std::min(H, y0 + C);
    const int by0 = y0 / block_px, by1 = std::min(nby - 1, (y1 - 1) / block_px);
    for (int cx = 0; cx < ncx; ++cx) {
      const int x0 = cx * C, x1 = std::min(W, x0 + C);
      const int bx0 = x0 / block_px, bx1 = std::min(nbx - 1, (x1 - 1) / block_px);
      float bound = lower.at<float>(by0, bx0);
      for (int by = by0; by <= by1; ++by) {
        for (int bx = bx0; bx <= bx1; ++bx) bound = std::min(bound, lower.at<float>(by, bx));
      }
      // A margin far beyond rounding (header): never above the threshold.
      cell_bound[static_cast<size_t>(cx)] = bound - 1e-6f * std::fabs(bound);
    }
    // The column maxima of the cell row's smoothed values (vectorised).
    std::copy_n(smooth.ptr<float>(y0), W, col_max.begin());
    for (int y = y0 + 1; y < y1; ++y) {
      const float* s = smooth.ptr<float>(y);
      float* c = col_max.data();
      for (int x = 0; x < W; ++x) c[x] = std::max(c[x], s[x]);
    }
    for (int cx = 0; cx < ncx; ++cx) {
      const int x0 = cx * C, x1 = std::min(W, x0 + C);
      const float cell_max = *std::max_element(col_max.begin() + x0, col_max.begin() + x1);
      if (!(cell_max > cell_bound[static_cast<size_t>(cx)])) continue;  // no "on" pixel
      ++tested;
      for (int y = y0; y < y1; ++y) {
        thr->RowSpan(y, x0, x1, thr_span.data());
        const float* s = smooth.ptr<float>(y);
        uint8_t* m = mask->ptr<uint8_t>(y);
        for (int x = x0; x < x1; ++x) m[x] = s[x] > thr_span[static_cast<size_t>(x - x0)] ? 255 : 0;
        MarkActive(m, x0, x1, block_px, active->ptr<uint8_t>(y / block_px));
      }
    }
  }
  if (cells_tested != nullptr) *cells_tested = tested;
}

}  // namespace

void ThresholdMask(const cv::Mat& smooth, const cv::Mat& thr_blocks, BlockGrid* thr, int block_px,
                   bool coarse_to_fine, cv::Mat* mask, cv::Mat* active, int* cells_tested) {
  const int W = smooth.cols, H = smooth.rows;
  *active = cv::Mat::zeros(thr_blocks.rows, thr_blocks.cols, CV_8U);
  if (coarse_to_fine) {
    *mask = cv::Mat::zeros(H, W, CV_8U);  // the cells left out are off
    CoarseToFineMask(smooth, thr_blocks, thr, block_px, mask, active, cells_tested);
    return;
  }
  mask->create(H, W, CV_8U);
  FullMask(smooth, thr, block_px, mask, active);
  if (cells_tested != nullptr) {
    *cells_tested = ((W + kThresholdCellPx - 1) / kThresholdCellPx) *
                    ((H + kThresholdCellPx - 1) / kThresholdCellPx);
  }
}

}  // namespace spot_internal
}  // namespace opl
