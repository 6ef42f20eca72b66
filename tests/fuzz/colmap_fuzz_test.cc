// Fuzzing the COLMAP sparse-model reader (issue 19: "COLMAP models ... are
// not fuzzed"; docs/testing.md, "Fuzzing"). A small model, in COLMAP's text
// and binary formats, is the seed corpus: each of its six files in turn is
// mutated while the other two files of its format stay intact, and the
// folder goes through ReadColmapModel. It must come back OK or with a
// one-line, bounded message naming the folder (a model is read as a folder);
// nothing may throw, crash or hang. A model it accepts must survive its
// writer: written in the same format and read again.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fuzz/fuzz_harness.h"
#include "io/temp_dir.h"
#include "opl/io/colmap_model.h"

namespace opl {
namespace fuzz {
namespace {

using testing_support::TempDir;

constexpr int kIterations = 300;  // per format, with the six seeds

// Two cameras (one with distortion, one of a model OPL refuses to map but
// must read), three images (one without 2D points, one with a space in its
// name), three points with tracks.
const char* kCamerasTxt =
    "# Camera list with one line of data per camera:\n"
    "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    "1 OPENCV 640 480 500 510 320.5 240.25 -0.1 0.01 0.001 -0.002\n"
    "7 OPENCV_FISHEYE 100 80 90 91 50 40 0.1 0.2 0.3 0.4\n";
const char* kImagesTxt =
    "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
    "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
    "1 0.70710678118654757 0 0 0.70710678118654757 1 2 3 1 shot 01.png\n"
    "10.5 20.25 12 30 40 -1 31 41 13\n"
    "2 1 0 0 0 -1 0 0.5 1 b.png\n"
    "11 21 12 99 98 14\n"
    "4 1 0 0 0 0 0 1 7 c.png\n"
    "\n";
const char* kPoints3DTxt =
    "# 3D point list with one line of data per point:\n"
    "12 1.5 -2 3.25 255 0 17 0.75 1 0 2 0\n"
    "13 0 0 1 1 2 3 -1 1 2\n"
    "14 4 5 6 7 8 9 0.5 2 1\n";

const char* kFileNames[3] = {"cameras", "images", "points3D"};

// The corpus: the model's three text files and the three binary files that
// WriteColmapModel makes of it.
std::vector<CorpusEntry> ModelCorpus() {
  const TempDir text, binary;
  text.Write("cameras.txt", kCamerasTxt);
  text.Write("images.txt", kImagesTxt);
  text.Write("points3D.txt", kPoints3DTxt);
  const Result<ColmapModel> model = ReadColmapModel(text.path());
  EXPECT_TRUE(model.ok()) << model.status().ToString();
  if (!model.ok()) return {};
  const Status written = WriteColmapModel(*model, binary.path(), ColmapFormat::kBinary);
  EXPECT_TRUE(written.ok()) << written.ToString();
  std::vector<CorpusEntry> corpus;
  for (const char* name : kFileNames) {
    corpus.push_back({std::string(name) + ".txt", testing_support::ReadAll(text.File(std::string(name) + ".txt"))});
  }
  for (const char* name : kFileNames) {
    corpus.push_back({std::string(name) + ".bin", testing_support::ReadAll(binary.File(std::string(name) + ".bin"))});
  }
  return corpus;
}

TEST(ColmapFuzz, TextAndBinaryModels) {
  const std::vector<CorpusEntry> corpus = ModelCorpus();
  ASSERT_EQ(corpus.size(), 6u);
  const TempDir dir;
  const FuzzStats stats = RunFuzzOnCorpus(
      "colmap_model", corpus, InputKind::kImage, FuzzSettings::FromEnvironment(kIterations),
      [&](const std::string& in, const std::string& seed_name) {
        // The folder: the mutated file and its format's two other seeds.
        const std::string ext = seed_name.substr(seed_name.size() - 4);
        for (const CorpusEntry& entry : corpus) {
          if (entry.name.size() > 4 && entry.name.substr(entry.name.size() - 4) == ext) {
            dir.Write(entry.name, entry.name == seed_name ? in : entry.bytes);
          }
        }
        const ColmapFormat format = ext == ".txt" ? ColmapFormat::kText : ColmapFormat::kBinary;
        const Result<ColmapModel> read = ReadColmapModel(dir.path(), format);
        TargetResult r;
        if (!read.ok()) {
          r.problem = CheckErrorMessage(read.status().message(), dir.path());
          return r;
        }
        r.accepted = true;
        const TempDir again_dir;
        const Status written = WriteColmapModel(*read, again_dir.path(), format);
        if (!written.ok()) {
          r.problem = "accepted, but the writer fails: " + written.ToString();
          return r;
        }
        const Result<ColmapModel> again = ReadColmapModel(again_dir.path(), format);
        if (!again.ok()) {
          r.problem = "accepted, but its written form fails: " + again.status().ToString();
        } else if (again->cameras.size() != read->cameras.size() ||
                   again->images.size() != read->images.size() ||
                   again->points3D.size() != read->points3D.size()) {
          r.problem = "accepted, but its written form reads back with other counts";
        }
        return r;
      });
  EXPECT_EQ(stats.inputs, 6 + FuzzSettings::FromEnvironment(kIterations).iterations);
  EXPECT_GT(stats.accepted, 6);  // the seeds and some mutations read
  EXPECT_LT(stats.accepted, stats.inputs);  // and some do not
}

}  // namespace
}  // namespace fuzz
}  // namespace opl
