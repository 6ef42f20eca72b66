// DecodeImage (vision/image_decode.h): OPL's own PNG and JPEG decoder gives
// the pixels cv::imdecode gives, prints nothing on stderr, and collects the
// libraries' warnings. The files are tests/data/image_decode/ (written by its
// make_fixtures.py: PNG by a zlib-only writer, JPEG by Pillow), whose samples
// follow formulas checked here too, so channel order and 16-bit byte order
// are checked against the files' own values, not only against OpenCV.
#include "opl/vision/image_decode.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/temp_dir.h"
#include "support/scene_images.h"

namespace opl {
namespace {

std::string Fixture(const std::string& name) {
  return test::SourceDir() + "/tests/data/image_decode/" + name;
}

std::vector<unsigned char> Bytes(const std::string& path) {
  Result<std::vector<unsigned char>> bytes = ReadImageFileBytes(path);
  EXPECT_TRUE(bytes.ok()) << bytes.status().message();
  return bytes.ok() ? *bytes : std::vector<unsigned char>();
}

// Everything written on file descriptor 2 (stderr) while `run` runs: fd 2 is
// pointed at a temporary file (dup2) and restored after.
template <typename F>
std::string WrittenOnFd2(F run) {
  char name[] = "/tmp/opl_fd2_XXXXXX";
  const int file = mkstemp(name);
  EXPECT_GE(file, 0);
  std::fflush(stderr);
  const int saved = dup(2);
  dup2(file, 2);
  run();
  std::fflush(stderr);
  dup2(saved, 2);
  close(saved);
  std::string written;
  lseek(file, 0, SEEK_SET);
  char buffer[4096];
  for (ssize_t n; (n = read(file, buffer, sizeof(buffer))) > 0;) written.append(buffer, n);
  close(file);
  unlink(name);
  return written;
}

// cv::imdecode with ReadShotImage's former flags; what libpng prints through
// it is dropped (in `printed` when asked for).
cv::Mat OpenCvDecode(const std::vector<unsigned char>& bytes, std::string* printed = nullptr) {
  cv::Mat image;
  const std::string written = WrittenOnFd2([&] {
    image = cv::imdecode(bytes, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR |
                                    cv::IMREAD_IGNORE_ORIENTATION);
  });
  if (printed != nullptr) *printed = written;
  return image;
}

constexpr int kWidth = 37, kHeight = 23;
int Grey(int x, int y) { return (7 * x + 11 * y) % 256; }
int Green(int x, int) { return (255 - 5 * x + 256 * 5) % 256; }
int Blue(int, int y) { return (3 * y + 100) % 256; }
int Wide(int v, int x) { return (v * 257 + x) % 65536; }

// Decodes `name` both ways: the same type, size and every pixel, no warning,
// nothing on stderr.
cv::Mat DecodeAndCompare(const std::string& name, int expected_type) {
  SCOPED_TRACE(name);
  const std::vector<unsigned char> bytes = Bytes(Fixture(name));
  Result<DecodedImage> ours = Status::IoError("not run");
  const std::string printed =
      WrittenOnFd2([&] { ours = DecodeImage(bytes.data(), bytes.size(), name); });
  EXPECT_EQ(printed, "");
  EXPECT_TRUE(ours.ok()) << ours.status().message();
  if (!ours.ok()) return cv::Mat();
  EXPECT_THAT(ours->warnings, ::testing::IsEmpty());
  const cv::Mat theirs = OpenCvDecode(bytes);
  EXPECT_EQ(ours->pixels.type(), expected_type);
  EXPECT_EQ(theirs.type(), expected_type);
  EXPECT_EQ(ours->pixels.cols, kWidth);
  EXPECT_EQ(ours->pixels.rows, kHeight);
  if (ours->pixels.type() != theirs.type() || ours->pixels.size() != theirs.size()) return cv::Mat();
  EXPECT_EQ(cv::norm(ours->pixels, theirs, cv::NORM_INF), 0.0);
  return ours->pixels;
}

TEST(ImageDecode, PngIsPixelIdenticalToOpenCv) {
  struct Case {
    const char* file;
    int type;
  };
  for (const Case& c : std::vector<Case>{
           {"grey8.png", CV_8UC1},
           {"grey1.png", CV_8UC1},
           {"grey2.png", CV_8UC1},
           {"grey4.png", CV_8UC1},
           {"grey16.png", CV_16UC1},
           {"grey8_trns.png", CV_8UC1},
           {"grey_alpha8.png", CV_8UC3},
           {"grey_alpha16.png", CV_16UC3},
           {"rgb8.png", CV_8UC3},
           {"rgb8_trns.png", CV_8UC3},
           {"rgb16.png", CV_16UC3},
           {"rgba8.png", CV_8UC3},
           {"rgba16.png", CV_16UC3},
           {"palette8.png", CV_8UC3},
           {"palette8_trns.png", CV_8UC3},
           {"palette4.png", CV_8UC3},
           {"rgb8_interlaced.png", CV_8UC3},
           {"grey16_interlaced.png", CV_16UC1},
           {"palette8_trns_interlaced.png", CV_8UC3},
           {"grey8_ancillary.png", CV_8UC1},
       }) {
    DecodeAndCompare(c.file, c.type);
  }
}

TEST(ImageDecode, PngSamplesAreTheFilesInBgrAndNativeByteOrder) {
  const cv::Mat grey = DecodeAndCompare("grey8.png", CV_8UC1);
  const cv::Mat bilevel = DecodeAndCompare("grey1.png", CV_8UC1);
  const cv::Mat grey4 = DecodeAndCompare("grey4.png", CV_8UC1);
  const cv::Mat grey16 = DecodeAndCompare("grey16_interlaced.png", CV_16UC1);
  const cv::Mat rgb = DecodeAndCompare("rgba8.png", CV_8UC3);
  const cv::Mat rgb16 = DecodeAndCompare("rgb16.png", CV_16UC3);
  const cv::Mat grey_alpha = DecodeAndCompare("grey_alpha8.png", CV_8UC3);
  const cv::Mat palette = DecodeAndCompare("palette8_trns_interlaced.png", CV_8UC3);
  ASSERT_FALSE(grey.empty() || bilevel.empty() || grey4.empty() || grey16.empty() ||
               rgb.empty() || rgb16.empty() || grey_alpha.empty() || palette.empty());
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      SCOPED_TRACE(std::to_string(x) + ", " + std::to_string(y));
      const int g = Grey(x, y);
      ASSERT_EQ(grey.at<uchar>(y, x), g);
      ASSERT_EQ(bilevel.at<uchar>(y, x), (g >> 7) * 255);  // 1 bit scaled to 0 or 255
      ASSERT_EQ(grey4.at<uchar>(y, x), (g >> 4) * 17);     // 4 bits scaled: 15 -> 255
      ASSERT_EQ(grey16.at<uint16_t>(y, x), Wide(g, x));
      ASSERT_EQ(rgb.at<cv::Vec3b>(y, x), cv::Vec3b(Blue(x, y), Green(x, y), g));  // alpha dropped
      ASSERT_EQ(rgb16.at<cv::Vec3w>(y, x),
                cv::Vec3w(Wide(Blue(x, y), x), Wide(Green(x, y), x), Wide(g, x)));
      ASSERT_EQ(grey_alpha.at<cv::Vec3b>(y, x), cv::Vec3b(g, g, g));
      const int i = (x + y) % 64;  // palette entry (i * 4, 255 - 3 i, 37 i mod 256)
      ASSERT_EQ(palette.at<cv::Vec3b>(y, x), cv::Vec3b((37 * i) % 256, 255 - 3 * i, 4 * i));
    }
  }
}

