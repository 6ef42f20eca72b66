// Decoding a photograph's file: PNG with libpng and JPEG with libjpeg(-turbo)
// through OPL's own error handlers, every other format with cv::imdecode
// (docs/images.md, "Image files").
//
//   Result<DecodedImage> image = ReadImageFile("cam0_A.jpg");
//   if (!image.ok()) return image.status();   // "cam0_A.jpg: cannot decode the image: ..."
//   for (const std::string& w : image->warnings) Warn("cam0_A.jpg: " + w);
//
// Pixels. For PNG and JPEG the pixels are exactly those of
// cv::imdecode(bytes, IMREAD_ANYDEPTH | IMREAD_ANYCOLOR |
// IMREAD_IGNORE_ORIENTATION) (tests/vision/image_decode_test.cc checks it):
// grey files give CV_8UC1 or CV_16UC1; every other PNG colour type (RGB,
// palette, grey + alpha, RGB + alpha) and colour JPEGs (YCbCr, RGB, CMYK)
// give BGR, CV_8UC3 or CV_16UC3, alpha dropped (not blended); 16-bit PNG
// samples in the machine's byte order; 1, 2 and 4-bit grey expanded to 8 bit
// (0..255 for bilevel). Sensor pixels: an EXIF orientation tag is NOT
// applied.
//
// Messages. libpng and libjpeg print their warnings and errors on stderr by
// default ("libpng warning: tEXt: CRC error", "Corrupt JPEG data: premature
// end of data segment"), which would add lines to the tools' one-line stderr
// (issue 19 item 7). Here nothing is printed: an error ends the decode with a
// Status naming the file; a warning (the file is damaged but decodes) is
// collected into DecodedImage::warnings, one safe line each, for the caller
// to report. PNG ancillary chunks other than tRNS (text, colour profiles,
// gamma, EXIF, ...) are skipped unread, as OpenCV ignores them too; their CRC
// is still checked (a bad one is a warning).
//
// A JPEG cut short decodes with the warning "Premature end of JPEG file": the
// rows after the cut are a flat grey (libjpeg's standard fill), where
// cv::imdecode left the rows of an earlier buffer there. A PNG cut short is
// an error, as with cv::imdecode.
//
// Limits (memory bombs): the size the file declares (PNG IHDR, JPEG SOF) is
// checked against kMaxImageSidePx and kMaxImagePixels before any pixel is
// allocated; a PNG chunk longer than the rest of the file is refused before
// libpng sees it, and libpng allocates at most kMaxPngChunkBytes for one
// chunk; a JPEG may have at most kMaxJpegScans scans (a progressive JPEG of
// tens of thousands of tiny scans would take minutes).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "opl/core/status.h"

namespace opl {

// The largest image OPL reads (docs/formats.md, "Limits"): the largest metric
// cameras give about 150 megapixels (14204 x 10652).
constexpr int kMaxImageSidePx = 32768;
constexpr long long kMaxImagePixels = 160LL * 1000 * 1000;
// The most libpng allocates for one chunk, and the most scans of a JPEG.
constexpr size_t kMaxPngChunkBytes = 64u << 20;
constexpr int kMaxJpegScans = 1000;

// The file format by its signature (not its name).
enum class ImageFileFormat { kPng, kJpeg, kOther };
ImageFileFormat SniffImageFileFormat(const unsigned char* bytes, size_t size);

struct DecodedImage {
  cv::Mat pixels;  // CV_8UC1, CV_8UC3 (BGR), CV_16UC1 or CV_16UC3 for PNG and JPEG
  ImageFileFormat format = ImageFileFormat::kOther;
  // The decoder's warnings, in the order it gave them (at most
  // kMaxDecodeWarnings, then one "... N more"), one safe line each (control
  // characters escaped, cut at 200 bytes); empty for a sound file.
  std::vector<std::string> warnings{};
};
constexpr int kMaxDecodeWarnings = 8;

// InvalidArgument "<name>: W x H pixels is beyond the limit of 32768 pixels a
// side and 160 megapixels" when width or height is beyond kMaxImageSidePx or
// their product beyond kMaxImagePixels; OK otherwise.
Status CheckImageSizeLimit(const std::string& name, long long width, long long height);

// Decodes an image file's bytes; `name` (the file) starts every message.
// Errors: IoError "<name>: cannot decode the image: <the decoder's reason>"
// (a PNG chunk longer than the file, a damaged header, a CRC error in a
// critical PNG chunk, a truncated PNG, ...) or "<name>: cannot read the image
// (not an image file?)" for a format OpenCV does not know;
// InvalidArgument for a size beyond the limit (CheckImageSizeLimit). Other
// formats than PNG and JPEG are decoded by cv::imdecode, whose exceptions
// become IoError too.
Result<DecodedImage> DecodeImage(const unsigned char* bytes, size_t size, const std::string& name);

// The whole file at `path`; IoError "<path>: cannot read the image" when it
// cannot be opened or read.
Result<std::vector<unsigned char>> ReadImageFileBytes(const std::string& path);

// ReadImageFileBytes, then DecodeImage with the path as the name.
Result<DecodedImage> ReadImageFile(const std::string& path);

}  // namespace opl
