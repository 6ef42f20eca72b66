#include "opl/locate/locate_source.h"

#include <algorithm>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"
#include "support/synthetic_source.h"

namespace opl {
namespace {

constexpr double kFullAngle = 29.0 * M_PI / 180.0;

Rigid3d RandomPose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1000.0, 1000.0);
  return Rigid3d(test::RandomRotation(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)));
}

void DropRandom(std::vector<SpotObservation>* spots, double fraction, std::mt19937_64& rng) {
  std::shuffle(spots->begin(), spots->end(), rng);
  spots->resize(spots->size() - static_cast<size_t>(fraction * spots->size()));
}

TEST(LocateSource, NoiseFreeAnyRotationPlanarAndMissingSpots) {
  std::mt19937_64 rng(31);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  std::uniform_real_distribution<double> tilt(-0.8, 0.8), dist(300.0, 3000.0);
  double worst_origin = 0.0, worst_rot = 0.0;
  for (int trial = 0; trial < 300; ++trial) {
    const Rigid3d truth = RandomPose(rng);
    auto spots = test::SpotsOnPlane(pattern, truth, dist(rng), tilt(rng), 0.0, rng);
    DropRandom(&spots, 0.3, rng);
    auto result = LocateSource(pattern, spots);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    worst_origin = std::max(worst_origin,
                            (result->scene_from_source.translation - truth.translation).norm());
    worst_rot = std::max(worst_rot, RotationAngleBetweenRad(result->scene_from_source.RotationMatrix(),
                                                            truth.RotationMatrix()));
    EXPECT_EQ(result->num_inliers, result->num_spots);
  }
  EXPECT_LT(worst_origin, 1e-6);
  EXPECT_LT(worst_rot, 1e-9);
}

TEST(LocateSource, NoiseFreeNonPlanarPoints) {
  // Each spot at its own random range along its ray: any surface will do.
  std::mt19937_64 rng(32);
  const BeamPattern pattern = test::TangentLatticePattern(7, 0.6);
  std::uniform_real_distribution<double> range(200.0, 5000.0);
  for (int trial = 0; trial < 100; ++trial) {
    const Rigid3d truth = RandomPose(rng);
    std::vector<SpotObservation> spots;
    for (const Beam& b : pattern.beams()) {
      spots.push_back({b.id, truth * (range(rng) * b.DirectionInSource()), std::nullopt});
    }
    auto result = LocateSource(pattern, spots);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    EXPECT_LT((result->scene_from_source.translation - truth.translation).norm(), 1e-6);
    EXPECT_LT(RotationAngleBetweenRad(result->scene_from_source.RotationMatrix(), truth.RotationMatrix()),
              1e-9);
  }
}

// 1000 seeded noisy trials: the empirical spread of the origin agrees with the
// reported first-order standard deviation within 10%.
TEST(LocateSource, ReportedUncertaintyMatchesEmpiricalSpread) {
  std::mt19937_64 rng(33);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  const Rigid3d truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, -2, 0.5).normalized())),
                      Eigen::Vector3d(100, 200, -50));
  const int trials = 1000;
  std::vector<Eigen::Vector3d> errors;
  Eigen::Vector3d reported_var = Eigen::Vector3d::Zero();
  for (int trial = 0; trial < trials; ++trial) {
    auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.3, 0.1, rng);
    auto result = LocateSource(pattern, spots);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    errors.push_back(result->scene_from_source.translation - truth.translation);
    reported_var += result->origin_covariance.diagonal();
    EXPECT_TRUE(result->weighted);
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& e : errors) mean += e;
  mean /= trials;
  Eigen::Vector3d var = Eigen::Vector3d::Zero();
  for (const auto& e : errors) var += (e - mean).cwiseAbs2();
  var /= (trials - 1);
  reported_var /= trials;
  for (int k = 0; k < 3; ++k) {
    const double ratio = std::sqrt(var(k) / reported_var(k));
    EXPECT_NEAR(ratio, 1.0, 0.10) << "axis " << k << ": empirical " << std::sqrt(var(k))
                                  << " reported " << std::sqrt(reported_var(k));
    // The estimate is unbiased to well within its spread.
    EXPECT_LT(std::abs(mean(k)), 4.0 * std::sqrt(var(k) / trials));
  }
}

