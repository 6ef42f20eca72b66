// The provenance written into each format (io/provenance_stamp.h): the file
// stays readable by its own readers (OPL's, OpenCV's, nlohmann's), the text
// before the stamp is kept byte for byte, and the PNG chunks' CRC-32 agrees
// with a bitwise reference computation (not zlib's table).
#include "opl/io/provenance_stamp.h"

#include <cstdint>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "opl/io/point_cloud_ply.h"
#include "opl/io/spots_csv.h"

namespace opl {
namespace {

Provenance TestProvenance() {
  Provenance p;
  p.tool = "opl_measure";
  p.version = "0.1.0 (commit 0123456789ab)";
  p.time_utc = "2026-12-02T10:00:00Z";
  p.command_line = {"opl_measure", "--calibration", "cal.json", "--out", "r\xC3\xA9sult.json"};
  p.inputs = {{"cal.json", 5120, std::string(64, 'f')}};
  return p;
}

TEST(StampProvenance, JsonGetsAMemberAndKeepsItsTextByteForByte) {
  const std::string pretty = "{\n  \"s\": 1.0,\n  \"grid\": {}\n}\n";
  Result<std::string> out = StampProvenance("r.json", pretty, TestProvenance());
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_EQ(out->rfind("{\n  \"s\": 1.0,\n  \"grid\": {},\n  \"provenance\": {", 0), 0u) << *out;
  EXPECT_EQ(out->substr(out->size() - 3), "\n}\n");
  const nlohmann::json j = nlohmann::json::parse(*out);
  EXPECT_EQ(j.at("s").dump(), "1.0");
  EXPECT_EQ(j.at("provenance").at("tool"), "opl_measure");
  EXPECT_EQ(j.at("provenance").at("command_line").at(4), "r\xC3\xA9sult.json");
  EXPECT_EQ(j.at("provenance").at("inputs").at(0).at("bytes"), 5120);

  Result<std::string> empty = StampProvenance("e.JSON", "{}", TestProvenance());
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(nlohmann::json::parse(*empty).size(), 1u);

  // An updated file (opl_camera --into): its old provenance is replaced.
  Result<std::string> again = StampProvenance("r.json", *out, TestProvenance());
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(nlohmann::json::parse(*again).size(), 3u);
  EXPECT_EQ(again->find("provenance"), again->rfind("provenance"));

  EXPECT_EQ(StampProvenance("a.json", "[1, 2]", TestProvenance()).status().message(),
            "a.json: the JSON root is not an object, cannot add its provenance");
  EXPECT_EQ(StampProvenance("b.json", "{\"a\": ", TestProvenance()).status().message().rfind(
                "b.json: not JSON, cannot add its provenance: ", 0),
            0u);
}

TEST(StampProvenance, CsvGetsCommentLinesThatTheSpotsReaderSkips) {
  const std::string csv = "\xEF\xBB\xBFid,x,y,z\r\nP1,1,2,3\r\n";
  Result<std::string> out = StampProvenance("spots.csv", csv, TestProvenance());
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->rfind("\xEF\xBB\xBF# opl tool: opl_measure\r\n# opl version: ", 0), 0u) << *out;
  EXPECT_EQ(out->substr(out->size() - 20), "id,x,y,z\r\nP1,1,2,3\r\n");
  Result<SpotsCsvData> spots = ParseSpotsCsv(*out, "spots.csv");
  ASSERT_TRUE(spots.ok()) << spots.status().ToString();
  ASSERT_EQ(spots->spots.size(), 1u);
  EXPECT_EQ(spots->spots[0].observation.point_in_scene.z(), 3.0);
  // The spot's line number counts the comment lines (physical lines).
  EXPECT_EQ(spots->spots[0].where, "spots.csv:7");  // 5 comment lines, the header, P1
}

TEST(StampProvenance, PlyGetsCommentsAfterTheFormatLine) {
  const std::string ply =
      "ply\nformat ascii 1.0\ncomment from the scanner\nelement vertex 1\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
  Result<std::string> out = StampProvenance("c.ply", ply, TestProvenance());
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->rfind("ply\nformat ascii 1.0\ncomment opl tool: opl_measure\n", 0), 0u) << *out;
  Result<PlyHeader> header = ParsePlyHeader(*out, "c.ply");
  ASSERT_TRUE(header.ok()) << header.status().ToString();
  ASSERT_EQ(header->elements.size(), 1u);
  EXPECT_EQ(header->elements[0].count, 1);
  EXPECT_EQ(StampProvenance("d.ply", "ply\nelement vertex 0\nend_header\n", TestProvenance())
                .status()
                .message(),
            "d.ply: a PLY header without a 'format' line, cannot add its provenance");
}

