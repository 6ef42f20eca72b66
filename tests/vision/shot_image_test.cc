// ReadShotImage (vision/shot_image.h): sensor pixels whatever the EXIF
// orientation says, tags in luma, spots in the laser's channel.
#include "opl/vision/shot_image.h"

#include <chrono>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "opl/lab/shot_file.h"
#include "opl/vision/spot_detection.h"

namespace opl {
namespace {

// A JPEG of `image` carrying an EXIF APP1 segment whose only entry is
// Orientation (0x0112) = `orientation` (lab/shot_file.h).
std::string JpegWithExifOrientation(const cv::Mat& image, int orientation) {
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95});
  return *InsertExifOrientation(std::string(jpeg.begin(), jpeg.end()), orientation);
}

TEST(ShotImage, ExifOrientationIsNotApplied) {
  // A 96 x 48 gradient: rotated by a viewer it would be 48 x 96.
  cv::Mat image(48, 96, CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) image.at<uchar>(y, x) = static_cast<uchar>(2 * x + y);
  }
  testing_support::TempDir dir;
  const std::string path = dir.Write("portrait.jpg", JpegWithExifOrientation(image, 6));
  // The tag is real: OpenCV's default read honours it (90 deg clockwise).
  const cv::Mat rotated = cv::imread(path, cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(rotated.cols, 48);
  ASSERT_EQ(rotated.rows, 96);

  Result<ShotImage> shot = ReadShotImage(path, SpotChannel::kRed);
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  ASSERT_EQ(shot->for_tags.cols, 96);
  ASSERT_EQ(shot->for_tags.rows, 48);
  EXPECT_EQ(shot->source_channels, 1);
  // The sensor's pixels, up to JPEG's loss.
  cv::Mat diff;
  cv::absdiff(shot->for_tags, image, diff);
  EXPECT_LT(cv::mean(diff)[0], 2.0);
}

TEST(ShotImage, RedLaserSpotKeepsItsContrastInTheRedChannel) {
  // A light grey wall with independent noise per channel and a red spot
  // (R only, 30 DN, sigma 2.5 px).
  const int w = 160, h = 120;
  const double u0 = 80.3, v0 = 60.7, sigma = 2.5, amplitude = 30.0;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 2.0);
  cv::Mat bgr(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double d2 = (x - u0) * (x - u0) + (y - v0) * (y - v0);
      const double spot = amplitude * std::exp(-0.5 * d2 / (sigma * sigma));
      const double level[3] = {150.0, 160.0, 170.0 + spot};  // B, G, R
      for (int c = 0; c < 3; ++c) {
        bgr.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>(level[c] + noise(rng));
      }
    }
  }
  testing_support::TempDir dir;
  const std::string path = dir.File("wall.png");
  ASSERT_TRUE(cv::imwrite(path, bgr));

  auto detect = [&](SpotChannel channel) {
    Result<ShotImage> shot = ReadShotImage(path, channel);
    EXPECT_TRUE(shot.ok());
    EXPECT_EQ(shot->source_channels, 3);
    Result<SpotDetectionResult> r = DetectSpots(shot->for_spots);
    EXPECT_TRUE(r.ok());
    return *r;
  };
  const SpotDetectionResult red = detect(SpotChannel::kRed);
  ASSERT_EQ(red.spots.size(), 1u);
  EXPECT_NEAR(red.spots[0].u_px, u0, 0.2);
  EXPECT_NEAR(red.spots[0].v_px, v0, 0.2);
  const SpotDetectionResult luma = detect(SpotChannel::kLuma);
  ASSERT_EQ(luma.spots.size(), 1u);
  // Luma keeps 0.299 of the amplitude and averages the noise down by
  // sqrt(0.299^2 + 0.587^2 + 0.114^2) = 0.668: SNR x 0.45 in expectation;
  // measured here (the noise estimated on this small image, luma rounded
  // to 8 bits): 13.8 against 8.6, x 0.62. The same channel would give 1.
  EXPECT_GT(red.spots[0].snr, 1.4 * luma.spots[0].snr)
      << red.spots[0].snr << " vs " << luma.spots[0].snr;
  EXPECT_TRUE(detect(SpotChannel::kGreen).spots.empty());
  EXPECT_TRUE(detect(SpotChannel::kBlue).spots.empty());

  // Tags are always read in luma.
  Result<ShotImage> shot = ReadShotImage(path, SpotChannel::kRed);
  cv::Mat grey, diff;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::absdiff(shot->for_tags, grey, diff);
  EXPECT_EQ(cv::countNonZero(diff), 0);
}

