#include "opl/vision/shot_image.h"

#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/vision/spot_detection.h"

namespace opl {

const char* SpotChannelName(SpotChannel channel) {
  switch (channel) {
    case SpotChannel::kRed: return "red";
    case SpotChannel::kGreen: return "green";
    case SpotChannel::kBlue: return "blue";
    case SpotChannel::kLuma: return "luma";
  }
  return "?";
}

Result<SpotChannel> ParseSpotChannel(const std::string& name) {
  for (SpotChannel c : {SpotChannel::kRed, SpotChannel::kGreen, SpotChannel::kBlue,
                        SpotChannel::kLuma}) {
    if (name == SpotChannelName(c)) return c;
  }
  return Status::InvalidArgument("spot channel '" + name +
                                 "' is not one of red, green, blue, luma");
}

Result<ShotImage> ReadShotImage(const std::string& path, SpotChannel channel) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Status::IoError(path + ": no such image");
  }
  // Sensor pixels: the EXIF orientation is not applied (header).
  cv::Mat image =
      cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR | cv::IMREAD_IGNORE_ORIENTATION);
  if (image.empty()) return Status::IoError(path + ": cannot read the image (not an image file?)");
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    return Status::InvalidArgument(path + ": image type " + OpenCvTypeName(image.type()) +
                                   " is not supported (8 or 16 bit)");
  }
  ShotImage shot;
  shot.source_channels = image.channels();
  {
    char signature[3] = {0, 0, 0};
    std::ifstream(path, std::ios::binary).read(signature, 3);
    shot.lossy_jpeg = static_cast<unsigned char>(signature[0]) == 0xFF &&
                      static_cast<unsigned char>(signature[1]) == 0xD8 &&
                      static_cast<unsigned char>(signature[2]) == 0xFF;
  }
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
  }
  return shot;
}

}  // namespace opl