TEST(ImageDecode, PngAncillaryChunksAreSkippedSilently) {
  // gAMA, cHRM, sRGB, a bogus iCCP profile, pHYs, text, tIME and an eXIf
  // orientation: OpenCV's read prints libpng's complaint about the profile;
  // ours skips the chunks (their CRC checked) and keeps the samples.
  const std::vector<unsigned char> bytes = Bytes(Fixture("rgb8_ancillary.png"));
  std::string printed_by_opencv;
  OpenCvDecode(bytes, &printed_by_opencv);
  EXPECT_THAT(printed_by_opencv, ::testing::HasSubstr("libpng warning: iCCP"));
  const cv::Mat rgb = DecodeAndCompare("rgb8_ancillary.png", CV_8UC3);
  ASSERT_FALSE(rgb.empty());
  EXPECT_EQ(rgb.at<cv::Vec3b>(3, 5), cv::Vec3b(Blue(5, 3), Green(5, 3), Grey(5, 3)));
}

TEST(ImageDecode, JpegIsPixelIdenticalToOpenCv) {
  struct Case {
    const char* file;
    int type;
  };
  for (const Case& c : std::vector<Case>{
           {"grey.jpg", CV_8UC1},
           {"grey_progressive.jpg", CV_8UC1},
           {"rgb_420.jpg", CV_8UC3},
           {"rgb_422.jpg", CV_8UC3},
           {"rgb_444.jpg", CV_8UC3},
           {"rgb_420_progressive.jpg", CV_8UC3},
           {"rgb_444_progressive.jpg", CV_8UC3},
           {"cmyk.jpg", CV_8UC3},
       }) {
    const cv::Mat image = DecodeAndCompare(c.file, c.type);
    ASSERT_FALSE(image.empty());
    // Up to the JPEG's loss, the file's samples (B, G, R).
    cv::Mat expected(kHeight, kWidth, c.type);
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        if (c.type == CV_8UC1) {
          expected.at<uchar>(y, x) = static_cast<uchar>(Grey(x, y));
        } else {
          expected.at<cv::Vec3b>(y, x) = cv::Vec3b(Blue(x, y), Green(x, y), Grey(x, y));
        }
      }
    }
    // 4:2:0 halves the chroma of this busy pattern: a few tens of DN at
    // worst, a few on average; a channel swap would give about 80 on average.
    EXPECT_LT(cv::norm(image, expected, cv::NORM_L1) / static_cast<double>(image.total() *
                                                                           image.channels()),
              8.0)
        << c.file;
  }
}

