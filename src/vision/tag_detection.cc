#include "opl/vision/tag_detection.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "opl/core/format.h"
#include "vision/apriltag_candidates.h"
#include "vision/tag_edge_fit.h"

namespace opl {
namespace {

using tag_internal::EdgeCurve;
using tag_internal::kTagCells;
using tag_internal::TagCandidate;

constexpr int kTag36h11MaxCorrectionBits = 5;  // (minimum distance 11 - 1) / 2

const cv::aruco::Dictionary& Tag36h11() {
  static const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  return *dictionary;
}

// Bits corrected to read `id` from the data cells sampled through the quad.
int Hamming(const cv::Mat& image, const std::array<Eigen::Vector2d, 4>& corners, int id, double sharpening,
            double* contrast) {
  const cv::Mat bits = tag_internal::ReadTagBits(image, corners, sharpening, contrast);
  return Tag36h11().getDistanceToId(bits, id, false);
}

// aruco's candidates (contour quads, ids) in `gray8`, refined by aruco as
// `refinement` says (kEdgeFit: not refined).
std::vector<TagCandidate> ArucoCandidates(const cv::Mat& gray8, const TagDetectionOptions& options) {
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
  switch (options.refinement) {
    case TagCornerRefinement::kOpenCvAprilTag:
      params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_APRILTAG;
      break;
    case TagCornerRefinement::kOpenCvSubpix:
      params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
      break;
    default:
      params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;
  }
  // More adaptive-threshold windows (3, 7, .., 23 px) than the default (3, 13,
  // 23) find tilted tags with a narrow quiet zone; candidates closer than
  // aruco's default distance are kept (the black square and its quiet zone
  // make two close quads) and duplicates removed after refinement.
  params->adaptiveThreshWinSizeStep = 4;
  params->minMarkerDistanceRate = 0.01;
  params->cornerRefinementWinSize = options.subpix_half_window_px;
  params->cornerRefinementMinAccuracy = 0.001;
  params->cornerRefinementMaxIterations = 100;
  params->errorCorrectionRate = static_cast<double>(options.max_hamming) / kTag36h11MaxCorrectionBits;
  std::vector<std::vector<cv::Point2f>> quads;
  std::vector<int> ids;
  cv::aruco::detectMarkers(gray8, dictionary, quads, ids, params);
  std::vector<TagCandidate> candidates;
  for (size_t k = 0; k < ids.size(); ++k) {
    if (quads[k].size() != 4) continue;
    TagCandidate c;
    c.id = ids[k];
    c.source = TagSource::kAruco;
    for (int i = 0; i < 4; ++i) c.corners_px[i] = Eigen::Vector2d(quads[k][i].x, quads[k][i].y);
    candidates.push_back(c);
  }
  return candidates;
}

Eigen::Vector2d Centre(const std::array<Eigen::Vector2d, 4>& corners) {
  return 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
}

double Side(const std::array<Eigen::Vector2d, 4>& corners) {
  double side = 0.0;
  for (int c = 0; c < 4; ++c) side += 0.25 * (corners[(c + 1) % 4] - corners[c]).norm();
  return side;
}

// Refines one candidate by the edge fit (or keeps it unrefined, see
// keep_unrefined_tags) and checks its id. `gray`: the full-resolution image
// (8 or 16 bit). False: no tag.
bool RefineCandidate(const cv::Mat& gray, const TagCandidate& candidate, const TagDetectionOptions& options,
                     TagDetection* det) {
  det->id = candidate.id;
  det->source = candidate.source;
  det->decision_margin = candidate.decision_margin;
  det->corners_px = candidate.corners_px;
  for (Eigen::Matrix2d& c : det->corner_covariance_px2) c.setZero();
  for (Eigen::Matrix2d& c : det->corner_cross_covariance_px2) c.setZero();
  const double side = Side(det->corners_px);
  Eigen::Vector2d centre = Centre(det->corners_px);

  // The pixels around the tag, as doubles (the edge fit and the id check
  // read nothing farther than the band from the quad); coordinates in the
  // window are shifted by its origin.
  const double margin = 2.0 * options.max_edge_band_px + 8.0 + 0.1 * side;
  double x0 = centre.x(), x1 = centre.x(), y0 = centre.y(), y1 = centre.y();
  for (const Eigen::Vector2d& c : det->corners_px) {
    x0 = std::min(x0, c.x()), x1 = std::max(x1, c.x());
    y0 = std::min(y0, c.y()), y1 = std::max(y1, c.y());
  }
  const int wx0 = std::clamp(static_cast<int>(std::floor(x0 - margin)), 0, gray.cols - 1);
  const int wy0 = std::clamp(static_cast<int>(std::floor(y0 - margin)), 0, gray.rows - 1);
  const int wx1 = std::clamp(static_cast<int>(std::ceil(x1 + margin)), 0, gray.cols - 1);
  const int wy1 = std::clamp(static_cast<int>(std::ceil(y1 + margin)), 0, gray.rows - 1);
  const cv::Rect window(wx0, wy0, wx1 - wx0 + 1, wy1 - wy0 + 1);
  cv::Mat gray64;
  gray(window).convertTo(gray64, CV_64F);
  const Eigen::Vector2d origin(wx0, wy0);
  std::array<Eigen::Vector2d, 4> local = det->corners_px;
  for (Eigen::Vector2d& c : local) c -= origin;
  centre -= origin;

  if (options.refinement != TagCornerRefinement::kEdgeFit) {
    det->hamming = Hamming(gray64, local, det->id, options.decode_sharpening, nullptr);
    return det->hamming <= options.max_hamming;
  }

  // The edge fit. Each edge's band and corner exclusion are in cells of the
  // tag as seen across and along that edge (an oblique tag's cells are
  // narrower one way than the other).
  const double cell = side / kTagCells;
  std::array<double, 4> length;
  for (int e = 0; e < 4; ++e) length[e] = (local[(e + 1) % 4] - local[e]).norm();
  std::array<EdgeCurve, 4> edges;
  bool ok = true;
  for (int e = 0; e < 4 && ok; ++e) {
    const double across_cell = 0.5 * (length[(e + 1) % 4] + length[(e + 3) % 4]) / kTagCells;
    tag_internal::EdgeFitSettings fit;
    fit.band_px = std::max(1.0, std::min(options.max_edge_band_px, options.edge_band_cells * across_cell));
    fit.corner_exclusion_px = options.edge_corner_exclusion_px;
    fit.max_sigma_px = options.max_edge_sigma_px;
    ok = tag_internal::FitEdge(gray64, local[e], local[(e + 1) % 4], centre, fit, &edges[e]);
  }
  std::array<Eigen::Vector2d, 4> refined;
  std::array<Eigen::Matrix2d, 4> covariance;
  // d corner c / d (theta, c, kappa) of its first edge (c - 1) and second (c).
  std::array<Eigen::Matrix<double, 2, 3>, 4> d_first, d_second;
  // A corner may move from the candidate's by at most 3 px and half a cell
  // (further: the fit locked on another edge, e.g. the quiet zone's).
  const double max_move = std::min(3.0, std::max(1.0, 0.5 * cell));
  for (int c = 0; c < 4 && ok; ++c) {
    // Corner c joins edge c-1 (from corner c-1 to c) and edge c.
    ok = tag_internal::IntersectEdges(edges[(c + 3) % 4], edges[c], local[c], max_move, &refined[c],
                                      &covariance[c], &d_first[c], &d_second[c]);
  }
  if (ok) {
    double contrast = 0.0;
    const int hamming = Hamming(gray64, refined, det->id, options.decode_sharpening, &contrast);
    if (hamming <= options.max_hamming) {
      det->hamming = hamming;
      det->edge_fitted = true;
      det->corner_covariance_px2 = covariance;
      // Corners c and c + 1 share edge c (the edges' fits are independent:
      // disjoint pixels).
      for (int c = 0; c < 4; ++c) {
        det->corner_cross_covariance_px2[c] = d_second[c] * edges[c].cov * d_first[(c + 1) % 4].transpose();
      }
      for (int c = 0; c < 4; ++c) det->corners_px[c] = refined[c] + origin;
      double rms2 = 0.0;
      det->edge_contrast = det->edge_sigma_px = 0.0;
      for (const EdgeCurve& e : edges) {
        det->edge_contrast += 0.25 * e.b;
        det->edge_sigma_px += 0.25 * e.sigma;
        rms2 += 0.25 * e.rms * e.rms;
      }
      det->edge_rms = std::sqrt(rms2);
      return true;
    }
  }
  // The edge fit failed: keep a cleanly decoded libapriltag candidate as it is.
  if (!options.keep_unrefined_tags || candidate.source != TagSource::kAprilTag ||
      candidate.hamming > options.fallback_max_hamming ||
      candidate.decision_margin < options.fallback_min_decision_margin) {
    return false;
  }
  double contrast = 0.0;
  det->hamming = Hamming(gray64, local, det->id, options.decode_sharpening, &contrast);
  if (det->hamming > options.max_hamming) return false;
  det->edge_fitted = false;
  det->edge_contrast = contrast;
  const double v = options.fallback_corner_sigma_px * options.fallback_corner_sigma_px;
  for (Eigen::Matrix2d& c : det->corner_covariance_px2) c = v * Eigen::Matrix2d::Identity();
  return true;
}

}  // namespace

Status TagDetectionOptions::Validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    return Status::InvalidArgument("TagDetectionOptions." + field + " = " + FormatNumber(value, 6) +
                                   ": " + rule);
  };
  if (!(quad_decimate == 1.5 || (quad_decimate >= 1.0 && quad_decimate <= 8.0 &&
                                 quad_decimate == std::floor(quad_decimate)))) {
    return bad("quad_decimate", quad_decimate, "must be 1.5 or an integer in [1, 8]");
  }
  if (!(quad_sigma >= 0.0 && quad_sigma <= 10.0)) return bad("quad_sigma", quad_sigma, "must be in [0, 10]");
  if (num_threads < 1 || num_threads > 64) return bad("num_threads", num_threads, "must be in [1, 64]");
  if (!(decode_sharpening >= 0.0 && decode_sharpening <= 10.0)) {
    return bad("decode_sharpening", decode_sharpening, "must be in [0, 10]");
  }
  if (!(candidate_max_megapixels >= 0.5 && std::isfinite(candidate_max_megapixels))) {
    return bad("candidate_max_megapixels", candidate_max_megapixels, "must be finite and >= 0.5");
  }
  if (!use_apriltag && !use_aruco && refinement == TagCornerRefinement::kEdgeFit) {
    return bad("use_apriltag", 0.0, "and use_aruco are both false: no candidates");
  }
  if (!(min_tag_side_px >= 6.0 && std::isfinite(min_tag_side_px))) {
    return bad("min_tag_side_px", min_tag_side_px, "must be finite and >= 6");
  }
  if (!(edge_corner_exclusion_px >= 1.0 && edge_corner_exclusion_px <= 50.0)) {
    return bad("edge_corner_exclusion_px", edge_corner_exclusion_px, "must be in [1, 50]");
  }
  if (!(edge_band_cells > 0.0 && edge_band_cells <= 0.9)) {
    return bad("edge_band_cells", edge_band_cells, "must be in (0, 0.9]");
  }
  if (!(max_edge_band_px >= 1.0 && std::isfinite(max_edge_band_px))) {
    return bad("max_edge_band_px", max_edge_band_px, "must be finite and >= 1");
  }
  if (!(max_edge_sigma_px > 0.0 && std::isfinite(max_edge_sigma_px))) {
    return bad("max_edge_sigma_px", max_edge_sigma_px, "must be finite and > 0");
  }
  if (max_hamming < 0 || max_hamming > kTag36h11MaxCorrectionBits) {
    return bad("max_hamming", max_hamming, "must be in [0, 5]");
  }
  if (fallback_max_hamming < 0 || fallback_max_hamming > 2) {
    return bad("fallback_max_hamming", fallback_max_hamming, "must be in [0, 2]");
  }
  if (!(fallback_min_decision_margin >= 0.0 && std::isfinite(fallback_min_decision_margin))) {
    return bad("fallback_min_decision_margin", fallback_min_decision_margin, "must be finite and >= 0");
  }
  if (!(fallback_corner_sigma_px > 0.0 && std::isfinite(fallback_corner_sigma_px))) {
    return bad("fallback_corner_sigma_px", fallback_corner_sigma_px, "must be finite and > 0");
  }
  if (subpix_half_window_px < 1 || subpix_half_window_px > 50) {
    return bad("subpix_half_window_px", subpix_half_window_px, "must be in [1, 50]");
  }
  switch (refinement) {
    case TagCornerRefinement::kNone:
    case TagCornerRefinement::kOpenCvAprilTag:
    case TagCornerRefinement::kOpenCvSubpix:
    case TagCornerRefinement::kEdgeFit:
      break;
    default:
      return bad("refinement", static_cast<double>(refinement), "unknown value");
  }
  return Status::Ok();
}

