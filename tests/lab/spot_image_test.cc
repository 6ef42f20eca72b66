// RenderSpotImage against closed forms: flux 2 pi sqrt(det C) A, centroid =
// centre, second moments = C + I/12 (pixel box), saturation, noise
// variance L / gain + read^2, speckle statistics, seeds.
#include "opl/lab/spot_image.h"

#include <cmath>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "opl/core/format.h"

namespace opl {
namespace {

struct Moments {
  double sum = 0, u = 0, v = 0;
  Eigen::Matrix2d second = Eigen::Matrix2d::Zero();
};

// Independent moments of a CV_32F image minus a constant background.
Moments ImageMoments(const cv::Mat& f, double background) {
  Moments m;
  double su = 0, sv = 0, suu = 0, suv = 0, svv = 0;
  for (int y = 0; y < f.rows; ++y) {
    for (int x = 0; x < f.cols; ++x) {
      const double w = f.at<float>(y, x) - background;
      m.sum += w;
      su += w * x;
      sv += w * y;
      suu += w * x * x;
      suv += w * x * y;
      svv += w * y * y;
    }
  }
  m.u = su / m.sum;
  m.v = sv / m.sum;
  m.second << suu / m.sum - m.u * m.u, suv / m.sum - m.u * m.v, suv / m.sum - m.u * m.v,
      svv / m.sum - m.v * m.v;
  return m;
}

SpotImageOptions CleanOptions(int w, int h) {
  SpotImageOptions o;
  o.width_px = w;
  o.height_px = h;
  o.background_dn = 0.0;
  o.keep_clean = true;
  return o;
}

TEST(SpotImage, RoundSpotFluxAndCentroid) {
  for (double diameter : {5.0, 8.0, 15.0}) {
    SpotToRender s;
    s.u_px = 100.3;
    s.v_px = 80.71;
    s.shape_covariance_px2 = RoundSpotShape(diameter);
    s.peak_dn = 1000.0;
    auto r = RenderSpotImage({s}, CleanOptions(200, 160));
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const double sigma = diameter / 4.0;
    const double flux = 2 * kPi * sigma * sigma * s.peak_dn;
    const Moments m = ImageMoments(r->clean_dn, 0.0);
    EXPECT_NEAR(m.sum / flux, 1.0, 1e-5) << diameter;
    EXPECT_NEAR(r->spots[0].flux_dn / flux, 1.0, 1e-5);
    EXPECT_NEAR(m.u, s.u_px, 1e-5);
    EXPECT_NEAR(m.v, s.v_px, 1e-5);
    // Pixel integration adds the box's variance 1/12 per axis.
    EXPECT_NEAR(m.second(0, 0), sigma * sigma + 1.0 / 12.0, 1e-3);
    EXPECT_NEAR(m.second(1, 1), sigma * sigma + 1.0 / 12.0, 1e-3);
    EXPECT_NEAR(m.second(0, 1), 0.0, 1e-4);
    // Peak pixel: the erf product at the nearest pixel, an independent formula.
    const int px = 100, py = 81;
    auto integral = [&](double c, int p) {
      return 0.5 * (std::erf((p + 0.5 - c) / (std::sqrt(2.0) * sigma)) -
                    std::erf((p - 0.5 - c) / (std::sqrt(2.0) * sigma)));
    };
    const double expected = flux * integral(s.u_px, px) * integral(s.v_px, py);
    EXPECT_NEAR(r->clean_dn.at<float>(py, px), expected, 1e-4 * expected);
  }
}

TEST(SpotImage, EllipticalSpotMoments) {
  // Rotated (supersampled) and axis-aligned (erf) paths, small and large.
  struct Case {
    double major, minor, angle;
  };
  for (const Case& c : {Case{12.0, 6.0, 0.5}, Case{6.0, 2.0, -1.1}, Case{9.0, 5.0, 0.0}}) {
    SpotToRender s;
    s.u_px = 60.37;
    s.v_px = 50.82;
    s.shape_covariance_px2 = EllipticalSpotShape(c.major, c.minor, c.angle);
    s.peak_dn = 500.0;
    auto r = RenderSpotImage({s}, CleanOptions(120, 100));
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const Eigen::Matrix2d& C = s.shape_covariance_px2;
    // Closed form of the shape: the rotated diagonal of sigma^2 = (D/4)^2.
    const double s1 = c.major / 4, s2 = c.minor / 4;
    EXPECT_NEAR(C(0, 0), s1 * s1 * std::cos(c.angle) * std::cos(c.angle) +
                             s2 * s2 * std::sin(c.angle) * std::sin(c.angle), 1e-12);
    EXPECT_NEAR(C.determinant(), s1 * s1 * s2 * s2, 1e-9);
    const Moments m = ImageMoments(r->clean_dn, 0.0);
    const double flux = 2 * kPi * std::sqrt(C.determinant()) * s.peak_dn;
    EXPECT_NEAR(m.sum / flux, 1.0, 1e-5) << c.major << " " << c.minor;
    EXPECT_NEAR(m.u, s.u_px, 1e-5);
    EXPECT_NEAR(m.v, s.v_px, 1e-5);
    const Eigen::Matrix2d expected = C + Eigen::Matrix2d::Identity() / 12.0;
    EXPECT_LT((m.second - expected).cwiseAbs().maxCoeff(), 2e-4)
        << "moments\n" << m.second << "\nexpected\n" << expected;
    // Pixels near the centre against a brute-force 600 x 600 midpoint sum.
    const Eigen::Matrix2d P = C.inverse();
    for (const auto& [px, py] : {std::pair<int, int>{60, 51}, {61, 50}, {58, 52}}) {
      double sum = 0;
      const int n = 600;
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          const Eigen::Vector2d d(px - 0.5 + (b + 0.5) / n - s.u_px, py - 0.5 + (a + 0.5) / n - s.v_px);
          sum += std::exp(-0.5 * d.dot(P * d));
        }
      }
      const double brute = s.peak_dn * sum / (n * n);
      EXPECT_NEAR(r->clean_dn.at<float>(py, px), brute, 1e-5 * brute + 1e-4) << px << " " << py;
    }
  }
}

