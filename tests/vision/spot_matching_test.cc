// Spot matching against known truth: synthetic scenes (not images) of two
// overlapping 11 x 11 laser grids on a wall 2.5-3 m from four calibrated,
// distorted 1024 x 768 cameras. Every detection carries the index of the
// scene point that made it (or -1 for a spurious one), so each accepted track
// is checked against the truth; the triangulated points against the true
// points through the reported covariance (chi^2 with 3 dof); spurious
// detections, some placed exactly on an epipolar line of a real spot, must
// stay unmatched; with two views the planted ambiguities must be reported,
// not guessed.
#include "opl/vision/spot_matching.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "opl/core/format.h"

namespace opl {
namespace {

constexpr double kNoisePx = 0.05;

struct Scene {
  std::vector<Camera> cameras;
  std::vector<Eigen::Vector3d> points;             // truth [m]
  std::vector<std::vector<SpotInView>> spots;      // per view, shuffled
  std::vector<std::vector<int>> truth;             // per view: point index, -1 spurious
  // Planted spurious detections on the epipolar line of point `point`'s
  // detection in view `source_view`: (view, spot index, point, source_view).
  struct Planted {
    int view, spot, point, source_view;
  };
  std::vector<Planted> planted;
};

CameraIntrinsics Intrinsics(int i) {
  CameraIntrinsics c;
  c.width_px = 1024;
  c.height_px = 768;
  c.fx_px = 1000.0 + 15.0 * i;
  c.fy_px = c.fx_px * 1.0005;
  c.cx_px = 511.5 + 3.0 * i;
  c.cy_px = 383.5 - 2.0 * i;
  c.k1 = -0.09 + 0.01 * i;
  c.k2 = 0.06;
  c.k3 = -0.01;
  c.p1 = 2e-4;
  c.p2 = -1.5e-4;
  return c;
}

// An 11 x 11 grid on the wall y = 0 (scene Z up), centred at (x, z), rotated
// by `angle` in the wall's plane, `spacing` apart [m].
void AddGrid(double x, double z, double spacing, double angle, std::vector<Eigen::Vector3d>* pts) {
  for (int r = -5; r <= 5; ++r) {
    for (int c = -5; c <= 5; ++c) {
      const double a = c * spacing, b = r * spacing;
      pts->emplace_back(x + std::cos(angle) * a - std::sin(angle) * b, 0.0,
                        z + std::sin(angle) * a + std::cos(angle) * b);
    }
  }
}

// `num_views` of the four cameras; each detection dropped with probability
// `drop`; `spurious` x (detections) false ones per view, `epipolar_fraction`
// of them on the epipolar line of a real spot of another view.
Scene MakeScene(int num_views, double drop, double spurious, double epipolar_fraction,
                unsigned seed) {
  Scene s;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Eigen::Vector3d target(0.0, 0.0, 1.2);
  const Eigen::Vector3d centers[4] = {{-0.9, -2.6, 1.7}, {0.85, -2.75, 0.8},
                                      {-0.75, -2.8, 0.65}, {1.0, -2.5, 1.75}};
  const double rolls[4] = {0.0, 0.12, -0.15, 0.05};
  for (int i = 0; i < num_views; ++i) {
    Camera c;
    c.name = "cam" + std::to_string(i);
    c.intrinsics = Intrinsics(i);
    c.cam_from_scene = *CamFromSceneLookingAt(centers[i], target, rolls[i]);
    s.cameras.push_back(c);
  }
  // Two overlapping grids, 42 and 50 mm spacing (15-20 px at 2.7 m).
  AddGrid(-0.08, 1.18, 0.042, 0.17, &s.points);
  AddGrid(0.1, 1.27, 0.050, -0.12, &s.points);
  s.spots.resize(static_cast<size_t>(num_views));
  s.truth.resize(static_cast<size_t>(num_views));
  std::vector<std::vector<Eigen::Vector2d>> clean(static_cast<size_t>(num_views));
  for (int v = 0; v < num_views; ++v) {
    const Camera& cam = s.cameras[static_cast<size_t>(v)];
    for (size_t p = 0; p < s.points.size(); ++p) {
      Eigen::Vector2d px;
      if (!cam.Project(s.points[p], &px) || !cam.InImage(px, 5.0)) continue;
      if (u01(rng) < drop) continue;
      // Per-spot covariance: sigma 0.04-0.06 px, mildly anisotropic.
      const double sa = kNoisePx * (0.8 + 0.4 * u01(rng)), sb = kNoisePx * (0.8 + 0.4 * u01(rng));
      const double th = kPi * u01(rng);
      Eigen::Matrix2d Rot;
      Rot << std::cos(th), -std::sin(th), std::sin(th), std::cos(th);
      const Eigen::Matrix2d S =
          Rot * Eigen::Vector2d(sa * sa, sb * sb).asDiagonal() * Rot.transpose();
      const Eigen::Matrix2d L = S.llt().matrixL();
      SpotInView d;
      d.pixel_px = px + L * Eigen::Vector2d(n01(rng), n01(rng));
      d.covariance_px2 = S;
      s.spots[static_cast<size_t>(v)].push_back(d);
      s.truth[static_cast<size_t>(v)].push_back(static_cast<int>(p));
    }
  }
  // Spurious detections.
  for (int v = 0; v < num_views; ++v) {
    const Camera& cam = s.cameras[static_cast<size_t>(v)];
    const double real = static_cast<double>(s.spots[static_cast<size_t>(v)].size());
    const int n = static_cast<int>(std::lround(spurious * real));
    int made = 0, tries = 0;
    while (made < n && tries++ < 100 * n) {
      SpotInView d;
      d.covariance_px2 = kNoisePx * kNoisePx * Eigen::Matrix2d::Identity();
      Scene::Planted planted{v, -1, -1, -1};
      if (u01(rng) < epipolar_fraction) {
        // On the epipolar line of a point seen by another view k: the image
        // of that view's ray through the point at another depth.
        const int k = (v + 1 + static_cast<int>(u01(rng) * (num_views - 1))) % num_views;
        const int p = static_cast<int>(u01(rng) * static_cast<double>(s.points.size()));
        const Eigen::Vector3d ck = s.cameras[static_cast<size_t>(k)].CenterInScene();
        const double depth = (s.points[static_cast<size_t>(p)] - ck).norm();
        const double delta = (0.05 + 0.2 * u01(rng)) * (u01(rng) < 0.5 ? -1.0 : 1.0);
        const Eigen::Vector3d X =
            ck + (1.0 + delta) * depth * (s.points[static_cast<size_t>(p)] - ck).normalized();
        Eigen::Vector2d px;
        if (!cam.Project(X, &px) || !cam.InImage(px, 5.0)) continue;
        // The point must have a detection in view k for this to be a trap.
        const auto& tk = s.truth[static_cast<size_t>(k)];
        if (std::find(tk.begin(), tk.end(), p) == tk.end()) continue;
        d.pixel_px = px;
        planted.point = p;
        planted.source_view = k;
      } else {
        d.pixel_px = Eigen::Vector2d(5.0 + 1014.0 * u01(rng), 5.0 + 758.0 * u01(rng));
      }
      s.spots[static_cast<size_t>(v)].push_back(d);
      s.truth[static_cast<size_t>(v)].push_back(-1);
      if (planted.point >= 0) {
        planted.spot = static_cast<int>(s.spots[static_cast<size_t>(v)].size()) - 1;
        s.planted.push_back(planted);
      }
      ++made;
    }
  }
  // Shuffle each view's list (and the planted indices with it).
  for (int v = 0; v < num_views; ++v) {
    const size_t n = s.spots[static_cast<size_t>(v)].size();
    std::vector<int> perm(n);
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<SpotInView> spots(n);
    std::vector<int> truth(n), where(n);
    for (size_t k = 0; k < n; ++k) {
      spots[k] = s.spots[static_cast<size_t>(v)][static_cast<size_t>(perm[k])];
      truth[k] = s.truth[static_cast<size_t>(v)][static_cast<size_t>(perm[k])];
      where[static_cast<size_t>(perm[k])] = static_cast<int>(k);
    }
    s.spots[static_cast<size_t>(v)] = spots;
    s.truth[static_cast<size_t>(v)] = truth;
    for (Scene::Planted& p : s.planted) {
      if (p.view == v) p.spot = where[static_cast<size_t>(p.spot)];
    }
  }
  return s;
}

int Truth(const Scene& s, const SpotRef& r) {
  return s.truth[static_cast<size_t>(r.view)][static_cast<size_t>(r.spot)];
}

// Detection of point p in view v, or -1.
int DetectionOf(const Scene& s, int v, int p) {
  const auto& t = s.truth[static_cast<size_t>(v)];
  const auto it = std::find(t.begin(), t.end(), p);
  return it == t.end() ? -1 : static_cast<int>(it - t.begin());
}

struct Figures {
  int points_3plus = 0;  // points with detections in >= 3 views
  int matched_3plus = 0;
  int wrong_tracks = 0;
  int spurious_matched = 0;
  double chi2_mean = 0.0;  // normalised 3D error, mean (3 expected)
  double chi2_max = 0.0;
  int chi2_above_p01 = 0;  // above the 99% quantile of chi^2(3), 11.345
  double rms_3d_mm = 0.0;
  double rms_sigma_mm = 0.0;  // RMS of the reported sigma (sqrt(trace / 3))
};

Figures Evaluate(const Scene& s, const SpotMatchResult& r) {
  Figures f;
  std::vector<int> track_of_point(s.points.size(), -1);
  double sum_e = 0.0, sum_sq = 0.0, sum_var = 0.0;
  for (size_t t = 0; t < r.tracks.size(); ++t) {
    const SpotTrack& track = r.tracks[t];
    const int p = Truth(s, track.spots.front());
    bool ok = p >= 0;
    for (const SpotRef& ref : track.spots) ok = ok && Truth(s, ref) == p;
    for (const SpotRef& ref : track.spots) f.spurious_matched += Truth(s, ref) < 0 ? 1 : 0;
    if (!ok) {
      {  // what went wrong, for the failure message
        std::printf("WRONG track chi2 %.3f:", track.ranking_chi2);
        for (size_t k = 0; k < track.spots.size(); ++k) {
          const SpotRef& ref = track.spots[k];
          bool planted = false;
          for (const auto& pl : s.planted) {
            planted = planted || (pl.view == ref.view && pl.spot == ref.spot);
          }
          std::printf(" (v%d s%d truth %d%s res %.3f,%.3f)", ref.view, ref.spot, Truth(s, ref),
                      planted ? " planted" : "", track.point.residuals_px[k].x(),
                      track.point.residuals_px[k].y());
        }
        std::printf("\n");
      }
      ++f.wrong_tracks;
      continue;
    }
    track_of_point[static_cast<size_t>(p)] = static_cast<int>(t);
    const Eigen::Vector3d d = track.point.point_in_scene - s.points[static_cast<size_t>(p)];
    const double e = d.dot(track.point.covariance.ldlt().solve(d));
    sum_e += e;
    f.chi2_max = std::max(f.chi2_max, e);
    f.chi2_above_p01 += e > 11.345 ? 1 : 0;
    sum_sq += d.squaredNorm();
    sum_var += track.point.covariance.trace();
  }
  const int good = static_cast<int>(r.tracks.size()) - f.wrong_tracks;
  if (good > 0) {
    f.chi2_mean = sum_e / good;
    f.rms_3d_mm = 1e3 * std::sqrt(sum_sq / good / 3.0);
    f.rms_sigma_mm = 1e3 * std::sqrt(sum_var / good / 3.0);
  }
  for (size_t p = 0; p < s.points.size(); ++p) {
    int views = 0;
    for (size_t v = 0; v < s.truth.size(); ++v) {
      views += DetectionOf(s, static_cast<int>(v), static_cast<int>(p)) >= 0 ? 1 : 0;
    }
    if (views >= 3) {
      ++f.points_3plus;
      f.matched_3plus += track_of_point[p] >= 0 ? 1 : 0;
    }
  }
  return f;
}

// Every detection is in exactly one track or in `unmatched`; one per view.
void ExpectPartition(const Scene& s, const SpotMatchResult& r) {
  std::vector<std::vector<int>> count(s.spots.size());
  for (size_t v = 0; v < s.spots.size(); ++v) count[v].assign(s.spots[v].size(), 0);
  for (const SpotTrack& t : r.tracks) {
    std::set<int> views;
    for (const SpotRef& ref : t.spots) {
      EXPECT_TRUE(views.insert(ref.view).second) << "two detections of one view in a track";
      ++count[static_cast<size_t>(ref.view)][static_cast<size_t>(ref.spot)];
    }
    EXPECT_GE(t.num_views(), r.min_views);
    EXPECT_EQ(t.point.residuals_px.size(), t.spots.size());
  }
  ASSERT_EQ(r.unmatched.size(), s.spots.size());
  for (size_t v = 0; v < s.spots.size(); ++v) {
    for (int k : r.unmatched[v]) ++count[v][static_cast<size_t>(k)];
    for (size_t k = 0; k < count[v].size(); ++k) {
      EXPECT_EQ(count[v][k], 1) << "view " << v << " spot " << k;
    }
  }
}

TEST(SpotMatching, FourViewsTwoGridsAreMatchedWithoutError) {
  const Scene s = MakeScene(4, 0.15, 0.10, 0.5, 7);
  ASSERT_GE(s.planted.size(), 20u);
  const auto r = MatchSpots(s.cameras, s.spots);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  std::printf("%s\n", r->ToText().c_str());
  EXPECT_EQ(r->min_views, 3);
  ExpectPartition(s, *r);
  const Figures f = Evaluate(s, *r);
  std::printf("points in >= 3 views %d, matched %d (%.2f%%), wrong tracks %d, spurious matched %d\n"
              "3D error: rms %.4f mm (reported sigma rms %.4f mm), chi2(3) mean %.3f max %.2f, "
              "%d above the 99%% quantile\n",
              f.points_3plus, f.matched_3plus, 100.0 * f.matched_3plus / f.points_3plus,
              f.wrong_tracks, f.spurious_matched, f.rms_3d_mm, f.rms_sigma_mm, f.chi2_mean,
              f.chi2_max, f.chi2_above_p01);
  EXPECT_EQ(f.wrong_tracks, 0);
  EXPECT_EQ(f.spurious_matched, 0);
  EXPECT_GE(f.matched_3plus, 0.97 * f.points_3plus);
  // Normalised errors against the reported covariance: chi^2 with 3 dof.
  EXPECT_GT(f.chi2_mean, 2.4);
  EXPECT_LT(f.chi2_mean, 3.7);
  EXPECT_LE(f.chi2_above_p01, std::max(4, static_cast<int>(0.04 * f.matched_3plus)));
  // Reprojection RMS per coordinate near the simulated 0.05 px (less: the
  // point absorbs 3 of the 2n degrees of freedom).
  EXPECT_GT(r->rms_reprojection_px, 0.02);
  EXPECT_LT(r->rms_reprojection_px, 0.06);
  // Every planted epipolar trap is left unmatched.
  for (const Scene::Planted& p : s.planted) {
    const auto& u = r->unmatched[static_cast<size_t>(p.view)];
    EXPECT_NE(std::find(u.begin(), u.end(), p.spot), u.end());
  }
}

// OPL_SPOT_MATCH_SEEDS=n runs n seeds instead of 3 (a longer sweep by hand;
// over 300 seeds a few scenes do hold one wrong track, a spurious detection
// inside the gate of a point's missing detection: the rate is in the
// header's failure mode (b)).
std::vector<unsigned> Seeds() {
  int n = 3;
  if (const char* env = std::getenv("OPL_SPOT_MATCH_SEEDS")) n = std::max(1, std::atoi(env));
  std::vector<unsigned> seeds;
  for (int k = 0; k < n; ++k) seeds.push_back(11u + static_cast<unsigned>(k));
  return seeds;
}

TEST(SpotMatching, OtherSeedsHaveNoWrongMatch) {
  for (unsigned seed : Seeds()) {
    const Scene s = MakeScene(4, 0.2, 0.10, 0.5, seed);
    const auto r = MatchSpots(s.cameras, s.spots);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const Figures f = Evaluate(s, *r);
    std::printf("seed %u: %d/%d points in >= 3 views matched, %d wrong, %d spurious matched, "
                "chi2(3) mean %.3f, %zu ambiguities\n",
                seed, f.matched_3plus, f.points_3plus, f.wrong_tracks, f.spurious_matched,
                f.chi2_mean, r->ambiguities.size());
    EXPECT_EQ(f.wrong_tracks, 0) << "seed " << seed;
    EXPECT_EQ(f.spurious_matched, 0) << "seed " << seed;
    EXPECT_GE(f.matched_3plus, 0.97 * f.points_3plus) << "seed " << seed;
  }
}

// Three views, as in a calibration session (docs/images.md). The spot
// detector can report a non-spot blob (a faint noise or tag-edge component)
// with a degenerate fit whose covariance is absurd: 1e6 to 1e27 px^2 were
// measured on the noisy 8-bit renders of examples/calibration_session_small.
// Such a detection lies inside every gate (its whitened distance is ~0), so
// choosing the third view's detection by the lowest whitened distance alone
// preferred it to the true detection next to it: the true track and the one
// with the blob then tied (both three views) and were refused as ambiguous,
// and the point was lost. The third view's detection is the most likely one
// (lowest r^T S^-1 r + ln det S), which such a blob never is.
TEST(SpotMatching, ThreeViewsIgnoreDetectionsWithDegenerateCovariance) {
  Scene s = MakeScene(3, 0.0, 0.0, 0.0, 5);
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  // In views 1 and 2, next to 16 true detections each (0.05-0.25 px away),
  // a detection with a degenerate covariance, and 4 more anywhere (8% of
  // the detections: under the 10% the search variances' percentile allows).
  int blobs = 0;
  for (int v = 1; v < 3; ++v) {
    auto& spots = s.spots[static_cast<size_t>(v)];
    auto& truth = s.truth[static_cast<size_t>(v)];
    const size_t real = spots.size();
    for (int k = 0; k < 20; ++k) {
      SpotInView d;
      const double big = std::pow(10.0, 6.0 + 20.0 * u01(rng));
      d.covariance_px2 << big, 0.3 * big, 0.3 * big, 0.5 * big;
      if (k < 16) {
        const size_t near = static_cast<size_t>(u01(rng) * static_cast<double>(real));
        const double a = 2.0 * kPi * u01(rng), r = 0.05 + 0.2 * u01(rng);
        d.pixel_px = spots[near].pixel_px + r * Eigen::Vector2d(std::cos(a), std::sin(a));
      } else {
        d.pixel_px = Eigen::Vector2d(5.0 + 1014.0 * u01(rng), 5.0 + 758.0 * u01(rng));
      }
      spots.push_back(d);
      truth.push_back(-1);
      ++blobs;
    }
  }
  const auto r = MatchSpots(s.cameras, s.spots);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  std::printf("%s\n", r->ToText().c_str());
  EXPECT_EQ(r->min_views, 3);
  ExpectPartition(s, *r);
  const Figures f = Evaluate(s, *r);
  std::printf("%d blobs; points in 3 views %d, matched %d, wrong tracks %d, spurious matched %d\n",
              blobs, f.points_3plus, f.matched_3plus, f.wrong_tracks, f.spurious_matched);
  EXPECT_EQ(f.wrong_tracks, 0);
  EXPECT_EQ(f.spurious_matched, 0);
  EXPECT_EQ(f.matched_3plus, f.points_3plus);
  EXPECT_EQ(r->ambiguities.size(), 0u);
  // Work bound (timing-free): one hypothesis per point, and at most one more
  // per blob (a blob seeding with a true detection). Before, with 50 blobs
  // per view (above the 10% the search percentile allows), the epipolar walk
  // over a band of 1e6 px and more did not end.
  EXPECT_LE(r->hypotheses, f.points_3plus + blobs);
}

// The detections come from the true cameras, the matcher gets cameras whose
// poses are off by ~0.5 px (0.5 mrad, 0.5 mm): pose_tolerance_px = 1 keeps
// the recall; no tolerance loses most tracks. The wider gate admits more
// coincidences (header, failure mode (b)): over seeds 32-71, recall 98.2%
// and 6 wrong tracks among ~8600 (no tolerance: recall 34%); this seed has
// none.
TEST(SpotMatching, PoseToleranceAbsorbsPoseErrors) {
  const Scene s = MakeScene(4, 0.15, 0.10, 0.5, 31);
  std::vector<Camera> off = s.cameras;
  std::mt19937_64 rng(8);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (Camera& c : off) {
    const Eigen::Vector3d w = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized() * 5e-4;
    c.cam_from_scene.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w.normalized())) * c.cam_from_scene.rotation;
    c.cam_from_scene.translation +=
        Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized() * 5e-4;
  }
  SpotMatchOptions tolerant;
  tolerant.pose_tolerance_px = 1.0;
  const auto r = MatchSpots(off, s.spots, tolerant);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const Figures f = Evaluate(s, *r);
  SpotMatchOptions strict;
  strict.pose_tolerance_px = 0.0;
  const auto r0 = MatchSpots(off, s.spots, strict);
  ASSERT_TRUE(r0.ok()) << r0.status().ToString();
  const Figures f0 = Evaluate(s, *r0);
  std::printf("poses off by ~0.5 px: tolerance 1 px: %d/%d matched, %d wrong, rms %.3f px; "
              "tolerance 0: %d/%d matched, %d wrong\n",
              f.matched_3plus, f.points_3plus, f.wrong_tracks, r->rms_reprojection_px,
              f0.matched_3plus, f0.points_3plus, f0.wrong_tracks);
  EXPECT_EQ(f.wrong_tracks, 0);
  EXPECT_EQ(f.spurious_matched, 0);
  EXPECT_GE(f.matched_3plus, 0.95 * f.points_3plus);
  EXPECT_LT(f0.matched_3plus, 0.8 * f0.points_3plus);
}