// Issue 19 item 7: libpng printed "libpng warning: tEXt: CRC error" (and
// iCCP complaints) on stderr, adding lines to the tools' one-line output.
// Now nothing is printed and the warning is the shot's (the front end
// reports it).
TEST(ShotImage, AncillaryPngChunksPrintNoWarning) {
  cv::Mat image(16, 24, CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) image.at<uchar>(y, x) = static_cast<uchar>(7 * x + y);
  }
  std::vector<uchar> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  // After IHDR (8 + 25 bytes): a tEXt chunk whose CRC is wrong.
  const std::string text = "Comment\0hello";
  std::string chunk = std::string("\0\0\0", 3) + static_cast<char>(text.size()) + "tEXt" + text +
                      std::string("\xde\xad\xbe\xef", 4);
  std::string bytes(png.begin(), png.end());
  bytes.insert(33, chunk);
  testing_support::TempDir dir;
  const std::string path = dir.Write("bad_crc.png", bytes);
  // The channel: OpenCV's own read prints the warning.
  ::testing::internal::CaptureStderr();
  const cv::Mat direct = cv::imread(path, cv::IMREAD_UNCHANGED);
  const std::string printed_by_opencv = ::testing::internal::GetCapturedStderr();
  EXPECT_THAT(printed_by_opencv, ::testing::HasSubstr("libpng warning"));
  ::testing::internal::CaptureStderr();
  Result<ShotImage> shot = ReadShotImage(path, SpotChannel::kRed);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  EXPECT_THAT(shot->decode_warnings, ::testing::ElementsAre("tEXt: CRC error"));
  EXPECT_FALSE(shot->lossy_jpeg);
  cv::Mat diff;
  cv::absdiff(shot->for_tags, image, diff);
  EXPECT_EQ(cv::countNonZero(diff), 0);
}

// A JPEG cut short (an interrupted copy) is measured, with the decoder's
// warning for the report; its rows before the cut are exact.
TEST(ShotImage, JpegCutShortDecodesWithAWarning) {
  cv::Mat image(64, 80, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uchar> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90}));
  testing_support::TempDir dir;
  const std::string whole = dir.Write("whole.jpg", std::string(jpeg.begin(), jpeg.end()));
  const std::string cut = dir.Write("cut.jpg", std::string(jpeg.begin(), jpeg.end() - 2000));
  ::testing::internal::CaptureStderr();
  Result<ShotImage> shot = ReadShotImage(cut, SpotChannel::kGreen);
  Result<ShotImage> sound = ReadShotImage(whole, SpotChannel::kGreen);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  ASSERT_TRUE(shot.ok()) << shot.status().message();
  ASSERT_TRUE(sound.ok()) << sound.status().message();
  EXPECT_TRUE(shot->lossy_jpeg);
  EXPECT_EQ(shot->source_channels, 3);
  EXPECT_THAT(shot->decode_warnings, ::testing::Contains("Premature end of JPEG file"));
  EXPECT_THAT(sound->decode_warnings, ::testing::IsEmpty());
  EXPECT_EQ(cv::norm(shot->for_spots.rowRange(0, 8), sound->for_spots.rowRange(0, 8),
                     cv::NORM_INF),
            0.0);
  EXPECT_GT(cv::norm(shot->for_spots, sound->for_spots, cv::NORM_INF), 0.0);
}

// Found by tests/fuzz: a 200-byte PNG whose tEXt chunk claims 0x7fffffff
// bytes made libpng allocate 2 GB (1.5 s) before finding the file short.
TEST(ShotImage, PngChunksLongerThanTheFileAreRefusedBeforeDecoding) {
  cv::Mat image(16, 24, CV_8UC1, cv::Scalar(90));
  std::vector<uchar> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  std::string bytes(png.begin(), png.end());
  bytes.insert(33, std::string("\x7f\xff\xff\xfftEXtComment", 15));
  testing_support::TempDir dir;
  const std::string path = dir.Write("long_chunk.png", bytes);
  const auto start = std::chrono::steady_clock::now();
  ::testing::internal::CaptureStderr();
  Result<ShotImage> shot = ReadShotImage(path, SpotChannel::kRed);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.5);
  ASSERT_FALSE(shot.ok());
  EXPECT_EQ(shot.status().code(), StatusCode::kIoError);
  EXPECT_EQ(shot.status().message(),
            path + ": cannot decode the image: PNG chunk 'tEXt' at byte 33 claims 2147483647 "
                   "bytes, more than the " + std::to_string(bytes.size() - 45) +
                   " left in the file");
}