TEST(SpotImage, SaturationClipsAndIsReported) {
  SpotImageOptions o = CleanOptions(80, 60);
  o.bit_depth = 8;
  o.background_dn = 10.0;
  SpotToRender s;
  s.u_px = 40.2;
  s.v_px = 30.6;
  s.shape_covariance_px2 = RoundSpotShape(10.0);
  s.peak_dn = 3.0 * SpotImageFullScale(o);
  auto r = RenderSpotImage({s}, o);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->image.type(), CV_8UC1);
  double max_value = 0;
  cv::minMaxLoc(r->image, nullptr, &max_value);
  EXPECT_EQ(max_value, 255.0);
  // Without noise a pixel saturates iff its clean value rounds to >= 255.
  int expected = 0;
  for (int y = 0; y < o.height_px; ++y) {
    for (int x = 0; x < o.width_px; ++x) {
      const double clean = r->clean_dn.at<float>(y, x);
      if (std::round(clean) >= 255.0) ++expected;
      EXPECT_EQ(r->image.at<uint8_t>(y, x), static_cast<uint8_t>(std::min(255.0, std::round(clean))));
    }
  }
  EXPECT_GT(expected, 10);
  EXPECT_EQ(r->saturated_pixels, expected);
  EXPECT_EQ(r->spots[0].saturated_pixels, expected);
  // Closed form: pixels whose centre is within the radius where the Gaussian
  // reaches 255 - 10 DN (the pixel average is slightly below the centre value).
  const double sigma = 2.5;
  const double radius = sigma * std::sqrt(2 * std::log(s.peak_dn / 245.0));
  EXPECT_NEAR(expected, kPi * radius * radius, 0.15 * kPi * radius * radius);
}

