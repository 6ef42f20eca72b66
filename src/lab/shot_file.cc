#include "opl/lab/shot_file.h"

#include <vector>

#include <opencv2/imgcodecs.hpp>

namespace opl {

Result<std::string> InsertExifOrientation(const std::string& jpeg, int orientation) {
  if (jpeg.size() < 4 || static_cast<unsigned char>(jpeg[0]) != 0xFF ||
      static_cast<unsigned char>(jpeg[1]) != 0xD8) {
    return Status::InvalidArgument("InsertExifOrientation: not a JPEG (no SOI marker)");
  }
  if (orientation < 1 || orientation > 8) {
    return Status::InvalidArgument("InsertExifOrientation: orientation " +
                                   std::to_string(orientation) + " is not in 1..8");
  }
  const unsigned char tiff[] = {
      'I', 'I', 42, 0, 8, 0, 0, 0,                           // header, IFD at offset 8
      1, 0,                                                  // one entry
      0x12, 0x01, 3, 0, 1, 0, 0, 0,                          // Orientation, SHORT, count 1
      static_cast<unsigned char>(orientation), 0, 0, 0,      // value
      0, 0, 0, 0};                                           // no next IFD
  std::string app1 = std::string("Exif\0\0", 6) +
                     std::string(reinterpret_cast<const char*>(tiff), sizeof(tiff));
  const size_t length = app1.size() + 2;  // the length field counts itself
  std::string out = jpeg.substr(0, 2);
  out += static_cast<char>(0xFF);
  out += static_cast<char>(0xE1);
  out += static_cast<char>(length >> 8);
  out += static_cast<char>(length & 0xFF);
  out += app1;
  out.append(jpeg, 2, std::string::npos);
  return out;
}

Result<std::string> EncodeShotImage(const cv::Mat& image, const ImageLook& look) {
  const bool jpeg = look.format == "jpeg";
  std::vector<unsigned char> bytes;
  bool encoded = false;
  try {
    encoded = jpeg ? cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, look.jpeg_quality})
                   : cv::imencode(".png", image, bytes);
  } catch (const cv::Exception&) {
    encoded = false;
  }
  if (!encoded) return Status::IoError(std::string("cannot encode the ") + (jpeg ? "JPEG" : "PNG"));
  std::string out(bytes.begin(), bytes.end());
  if (jpeg && look.exif_orientation != 0) return InsertExifOrientation(out, look.exif_orientation);
  return out;
}

}  // namespace opl