TEST(SpotMatching, TwoViewsReportAmbiguitiesInsteadOfGuessing) {
  // Views 0 and 1, nothing dropped, spurious detections in view 1 only, all
  // on the epipolar line of a real spot of view 0.
  Scene s = MakeScene(2, 0.0, 0.0, 1.0, 21);
  {
    // Plant 15 traps in view 1 (MakeScene's spurious go to both views).
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    const Camera& c0 = s.cameras[0];
    const Camera& c1 = s.cameras[1];
    std::set<int> used;
    while (s.planted.size() < 15) {
      const int p = static_cast<int>(u01(rng) * static_cast<double>(s.points.size()));
      if (DetectionOf(s, 0, p) < 0 || DetectionOf(s, 1, p) < 0 || !used.insert(p).second) continue;
      const double depth = (s.points[static_cast<size_t>(p)] - c0.CenterInScene()).norm();
      const double delta = (0.08 + 0.15 * u01(rng)) * (u01(rng) < 0.5 ? -1.0 : 1.0);
      const Eigen::Vector3d ray =
          (s.points[static_cast<size_t>(p)] - c0.CenterInScene()).normalized();
      const Eigen::Vector3d X = c0.CenterInScene() + (1.0 + delta) * depth * ray;
      Eigen::Vector2d px;
      if (!c1.Project(X, &px) || !c1.InImage(px, 5.0)) continue;
      SpotInView d;
      d.pixel_px = px;
      d.covariance_px2 = kNoisePx * kNoisePx * Eigen::Matrix2d::Identity();
      s.spots[1].push_back(d);
      s.truth[1].push_back(-1);
      s.planted.push_back({1, static_cast<int>(s.spots[1].size()) - 1, p, 0});
    }
  }
  SpotMatchOptions options;
  options.min_views = 2;
  const auto r = MatchSpots(s.cameras, s.spots, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  std::printf("%s\n", r->ToText().c_str());
  ExpectPartition(s, *r);
  const Figures f = Evaluate(s, *r);
  EXPECT_EQ(f.wrong_tracks, 0);
  EXPECT_EQ(f.spurious_matched, 0);
  int seen_in_both = 0;
  for (size_t p = 0; p < s.points.size(); ++p) {
    seen_in_both += DetectionOf(s, 0, static_cast<int>(p)) >= 0 &&
                    DetectionOf(s, 1, static_cast<int>(p)) >= 0;
  }
  std::printf("two views: %zu of %d points matched, %zu ambiguities reported\n",
              r->tracks.size(), seen_in_both, r->ambiguities.size());
  EXPECT_GE(r->ambiguities.size(), s.planted.size());
  // Each ambiguity of two equally supported explanations was refused
  // because their likelihoods are within ambiguity_chi2 (the decision
  // value the ambiguity carries).
  for (const SpotAmbiguity& amb : r->ambiguities) {
    if (amb.best.size() != amb.second.size()) continue;
    EXPECT_LT(amb.second_nll - amb.best_nll, options.ambiguity_chi2);
    EXPECT_NE(amb.best_nll, amb.best_chi2);  // the ln det terms are in it
  }
  // Some points remain matchable in two views.
  EXPECT_GT(static_cast<int>(r->tracks.size()), seen_in_both / 4);
  // Each trap's real spot in view 0 is left unmatched and named by an
  // ambiguity whose explanations are the true partner and the trap.
  for (const Scene::Planted& p : s.planted) {
    const int a = DetectionOf(s, 0, p.point);
    const auto& u = r->unmatched[0];
    EXPECT_NE(std::find(u.begin(), u.end(), a), u.end()) << "point " << p.point;
    bool reported = false;
    for (const SpotAmbiguity& amb : r->ambiguities) {
      for (const SpotRef& b : amb.blocked) reported = reported || (b.view == 0 && b.spot == a);
    }
    EXPECT_TRUE(reported) << "point " << p.point;
  }
}

TEST(SpotMatching, NoiseFreeTracksAreExactAndComplete) {
  Scene s = MakeScene(4, 0.0, 0.0, 0.0, 3);
  for (auto& view : s.spots) {
    for (SpotInView& d : view) d.covariance_px2 = kNoisePx * kNoisePx * Eigen::Matrix2d::Identity();
  }
  // Replace the noisy pixels by the exact projections.
  for (size_t v = 0; v < s.spots.size(); ++v) {
    for (size_t k = 0; k < s.spots[v].size(); ++k) {
      ASSERT_TRUE(s.cameras[v].Project(s.points[static_cast<size_t>(s.truth[v][k])],
                                       &s.spots[v][k].pixel_px));
    }
  }
  const auto r = MatchSpots(s.cameras, s.spots);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const Figures f = Evaluate(s, *r);
  EXPECT_EQ(f.wrong_tracks, 0);
  EXPECT_EQ(f.matched_3plus, f.points_3plus);
  for (const SpotTrack& t : r->tracks) {
    const int p = Truth(s, t.spots.front());
    EXPECT_LT((t.point.point_in_scene - s.points[static_cast<size_t>(p)]).norm(), 1e-9);
    int views = 0;
    for (size_t v = 0; v < s.spots.size(); ++v) {
      views += DetectionOf(s, static_cast<int>(v), p) >= 0 ? 1 : 0;
    }
    EXPECT_EQ(t.num_views(), views) << "point " << p;
  }
  EXPECT_LT(r->rms_reprojection_px, 1e-8);
}

TEST(SpotMatching, BadInputIsNamed) {
  const Scene s = MakeScene(4, 0.1, 0.0, 0.0, 9);
  {
    std::vector<Camera> three(s.cameras.begin(), s.cameras.begin() + 3);
    const auto r = MatchSpots(three, s.spots);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("3 cameras but 4 views"), std::string::npos)
        << r.status().message();
  }
  {
    auto spots = s.spots;
    spots[1][3].covariance_px2 << 1.0, 2.0, 2.0, 1.0;  // indefinite
    const auto r = MatchSpots(s.cameras, spots);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("view 1 spot 3: covariance_px2"), std::string::npos)
        << r.status().message();
  }
  {
    auto spots = s.spots;
    spots[2][0].pixel_px.x() = std::nan("");
    const auto r = MatchSpots(s.cameras, spots);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("view 2 spot 0: pixel_px"), std::string::npos)
        << r.status().message();
  }
  {
    SpotMatchOptions o;
    o.min_views = 5;
    const auto r = MatchSpots(s.cameras, s.spots, o);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("min_views = 5"), std::string::npos)
        << r.status().message();
  }
  {
    // Two views with the automatic min_views use 2; an explicit 3 is refused.
    std::vector<Camera> two(s.cameras.begin(), s.cameras.begin() + 2);
    std::vector<std::vector<SpotInView>> spots(s.spots.begin(), s.spots.begin() + 2);
    SpotMatchOptions o;
    o.min_views = 3;
    EXPECT_FALSE(MatchSpots(two, spots, o).ok());
    const auto r = MatchSpots(two, spots);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    EXPECT_EQ(r->min_views, 2);
  }
  {
    auto cams = s.cameras;
    cams[3].intrinsics.fx_px = -1.0;
    const auto r = MatchSpots(cams, s.spots);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("view 3"), std::string::npos) << r.status().message();
  }
  {
    const auto r = MatchSpots({s.cameras[0]}, {s.spots[0]});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  }
}

TEST(SpotMatching, OptionsValidateNamesTheField) {
  SpotMatchOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.gate_sigmas = 0.0;
  EXPECT_NE(o.Validate().message().find("gate_sigmas = 0"), std::string::npos);
  o = SpotMatchOptions();
  o.pose_tolerance_px = -0.1;
  EXPECT_NE(o.Validate().message().find("pose_tolerance_px = -0.1"), std::string::npos);
  o = SpotMatchOptions();
  o.min_views = 1;
  EXPECT_NE(o.Validate().message().find("min_views = 1"), std::string::npos);
  o = SpotMatchOptions();
  o.min_triangulation_angle_deg = 95.0;
  EXPECT_NE(o.Validate().message().find("min_triangulation_angle_deg = 95"), std::string::npos);
  o = SpotMatchOptions();
  o.ambiguity_chi2 = std::nan("");
  EXPECT_FALSE(o.Validate().ok());
  o = SpotMatchOptions();
  o.grid_cell_px = 0.0;
  EXPECT_NE(o.Validate().message().find("grid_cell_px"), std::string::npos);
}

}  // namespace
}  // namespace opl
