// Fuzzing the library's readers (issue 19 item 10; docs/testing.md,
// "Fuzzing"): for every input format, the seed corpus of tests/fuzz/corpus/
// <format>/ (the examples cut small and every hostile input of issue 19's
// findings) and a few hundred seeded mutations of it go through the reader.
// Each must come back OK or with an error whose message is one line, of
// bounded length, naming the input; nothing may throw out, crash, or take
// more than OPL_FUZZ_SLOW_SECONDS. What a reader accepts must also be
// written back by its writer and read again (a reader may not accept what
// the library cannot represent). OPL_FUZZ_ITERATIONS raises the count
// (tests/fuzz/run_long.sh).
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "fuzz/fuzz_harness.h"
#include "io/temp_dir.h"
#include "opl/io/board_json.h"
#include "opl/io/cameras_json.h"
#include "opl/io/frame_metadata_jsonl.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/module_design_json.h"
#include "opl/io/point_table.h"
#include "opl/io/points_csv.h"
#include "opl/io/scale_point_file.h"
#include "opl/io/scene_json.h"
#include "opl/io/spots_csv.h"
#include "opl/sim/pattern_models.h"
#include "opl/vision/shot_image.h"

namespace opl {
namespace fuzz {
namespace {

using testing_support::TempDir;

// Mutated inputs per format in ctest: with the seeds, about 0.1 to 1 s a
// format in Release and a few times that under ASan + UBSan.
constexpr int kIterations = 300;

// The name every parsed text is given: messages must contain it.
const std::string kName = "fuzz_input";

// The outcome of a reader's Result: accepted, or the check of its message.
template <typename T>
TargetResult Judge(const Result<T>& result, const std::string& name) {
  if (result.ok()) return {true, ""};
  return {false, CheckErrorMessage(result.status().message(), name)};
}
TargetResult Judge(const Status& status, const std::string& name) {
  if (status.ok()) return {true, ""};
  return {false, CheckErrorMessage(status.message(), name)};
}

// A problem when an accepted input does not survive its writer and reader.
std::string RoundTrip(const Status& status, const std::string& what) {
  return status.ok() ? "" : "accepted, but " + what + ": " + status.ToString();
}

FuzzSettings Settings() { return FuzzSettings::FromEnvironment(kIterations); }

TargetResult SpotsTarget(const std::string& text) {
  const Result<SpotsCsvData> read = ParseSpotsCsv(text, kName);
  TargetResult r = Judge(read, kName);
  if (!read.ok()) return r;
  if (!read->slices.empty() && read->slices.size() != read->spots.size()) {
    return {true, "slices has " + std::to_string(read->slices.size()) + " entries for " +
                      std::to_string(read->spots.size()) + " spots"};
  }
  const Result<std::string> written = FormatSpotsCsv(read->spots);
  if (!written.ok()) return {true, RoundTrip(written.status(), "FormatSpotsCsv fails")};
  const Result<SpotsCsvData> again = ParseSpotsCsv(*written, kName);
  if (!again.ok()) return {true, RoundTrip(again.status(), "its written form does not read")};
  if (again->spots.size() != read->spots.size()) return {true, "written form has another count"};
  return r;
}

TEST(ReaderFuzz, SpotsCsv) {
  const FuzzStats stats = RunFuzz("spots_csv", InputKind::kText, Settings(),
                                  [](const std::string& in, const std::string&) {
                                    return SpotsTarget(in);
                                  });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, SlicesCsv) {
  const FuzzStats stats = RunFuzz("slices_csv", InputKind::kText, Settings(),
                                  [](const std::string& in, const std::string&) {
                                    return SpotsTarget(in);
                                  });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, PointTable) {
  // Three mappings: the example export's, a comma table with a slice column
  // and extra fields, and whitespace with a skipped header row.
  std::vector<PointTableFormat> formats;
  for (const char* columns : {"id,x,y,z,sx,sy,sz", "source,beam,x,y,z,slice", "-,x,y,z"}) {
    Result<PointTableFormat> f = ParseColumnMapping(columns);
    ASSERT_TRUE(f.ok()) << f.status().ToString();
    formats.push_back(*f);
  }
  formats[0].skip_rows = 2;
  formats[1].delimiter = PointTableFormat::Delimiter::kComma;
  formats[1].allow_extra_fields = true;
  formats[2].delimiter = PointTableFormat::Delimiter::kWhitespace;
  formats[2].skip_rows = 1;
  formats[2].comment = '\0';
  const FuzzStats stats =
      RunFuzz("point_table", InputKind::kText, Settings(),
              [&](const std::string& in, const std::string&) {
                TargetResult all{false, ""};
                for (const PointTableFormat& format : formats) {
                  const TargetResult r = Judge(ParsePointTable(in, kName, format), kName);
                  all.accepted |= r.accepted;
                  if (!r.problem.empty()) return r;
                }
                return all;
              });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, PointsCsv) {
  const FuzzStats stats =
      RunFuzz("points_csv", InputKind::kText, Settings(),
              [](const std::string& in, const std::string&) {
                Result<PointsCsv> read = PointsCsv::Parse(in, kName);
                TargetResult r = Judge(read, kName);
                if (!read.ok()) return r;
                const int n = read->num_points();
                // Written as read (scaling may carry a point beyond the
                // reader's |value| <= 1e12, which is the tool's business).
                const Result<PointsCsv> again = PointsCsv::Parse(read->Format(), kName);
                if (!again.ok()) {
                  return TargetResult{true, RoundTrip(again.status(), "its written form fails")};
                }
                if (again->num_points() != n) return TargetResult{true, "count changed"};
                PointsCsv scaled = *read;
                if (const Status status = scaled.Scale(1.5); !status.ok()) {
                  return TargetResult{true, RoundTrip(status, "Scale(1.5) fails")};
                }
                return r;
              });
  EXPECT_GT(stats.accepted, 0);
}

// PLY (ascii and binary), XYZ and CSV point files, streamed by ScalePointFile
// (opl_measure --apply): the format from the seed's extension; after a
// failure no output (and no temporary file) may be left.
TEST(ReaderFuzz, PointFile) {
  const TempDir dir(std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp");
  ASSERT_FALSE(dir.path().empty());
  const FuzzStats stats = RunFuzz(
      "point_file", InputKind::kText, Settings(),
      [&](const std::string& in, const std::string& seed_name) {
        const std::string ext = std::filesystem::path(seed_name).extension().string();
        const std::string in_path = dir.Write("in" + ext, in);
        const std::string out_path = dir.File("out" + ext);
        ScalePointFileOptions options;
        options.buffer_bytes = 4096;  // the smallest: buffer boundaries inside records
        ScalePointFileSummary summary;
        const Status status = ScalePointFile(in_path, out_path, 1.5, options, &summary);
        TargetResult r = Judge(status, in_path);
        const size_t entries = dir.Entries().size();
        std::filesystem::remove(in_path);
        if (!status.ok() && entries != 1) {
          r.problem = "failed, and left " + std::to_string(entries - 1) + " file(s) beside the input";
        }
        if (status.ok() && !std::filesystem::exists(out_path)) r.problem = "OK but no output";
        std::filesystem::remove(out_path);
        return r;
      });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, CalibrationJson) {
  const FuzzStats stats = RunFuzz(
      "calibration_json", InputKind::kText, Settings(),
      [](const std::string& in, const std::string&) {
        const Result<ModuleCalibration> read = ParseModuleCalibrationJson(in, kName);
        TargetResult r = Judge(read, kName);
        if (!read.ok()) return r;
        const Result<std::string> written = FormatModuleCalibrationJson(*read);
        if (!written.ok()) return TargetResult{true, RoundTrip(written.status(), "Format fails")};
        const Result<ModuleCalibration> again = ParseModuleCalibrationJson(*written, kName);
        if (!again.ok()) r.problem = RoundTrip(again.status(), "its written form fails");
        return r;
      });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, DesignJson) {
  // Relative pattern files resolve against the corpus folder (aux/).
  const std::string base = CorpusDir() + "/design_json";
  const FuzzStats stats = RunFuzz(
      "design_json", InputKind::kText, Settings(),
      [&](const std::string& in, const std::string&) {
        const Result<ModuleDesign> read = ParseModuleDesignJson(in, kName, base);
        TargetResult r = Judge(read, kName);
        if (!read.ok()) return r;
        const Result<std::string> written = FormatModuleDesignJson(*read, base);
        if (!written.ok()) return TargetResult{true, RoundTrip(written.status(), "Format fails")};
        const Result<ModuleDesign> again = ParseModuleDesignJson(*written, kName, base);
        if (!again.ok()) return TargetResult{true, RoundTrip(again.status(), "reading it back")};
        return r;
      });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, PatternCsv) {
  const TempDir dir(std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp");
  const FuzzStats stats =
      RunFuzz("pattern_csv", InputKind::kText, Settings(),
              [&](const std::string& in, const std::string&) {
                const std::string path = dir.Write("pattern.csv", in);
                return Judge(ReadPatternCsv(path), path);
              });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, SceneJson) {
  // The corpus's module files are in scene_json/aux/.
  const std::string base = CorpusDir() + "/scene_json";
  const FuzzStats stats = RunFuzz(
      "scene_json", InputKind::kText, Settings(),
      [&](const std::string& in, const std::string&) {
        const TargetResult render = Judge(ParseSceneJson(in, kName, base, SceneUse::kRender), kName);
        if (!render.problem.empty()) return render;
        const Result<Scene> measure = ParseSceneJson(in, kName, base, SceneUse::kMeasure);
        TargetResult r = Judge(measure, kName);
        if (!measure.ok()) {
          if (render.accepted) r.problem = "accepted to render but not to measure: " +
                                           measure.status().message();
          return r;
        }
        const Result<Scene> again = ParseSceneJson(FormatMeasurementSceneJson(*measure, ""), kName,
                                                   base, SceneUse::kMeasure);
        if (!again.ok()) r.problem = RoundTrip(again.status(), "its measurement form fails");
        return r;
      });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, CamerasJson) {
  const FuzzStats stats = RunFuzz(
      "cameras_json", InputKind::kText, Settings(),
      [](const std::string& in, const std::string&) {
        const Result<std::vector<SceneCamera>> read = ParseCamerasJson(in, kName);
        TargetResult r = Judge(read, kName);
        if (!read.ok()) return r;
        const Result<std::vector<SceneCamera>> again =
            ParseCamerasJson(FormatCamerasJson(*read), kName);
        if (!again.ok()) r.problem = RoundTrip(again.status(), "its written form fails");
        return r;
      });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, BoardJson) {
  const FuzzStats stats = RunFuzz(
      "board_json", InputKind::kText, Settings(),
      [](const std::string& in, const std::string&) {
        const Result<CalibrationBoard> read = ParseBoardJson(in, kName);
        TargetResult r = Judge(read, kName);
        if (!read.ok()) return r;
        const Result<CalibrationBoard> again = ParseBoardJson(FormatBoardJson(*read), kName);
        if (!again.ok()) r.problem = RoundTrip(again.status(), "its written form fails");
        return r;
      });
  EXPECT_GT(stats.accepted, 0);
}

TEST(ReaderFuzz, FrameMetadataJsonl) {
  const FuzzStats stats =
      RunFuzz("frames_jsonl", InputKind::kText, Settings(),
              [](const std::string& in, const std::string&) {
                return Judge(ParseFrameMetadataJsonl(in, kName), kName);
              });
  EXPECT_GT(stats.accepted, 0);
}

// PNG and JPEG shots through ReadShotImage (the image front end's reader):
// a decoded image must be within the documented size limit, 8 or 16 bit.
// Nothing may reach stderr (issue 19 item 7: libpng and libjpeg print their
// warnings there by default; OPL's decoder collects them into
// decode_warnings, which must be safe lines).
TargetResult ImageTarget(const TempDir& dir, const std::string& in, const std::string& ext,
                         int* warned) {
  const std::string path = dir.Write("shot" + ext, in);
  ::testing::internal::CaptureStderr();
  const Result<ShotImage> read = ReadShotImage(path, SpotChannel::kRed);
  const std::string printed = ::testing::internal::GetCapturedStderr();
  TargetResult r = Judge(read, path);
  if (!printed.empty()) {
    r.problem = "the decoder printed on stderr: '" + printed.substr(0, 200) + "'";
    return r;
  }
  if (!read.ok()) return r;
  const cv::Mat& tags = read->for_tags;
  const cv::Mat& spots = read->for_spots;
  if (tags.empty() || tags.size() != spots.size() || tags.channels() != 1 ||
      spots.channels() != 1 || tags.cols > kMaxImageSidePx || tags.rows > kMaxImageSidePx ||
      static_cast<long long>(tags.cols) * tags.rows > kMaxImagePixels ||
      (tags.depth() != CV_8U && tags.depth() != CV_16U)) {
    r.problem = "accepted an image of " + std::to_string(tags.cols) + " x " +
                std::to_string(tags.rows) + " with " + std::to_string(tags.channels()) +
                " channel(s), depth " + std::to_string(tags.depth());
  }
  if (read->decode_warnings.size() > static_cast<size_t>(kMaxDecodeWarnings) + 1) {
    r.problem = std::to_string(read->decode_warnings.size()) + " decode warnings kept";
  }
  for (const std::string& w : read->decode_warnings) {
    if (w.empty() || w.size() > 210 || std::any_of(w.begin(), w.end(), [](char c) {
          return static_cast<unsigned char>(c) < 0x20 || c == 0x7f;
        })) {
      r.problem = "a decode warning is not one safe line: '" + w.substr(0, 80) + "'";
    }
  }
  *warned += read->decode_warnings.empty() ? 0 : 1;
  return r;
}

TEST(ReaderFuzz, Png) {
  const TempDir dir(std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp");
  int warned = 0;
  const FuzzStats stats = RunFuzz("png", InputKind::kImage, Settings(),
                                  [&](const std::string& in, const std::string&) {
                                    return ImageTarget(dir, in, ".png", &warned);
                                  });
  EXPECT_GT(stats.accepted, 0);
  std::printf("  %d accepted with decoder warnings (collected, none printed)\n", warned);
}

TEST(ReaderFuzz, Jpeg) {
  const TempDir dir(std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp");
  int warned = 0;
  const FuzzStats stats = RunFuzz("jpeg", InputKind::kImage, Settings(),
                                  [&](const std::string& in, const std::string&) {
                                    return ImageTarget(dir, in, ".jpg", &warned);
                                  });
  EXPECT_GT(stats.accepted, 0);
  // Mutated JPEGs are mostly damaged but decodable: the warnings must come.
  EXPECT_GT(warned, 0);
  std::printf("  %d accepted with decoder warnings (collected, none printed)\n", warned);
}

}  // namespace
}  // namespace fuzz
}  // namespace opl
