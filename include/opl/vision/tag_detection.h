// AprilTag (tag36h11) detection with sub-pixel corners
// (docs/targets_and_calibration.md has the model and the measured figures).
//
// The tag. A tag36h11 marker is 8 x 8 cells: 6 x 6 data bits inside a black
// border one cell wide, and needs a white quiet zone around it (at least one
// cell). Its CORNERS are the outer corners of the black square. Corner order
// (TagDetection::corners_px, TagBoard::TagCorners, lab/planar_target_image.h)
// is the order of cv::aruco: as the tag is printed (cv::aruco::drawMarker's
// image), 0 = top-left, 1 = top-right, 2 = bottom-right, 3 = bottom-left;
// seen upright in an image (v down) this runs clockwise. The TAG FRAME has its
// origin at the centre of the black square, x to the right and y down as
// printed, z = x cross y (into the tag, away from the viewer); with side s the
// corners are (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2), z = 0.
//
// The detector. Candidates and ids come from libapriltag 3.x (tag36h11) and
// from OpenCV's aruco module (DICT_APRILTAG_36h11), merged (the same id with
// overlapping quads is one tag); libapriltag finds far more small and
// oblique tags on real photographs, aruco adds a few with a narrow quiet
// zone (figures in the doc). libapriltag's pixel convention (its (0, 0) is
// the first pixel's corner) and corner order are converted to ours in one
// place (src/vision/apriltag_candidates.h). The corners are then refined by
// an edge fit of our own (TagCornerRefinement::kEdgeFit, the default),
// because neither detector's corners reach 0.05 px on blurred, distorted
// images (the other refinements, aruco's alone, are kept for comparison).
// Each of the four edges of the black square is fitted, over the pixels of
// a band around it (away from the corners), by the model of a blurred step,
//   I(p) = a + b Phi(d(p) / sigma),  d(p) = cos(t) x + sin(t) y - c + kappa s^2,
// (a, b: the two levels, sigma: the edge spread, t, c: the line, kappa: its
// curvature, which absorbs lens distortion; s: position along the edge) by
// Levenberg-Marquardt; each corner is the intersection of its two edge
// curves, and the id is re-read through them. A tag the edge fit cannot
// refine (about 2 px per cell, heavy blur) is kept with libapriltag's own
// corners and a larger covariance when libapriltag decoded it cleanly
// (keep_unrefined_tags; TagDetection::edge_fitted = false). The edge fit's
// corner covariance is propagated from the two fits' covariances
// (residual variance x (J^T J)^-1): a first-order estimate for white pixel
// noise, which does not include model error (see the doc for how it compares
// with the actual error).
//
// A 16-bit image is fitted at full depth; libapriltag and aruco see it
// stretched to 8 bits by its maximum.
//
// Errors (Status, never an abort): an empty image, an image that is not
// single-channel 8- or 16-bit (CV_8UC1, CV_16UC1; 3-channel 8-bit BGR is
// converted to gray), bad options, libapriltag failing to allocate its
// detector (NoSolution). Finding no tag is not an error (an empty
// list).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "opl/core/status.h"

namespace opl {

enum class TagCornerRefinement {
  kNone,           // aruco's contour quads, unrefined (CORNER_REFINE_NONE)
  kOpenCvSubpix,   // aruco's contour quads refined by cornerSubPix (CORNER_REFINE_SUBPIX)
  kOpenCvAprilTag, // aruco's AprilTag-2 quads (CORNER_REFINE_APRILTAG; ~20x slower)
  kEdgeFit,        // libapriltag's (and aruco's) candidates refined by the edge fit above (default)
};

// Which detector proposed a tag's candidate quad and id.
enum class TagSource { kAprilTag, kAruco };

struct TagDetectionOptions {
  TagCornerRefinement refinement = TagCornerRefinement::kEdgeFit;

  // --- Candidates (kEdgeFit; the other refinements are aruco's alone) ---
  // libapriltag 3.x (tag36h11) proposes candidates.
  bool use_apriltag = true;
  // OpenCV aruco (DICT_APRILTAG_36h11) proposes candidates too; merged with
  // libapriltag's (same id and overlapping quad = one tag). MEASURED on the
  // composite photographs (docs): it adds 5 of 889 tags to libapriltag's
  // 674 (mostly tags with a half-cell quiet zone), for ~12 ms on 18 MP.
  bool use_aruco = true;
  // libapriltag's quad_decimate: quads are searched in the image decimated
  // (point-sampled) by this factor, ids are decoded at full resolution.
  // 1.5 or an integer in [1, 8]; default 1 (every tag libapriltag can find;
  // 2 is about 3x faster and loses tags below ~20 px). Applied after the
  // candidate_max_megapixels reduction below.
  double quad_decimate = 1.0;
  // libapriltag's quad_sigma: Gaussian blur of the image searched for quads
  // [px of that image], in [0, 10]; default 0 (none; 0.8 helps very noisy
  // images).
  double quad_sigma = 0.0;
  // libapriltag's nthreads: threads of one detection, in [1, 64]; default 1
  // (callers that detect several images in parallel need no more).
  int num_threads = 1;
  // libapriltag's refine_edges: snaps its quads' edges to strong gradients
  // when quad_decimate > 1 (ignored at 1); default true.
  bool refine_edges = true;
  // libapriltag's decode_sharpening: sharpening of the samples its decoder
  // reads, in [0, 10]; default 0.25 (its default; helps small tags).
  double decode_sharpening = 0.25;
  // Large images: the candidates are searched in a copy reduced by the
  // smallest integer factor f that brings it to at most this many megapixels
  // (cv::INTER_AREA), then refined by the edge fit at full resolution. Tags
  // must then be about f times as large as at f = 1 (libapriltag needs ~16 px
  // per side for most tags, docs). >= 0.5. 2.5 MP: an 18 MP image is searched
  // at f = 3 (~65 ms with libapriltag on 2 threads; at f = 2 its search takes
  // ~220 ms on a noisy 18 MP render: noise makes many more clusters).
  double candidate_max_megapixels = 2.5;