// CRC-32 (ISO 3309, as PNG uses it), bit by bit.
uint32_t ReferenceCrc32(const std::string& bytes) {
  uint32_t crc = 0xffffffffu;
  for (unsigned char byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return crc ^ 0xffffffffu;
}

uint32_t BigEndian32(const std::string& b, size_t at) {
  return (uint32_t{static_cast<unsigned char>(b[at])} << 24) |
         (uint32_t{static_cast<unsigned char>(b[at + 1])} << 16) |
         (uint32_t{static_cast<unsigned char>(b[at + 2])} << 8) |
         uint32_t{static_cast<unsigned char>(b[at + 3])};
}

TEST(StampProvenance, PngGetsTextChunksAndDecodesToTheSamePixels) {
  cv::Mat image(7, 9, CV_8UC3);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) image.at<cv::Vec3b>(r, c) = cv::Vec3b(r * 20, c * 25, 7);
  }
  std::vector<uchar> encoded;
  ASSERT_TRUE(cv::imencode(".png", image, encoded));
  const std::string png(encoded.begin(), encoded.end());
  Result<std::string> out = StampProvenance("o.png", png, TestProvenance());
  ASSERT_TRUE(out.ok()) << out.status().ToString();

  // Every chunk's CRC, the famous IEND one included, by the reference.
  size_t at = 8;
  int chunks = 0;
  while (at + 12 <= out->size()) {
    const uint32_t length = BigEndian32(*out, at);
    ASSERT_LE(at + 12 + length, out->size());
    EXPECT_EQ(BigEndian32(*out, at + 8 + length), ReferenceCrc32(out->substr(at + 4, 4 + length)))
        << "chunk " << out->substr(at + 4, 4);
    at += 12 + length;
    ++chunks;
  }
  EXPECT_EQ(at, out->size());
  EXPECT_EQ(out->substr(out->size() - 12), std::string("\0\0\0\0IEND\xAE\x42\x60\x82", 12));
  EXPECT_GE(chunks, 6);

  const cv::Mat decoded = cv::imdecode(std::vector<uchar>(out->begin(), out->end()),
                                       cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(decoded.empty());
  EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);

  Result<std::vector<std::pair<std::string, std::string>>> text = PngTextChunks(*out);
  ASSERT_TRUE(text.ok()) << text.status().ToString();
  ASSERT_EQ(text->size(), 3u);
  EXPECT_EQ((*text)[0], (std::pair<std::string, std::string>(
                            "Software", "OPL opl_measure 0.1.0 (commit 0123456789ab)")));
  EXPECT_EQ((*text)[1].second, "2026-12-02T10:00:00Z");
  EXPECT_EQ((*text)[2].first, "opl:provenance");
  EXPECT_EQ(nlohmann::json::parse((*text)[2].second).at("command_line").at(4),
            "r\xC3\xA9sult.json");

  EXPECT_EQ(StampProvenance("p.png", "GIF89a", TestProvenance()).status().message(),
            "p.png: not a PNG (no PNG signature)");
  EXPECT_EQ(StampProvenance("p.png", png.substr(0, png.size() - 12), TestProvenance())
                .status()
                .message(),
            "p.png: a PNG without an IEND chunk (truncated)");
}