TEST(SpotImage, FlatFieldNoiseStatistics) {
  struct Case {
    double level, gain, read;
  };
  // PTRS path (500 and 2000 electrons), Knuth path (3 electrons), read only.
  for (const Case& c : {Case{1000, 2.0, 5.0}, Case{1000, 0.5, 0.0}, Case{3, 1.0, 0.0},
                        Case{500, 0.0, 7.0}}) {
    SpotImageOptions o;
    o.width_px = 400;
    o.height_px = 400;
    o.background_dn = c.level;
    o.gain_e_per_dn = c.gain;
    o.read_noise_dn = c.read;
    o.seed = 7;
    auto r = RenderSpotImage({}, o);
    ASSERT_TRUE(r.ok());
    cv::Mat f;
    r->image.convertTo(f, CV_64F);
    cv::Scalar mean, stddev;
    cv::meanStdDev(f, mean, stddev);
    // Rounding to integers adds 1/12 DN^2 unless the values are integers
    // already (gain 1 without read noise).
    const double quantisation = (c.gain == 1.0 && c.read == 0.0) ? 0.0 : 1.0 / 12.0;
    const double variance = (c.gain > 0 ? c.level / c.gain : 0.0) + c.read * c.read + quantisation;
    EXPECT_NEAR(mean[0], c.level, 0.02 + 4 * std::sqrt(variance / 160000.0)) << c.level;
    EXPECT_NEAR(stddev[0] * stddev[0] / variance, 1.0, 0.02)
        << "level " << c.level << " gain " << c.gain << " read " << c.read;
  }
}

TEST(SpotImage, BackgroundGradient) {
  SpotImageOptions o;
  o.width_px = 101;
  o.height_px = 51;
  o.background_dn = 1000;
  o.background_gradient_u_dn_per_px = 2.0;
  o.background_gradient_v_dn_per_px = -3.0;
  auto r = RenderSpotImage({}, o);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->image.at<uint16_t>(0, 0), 1000 - 2 * 50 + 3 * 25);
  EXPECT_EQ(r->image.at<uint16_t>(50, 100), 1000 + 2 * 50 - 3 * 25);
  EXPECT_EQ(r->image.at<uint16_t>(25, 50), 1000);
}

// Lag-k autocorrelation coefficient of a CV_64F field along u.
double AutocorrelationU(const cv::Mat& f, int lag) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(f, mean, stddev);
  double s = 0;
  int n = 0;
  for (int y = 0; y < f.rows; ++y) {
    for (int x = 0; x + lag < f.cols; ++x) {
      s += (f.at<double>(y, x) - mean[0]) * (f.at<double>(y, x + lag) - mean[0]);
      ++n;
    }
  }
  return s / n / (stddev[0] * stddev[0]);
}

TEST(SpotImage, SpeckleFieldStatistics) {
  const double grain = 1.5;
  auto r = RenderSpeckleField(600, 600, grain, 3);
  ASSERT_TRUE(r.ok());
  cv::Scalar mean, stddev;
  cv::meanStdDev(*r, mean, stddev);
  EXPECT_NEAR(mean[0], 1.0, 0.03);
  EXPECT_NEAR(stddev[0] / mean[0], 1.0, 0.05);  // fully developed: contrast 1
  // Intensity correlation exp(-r^2 / (2 grain^2)).
  for (int lag : {1, 2, 3}) {
    EXPECT_NEAR(AutocorrelationU(*r, lag), std::exp(-lag * lag / (2 * grain * grain)), 0.04)
        << "lag " << lag;
  }
  // Exponential statistics: P(S > 2) = exp(-2).
  const double above = cv::countNonZero(*r > 2.0) / (600.0 * 600.0);
  EXPECT_NEAR(above, std::exp(-2.0), 0.01);
  EXPECT_FALSE(RenderSpeckleField(0, 10, 1.0, 1).ok());
  EXPECT_FALSE(RenderSpeckleField(10, 10, 0.0, 1).ok());
}

