// Identifying spots: which source and which beam made each point of an
// unordered point set (docs/identify.md).
//
// Photogrammetry exports the projected laser spots as 3D points in an unscaled
// scene frame, in no particular order, mixed with points that are not spots of
// any grid (speckle, reflections, targets). IdentifySpots assigns every point
// to a (source, beam id) of a module calibration, or leaves it unassigned.
//
// The model. A source at scene_from_source = (R, t) sends beam b along the
// calibrated unit direction d_b (source frame), so its spot p_b satisfies
//
//   q_b = R^T (point_in_scene - t),    angle(q_b, d_b) ~ spot noise / range.
//
// Nothing else is assumed: any rotation, any distance, any surface (the
// points need not be coplanar), several grids overlapping, spots missing,
// spurious points. Only angles and ratios are used, so the result does not
// depend on the (arbitrary) units of the scene.
//
// The algorithm (docs/identify.md has the details and the measured figures):
//  1. Seeds. For every point, its nearest neighbours in 3D; a seed is a point
//     p0 with two pairs of opposite neighbours p0 +- a, p0 +- b (a local
//     "cross" of the lattice) and its patch (the cross plus the points found
//     at p0 +- a +- b, p0 +- 2a, p0 +- 2b, predicted to second order along
//     each axis); best supported first.
//     Interleaved grids (two grids of one pattern translated by about half
//     a pitch, e.g. side-by-side sources on a wall) make crosses that mix
//     both grids: every other point of an axis belongs to the other grid.
//     Such a seed explains nothing, or fits a wrong pose to part of the
//     union with a noise far above the spots'. Hence: the second-order
//     prediction does not support a mixed axis (its bend alternates);
//     when a seed gives no clear detection (noise below a quarter of the
//     acceptance limit), the detections of its derived crosses (2a, b),
//     (a, 2b) and (a + b, a - b), with the patch points on their lattice,
//     compete with its own (budget: max_seeds more); a detection that is
//     not clear is decided only after 16 seeds gave nothing clear (then
//     the seeds run again deciding on everything); and when a source is
//     found and others remain, seeds are computed again from the points
//     still free (the other grid's own crosses used the found grid's
//     points; budget: max_seeds more).
//  1b. Large sets (above 4096 points). Before a seed is tried its patch is
//     grown over its grid: breadth-first, a node next to grown ones is
//     predicted from them (linearly, and by parallelograms across) and takes
//     the one free point within a quarter step of the prediction (none when
//     two are there). The grown offsets are the histogram of step 2 (no
//     pose needed), and a hypothesis' patch pose is carried out ring by
//     ring (radius 4, 8, 16, ...) over an even subset of the grown nodes,
//     from each P3P pose of the cross (a small patch does not tell a pose
//     from its tilted twin), so that it holds over the whole grid; the
//     growth stages of step 3 look only at points near the seed. Without it
//     a 71 x 71 grid took dozens of failed seeds (a patch pose holds only a
//     few nodes away). The k nearest neighbours of step 1 come from a grid
//     of cells instead of a sweep (the same neighbours, exactly), and the
//     growth's radius queries from the same grid.
//  2. Hypotheses. The patch is taken as lattice nodes L + g o (o its offsets,
//     g one of the 8 symmetries of the square). The patch's pose at the
//     central node gives a pose; every point is mapped through it to
//     continuous lattice coordinates (an affine lattice model fitted to the
//     pattern: tangent angles for equal-angle patterns, direction cosines for
//     gratings) and the integer offsets from p0 are histogrammed; for each g
//     the nodes L that put most offsets inside the pattern (2D prefix sums)
//     are hypotheses. Those of all sources, merged by count, are checked
//     exactly: the patch's pose at (L, g), scored by the points whose nearest
//     beam (looked up through the lattice model, 3 x 3 nodes) is within
//     `score_gate_fraction` of the spacing. Once the best score reaches the
//     next count (or its pattern's beam count) that pose is refined (step 3);
//     a clear refinement settles the seed. The patch's pose: a least-squares
//     fit started from the best P3P pose of the seed's cross, or LocateSource
//     with RANSAC when no P3P pose fits 90% of the patch.
//  3. Refinement. The best distinct candidates grow from the seed: points in
//     the loose gate within 2, 3, 5, 8 nodes, then all, LocateSource after
//     each stage; then the gate shrinks to assign_gate_sigma * sigma (sigma:
//     robust per-component angular noise, median / sqrt(2 ln 2)) until the
//     assignment is stable. Two points in the gate of one beam: the better is
//     kept only when its chi^2 is lower by `conflict_margin_chi2`, otherwise
//     neither. Too few points, or sigma above `max_sigma_fraction` of the
//     spacing: rejected.
//  4. Alternatives. The best hypothesis' points relabelled by the 8
//     symmetries about the pattern centre, in its own and every other unfound
//     source, are posed (P3P on well-spread points) and refined too.
//  5. Ambiguity. Each refined hypothesis h has a truncated chi^2 over every
//     point still to identify, C_h = sum min(r^2 / sigma^2, assign_gate_sigma^2)
//     (r: angle to the nearest beam under h's pose, one common sigma). The
//     lowest C wins; another hypothesis with a different correspondence (a
//     roll, a mirror on a plane, another source's pattern) within
//     `ambiguity_chi2` (25: a 5 sigma likelihood-ratio margin) makes the
//     source ambiguous: none of its points is assigned and the reason is
//     given. A pattern symmetric under a roll (a perfect equal-angle or
//     grating design) is always ambiguous; calibrated directions that break
//     the symmetry by a few noise sigmas resolve it.
//  6. The found source's points leave the pool; the next seeds look for the
//     remaining sources. Finally a point assigned to one source that also
//     lies in the gate of a beam of another found source is unassigned
//     (overlapping grids: it could be either's spot).
//
// Input contract. A spot whose `source` is empty and/or whose
// `observation.beam_id` is 0 is to be identified. A spot naming a source but
// beam 0 may only be assigned to that source. A spot naming both is passed
// through unchanged (it is not used as an anchor; its beam is not given to
// another point). Errors (Status, never an abort): InvalidArgument for bad
// options or calibration, a non-finite point, a negative beam id, a spot
// naming an unknown source; the message starts with the spot's `where`
// (e.g. "spots.csv:14: ..."). Ambiguity and not-found are results, reported
// per source, not errors.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"