TEST(ShotImage, Errors) {
  testing_support::TempDir dir;
  Result<ShotImage> missing = ReadShotImage(dir.File("none.png"), SpotChannel::kRed);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_NE(missing.status().message().find("none.png: no such image"), std::string::npos);

  const std::string text = dir.Write("notes.png", "not an image");
  Result<ShotImage> garbage = ReadShotImage(text, SpotChannel::kRed);
  ASSERT_FALSE(garbage.ok());
  EXPECT_NE(garbage.status().message().find("cannot read the image"), std::string::npos);

  const std::string tiff = dir.File("float.tiff");
  ASSERT_TRUE(cv::imwrite(tiff, cv::Mat(8, 8, CV_32FC1, cv::Scalar(0.5))));
  Result<ShotImage> floating = ReadShotImage(tiff, SpotChannel::kRed);
  ASSERT_FALSE(floating.ok());
  EXPECT_NE(floating.status().message().find("CV_32FC1"), std::string::npos)
      << floating.status().message();

  // Issue 19: a 60-byte PNG claiming 100000 x 100000 pixels ended in an
  // uncaught OpenCV exception (exit 1): refused from its header.
  auto png_header = [](uint32_t width, uint32_t height) {
    std::string bytes = std::string("\x89PNG\r\n\x1a\n", 8) + std::string("\0\0\0\x0dIHDR", 8);
    for (uint32_t v : {width, height}) {
      for (int shift = 24; shift >= 0; shift -= 8) bytes += static_cast<char>((v >> shift) & 0xFF);
    }
    bytes += std::string("\x08\x02\0\0\0", 5);
    return bytes + std::string(60 - bytes.size(), '\0');
  };
  const std::string huge = dir.Write("huge.png", png_header(100000, 100000));
  ASSERT_EQ(testing_support::ReadAll(huge).size(), 60u);
  Result<ShotImage> too_big = ReadShotImage(huge, SpotChannel::kRed);
  ASSERT_FALSE(too_big.ok());
  EXPECT_EQ(too_big.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(too_big.status().message(),
            huge + ": 100000 x 100000 pixels is beyond the limit of 32768 pixels a side and 160 "
                   "megapixels");
  const std::string wide = dir.Write("wide.png", png_header(40000, 10));
  EXPECT_EQ(ReadShotImage(wide, SpotChannel::kRed).status().message(),
            wide + ": 40000 x 10 pixels is beyond the limit of 32768 pixels a side and 160 "
                   "megapixels");
  const std::string many = dir.Write("many.png", png_header(20000, 20000));
  EXPECT_THAT(ReadShotImage(many, SpotChannel::kRed).status().message(),
              ::testing::HasSubstr("20000 x 20000 pixels is beyond the limit"));
  // Within the limit, a truncated file: the decoder's refusal, one line.
  const std::string truncated = dir.Write("truncated.png", png_header(1000, 1000));
  Result<ShotImage> cut = ReadShotImage(truncated, SpotChannel::kRed);
  ASSERT_FALSE(cut.ok());
  EXPECT_EQ(cut.status().code(), StatusCode::kIoError);
  EXPECT_EQ(cut.status().message().find('\n'), std::string::npos);
  EXPECT_EQ(cut.status().message().rfind(truncated + ": ", 0), 0u) << cut.status().message();

  // JPEG: the size from the frame header (SOF), after the APP segments.
  std::vector<unsigned char> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3)), jpeg));
  const std::string small = dir.Write("small.jpg", std::string(jpeg.begin(), jpeg.end()));
  const auto size = ReadImageHeaderSize(small);
  ASSERT_TRUE(size.has_value());
  EXPECT_EQ(size->first, 64);
  EXPECT_EQ(size->second, 48);
  for (size_t i = 0; i + 9 < jpeg.size(); ++i) {
    if (jpeg[i] == 0xFF && jpeg[i + 1] == 0xC0) {
      jpeg[i + 5] = jpeg[i + 6] = jpeg[i + 7] = jpeg[i + 8] = 0xEA;  // 60138 x 60138
      break;
    }
  }
  const std::string big_jpeg = dir.Write("big.jpg", std::string(jpeg.begin(), jpeg.end()));
  EXPECT_EQ(ReadShotImage(big_jpeg, SpotChannel::kRed).status().message(),
            big_jpeg + ": 60138 x 60138 pixels is beyond the limit of 32768 pixels a side and 160 "
                       "megapixels");
  EXPECT_FALSE(ReadImageHeaderSize(text).has_value());

  // A format whose header is not read here (BMP) claiming 100000 x 100000:
  // OpenCV's own refusal (an exception) becomes a Status naming the file.
  std::string bmp = "BM";
  auto le32 = [&bmp](uint32_t v) {
    for (int k = 0; k < 4; ++k) bmp += static_cast<char>((v >> (8 * k)) & 0xFF);
  };
  le32(60); le32(0); le32(54); le32(40); le32(100000); le32(100000);
  bmp += std::string("\x01\0\x18\0", 4);
  le32(0); le32(0); le32(2835); le32(2835); le32(0); le32(0);
  bmp += std::string(6, '\0');
  const std::string huge_bmp = dir.Write("huge.bmp", bmp);
  Result<ShotImage> bmp_shot = ReadShotImage(huge_bmp, SpotChannel::kRed);
  ASSERT_FALSE(bmp_shot.ok());
  EXPECT_EQ(bmp_shot.status().message().rfind(huge_bmp + ": ", 0), 0u)
      << bmp_shot.status().message();
  EXPECT_EQ(bmp_shot.status().message().find('\n'), std::string::npos);

  EXPECT_EQ(*ParseSpotChannel("green"), SpotChannel::kGreen);
  EXPECT_FALSE(ParseSpotChannel("infrared").ok());
  for (SpotChannel c : {SpotChannel::kRed, SpotChannel::kGreen, SpotChannel::kBlue,
                        SpotChannel::kLuma}) {
    EXPECT_EQ(*ParseSpotChannel(SpotChannelName(c)), c);
  }
}

}  // namespace
}  // namespace opl
