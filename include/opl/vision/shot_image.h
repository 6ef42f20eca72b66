// Reading a photograph for the front end: the pixels as the sensor wrote
// them, and the channel in which the laser spots are looked for
// (docs/images.md, "Image files" and "The chain", step 1).
//
//   Result<ShotImage> shot = ReadShotImage("cam0_A.jpg", SpotChannel::kRed);
//   DetectTags(shot->for_tags);    // grey (luma): black-and-white tags
//   DetectSpots(shot->for_spots);  // the laser's channel
//
// Orientation. A camera that writes an EXIF orientation tag (portrait
// shots) leaves the pixels as the sensor read them and asks viewers to
// rotate. Calibrations are of sensor pixels, so the tag is IGNORED: the
// image is what the sensor wrote, whatever the tag says
// (cv::IMREAD_IGNORE_ORIENTATION). A viewer that honours the tag shows it
// rotated; that is expected.
//
// Colour. Tags are black and white: they are detected in the luma image
// (0.299 R + 0.587 G + 0.114 B, cv::COLOR_BGR2GRAY). A laser spot is
// detected in the channel of the laser's colour: for a red (e.g. 658 nm)
// laser the red channel, which keeps the spot's whole contrast, where luma
// keeps 30% of it while adding the wall's green and blue noise and texture;
// or red minus green (SpotChannel::kRedMinusGreen), in which white light
// cancels.
// A grey image is used for both as it is.
//
// Size limit. An image may have at most kMaxImageSidePx pixels a side and
// kMaxImagePixels pixels in all (vision/image_decode.h; docs/formats.md,
// "Limits"): the largest metric cameras give about 150 megapixels
// (14204 x 10652). For PNG and JPEG the size is read from the file's header
// (IHDR, SOF) BEFORE decoding, so a 60-byte file claiming 100000 x 100000
// pixels is refused at once instead of making the decoder allocate for it;
// other formats are checked after decoding (OpenCV's own limit, 2^30 pixels,
// guards their allocation).
//
// Decoding (vision/image_decode.h): PNG and JPEG with OPL's own libpng and
// libjpeg decoder, pixel for pixel what cv::imdecode gives, and silent: a
// damaged file that still decodes (a bad CRC in a PNG text chunk, a JPEG cut
// short) gives its decoder's warnings in ShotImage::decode_warnings, which
// the image front end reports per image; nothing is printed on stderr.
// Other formats (TIFF, BMP, ...) go through cv::imdecode.
//
// Errors (Status): IoError naming the file when it is missing, not a regular
// file or not an image, or when the decoder fails ("cannot decode the image:
// ..."); InvalidArgument for a depth other than 8 or 16 bit (the message
// names the type) or a size beyond the limit ("<file>: 100000 x 100000
// pixels is beyond the limit of 32768 pixels a side and 160 megapixels").
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "opl/core/status.h"
#include "opl/vision/image_decode.h"

namespace opl {

// The width and height a PNG (IHDR) or JPEG (SOF) file's header declares, read
// without decoding; nullopt for another format or a header that cannot be
// read (the decoder then reports it).
std::optional<std::pair<long long, long long>> ReadImageHeaderSize(const std::string& path);

// The channel of a colour photograph in which laser spots are detected.
enum class SpotChannel {
  kRed,    // red lasers (635-670 nm): the default
  kGreen,  // green lasers (515-532 nm)
  kBlue,   // blue and violet lasers (405-488 nm)
  kLuma,   // the grey image (a white or infrared source on a monochrome-like image)
  // Red minus green, saturated at 0 (8 and 16 bit alike): a red laser keeps
  // ~90% of its contrast (a 658 nm diode on a typical RGB sensor reads
  // G ~ 0.1 R) while white light (lamps, specular highlights, a white wall)
  // cancels. A pixel whose red is saturated (the type's maximum) and whose
  // green is not stays saturated (full scale): the spot detector then
  // excludes it from the fit as it would in the red channel. A pixel
  // saturated in both is white light clipped: 0.
  kRedMinusGreen,
};

// "red", "green", "blue", "luma", "red-minus-green".
const char* SpotChannelName(SpotChannel channel);
// The inverse of SpotChannelName; InvalidArgument naming the value and the choices.
Result<SpotChannel> ParseSpotChannel(const std::string& name);

struct ShotImage {
  cv::Mat for_tags;   // grey, CV_8UC1 or CV_16UC1
  cv::Mat for_spots;  // grey or the chosen channel, same size and depth
  int source_channels = 1;  // 1 (grey), 3 (BGR) or 4 (BGRA) as stored in the file
  bool lossy_jpeg = false;  // the file is a JPEG (by its signature, not its name)
  // The decoder's warnings about a damaged file that still decoded
  // (DecodedImage::warnings: one safe line each); empty for a sound file.
  std::vector<std::string> decode_warnings{};
};

Result<ShotImage> ReadShotImage(const std::string& path, SpotChannel channel);

// Red minus green of a BGR(A) image, 8 or 16 bit (SpotChannel::
// kRedMinusGreen): max(R - G, 0), full scale where R is and G is not.
cv::Mat RedMinusGreen(const cv::Mat& bgr);

}  // namespace opl
