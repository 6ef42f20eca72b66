// Writing a rendered shot as a camera would: the file format of the scene's
// ImageLook (lab/scene.h): PNG (lossless, 8 or 16 bit) or JPEG at a chosen
// quality, optionally carrying an EXIF Orientation tag as a camera held in
// portrait writes it (the pixels stay as the sensor read them).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/lab/scene.h"

namespace opl {

// The file's bytes: look.format "png" or "jpeg" (look.jpeg_quality), with
// look.exif_orientation when not 0. IoError when OpenCV cannot encode the
// image (e.g. 16 bit as JPEG).
Result<std::string> EncodeShotImage(const cv::Mat& image, const ImageLook& look);

// `jpeg` (a JPEG file's bytes, starting with SOI) with an EXIF APP1 segment
// inserted after SOI whose only entry is Orientation (0x0112) =
// `orientation` (1..8; little-endian TIFF). InvalidArgument when `jpeg` does
// not start with SOI or the orientation is out of range.
Result<std::string> InsertExifOrientation(const std::string& jpeg, int orientation);

}  // namespace opl