TEST(ImageDecode, JpegsOpenCvWritesAreIdenticalToo) {
  // An 18 MP-like texture, cut small: restart markers, optimised Huffman
  // tables, progressive, and a 16 x 16 MCU that does not divide the size.
  cv::Mat image(123, 97, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::GaussianBlur(image, image, cv::Size(5, 5), 1.5);
  for (const std::vector<int>& params : std::vector<std::vector<int>>{
           {cv::IMWRITE_JPEG_QUALITY, 90},
           {cv::IMWRITE_JPEG_QUALITY, 75, cv::IMWRITE_JPEG_RST_INTERVAL, 3},
           {cv::IMWRITE_JPEG_QUALITY, 95, cv::IMWRITE_JPEG_OPTIMIZE, 1},
           {cv::IMWRITE_JPEG_QUALITY, 85, cv::IMWRITE_JPEG_PROGRESSIVE, 1},
       }) {
    for (const bool grey : {false, true}) {
      cv::Mat source = image;
      if (grey) cv::extractChannel(image, source, 1);
      std::vector<unsigned char> bytes;
      ASSERT_TRUE(cv::imencode(".jpg", source, bytes, params));
      Result<DecodedImage> ours = DecodeImage(bytes.data(), bytes.size(), "texture.jpg");
      ASSERT_TRUE(ours.ok()) << ours.status().message();
      EXPECT_THAT(ours->warnings, ::testing::IsEmpty());
      EXPECT_EQ(ours->format, ImageFileFormat::kJpeg);
      const cv::Mat theirs = OpenCvDecode(bytes);
      ASSERT_EQ(ours->pixels.type(), theirs.type());
      EXPECT_EQ(cv::norm(ours->pixels, theirs, cv::NORM_INF), 0.0) << params[1];
    }
  }
}

// Issue 19 item 7: a JPEG cut short made libjpeg print "Premature end of
// JPEG file" (and OpenCV kept rows of an earlier buffer); a PNG with a bad
// CRC in a text chunk made libpng print "libpng warning: tEXt: CRC error".
// Both decode; nothing reaches stderr; the warning is collected.
TEST(ImageDecode, WarningsAreCollectedNotPrinted) {
  std::vector<unsigned char> jpeg = Bytes(Fixture("rgb_444.jpg"));
  jpeg.resize(jpeg.size() * 2 / 3);
  Result<DecodedImage> cut = Status::IoError("not run");
  EXPECT_EQ(WrittenOnFd2([&] { cut = DecodeImage(jpeg.data(), jpeg.size(), "cut.jpg"); }), "");
  ASSERT_TRUE(cut.ok()) << cut.status().message();
  EXPECT_THAT(cut->warnings, ::testing::Contains("Premature end of JPEG file"));
  ASSERT_EQ(cut->pixels.size(), cv::Size(kWidth, kHeight));
  // The rows before the cut are the whole file's; the last row is flat grey
  // (libjpeg's fill after the end: zero coefficients, DC 128).
  const cv::Mat whole = OpenCvDecode(Bytes(Fixture("rgb_444.jpg")));
  EXPECT_EQ(cv::norm(cut->pixels.row(0), whole.row(0), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(cut->pixels.row(kHeight - 1), cv::Mat(1, kWidth, CV_8UC3, cv::Scalar::all(128)),
                     cv::NORM_INF),
            0.0);

  std::vector<unsigned char> png = Bytes(Fixture("grey8.png"));
  const std::string text = "Comment\0hello";
  std::string chunk = std::string("\0\0\0", 3) + static_cast<char>(text.size()) + "tEXt" + text +
                      std::string("\xde\xad\xbe\xef", 4);
  png.insert(png.begin() + 33, chunk.begin(), chunk.end());  // after IHDR
  Result<DecodedImage> crc = Status::IoError("not run");
  EXPECT_EQ(WrittenOnFd2([&] { crc = DecodeImage(png.data(), png.size(), "crc.png"); }), "");
  ASSERT_TRUE(crc.ok()) << crc.status().message();
  EXPECT_THAT(crc->warnings, ::testing::ElementsAre("tEXt: CRC error"));
  EXPECT_EQ(cv::norm(crc->pixels, OpenCvDecode(Bytes(Fixture("grey8.png"))), cv::NORM_INF), 0.0);
  // OpenCV's own read of it prints.
  std::string printed_by_opencv;
  OpenCvDecode(png, &printed_by_opencv);
  EXPECT_THAT(printed_by_opencv, ::testing::HasSubstr("libpng warning: tEXt: CRC error"));
}

TEST(ImageDecode, ManyWarningsAreCountedNotAllKept) {
  // Every restart marker of a JPEG with one every MCU row damaged: one
  // warning each.
  cv::Mat image(256, 64, CV_8UC1);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<unsigned char> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_RST_INTERVAL, 8}));
  int damaged = 0;
  for (size_t i = 2; i + 1 < bytes.size(); ++i) {
    if (bytes[i] == 0xFF && bytes[i + 1] >= 0xD0 && bytes[i + 1] <= 0xD7) {
      bytes[i + 1] = static_cast<unsigned char>(0xD0 + (bytes[i + 1] - 0xD0 + 3) % 8);
      ++damaged;
    }
  }
  ASSERT_GT(damaged, kMaxDecodeWarnings + 2);
  Result<DecodedImage> r = Status::IoError("not run");
  EXPECT_EQ(WrittenOnFd2([&] { r = DecodeImage(bytes.data(), bytes.size(), "rst.jpg"); }), "");
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r->warnings.size(), static_cast<size_t>(kMaxDecodeWarnings + 1));
  EXPECT_THAT(r->warnings.front(), ::testing::HasSubstr("Corrupt JPEG data"));
  EXPECT_THAT(r->warnings.back(), ::testing::MatchesRegex("\\.\\.\\. [0-9]+ more warning\\(s\\)"));
}

