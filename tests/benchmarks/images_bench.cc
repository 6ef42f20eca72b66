// Benchmark of the image front end (issue 6): examples/scene_18mp.json, four
// 18 MP cameras (4912 x 3684) at about 3 m, two grids shot one at a time:
// 8 images to a scale factor on 2 threads (target: 10 s wall), and the
// detection alone per image (spots; tags: target 150 ms on 2 threads, with
// libapriltag-only and aruco-only candidates as references). The images are rendered once into
// a cache folder ($TMPDIR/opl_bench_scene_18mp; rendering is not timed and
// takes about a minute the first time).
//
// References in the same run: reading the 8 PNGs alone (the floor of any
// front end), and a Gaussian blur of one image (the cost of one pass over
// 18 MP).
#include <cstdlib>
#include <filesystem>
#include <string>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/sim/module_design.h"
#include "opl/vision/spot_detection.h"
#include "opl/vision/tag_detection.h"

namespace opl {
namespace {

struct Fixture {
  Scene scene;
  ModuleCalibration calibration;
  std::string dir;
  bool ok = false;
};

const Fixture& Scene18Mp() {
  static const Fixture fixture = [] {
    Fixture f;
    const char* src = std::getenv("OPL_SOURCE_DIR");
    const std::string source_dir = src ? src : OPL_BENCH_SOURCE_DIR;
    Result<Scene> scene = ReadSceneJson(source_dir + "/examples/scene_18mp.json");
    if (!scene.ok()) {
      std::fprintf(stderr, "images_bench: %s\n", scene.status().ToString().c_str());
      return f;
    }
    f.scene = *scene;
    Result<ModuleCalibration> cal = ExactCalibration(*f.scene.module);
    if (!cal.ok()) return f;
    f.calibration = *cal;
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / "opl_bench_scene_18mp";
    std::filesystem::create_directories(dir);
    Result<SceneRenderer> renderer = SceneRenderer::Create(f.scene);
    if (!renderer.ok()) return f;
    for (size_t i = 0; i < f.scene.shots.size(); ++i) {
      const std::filesystem::path file = dir / f.scene.shots[i].file;
      if (std::filesystem::exists(file)) continue;
      Result<RenderedShot> shot = renderer->RenderShot(static_cast<int>(i));
      if (!shot.ok() || !cv::imwrite(file.string() + ".tmp.png", shot->image)) return f;
      std::filesystem::rename(file.string() + ".tmp.png", file);
    }
    f.dir = dir.string();
    f.ok = true;
    return f;
  }();
  return fixture;
}

void BM_Scene18MP_ImagesToScale(benchmark::State& state) {
  const Fixture& f = Scene18Mp();
  if (!f.ok) {
    state.SkipWithError("scene_18mp could not be rendered");
    return;
  }
  ImageMeasureOptions options;
  options.front_end.num_threads = 2;
  double s = 0.0;
  for (auto _ : state) {
    Result<ImageMeasureReport> r = MeasureScaleFromImages(f.scene, f.dir, f.calibration, options);
    if (!r.ok()) {
      state.SkipWithError(r.status().ToString().c_str());
      return;
    }
    s = r->measure.scale.scale_factor;
    if (std::getenv("OPL_BENCH_VERBOSE")) std::fprintf(stderr, "%s", r->ToText().c_str());
    benchmark::DoNotOptimize(s);
  }
  state.counters["s_minus_1_ppm"] = (s - 1.0) * 1e6;
}
BENCHMARK(BM_Scene18MP_ImagesToScale)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

cv::Mat FirstImage() {
  const Fixture& f = Scene18Mp();
  if (!f.ok) return cv::Mat();
  return cv::imread(f.dir + "/" + f.scene.shots[0].file, cv::IMREAD_UNCHANGED);
}

void BM_Scene18MP_SpotDetectionPerImage(benchmark::State& state) {
  const cv::Mat image = FirstImage();
  if (image.empty()) {
    state.SkipWithError("no image");
    return;
  }
  size_t n = 0;
  for (auto _ : state) {
    Result<SpotDetectionResult> r = DetectSpots(image);
    n = r.ok() ? r->spots.size() : 0;
  }
  state.counters["spots"] = static_cast<double>(n);
}
BENCHMARK(BM_Scene18MP_SpotDetectionPerImage)->Unit(benchmark::kMillisecond)->UseRealTime();

// Tags per image on 2 threads (libapriltag's nthreads; OpenCV's own pool for
// aruco), with the references: libapriltag's candidates alone, aruco's alone
// (the detector before issue 17), each refined by the edge fit.
void TagDetectionPerImage(benchmark::State& state, bool use_apriltag, bool use_aruco) {
  const cv::Mat image = FirstImage();
  if (image.empty()) {
    state.SkipWithError("no image");
    return;
  }
  TagDetectionOptions options;
  options.num_threads = 2;
  options.use_apriltag = use_apriltag;
  options.use_aruco = use_aruco;
  size_t n = 0;
  for (auto _ : state) {
    Result<std::vector<TagDetection>> r = DetectTags(image, options);
    n = r.ok() ? r->size() : 0;
  }
  state.counters["tags"] = static_cast<double>(n);
}
void BM_Scene18MP_TagDetectionPerImage(benchmark::State& state) {
  const TagDetectionOptions defaults;
  TagDetectionPerImage(state, defaults.use_apriltag, defaults.use_aruco);
}
BENCHMARK(BM_Scene18MP_TagDetectionPerImage)->Unit(benchmark::kMillisecond)->UseRealTime();
void BM_Scene18MP_TagDetectionPerImage_AprilTagOnly(benchmark::State& state) {
  TagDetectionPerImage(state, true, false);
}
BENCHMARK(BM_Scene18MP_TagDetectionPerImage_AprilTagOnly)->Unit(benchmark::kMillisecond)->UseRealTime();
void BM_Scene18MP_TagDetectionPerImage_ArucoOnly(benchmark::State& state) {
  TagDetectionPerImage(state, false, true);
}
BENCHMARK(BM_Scene18MP_TagDetectionPerImage_ArucoOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Scene18MP_ReferenceReadEightPngs(benchmark::State& state) {
  const Fixture& f = Scene18Mp();
  if (!f.ok) {
    state.SkipWithError("no images");
    return;
  }
  for (auto _ : state) {
    for (const SceneShot& shot : f.scene.shots) {
      cv::Mat m = cv::imread(f.dir + "/" + shot.file, cv::IMREAD_UNCHANGED);
      benchmark::DoNotOptimize(m.data);
    }
  }
}
BENCHMARK(BM_Scene18MP_ReferenceReadEightPngs)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace opl