// The JPEG's COM segment sits after the JFIF APP0 segment; OpenCV decodes
// the same pixels, and the segment's bytes are the JSON object.
TEST(StampProvenance, JpegGetsACommentSegmentAfterItsAppSegments) {
  cv::Mat image(16, 16, CV_8UC1, cv::Scalar(90));
  std::vector<uchar> encoded;
  ASSERT_TRUE(cv::imencode(".jpg", image, encoded));
  const std::string jpeg(encoded.begin(), encoded.end());
  ASSERT_EQ(jpeg.substr(2, 2), "\xFF\xE0");  // JFIF APP0 first
  const size_t app0 = 2 + 2 + ((static_cast<unsigned char>(jpeg[4]) << 8) |
                               static_cast<unsigned char>(jpeg[5]));
  Result<std::string> out = StampProvenance("o.JPG", jpeg, TestProvenance());
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_EQ(out->substr(0, app0), jpeg.substr(0, app0));
  EXPECT_EQ(out->substr(app0, 2), "\xFF\xFE");
  const size_t length = (static_cast<unsigned char>((*out)[app0 + 2]) << 8) |
                        static_cast<unsigned char>((*out)[app0 + 3]);
  const nlohmann::json j = nlohmann::json::parse(out->substr(app0 + 4, length - 2));
  EXPECT_EQ(j.at("tool"), "opl_measure");
  EXPECT_EQ(out->substr(app0 + 2 + length), jpeg.substr(app0));
  const cv::Mat decoded = cv::imdecode(std::vector<uchar>(out->begin(), out->end()),
                                       cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(decoded.empty());
  EXPECT_EQ(cv::norm(decoded, cv::imdecode(encoded, cv::IMREAD_UNCHANGED), cv::NORM_INF), 0.0);
  EXPECT_EQ(StampProvenance("x.jpeg", "abcd", TestProvenance()).status().message(),
            "x.jpeg: not a JPEG (no SOI marker)");
}

// The SVG's metadata element follows the root's <title>; the text around it
// is kept byte for byte, and the element's text (XML-unescaped) is the JSON.
TEST(StampProvenance, SvgGetsAMetadataElementAfterItsTitle) {
  Provenance p = TestProvenance();
  p.command_line.push_back("--label=a<b&c");
  const std::string head = "<?xml version=\"1.0\"?>\n<svg width=\"10px\">\n<title>T</title>";
  const std::string tail = "\n<g/>\n</svg>\n";
  Result<std::string> out = StampProvenance("plot.SVG", head + tail, p);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  ASSERT_EQ(out->compare(0, head.size(), head), 0);
  ASSERT_EQ(out->substr(out->size() - tail.size()), tail);
  const std::string open = "\n<metadata id=\"opl-provenance\">";
  ASSERT_EQ(out->compare(head.size(), open.size(), open), 0);
  std::string text = out->substr(head.size() + open.size());
  text = text.substr(0, text.find("</metadata>"));
  EXPECT_EQ(text.find('<'), std::string::npos);
  for (const auto& [from, to] : {std::pair<std::string, std::string>{"&lt;", "<"}, {"&gt;", ">"},
                                 {"&amp;", "&"}}) {
    for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + 1)) {
      text.replace(at, from.size(), to);
    }
  }
  EXPECT_EQ(nlohmann::json::parse(text).at("command_line").back(), "--label=a<b&c");
  // Without a title: right after the root's start tag.
  Result<std::string> untitled = StampProvenance("p.svg", "<svg a=\"1\"><g/></svg>", p);
  ASSERT_TRUE(untitled.ok());
  EXPECT_EQ(untitled->find("<svg a=\"1\">\n<metadata id=\"opl-provenance\">"), 0u);
  EXPECT_EQ(StampProvenance("p.svg", "<html/>", p).status().message(),
            "p.svg: not an SVG (no <svg> element)");
}

TEST(StampProvenance, RefusesAFormatItHasNoPlaceIn) {
  EXPECT_EQ(StampProvenance("board.pdf", "%PDF", TestProvenance()).status().message(),
            "board.pdf: no provenance format for '.pdf' files");
  EXPECT_EQ(StampProvenance("dir.v2/out", "x", TestProvenance()).status().message(),
            "dir.v2/out: no provenance format for '(no extension)' files");
}

}  // namespace
}  // namespace opl
