// Spot matching: which detected laser spots of several calibrated views are
// images of the same 3D point (docs/multiview.md, issue 6).
//
// The model. View i is a calibrated camera (camera_model.h: intrinsics and
// cam_from_scene, held exact) that photographed the laser grids at the same
// instant as the others. A spot detector found in it an unordered list of
// spots, each a pixel u with a 2x2 covariance Sigma (px^2). Some spots of the
// grids are missing in some views, some detections are not spots at all
// (speckle, reflections). A track is a set of detections, at most one per
// view, that a single scene point X explains:
//
//   (pi_i(X) - u_i)^T (Sigma_i + tau^2 I)^-1 (pi_i(X) - u_i) <= g^2  for each i,
//
// pi_i the projection with its Brown-Conrady distortion, g = gate_sigmas and
// tau = pose_tolerance_px / g: the gate of a detection is its g-sigma ellipse
// widened (in quadrature) by pose_tolerance_px, which stands for what the
// poses and calibrations, held exact, get wrong. Every detection is in at
// most one track. The grids are dense (neighbours 15-60 px apart): an
// epipolar line usually passes near several spots, so a match between two
// views is often ambiguous and a third view is what confirms it.
//
// The algorithm.
//  1. Per view: each detection is undistorted once (UndistortPixel) into a
//     normalised ray and into its ideal (distortion-free) pixel, its
//     covariance carried to ideal pixels through the distortion's Jacobian;
//     two bucket grids (ideal pixels, real pixels) index the detections.
//  2. Seeds: for every pair of views (i, j) and every detection a of i, the
//     epipolar line of a in j's ideal pixels is walked through the grid; a
//     detection b at distance d from it is a candidate when
//       d^2 <= g^2 (n^T Sigma_b n + t^2 n_a^T Sigma_a n_a) + pose_tolerance^2,
//     n, n_a the unit normals of the two epipolar lines, t = f_j Z_i / (f_i Z_j)
//     the transfer of a's error into j (Z: depths of the two-ray midpoint).
//  3. Each candidate pair is triangulated (midpoint, then Gauss-Newton) with
//     its first-order covariance C; points behind a camera or seen under less
//     than min_triangulation_angle_deg are dropped. The point is projected
//     into every other view k (Jacobian J_k) and the real-pixel grid gives,
//     among the detections with r^T S^-1 r <= g^2 (S = J_k C J_k^T + Sigma
//     + tau^2 I), the most likely one: the lowest r^T S^-1 r + ln det S (a
//     detection with a degenerate covariance, which the spot detector can
//     report for a non-spot blob, lies inside every gate with r^T S^-1 r ~ 0
//     and must not be preferred to the true detection beside it). The views
//     that agree are the hypothesis' support. A pair
//     already inside a stored hypothesis (seeded by another pair of its
//     views) is not tried again.
//  4. A hypothesis with at least min_views views (identical ones from other
//     seed pairs merged) is triangulated from all of them (TriangulatePoint:
//     weighted, with covariance); an observation outside its gate is dropped
//     (the worst first) while min_views remain. Its ranking chi^2 is
//     sum_i r_i^T (Sigma_i + tau^2 I)^-1 r_i; hypotheses are ordered and
//     compared by nll = chi^2 + sum_i ln det(Sigma_i + tau^2 I) (twice the
//     negative log-likelihood), for the same reason as in step 3.
//  5. Greedy acceptance, most views first, then lowest nll. Before
//     accepting h, its best competitor c is looked at: a hypothesis sharing
//     a detection with h, neither a subset of the other, with at least as
//     many views, still live or "contested" (it lost a detection to an
//     earlier ambiguity but still explains its others). When c has more
//     views, or as many and nll(c) - nll(h) < ambiguity_chi2, the two
//     are equally good explanations and h is not accepted: when they share
//     one detection that detection is blocked (left unmatched); when they
//     share two or more (they agree on the point) the detections where they
//     differ are blocked. The case is reported (SpotAmbiguity). Accepting a
//     track removes its detections from every other hypothesis (explained
//     away); blocking makes the holders contested. Either way a holder that
//     keeps min_views free detections is triangulated again as a new,
//     smaller hypothesis.
//
// Complexity, for V views of S detections each and G detections within an
// epipolar band: step 2 walks V^2 S lines of O(image size / cell) cells,
// steps 3-4 cost O(V^2 S G V) plus one TriangulatePoint per distinct
// hypothesis; the acceptance is O(H log H) for H hypotheses. Nothing is
// O(S^2). Measured (spot_matching_bench, one core, Release, shared
// machine): 4 views x 242 points with 5% spurious detections, median
// 6.1-7.4 ms; 8 views, 30-32 ms.
//
// Failure modes. (a) Two views only (min_views = 2): a match is ambiguous
// whenever another detection lies in the epipolar band (common when the
// baseline runs along the grid rows); it is reported and left unmatched, but
// a wrong detection in the band of a spot whose true partner is missing
// cannot be told from the right one and is accepted. (b) A spurious
// detection (or a spot of the other grid) within the gate of a point's
// projection in a view that missed the point joins its track: the gate is
// what the data cannot resolve; a smaller pose_tolerance_px makes this
// rarer. Measured (spot_matching_test's scene, 300 seeds: 4 views, 242
// points, 20% of detections missing, 10% spurious, half of those placed on
// an epipolar line of a real spot): 7 wrong tracks among 59311 (in 7 of the
// 300 scenes), each holding one such epipolar trap: 6 times two or three
// true detections plus the trap lying within 0.2 px of the point's missing
// detection, once two detections of different points whose rays meet plus
// the trap on the line of one of them; recall 99.8%. (c) Poses or
// calibrations worse than pose_tolerance_px lose true matches (detections
// fall outside their gates). Measured, same scenes with every pose off by
// ~0.5 px (0.5 mrad, 0.5 mm), 40 seeds: pose_tolerance_px = 1 gives recall
// 98.2% and 6 wrong tracks among ~8600 (the wider gate, (b)); 0 gives 34%.
// (d) Points whose rays meet under less than min_triangulation_angle_deg
// are not matched. (e) The epipolar prefilter assumes depth ratios between
// two views below 4 when the noise, not pose_tolerance_px, sets the gate.
// (f) Greedy acceptance is not a global optimum: a wrong track accepted
// first (more views, or lower chi^2) takes detections its competitors
// needed.
//
// Errors (Status, never an abort): InvalidArgument for bad options, a
// camera count that differs from the number of views, fewer than 2 views,
// min_views above the number of views, an invalid camera (names the view), a
// non-finite pixel or a covariance that is not symmetric positive definite
// (names view and spot). Ambiguities and unmatched detections are results.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/vision/camera_model.h"
#include "opl/vision/triangulation.h"

