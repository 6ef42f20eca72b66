// Benchmark of laser-spot detection (issue 6): an 18 MP (5472 x 3648) 16-bit
// image with two 11 x 11 grids of spots (242 spots, 1/e^2 diameters 6-14 px,
// peaks 3000-20000 DN, a few saturated), background 1000 DN with a gradient,
// shot noise (gain 1 e/DN) and 8 DN read noise. References in the same run:
// cv::GaussianBlur of the same image (7 x 7, sigma 1) and a plain copy.
// Target: well under 0.5 s per image (the 8-image chain in 10 s on 2 cores).
//   opl_bench --benchmark_filter=Spot --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <cmath>
#include <random>

#include <benchmark/benchmark.h>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "opl/lab/spot_image.h"
#include "opl/sim/random.h"
#include "opl/vision/spot_detection.h"

namespace {

const cv::Mat& BenchImage() {
  static const cv::Mat image = [] {
    std::vector<opl::SpotToRender> spots;
    std::mt19937_64 rng(2026);
    auto grid = [&](double cu, double cv, double spacing, double angle) {
      for (int r = -5; r <= 5; ++r) {
        for (int c = -5; c <= 5; ++c) {
          opl::SpotToRender s;
          s.u_px = cu + spacing * (c * std::cos(angle) - r * std::sin(angle)) + opl::Uniform01(rng);
          s.v_px = cv + spacing * (c * std::sin(angle) + r * std::cos(angle)) + opl::Uniform01(rng);
          const double d = 6.0 + 8.0 * opl::Uniform01(rng);
          s.shape_covariance_px2 =
              opl::EllipticalSpotShape(d, d * (0.7 + 0.3 * opl::Uniform01(rng)),
                                       opl::kPi * opl::Uniform01(rng));
          s.peak_dn = 3000.0 + 17000.0 * opl::Uniform01(rng);
          if (r == 0 && c == 0) s.peak_dn = 150000.0;  // central (zeroth-order) beam saturates
          spots.push_back(s);
        }
      }
    };
    grid(1800.0, 1824.0, 200.0, 0.0);
    grid(4000.0, 1824.0, 200.0, 0.1);
    opl::SpotImageOptions o;
    o.width_px = 5472;
    o.height_px = 3648;
    o.background_dn = 1000.0;
    o.background_gradient_u_dn_per_px = 0.05;
    o.gain_e_per_dn = 1.0;
    o.read_noise_dn = 8.0;
    o.seed = 6;
    auto r = opl::RenderSpotImage(spots, o);
    return r.ok() ? r->image : cv::Mat();
  }();
  return image;
}

void BM_SpotDetection18MP(benchmark::State& state) {
  const cv::Mat& image = BenchImage();
  size_t found = 0;
  for (auto _ : state) {
    auto r = opl::DetectSpots(image);
    found = r.ok() ? r->spots.size() : 0;
    benchmark::DoNotOptimize(r);
  }
  state.counters["spots"] = static_cast<double>(found);
}
BENCHMARK(BM_SpotDetection18MP)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SpotReferenceGaussianBlur18MP(benchmark::State& state) {
  const cv::Mat& image = BenchImage();
  cv::Mat out;
  for (auto _ : state) {
    cv::GaussianBlur(image, out, cv::Size(7, 7), 1.0);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_SpotReferenceGaussianBlur18MP)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SpotReferenceCopy18MP(benchmark::State& state) {
  const cv::Mat& image = BenchImage();
  cv::Mat out;
  for (auto _ : state) {
    image.copyTo(out);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_SpotReferenceCopy18MP)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
