#include "opl/vision/shot_image.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <new>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "opl/core/message_text.h"
#include "opl/vision/spot_detection.h"

namespace opl {

const char* SpotChannelName(SpotChannel channel) {
  switch (channel) {
    case SpotChannel::kRed: return "red";
    case SpotChannel::kGreen: return "green";
    case SpotChannel::kBlue: return "blue";
    case SpotChannel::kLuma: return "luma";
    case SpotChannel::kRedMinusGreen: return "red-minus-green";
  }
  return "?";
}

Result<SpotChannel> ParseSpotChannel(const std::string& name) {
  for (SpotChannel c : {SpotChannel::kRed, SpotChannel::kGreen, SpotChannel::kBlue,
                        SpotChannel::kLuma, SpotChannel::kRedMinusGreen}) {
    if (name == SpotChannelName(c)) return c;
  }
  return Status::InvalidArgument("spot channel '" + name +
                                 "' is not one of red, green, blue, luma, red-minus-green");
}

cv::Mat RedMinusGreen(const cv::Mat& bgr) {
  CV_Assert((bgr.depth() == CV_8U || bgr.depth() == CV_16U) &&
            (bgr.channels() == 3 || bgr.channels() == 4));
  cv::Mat red, green, out;
  cv::extractChannel(bgr, red, 2);
  cv::extractChannel(bgr, green, 1);
  cv::subtract(red, green, out);  // saturates at 0
  const double full = bgr.depth() == CV_8U ? 255.0 : 65535.0;
  // Red clipped, green not: a saturated red spot stays saturated.
  cv::Mat red_clipped, green_clipped;
  cv::compare(red, full, red_clipped, cv::CMP_GE);
  cv::compare(green, full, green_clipped, cv::CMP_LT);
  out.setTo(full, red_clipped & green_clipped);
  return out;
}

namespace {

// Big-endian unsigned integer of `n` bytes at `p`.
long long BigEndian(const unsigned char* p, int n) {
  long long v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

// The size a JPEG's first frame header (SOF0..SOF15 but DHT, JPG, DAC)
// declares, walking the segments from the start of the file.
std::optional<std::pair<long long, long long>> JpegSize(std::ifstream& in) {
  in.seekg(2);  // after SOI
  for (int segment = 0; segment < 10000 && in; ++segment) {
    int c = in.get();
    if (c != 0xFF) return std::nullopt;
    while (c == 0xFF) c = in.get();  // fill bytes
    if (c == EOF) return std::nullopt;
    const int marker = c;
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) continue;  // no length
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // EOI, SOS: no frame header
    unsigned char length_bytes[2];
    if (!in.read(reinterpret_cast<char*>(length_bytes), 2)) return std::nullopt;
    const long long length = BigEndian(length_bytes, 2);
    if (length < 2) return std::nullopt;
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 &&
                     marker != 0xCC;
    if (sof) {
      unsigned char frame[5];  // precision, height, width
      if (length < 7 || !in.read(reinterpret_cast<char*>(frame), 5)) return std::nullopt;
      const long long height = BigEndian(frame + 1, 2), width = BigEndian(frame + 3, 2);
      if (height == 0) return std::nullopt;  // height given later (DNL): the decoder decides
      return std::make_pair(width, height);
    }
    in.seekg(length - 2, std::ios::cur);
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::pair<long long, long long>> ReadImageHeaderSize(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char head[24] = {};
  if (!in.read(reinterpret_cast<char*>(head), 3)) return std::nullopt;
  if (head[0] == 0xFF && head[1] == 0xD8 && head[2] == 0xFF) return JpegSize(in);
  static const unsigned char kPng[12] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n',
                                         0, 0, 0, 13};
  if (!in.read(reinterpret_cast<char*>(head) + 3, 21)) return std::nullopt;
  if (std::equal(kPng, kPng + 12, head) && std::equal(head + 12, head + 16, "IHDR")) {
    return std::make_pair(BigEndian(head + 16, 4), BigEndian(head + 20, 4));
  }
  return std::nullopt;
}

namespace {

// Decodes and converts; may throw cv::Exception (caught by ReadShotImage).
Result<ShotImage> DecodeShotImage(const std::string& path, SpotChannel channel) {
  Result<std::vector<unsigned char>> bytes = ReadImageFileBytes(path);
  if (!bytes.ok()) return bytes.status();
  // Sensor pixels: the EXIF orientation is not applied (header).
  Result<DecodedImage> decoded = DecodeImage(bytes->data(), bytes->size(), path);
  if (!decoded.ok()) return decoded.status();
  const cv::Mat& image = decoded->pixels;
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    return Status::InvalidArgument(path + ": image type " + OpenCvTypeName(image.type()) +
                                   " is not supported (8 or 16 bit)");
  }
  ShotImage shot;
  shot.source_channels = image.channels();
  shot.lossy_jpeg = decoded->format == ImageFileFormat::kJpeg;
  shot.decode_warnings = std::move(decoded->warnings);
  if (image.channels() == 1) {
    shot.for_tags = image;
    shot.for_spots = image;
    return shot;
  }
  if (image.channels() != 3 && image.channels() != 4) {
    return Status::InvalidArgument(path + ": image type " + OpenCvTypeName(image.type()) +
                                   " is not supported (1, 3 or 4 channels)");
  }
  cv::cvtColor(image, shot.for_tags,
               image.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
  switch (channel) {
    case SpotChannel::kLuma: shot.for_spots = shot.for_tags; break;
    case SpotChannel::kRed: cv::extractChannel(image, shot.for_spots, 2); break;  // BGR(A)
    case SpotChannel::kGreen: cv::extractChannel(image, shot.for_spots, 1); break;
    case SpotChannel::kBlue: cv::extractChannel(image, shot.for_spots, 0); break;
    case SpotChannel::kRedMinusGreen: shot.for_spots = RedMinusGreen(image); break;
  }
  return shot;
}

}  // namespace

Result<ShotImage> ReadShotImage(const std::string& path, SpotChannel channel) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Status::IoError(path + ": no such image");
  }
  if (const auto size = ReadImageHeaderSize(path)) {
    OPL_RETURN_IF_ERROR(CheckImageSizeLimit(path, size->first, size->second));
  }
  try {
    return DecodeShotImage(path, channel);
  } catch (const cv::Exception& e) {
    std::string what = e.err.empty() ? std::string(e.what()) : e.err;
    return Status::IoError(path + ": cannot decode the image: " + SafeForMessage(what));
  } catch (const std::bad_alloc&) {
    return Status::IoError(path + ": cannot decode the image: out of memory");
  }
}

}  // namespace opl