  // --- Refinement ---
  // Tags whose side (mean edge length) is shorter are ignored [px], >= 6.
  // (Tags with a corner less than 1 px inside the image are ignored too: cut
  // by the border, their edge fits are biased.)
  double min_tag_side_px = 8.0;
  // Edge fit: pixels closer than this to a corner (along the edge) are not
  // used, so the fit sees one straight-ish step only [px], >= 1.
  double edge_corner_exclusion_px = 2.5;
  // Edge fit: half-width of the band fitted around each edge, as a fraction
  // of a cell (side / 8); the band must stay inside the black border and the
  // quiet zone, in (0, 0.9].
  double edge_band_cells = 0.6;
  // Edge fit: upper bound of that half-width [px], >= 1; 4 px holds the
  // blurred step of a PSF sigma up to ~1.3 px and bounds the cost on large tags.
  double max_edge_band_px = 4.0;
  // Edge fit: a fit whose edge spread sigma exceeds this fails [px], > 0.
  double max_edge_sigma_px = 4.0;
  // Maximum number of bit errors corrected in the id, in [0, 5]: a tag whose
  // data cells, re-read through its corners, differ from its code in more
  // bits is dropped (aruco's errorCorrectionRate is set from it; libapriltag
  // corrects at most min(max_hamming, 2)).
  int max_hamming = 2;

  // --- Tags the edge fit cannot refine (small, blurred) ---
  // When the edge fit fails (too few pixels per edge, a blurred step, a
  // corner that moved too far, or an id that no longer reads through the
  // fitted corners) a libapriltag candidate is still kept, with its own
  // corners (TagDetection::edge_fitted = false), if libapriltag decoded it
  // with at most fallback_max_hamming corrected bits and a decision margin of
  // at least fallback_min_decision_margin [grey levels], and its cells
  // re-read by us through its corners give the same id within max_hamming.
  bool keep_unrefined_tags = true;
  int fallback_max_hamming = 1;           // in [0, 2]
  double fallback_min_decision_margin = 0.0; // >= 0
  // Standard deviation of each coordinate of such a corner [px] (its
  // covariance is this squared times identity): the RMS error of
  // libapriltag's corners measured on the composite photographs (docs).
  double fallback_corner_sigma_px = 0.45;

  // OpenCV's cornerSubPix half window for kOpenCvSubpix [px], >= 1.
  int subpix_half_window_px = 3;

  // OK, or names the field, its value and the broken constraint.
  Status Validate() const;
};

struct TagDetection {
  int id = 0;                                  // tag36h11 id
  std::array<Eigen::Vector2d, 4> corners_px;   // corner order above
  // Covariance of each corner [px^2]: the edge fit's (edge_fitted), else
  // fallback_corner_sigma_px^2 I (kEdgeFit) or zero (the OpenCV refinements).
  std::array<Eigen::Matrix2d, 4> corner_covariance_px2;
  TagSource source = TagSource::kAprilTag;     // who proposed the candidate
  bool edge_fitted = false;   // corners from the edge fit (else the candidate's)
  int hamming = 0;            // bits corrected to read the id (our re-read through corners_px)
  double decision_margin = 0.0; // libapriltag's decision margin [grey levels of the 8-bit image]; 0 for aruco
  double edge_contrast = 0.0; // fitted step b (white - black) [grey levels of the input]; unrefined: quiet zone - border means
  double edge_sigma_px = 0.0; // mean fitted edge spread [px], edge fit only
  double edge_rms = 0.0;      // RMS residual of the edge fits [grey levels], edge fit only
  // Covariance of corner c with corner (c + 1) % 4, E[(x_c - mu)(x_{c+1} - mu)^T]
  // [px^2]: through the edge they share (edge fit only; else zero). Corners
  // c and c + 2 share no edge: uncorrelated.
  std::array<Eigen::Matrix2d, 4> corner_cross_covariance_px2 = {Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero(),
                                                                Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero()};
};

// Detects the tag36h11 tags in a grayscale image (see above). Tags are
// returned in increasing id; an id seen twice is returned twice.
Result<std::vector<TagDetection>> DetectTags(const cv::Mat& image,
                                             const TagDetectionOptions& options = {});

}  // namespace opl