TEST(ImageDecode, ErrorsNameTheFileOnOneLine) {
  auto decode = [](const std::vector<unsigned char>& bytes, const std::string& name) {
    Result<DecodedImage> r = Status::Ok();
    EXPECT_EQ(WrittenOnFd2([&] { r = DecodeImage(bytes.data(), bytes.size(), name); }), "");
    EXPECT_FALSE(r.ok());
    return r.ok() ? std::string() : r.status().message();
  };
  // A PNG cut inside its image data: an error, as with cv::imdecode.
  std::vector<unsigned char> png = Bytes(Fixture("rgb8.png"));
  png.resize(png.size() / 2);
  EXPECT_EQ(decode(png, "cut.png"),
            "cut.png: cannot decode the image: PNG chunk 'IDAT' at byte 33 claims " +
                std::to_string(Bytes(Fixture("rgb8.png")).size() - 45 - 12) +
                " bytes, more than the " + std::to_string(png.size() - 45) + " left in the file");
  EXPECT_TRUE(OpenCvDecode(png).empty());
  // A damaged IDAT (its zlib check): libpng's error.
  png = Bytes(Fixture("grey8.png"));
  png[png.size() - 12 - 8] ^= 0x55;  // in the Adler-32 of the IDAT's zlib stream
  EXPECT_THAT(decode(png, "adler.png"),
              ::testing::StartsWith("adler.png: cannot decode the image: IDAT: "));
  // A JPEG whose header is damaged (SOF's component count).
  std::vector<unsigned char> jpeg = Bytes(Fixture("rgb_420.jpg"));
  for (size_t i = 2; i + 9 < jpeg.size(); ++i) {
    if (jpeg[i] == 0xFF && jpeg[i + 1] == 0xC0) {
      jpeg[i + 9] = 0;
      break;
    }
  }
  const std::string bad_sof = decode(jpeg, "sof.jpg");
  EXPECT_THAT(bad_sof, ::testing::StartsWith("sof.jpg: cannot decode the image: "));
  EXPECT_EQ(bad_sof.find('\n'), std::string::npos);
  // Not an image; an empty file.
  EXPECT_EQ(decode({'h', 'e', 'l', 'l', 'o'}, "notes.txt"),
            "notes.txt: cannot read the image (not an image file?)");
  EXPECT_EQ(decode({}, "empty.png"), "empty.png: cannot read the image (not an image file?)");
  EXPECT_EQ(decode({0xFF, 0xD8, 0xFF}, "stub.jpg").rfind("stub.jpg: cannot decode the image: ", 0),
            0u);
}