TEST(SpotImage, SpeckleOnASpotHasTheGivenContrast) {
  // A broad spot; the ratio of its speckled to its clean light is 1 - c + c S.
  SpotToRender s;
  s.u_px = 150;
  s.v_px = 150;
  s.shape_covariance_px2 = RoundSpotShape(240.0);
  s.peak_dn = 1000.0;
  SpotImageOptions o = CleanOptions(300, 300);
  const auto clean = RenderSpotImage({s}, o);
  o.speckle_contrast = 0.5;
  o.speckle_grain_px = 1.5;
  const auto speckled = RenderSpotImage({s}, o);
  ASSERT_TRUE(clean.ok() && speckled.ok());
  cv::Mat ratio = speckled->clean_dn / clean->clean_dn;
  cv::Scalar mean, stddev;
  cv::meanStdDev(ratio, mean, stddev);
  EXPECT_NEAR(mean[0], 1.0, 0.02);
  EXPECT_NEAR(stddev[0], 0.5, 0.03);
  double min_ratio = 0;
  cv::minMaxLoc(ratio, &min_ratio);
  EXPECT_GE(min_ratio, 0.5 - 1e-6);  // 1 - c + c S with S >= 0
}

TEST(SpotImage, SeedsRepeat) {
  SpotToRender s;
  s.u_px = 50.5;
  s.v_px = 40.2;
  s.shape_covariance_px2 = RoundSpotShape(8.0);
  s.peak_dn = 3000;
  SpotImageOptions o;
  o.width_px = 100;
  o.height_px = 80;
  o.speckle_contrast = 0.5;
  o.gain_e_per_dn = 1.0;
  o.read_noise_dn = 3.0;
  o.seed = 11;
  const auto a = RenderSpotImage({s}, o);
  const auto b = RenderSpotImage({s}, o);
  o.seed = 12;
  const auto c = RenderSpotImage({s}, o);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(cv::norm(a->image, b->image, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a->image, c->image, cv::NORM_INF), 0.0);
}

TEST(SpotImage, WindowIsLimitedAndSpotsOutsideAreFine) {
  SpotToRender s;
  s.u_px = 20;
  s.v_px = 20;
  s.shape_covariance_px2 = RoundSpotShape(8.0);  // sigma 2: window +-10 px
  SpotToRender outside = s;
  outside.u_px = -100;
  auto r = RenderSpotImage({s, outside}, CleanOptions(60, 60));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->spots[0].window, cv::Rect(10, 10, 21, 21));
  EXPECT_EQ(r->spots[1].window.area(), 0);
  EXPECT_EQ(r->clean_dn.at<float>(20, 31), 0.0f);
  EXPECT_GT(r->clean_dn.at<float>(20, 30), 0.0f);
}

TEST(SpotImage, RejectsBadInput) {
  SpotImageOptions o;
  o.bit_depth = 12;
  auto r = RenderSpotImage({}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("bit_depth = 12"), std::string::npos) << r.status().message();
  o = SpotImageOptions();
  o.speckle_contrast = 1.5;
  EXPECT_FALSE(o.Validate().ok());
  o = SpotImageOptions();
  o.read_noise_dn = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = SpotImageOptions();
  o.width_px = 0;
  EXPECT_FALSE(o.Validate().ok());
  EXPECT_TRUE(SpotImageOptions().Validate().ok());

  SpotToRender bad;
  bad.shape_covariance_px2 << 1.0, 2.0, 2.0, 1.0;  // not positive definite
  r = RenderSpotImage({SpotToRender(), bad}, SpotImageOptions());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("spot 1:"), std::string::npos) << r.status().message();
  bad = SpotToRender();
  bad.peak_dn = -5;
  EXPECT_FALSE(RenderSpotImage({bad}, SpotImageOptions()).ok());
  bad = SpotToRender();
  bad.u_px = std::nan("");
  EXPECT_FALSE(RenderSpotImage({bad}, SpotImageOptions()).ok());
}

}  // namespace
}  // namespace opl
