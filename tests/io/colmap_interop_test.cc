// OPL's COLMAP model files against COLMAP itself (`colmap model_converter`,
// `colmap model_analyzer`): COLMAP reads what OPL writes, in both formats, and
// OPL reads what COLMAP writes. Skipped when colmap is not on PATH.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "opl/io/colmap_model.h"
#include "support/colmap_cli.h"

namespace opl {
namespace {

using testing_support::RunColmap;
using testing_support::TempDir;
using ::testing::HasSubstr;

// Two cameras, three images, three points; values that need 17 digits.
ColmapModel TinyModel() {
  ColmapModel m;
  ColmapCamera c1;
  c1.camera_id = 1;
  c1.model_id = kColmapOpenCv;
  c1.width_px = 640;
  c1.height_px = 480;
  c1.params = {500.0 + 1.0 / 3.0, 501.25, 320.5, 240.125, -0.0625, 0.01, 1e-4, -2e-4};
  ColmapCamera c2;
  c2.camera_id = 5;
  c2.model_id = kColmapSimpleRadial;
  c2.width_px = 100;
  c2.height_px = 80;
  c2.params = {90, 50, 40, -1.0 / 7.0};
  m.cameras = {{1, c1}, {5, c2}};
  for (uint32_t id : {2u, 3u, 9u}) {
    ColmapImage image;
    image.image_id = id;
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * id, Eigen::Vector3d(1, 2, 3).normalized()));
    image.qvec_wxyz = {q.w(), q.x(), q.y(), q.z()};
    image.tvec = Eigen::Vector3d(id / 3.0, -1.0 / id, 0.5);
    image.camera_id = id == 9 ? 5 : 1;
    image.name = "img_" + std::to_string(id) + ".png";
    m.images[id] = image;
  }
  for (uint64_t id : {4u, 8u, 100u}) {
    ColmapPoint3D point;
    point.point3D_id = id;
    point.xyz_in_world = Eigen::Vector3d(id / 7.0, -(id / 11.0), 1.0 + id / 13.0);
    point.rgb = {static_cast<uint8_t>(id), 7, 255};
    point.error_px = 0.1 * static_cast<double>(id) / 3.0;
    m.points3D[id] = point;
  }
  // Observations: point 4 in images 2 and 3, point 8 in images 3 and 9,
  // point 100 in image 2; each image also has a 2D point without a 3D point.
  const auto observe = [&](uint32_t image_id, uint64_t point_id, double x, double y) {
    ColmapImage& image = m.images[image_id];
    image.points2D.push_back({Eigen::Vector2d(x, y), point_id});
    if (point_id != kColmapNoPoint3D) {
      m.points3D[point_id].track.push_back(
          {image_id, static_cast<uint32_t>(image.points2D.size() - 1)});
    }
  };
  observe(2, 4, 10.0 / 3.0, 20.5);
  observe(2, kColmapNoPoint3D, 1.5, 2.5);
  observe(2, 100, 100.125, 200.0 / 9.0);
  observe(3, 4, 11.0 / 3.0, 21.5);
  observe(3, 8, 300.0, 400.0 / 3.0);
  observe(9, kColmapNoPoint3D, 0.5, 0.5);
  observe(9, 8, 33.0, 44.0 / 7.0);
  return m;
}