TEST(ImageDecode, DeclaredSizeBeyondTheLimitIsRefusedBeforeAllocating) {
  // A JPEG whose SOF claims 30000 x 30000 (900 MP, each side within 32768):
  // refused from the header, in microseconds, not after allocating 2.7 GB.
  std::vector<unsigned char> jpeg = Bytes(Fixture("grey.jpg"));
  for (size_t i = 2; i + 9 < jpeg.size(); ++i) {
    if (jpeg[i] == 0xFF && jpeg[i + 1] == 0xC0) {
      jpeg[i + 5] = jpeg[i + 7] = 0x75;  // 30000 = 0x7530
      jpeg[i + 6] = jpeg[i + 8] = 0x30;
      break;
    }
  }
  Result<DecodedImage> r = DecodeImage(jpeg.data(), jpeg.size(), "big.jpg");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(),
            "big.jpg: 30000 x 30000 pixels is beyond the limit of 32768 pixels a side and 160 "
            "megapixels");
  std::vector<unsigned char> png = Bytes(Fixture("grey8.png"));
  png[16] = png[17] = png[20] = png[21] = 0;
  png[18] = png[22] = 0x75;
  png[19] = png[23] = 0x30;
  r = DecodeImage(png.data(), png.size(), "big.png");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(),
            "big.png: 30000 x 30000 pixels is beyond the limit of 32768 pixels a side and 160 "
            "megapixels");
}

TEST(ImageDecode, OtherFormatsGoThroughOpenCv) {
  testing_support::TempDir dir;
  cv::Mat image(20, 30, CV_16UC3, cv::Scalar(1000, 20000, 65535));
  const std::string tiff = dir.File("image.tiff");
  ASSERT_TRUE(cv::imwrite(tiff, image));
  Result<DecodedImage> r = ReadImageFile(tiff);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->format, ImageFileFormat::kOther);
  EXPECT_EQ(cv::norm(r->pixels, image, cv::NORM_INF), 0.0);
  EXPECT_EQ(ReadImageFile(dir.File("none.png")).status().message(),
            dir.File("none.png") + ": cannot read the image");
}

}  // namespace
}  // namespace opl