namespace opl {

// Where IdentifySpots stands (IdentifyOptions::progress). The search ends
// when every source is found or the seed budgets run out, so there is no
// total to count towards: seeds_tried counts the seeds and derived crosses
// tried so far (both passes), and the other fields what they found.
struct IdentifyProgress {
  int seeds_tried = 0;
  int sources_found = 0;    // of num_sources, found without ambiguity
  int num_sources = 0;
  int points_assigned = 0;  // of points (the unassigned spots given)
  int points = 0;
  bool finished = false;    // the last call, with the result's counts
};

struct IdentifyOptions {
  // Final assignment gate, in robust noise standard deviations: a point is
  // assigned to a beam when the angle between its direction (seen from the
  // located origin) and the beam's is below assign_gate_sigma * sigma, sigma
  // the per-component angular noise estimated from the source's residuals.
  double assign_gate_sigma = 4.5;
  // Floor of that sigma, radians (noise-free data would otherwise give a zero
  // gate). 1e-6 rad is 1 um at 1 m.
  double min_sigma_rad = 1e-6;
  // Gate used to score pose hypotheses before refinement, as a fraction of
  // the pattern's median angle between neighbouring beams (the pose from
  // three neighbouring spots is only approximate far from them).
  double score_gate_fraction = 0.15;
  // A detection whose robust angular noise sigma exceeds this fraction of the
  // beam spacing is rejected (0.02: 1 mrad for a 29 deg 11 x 11 grid, four
  // times the noise of 0.1 mm spots 0.4 m away). Calibrated directions of
  // another source or a wrong correspondence of a nearly symmetric pattern
  // scatter by the pattern differences (mrad); nominal directions add
  // nominal_tolerance_rad.
  double max_sigma_fraction = 0.02;
  // When the calibration's directions are only nominal (design values, not a
  // calibration of this module), their error adds to the noise: the gate
  // becomes sqrt((assign_gate_sigma sigma)^2 + nominal_tolerance_rad^2).
  bool directions_nominal = false;
  double nominal_tolerance_rad = 3e-3;
  // A source counts as found only with at least this many assigned points.
  int min_spots = 8;
  // ... and at least this fraction of its pattern's beams. A pose fitted to
  // a few points of overlapping grids can explain a dozen by chance; a real
  // grid shows most of its spots (the requirement: up to 30% missing).
  double min_fraction = 0.25;
  // Two points within the gate of one beam: the better one is assigned only
  // when its r^2 / sigma^2 is lower than the other's by at least this much
  // (20: likelihood ratio ~ 2e4); otherwise neither is.
  double conflict_margin_chi2 = 20.0;
  // Two hypotheses with different correspondences whose truncated chi^2
  // (header comment, step 4) differ by less than this are indistinguishable:
  // the source is reported ambiguous.
  double ambiguity_chi2 = 25.0;
  // Neighbours examined per point when looking for seeds (3D nearest).
  int neighbours = 16;
  // Seeds tried per round before giving up on the remaining sources; the
  // derived crosses and the seeds of the free points (header comment,
  // step 1) have budgets of as many again.
  int max_seeds = 400;
  // Candidate hypotheses refined per seed (the best by exact score).
  int max_refined = 8;
  // Prior on the orientation of sources, by name: the expected rotation of
  // scene_from_source (e.g. how a module is mounted in a calibration set-up:
  // identify_slices.h). A hypothesis of such a source rotated by more than
  // expected_rotation_tolerance_deg from it is not considered, so that an
  // ideal pattern, symmetric under a 90 deg roll, is numbered as mounted
  // instead of being ambiguous. Empty: no prior (measurements).
  std::map<std::string, Eigen::Matrix3d> expected_rotation;
  double expected_rotation_tolerance_deg = 30.0;
  // Prior on the projection origins, by name (scene units): a hypothesis of
  // such a source whose origin is farther than expected_origin_tolerance from
  // it is not considered. This tells apart sources with the same pattern
  // mounted side by side. Empty: no prior.
  std::map<std::string, Eigen::Vector3d> expected_origin;
  double expected_origin_tolerance = 0.0;  // > 0 when expected_origin is given
  // Threads for the seed search (step 1), >= 1. The result does not depend
  // on it (the points are split into ranges and the seeds merged in order).
  int num_threads = 1;
  // Seed of the only random choice (LocateSource's RANSAC when it runs);
  // fixed: results repeat run to run.
  uint64_t seed = 1;