namespace opl {

// One detection of a view (e.g. from a DetectedSpot: (u_px, v_px) and its
// covariance_px2).
struct SpotInView {
  Eigen::Vector2d pixel_px = Eigen::Vector2d::Zero();  // OpenCV pixel convention
  // Covariance of the pixel [px^2], symmetric positive definite.
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Identity();
};

// A detection: its view and its index in that view's list.
struct SpotRef {
  int view = -1;
  int spot = -1;
  bool operator==(const SpotRef& o) const { return view == o.view && spot == o.spot; }
};

struct SpotMatchOptions {
  // Gate in standard deviations g: a detection agrees with a prediction when
  // its whitened distance is below g (chi^2 with 2 dof below g^2; 4: a true
  // match is lost with probability 3e-4 per view).
  double gate_sigmas = 4.0;
  // Pixel error of the poses and calibrations (held exact) [px]: widens every
  // gate in quadrature (radius sqrt((g sigma)^2 + tol^2)) and the ranking
  // chi^2 (header). Larger: robust to worse poses, more chance coincidences.
  double pose_tolerance_px = 0.25;
  // Views a track must have. 0: automatic, 3 when there are 3 or more views,
  // else 2. Otherwise at least 2 and at most the number of views; 2 with more
  // views accepts two-view tracks (unconfirmed by a third).
  int min_views = 0;
  // Points whose largest angle between rays is below this [deg] are not
  // matched (their depth is barely determined).
  double min_triangulation_angle_deg = 1.0;
  // Two hypotheses with equal support whose nll (chi^2 + sum ln det, header
  // step 4) differ by less than this are ambiguous (9: a likelihood ratio of
  // 90); neither is taken.
  double ambiguity_chi2 = 9.0;
  // Side of the bucket grid cells [px].
  double grid_cell_px = 8.0;

  // OK, or names the field, its value and the broken constraint.
  Status Validate() const;
};

struct SpotTrack {
  std::vector<SpotRef> spots;  // one per view, by increasing view
  // TriangulatePoint from all the track's detections: point, covariance,
  // residuals (in the order of `spots`), RMS, chi2, angle.
  TriangulatedPoint point;
  double ranking_chi2 = 0.0;  // sum r^T (Sigma + tau^2 I)^-1 r (header, step 4)
  int num_views() const { return static_cast<int>(spots.size()); }
};

// Two equally good explanations of the same detection(s); neither was taken.
struct SpotAmbiguity {
  std::vector<SpotRef> best;    // the better hypothesis' detections
  std::vector<SpotRef> second;  // its competitor's
  double best_chi2 = 0.0;       // ranking chi^2 of each
  double second_chi2 = 0.0;
  // What decided (header step 5): nll = chi^2 + sum ln det(Sigma_i + tau^2
  // I) of each. With as many views, second_nll - best_nll < ambiguity_chi2;
  // the chi^2 alone may differ by more, or the other way round.
  double best_nll = 0.0;
  double second_nll = 0.0;
  std::vector<SpotRef> blocked;  // detections left unmatched because of it
};

struct SpotMatchResult {
  std::vector<SpotTrack> tracks;              // ordered by their first detection
  std::vector<std::vector<int>> unmatched;    // per view, spot indices in no track
  std::vector<SpotAmbiguity> ambiguities;
  int min_views = 0;                 // the value used
  int candidate_pairs = 0;           // seed pairs within an epipolar gate
  int hypotheses = 0;                // distinct hypotheses with >= min_views views
  int rejected_geometry = 0;         // seeds/hypotheses behind a camera or too narrow
  int not_undistortable = 0;         // detections UndistortPixel could not invert
  double rms_reprojection_px = 0.0;  // over every detection of every track, per coordinate

  // Tracks with exactly n views (n >= 2).
  int TracksWithViews(int n) const;
  // A few lines: counts per view, tracks by views, RMS, ambiguities.
  std::string ToText() const;
};

// Matches the detections of calibrated views (header comment). cameras[i]
// took spots_per_view[i].
Result<SpotMatchResult> MatchSpots(const std::vector<Camera>& cameras,
                                   const std::vector<std::vector<SpotInView>>& spots_per_view,
                                   const SpotMatchOptions& options = SpotMatchOptions());

}  // namespace opl