Result<std::vector<TagDetection>> DetectTags(const cv::Mat& image, const TagDetectionOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (image.empty()) return Status::InvalidArgument("DetectTags: image is empty");
  cv::Mat gray;
  double scale_to_8bit = 1.0;
  if (image.type() == CV_8UC1) {
    gray = image;
  } else if (image.type() == CV_8UC3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.type() == CV_16UC1) {
    gray = image;
    // Stretch to 8 bits for the candidate search by the image's maximum, so
    // that 10- or 12-bit data in a 16-bit container are not crushed to a few
    // levels.
    double lo = 0.0, hi = 0.0;
    cv::minMaxLoc(gray, &lo, &hi);
    scale_to_8bit = 255.0 / std::max(hi, 1.0);
  } else {
    return Status::InvalidArgument("DetectTags: image type " + std::to_string(image.type()) +
                                   " (depth " + std::to_string(image.depth()) + ", " +
                                   std::to_string(image.channels()) +
                                   " channels): expected CV_8UC1, CV_16UC1 or CV_8UC3");
  }
  cv::Mat gray8;
  if (gray.depth() == CV_8U) {
    gray8 = gray;
  } else {
    gray.convertTo(gray8, CV_8U, scale_to_8bit);
  }

  // Candidates. Large images (edge fit only): in a reduced copy, refined at
  // full resolution.
  const bool edge_fit = options.refinement == TagCornerRefinement::kEdgeFit;
  int factor = 1;
  if (edge_fit) {
    const double megapixels = static_cast<double>(gray8.total()) * 1e-6;
    while (megapixels / (factor * factor) > options.candidate_max_megapixels) ++factor;
  }
  cv::Mat searched = gray8;
  if (factor > 1) {
    cv::resize(gray8, searched, cv::Size(gray8.cols / factor, gray8.rows / factor), 0.0, 0.0, cv::INTER_AREA);
  }
  std::vector<TagCandidate> candidates;
  if (edge_fit && options.use_apriltag) {
    tag_internal::AprilTagSettings at;
    at.quad_decimate = options.quad_decimate;
    at.quad_sigma = options.quad_sigma;
    at.nthreads = options.num_threads;
    at.refine_edges = options.refine_edges;
    at.decode_sharpening = options.decode_sharpening;
    at.max_bits_corrected = std::min(options.max_hamming, 2);
    Result<std::vector<TagCandidate>> found = tag_internal::FindAprilTagCandidates(searched, at);
    OPL_RETURN_IF_ERROR(found.status());
    // The clearest decodes first: they win over duplicates.
    std::stable_sort(found->begin(), found->end(), [](const TagCandidate& a, const TagCandidate& b) {
      return a.decision_margin > b.decision_margin;
    });
    candidates = std::move(*found);
  }
  if (!edge_fit || options.use_aruco) {
    std::vector<TagCandidate> aruco = ArucoCandidates(searched, options);
    candidates.insert(candidates.end(), aruco.begin(), aruco.end());
  }
  if (factor > 1) {
    // Pixel centres: reduced (x', y') is full-resolution f x' + (f - 1) / 2.
    const double f = factor, offset = 0.5 * (f - 1.0);
    for (TagCandidate& c : candidates) {
      for (Eigen::Vector2d& p : c.corners_px) p = f * p + Eigen::Vector2d(offset, offset);
    }
  }

  std::vector<TagDetection> detections;
  for (const TagCandidate& candidate : candidates) {
    const double side = Side(candidate.corners_px);
    if (!(side >= options.min_tag_side_px)) continue;
    // Every corner at least 1 px inside the image: libapriltag, unlike aruco,
    // proposes tags cut by the image border, whose edge fits are biased with
    // a tiny covariance (one such tag, 0.08 px off with a reported 0.005 px,
    // took a noise-free calibration in tests/pipeline from 1.4 to 8.8 urad).
    const double inset = 1.0;
    bool inside = true;
    for (const Eigen::Vector2d& p : candidate.corners_px) {
      inside = inside && p.x() >= inset && p.y() >= inset && p.x() <= gray.cols - 1 - inset &&
               p.y() <= gray.rows - 1 - inset;
    }
    if (!inside) continue;
    // The same tag proposed twice (by both detectors, or aruco's black square
    // and quiet zone): the first one refined is kept.
    const Eigen::Vector2d centre = Centre(candidate.corners_px);
    bool duplicate = false;
    for (const TagDetection& other : detections) {
      if (other.id == candidate.id && (Centre(other.corners_px) - centre).norm() < 0.35 * side) duplicate = true;
    }
    if (duplicate) continue;
    TagDetection det;
    if (RefineCandidate(gray, candidate, options, &det)) detections.push_back(det);
  }
  std::stable_sort(detections.begin(), detections.end(),
                   [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  return detections;
}

}  // namespace opl