// Every field equal, exactly, except qvec: COLMAP normalises it when reading
// (to within a few ulp of our unit quaternion).
void ExpectSameModel(const ColmapModel& a, const ColmapModel& b) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (const auto& [id, c] : a.cameras) {
    const ColmapCamera& d = b.cameras.at(id);
    EXPECT_EQ(c.model_id, d.model_id);
    EXPECT_EQ(c.width_px, d.width_px);
    EXPECT_EQ(c.height_px, d.height_px);
    EXPECT_EQ(c.params, d.params) << "camera " << id;
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (const auto& [id, i] : a.images) {
    const ColmapImage& j = b.images.at(id);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(i.qvec_wxyz[k], j.qvec_wxyz[k], 1e-15) << id;
    EXPECT_EQ(i.tvec, j.tvec) << "image " << id;
    EXPECT_EQ(i.camera_id, j.camera_id);
    EXPECT_EQ(i.name, j.name);
    ASSERT_EQ(i.points2D.size(), j.points2D.size());
    for (size_t k = 0; k < i.points2D.size(); ++k) {
      EXPECT_EQ(i.points2D[k].xy_px, j.points2D[k].xy_px);
      EXPECT_EQ(i.points2D[k].point3D_id, j.points2D[k].point3D_id);
    }
  }
  ASSERT_EQ(a.points3D.size(), b.points3D.size());
  for (const auto& [id, p] : a.points3D) {
    const ColmapPoint3D& q = b.points3D.at(id);
    EXPECT_EQ(p.xyz_in_world, q.xyz_in_world) << "point " << id;
    EXPECT_EQ(p.rgb, q.rgb);
    EXPECT_EQ(p.error_px, q.error_px);
    ASSERT_EQ(p.track.size(), q.track.size());
    for (size_t k = 0; k < p.track.size(); ++k) {
      EXPECT_EQ(p.track[k].image_id, q.track[k].image_id);
      EXPECT_EQ(p.track[k].point2D_idx, q.track[k].point2D_idx);
    }
  }
}

class ColmapInterop : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!testing_support::ColmapOnPath()) GTEST_SKIP() << "colmap is not on PATH";
  }
};

TEST_F(ColmapInterop, ColmapReadsOurBinaryAndWeReadItsText) {
  TempDir dir;
  const ColmapModel model = TinyModel();
  ASSERT_TRUE(model.Validate().ok()) << model.Validate().ToString();
  ASSERT_TRUE(WriteColmapModel(model, dir.File("ours_bin"), ColmapFormat::kBinary).ok());
  std::filesystem::create_directory(dir.File("colmap_txt"));
  const testing_support::ColmapRun run =
      RunColmap("model_converter --input_path '" + dir.File("ours_bin") + "' --output_path '" +
                dir.File("colmap_txt") + "' --output_type TXT");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  Result<ColmapModel> theirs = ReadColmapModel(dir.File("colmap_txt"));
  ASSERT_TRUE(theirs.ok()) << theirs.status().ToString();
  EXPECT_EQ(theirs->format, ColmapFormat::kText);
  ExpectSameModel(model, *theirs);
}

// COLMAP writes its records in its own (hash map) order, so the files are
// compared as models, not byte for byte.
TEST_F(ColmapInterop, WeReadTheBinaryColmapWritesFromOurText) {
  TempDir dir;
  const ColmapModel model = TinyModel();
  ASSERT_TRUE(WriteColmapModel(model, dir.File("ours_txt"), ColmapFormat::kText).ok());
  std::filesystem::create_directory(dir.File("colmap_bin"));
  const testing_support::ColmapRun run =
      RunColmap("model_converter --input_path '" + dir.File("ours_txt") + "' --output_path '" +
                dir.File("colmap_bin") + "' --output_type BIN");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  Result<ColmapModel> theirs = ReadColmapModel(dir.File("colmap_bin"));
  ASSERT_TRUE(theirs.ok()) << theirs.status().ToString();
  EXPECT_EQ(theirs->format, ColmapFormat::kBinary);
  ExpectSameModel(model, *theirs);
}

TEST_F(ColmapInterop, ModelAnalyzerReadsWhatWeWrite) {
  TempDir dir;
  ASSERT_TRUE(WriteColmapModel(TinyModel(), dir.File("m"), ColmapFormat::kText).ok());
  const testing_support::ColmapRun run = RunColmap("model_analyzer --path '" + dir.File("m") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_THAT(run.output, HasSubstr("Cameras: 2"));
  EXPECT_THAT(run.output, HasSubstr("Registered images: 3"));
  EXPECT_THAT(run.output, HasSubstr("Points: 3"));
  EXPECT_THAT(run.output, HasSubstr("Observations: 5"));
}

}  // namespace
}  // namespace opl