  // Called as the search goes (IdentifyProgress, below): once before the
  // first seed, after every seed tried, and once at the end with the final
  // counts. For a progress display of large point sets (the tools draw it on
  // a terminal); it must not call back into the identification. Empty: none.
  std::function<void(const IdentifyProgress&)> progress{};

  // Checks every field; the message names the field, its value and the rule.
  Status Validate() const;
};

enum class IdentifyOutcome { kFound, kNotFound, kAmbiguous };

// "found", "not found", "ambiguous".
const char* IdentifyOutcomeName(IdentifyOutcome outcome);

struct IdentifiedSource {
  std::string name;
  IdentifyOutcome outcome = IdentifyOutcome::kNotFound;
  std::string detail;          // why ambiguous / not found; empty when found
  Rigid3d scene_from_source;   // when found (scene units)
  int assigned = 0;            // points assigned to it by IdentifySpots
  double rms_residual_rad = 0;  // RMS angle residual of its assigned points, per component
  double sigma_rad = 0;        // robust per-component angular noise used for the gate
  // The module placement of the spots it was identified among (Spot::
  // placement), when MeasureScale identified several placements' spots,
  // one placement at a time; empty otherwise.
  std::string placement{};
};

struct IdentifyResult {
  // One entry per input spot, in input order: index into `sources`
  // (= calibration order) or -1, and beam id or 0. Passed-through spots
  // (source and beam given) appear with their own source and beam.
  std::vector<int> source_index;
  std::vector<int> beam_id;
  // One per calibrated source, calibration order (MeasureScale with spots
  // at several placements: that per placement, in order of first appearance).
  std::vector<IdentifiedSource> sources;
  int passed_through = 0;                 // spots given with source and beam

  int num_assigned() const;    // entries with source_index >= 0 (passed through included)
  int num_unassigned() const;  // entries with source_index == -1
  // Short readable report: per source outcome, assigned count, rms (urad),
  // detail; the number of unassigned points.
  std::string ToText() const;
};

// See the header comment for the contract.
Result<IdentifyResult> IdentifySpots(const ModuleCalibration& calibration,
                                     const std::vector<Spot>& spots,
                                     const IdentifyOptions& options = IdentifyOptions());

// The assigned spots with source and beam filled in (unassigned ones dropped),
// input order. `result` must come from IdentifySpots on these spots (sizes
// equal); otherwise an empty vector.
std::vector<Spot> AssignedSpots(const std::vector<Spot>& spots, const IdentifyResult& result);

}  // namespace opl