TEST(LocateSource, UnweightedCovarianceIsScaledByVarianceFactor) {
  std::mt19937_64 rng(34);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  const Rigid3d truth = RandomPose(rng);
  auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.0, 0.1, rng);
  auto weighted = LocateSource(pattern, spots);
  for (auto& s : spots) s.cov_in_scene.reset();
  auto unweighted = LocateSource(pattern, spots);
  ASSERT_TRUE(weighted.ok() && unweighted.ok());
  EXPECT_FALSE(unweighted->weighted);
  EXPECT_TRUE(unweighted->covariance_scaled);
  // Isotropic noise on a screen ~1 m away: both describe the same spread.
  const double ratio = std::sqrt(unweighted->origin_covariance.trace() / weighted->origin_covariance.trace());
  EXPECT_NEAR(ratio, 1.0, 0.25);
  // Angular noise ~ 0.1 mm / 1 m: variance factor of the weighted solve ~ 1.
  EXPECT_NEAR(weighted->variance_factor, 1.0, 0.3);
  EXPECT_NEAR(unweighted->rms_residual_rad, 0.1 / 1050.0, 0.04 / 1050.0);
}

TEST(LocateSource, OutliersAreFlaggedAndDoNotPullTheOrigin) {
  std::mt19937_64 rng(35);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  const double sigma = 0.1;
  // Clean-noise spread of the origin, from the reported covariance.
  for (int trial = 0; trial < 50; ++trial) {
    const Rigid3d truth = RandomPose(rng);
    std::vector<Eigen::Vector3d> clean;
    auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.2, sigma, rng, &clean);
    auto reference = LocateSource(pattern, spots);
    ASSERT_TRUE(reference.ok());
    const Eigen::Vector3d clean_std = reference->origin_covariance.diagonal().cwiseSqrt();
    // Move 10% of the spots by 5 mm across their ray.
    std::vector<int> idx(spots.size());
    for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
    std::shuffle(idx.begin(), idx.end(), rng);
    std::vector<int> moved_ids;
    for (size_t k = 0; k < spots.size() / 10; ++k) {
      SpotObservation& s = spots[idx[k]];
      const Eigen::Vector3d ray = (s.point_in_scene - truth.translation).normalized();
      Eigen::Vector3d dir = ray.cross(Eigen::Vector3d::Random()).normalized();
      s.point_in_scene += 5.0 * dir;
      moved_ids.push_back(s.beam_id);
    }
    auto result = LocateSource(pattern, spots);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    std::vector<int> flagged = result->OutlierBeamIds();
    std::sort(flagged.begin(), flagged.end());
    std::sort(moved_ids.begin(), moved_ids.end());
    EXPECT_EQ(flagged, moved_ids);
    const Eigen::Vector3d err = result->scene_from_source.translation - truth.translation;
    for (int k = 0; k < 3; ++k) EXPECT_LT(std::abs(err(k)), 3.0 * clean_std(k)) << "trial " << trial;
  }
}

TEST(LocateSource, InitialGuessIsOptionalAndUsedWhenGood) {
  std::mt19937_64 rng(36);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  const Rigid3d truth = RandomPose(rng);
  auto spots = test::SpotsOnPlane(pattern, truth, 1500.0, 0.0, 0.0, rng);
  LocateOptions options;
  options.initial_scene_from_source = truth;
  auto with_guess = LocateSource(pattern, spots, options);
  ASSERT_TRUE(with_guess.ok());
  EXPECT_EQ(with_guess->ransac_iterations, 0);
  // A wrong guess falls back to RANSAC and still finds the pose.
  options.initial_scene_from_source = Rigid3d();
  auto with_bad_guess = LocateSource(pattern, spots, options);
  ASSERT_TRUE(with_bad_guess.ok());
  EXPECT_GT(with_bad_guess->ransac_iterations, 0);
  EXPECT_LT((with_bad_guess->scene_from_source.translation - truth.translation).norm(), 1e-6);
}

TEST(LocateSource, BadInputIsRejectedWithAClearStatus) {
  std::mt19937_64 rng(37);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  const Rigid3d truth = RandomPose(rng);
  const auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.0, 0.0, rng);

  auto few = std::vector<SpotObservation>(spots.begin(), spots.begin() + 3);
  auto r = LocateSource(pattern, few);
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
  EXPECT_NE(r.status().message().find("too few spots"), std::string::npos);

  // The central row only: collinear spots.
  std::vector<SpotObservation> row;
  for (const auto& s : spots) {
    if (BeamRow(s.beam_id, 11) == 5) row.push_back(s);
  }
  r = LocateSource(pattern, row);
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
  EXPECT_NE(r.status().message().find("one line"), std::string::npos) << r.status().message();

  auto unknown = spots;
  unknown[3].beam_id = 122;
  r = LocateSource(pattern, unknown);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("beam 122"), std::string::npos);

  auto dup = spots;
  dup[4].beam_id = dup[5].beam_id;
  r = LocateSource(pattern, dup);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("duplicate"), std::string::npos);

  auto nan = spots;
  nan[7].point_in_scene.y() = std::numeric_limits<double>::quiet_NaN();
  r = LocateSource(pattern, nan);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("not finite"), std::string::npos);

  auto mixed = spots;
  mixed[0].cov_in_scene = Eigen::Matrix3d::Identity();
  r = LocateSource(pattern, mixed);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);

  auto zero_cov = spots;
  for (auto& s : zero_cov) s.cov_in_scene = Eigen::Matrix3d::Zero();
  r = LocateSource(pattern, zero_cov);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);

  LocateOptions bad;
  bad.outlier_threshold = -1.0;
  r = LocateSource(pattern, spots, bad);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("outlier_threshold"), std::string::npos);

  // Spots that no pose explains: scattered at random.
  std::vector<SpotObservation> junk = spots;
  std::uniform_real_distribution<double> u(-1000, 1000);
  for (auto& s : junk) s.point_in_scene = Eigen::Vector3d(u(rng), u(rng), u(rng));
  r = LocateSource(pattern, junk);
  EXPECT_EQ(r.status().code(), StatusCode::kNoSolution);
}

}  // namespace
}  // namespace opl

namespace opl {
namespace {

// With flagging switched off and RANSAC accepting everything, only the robust
// loss stands between the outliers and the estimate: least squares is pulled
// far off, Huber and Cauchy (solved by IRLS) stay close to the truth.
TEST(LocateSource, RobustLossLimitsOutlierInfluence) {
  std::mt19937_64 rng(38);
  const BeamPattern pattern = test::TangentLatticePattern(11, kFullAngle);
  const Rigid3d truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 1, 0).normalized())),
                      Eigen::Vector3d(-30, 40, 500));
  auto spots = test::SpotsOnPlane(pattern, truth, 1000.0, 0.1, 0.1, rng);
  // 15% of spots pushed 5 mm (~50 sigma), all the same way across their rays.
  for (size_t k = 0; k < spots.size(); k += 7) {
    const Eigen::Vector3d ray = (spots[k].point_in_scene - truth.translation).normalized();
    spots[k].point_in_scene += 5.0 * ray.cross(truth.RotationMatrix().col(2)).normalized();
  }
  LocateOptions options;
  options.outlier_threshold = 1e9;            // no flagging
  options.ransac_inlier_threshold_rad = 0.1;  // RANSAC keeps every spot
  auto error_with = [&](RobustLoss loss) {
    options.loss = loss;
    auto r = LocateSource(pattern, spots, options);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    EXPECT_TRUE(r->OutlierBeamIds().empty());
    return (r->scene_from_source.translation - truth.translation).norm();
  };
  const double e_none = error_with(RobustLoss::kNone);
  const double e_huber = error_with(RobustLoss::kHuber);
  const double e_cauchy = error_with(RobustLoss::kCauchy);
  // Clean-noise origin spread here is ~0.2 mm. Huber (a = 3 sigma) bounds the
  // influence of a 50-sigma spot to ~3/50 of least squares'; Cauchy's
  // influence falls further with distance.
  std::printf("origin error: none %.3f, huber %.3f, cauchy %.3f mm\n", e_none, e_huber, e_cauchy);
  EXPECT_GT(e_none, 0.8);
  EXPECT_LT(e_huber, 0.5 * e_none);
  EXPECT_LT(e_cauchy, 0.25 * e_none);
  EXPECT_LT(e_cauchy, e_huber);
}

}  // namespace
}  // namespace opl
