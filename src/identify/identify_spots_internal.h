// Private to src/identify: the pieces of IdentifySpots shared by its files
// (opl/identify/identify_spots.h has the contract and the algorithm's steps).
//
//   pattern_index.h/.cc       a pattern's lattice model and nearest-beam lookup
//   nearest_neighbours.h/.cc  one index of the points: k nearest (step 1),
//                             points within a radius (step 1b)
//   identify_seeds.cc         step 1: seeds (lattice crosses among the points)
//   identify_growth.cc        step 1b (large sets): a seed's patch grown over its grid
//   identify_hypotheses.cc    step 2: hypotheses of a seed, their poses, scores
//   identify_refine.cc        step 3: a candidate grown and refined; assignment
//   identify_rivals.cc        steps 4-5: alternatives of a detection, its cost
//   identify_spots.cc         IdentifySpots: the search over seeds, decisions
//   identify_result.cc        options validation, result counts and text
//
// Frames: points are in the scene frame; a pose PoseRt is source_from_scene,
// a Rigid3d scene_from_source. Angles are chords of unit vectors in the
// source frame, in rad (~ the angle for small angles).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "identify/pattern_index.h"
#include "opl/geometry/rigid3.h"
#include "opl/identify/identify_spots.h"
#include "opl/locate/p3p.h"
#include "opl/locate/pose_normal_equations.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"

namespace opl {
namespace identify_internal {

class NearestNeighbours;  // nearest_neighbours.h

// The points to identify.
struct Pool {
  std::vector<Eigen::Vector3d> p;   // scene
  std::vector<int> spot;            // input index
  std::vector<int> only_source;     // -1: any source
  std::vector<char> taken;          // assigned to a found source
  std::vector<char> blocked;        // not to be used as a seed point any more
  int size() const { return static_cast<int>(p.size()); }
};

struct Seed {
  int p0 = 0, pa = 0, pb = 0;
  double quality = 0.0;  // smaller is better
  // The seed's lattice patch: points and their (col, row) offsets from p0
  // along (a, b): p0, p0 +- a, p0 +- b and the supported p0 +- a +- b,
  // p0 +- 2a, p0 +- 2b.
  std::vector<std::pair<int, Eigen::Vector2i>> patch;
  // Large sets only (GrowSeed): the patch grown over the grid, every node
  // (point, offset), the patch's first; and the far nodes (beyond the
  // patch's +-2) that carry the patch pose out (Identifier::ExtendPatchPose):
  // rings of radius (2, 4], (4, 8], ..., of each an even sub-lattice of at
  // most about 24 nodes.
  std::vector<std::pair<int, Eigen::Vector2i>> grown{};
  std::vector<std::pair<int, Eigen::Vector2i>> far{};
};

// Point sets above this size are identified with grown seeds (GrowSeed);
// smaller ones exactly as before growth existed.
inline constexpr int kGrowPoolSize = 4096;

// The scale of GrowSeed's queries: cells of half the set's typical lattice
// step (the median step of the best seeds, at most 32 of them), at least
// 2^-20 of the points' extent, on a lattice anchored at the points' lower
// corner. A query whose ball's bounding box spans more than 4096 of them
// (the product over the axes of the differences of its corners' cell
// indices) is not a local one: the growth has left the scale of the set's
// lattices. So is one whose box lies beyond the points' (nothing there).
struct GrowthScale {
  Eigen::Vector3d corner = Eigen::Vector3d::Zero();  // scene
  double cell = 1.0;                                 // scene units
  bool Local(const Eigen::Vector3d& centre, double radius) const;
};
GrowthScale MakeGrowthScale(const std::vector<Seed>& seeds, const Pool& pool);

// Grows the seed's patch over its lattice (identify_growth.cc): nodes
// predicted from their grown neighbours take the one free point near the
// prediction, found by `points` (an index of pool.p: Within); fills
// seed->grown and seed->far. Offsets stay within [-max_extent, max_extent];
// a node whose query is not local (`scale`) is not grown.
void GrowSeed(const Pool& pool, const NearestNeighbours& points, const GrowthScale& scale, int max_extent,
              Seed* seed);

// The seeds of the pool (identify_spots.h, step 1), best first: points with
// two pairs of opposite neighbours among their min(k, size - 1) nearest
// (`neighbours`, an index of pool.p built for k), worked in `threads`
// threads (the result does not depend on their number).
std::vector<Seed> FindSeeds(const Pool& pool, const NearestNeighbours& neighbours, int threads);

// The crosses (2a, b), (a, 2b) and (a + b, a - b) derived from a seed's
// cross (a, b), with the patch points on their lattice.
std::vector<Seed> DerivedSeeds(const Seed& seed);

// One refined explanation of some points by one source.
struct Detection {
  int source = -1;
  Rigid3d scene_from_source;
  double sigma = 0.0;  // robust per-component angular noise, rad
  std::vector<int> point;   // pool indices
  std::vector<int> beam;    // beam ids, parallel
  std::vector<double> residual;  // angles, rad, parallel
  double cost = 0.0;        // truncated chi^2 over the pool (set by the caller)
  int conflicts = 0;
};

// Most eligible points a hypothesis is scored on (Identifier::Candidates):
// above it, an evenly strided subset and a scaled count.
inline constexpr Eigen::Index kScoreSampleSize = 4096;

struct Candidate {
  int source = -1;
  PoseRt pose;  // source_from_scene
  int score = 0;
  // Lattice node (col, row) of the seed point; refinement grows from it when
  // `grow` (a pose from three neighbouring spots is right only near them).
  Eigen::Vector2i node = Eigen::Vector2i::Zero();
  bool grow = false;
  // The seed's point (at `node`) and its longer cross step, scene units:
  // for large sets the growth stages look only at the points near it
  // (Identifier::Refine). -1: at all points.
  int seed_point = -1;
  double seed_step = 0.0;
};

// True when a and b give (mostly) the same correspondence.
bool SameCorrespondence(const Detection& a, const Detection& b);

// The steps of the search on one pool of points for the sources of one
// calibration (their PatternIndex), and the limits that accept a detection.
// The pool is read (taken points are skipped), never changed. One thread.
class Identifier {
 public:
  Identifier(const ModuleCalibration& calibration, const IdentifyOptions& options, Pool* pool,
             const std::vector<std::vector<char>>& beam_reserved)
      : calibration_(calibration), options_(options), pool_(*pool), reserved_(beam_reserved) {
    for (const SourceCalibration& s : calibration.sources) index_.push_back(BuildIndex(s.pattern));
  }

  const PatternIndex& index(int s) const { return index_[s]; }

  // Large sets (step 1b): Refine's growth stages look only at the points
  // near the seed's (Candidate::seed_point). Off (the default): at every point.
  void set_local_growth(bool local) { local_growth_ = local; }

  bool Eligible(int i, int s) const {
    return !pool_.taken[i] && (pool_.only_source[i] < 0 || pool_.only_source[i] == s);
  }

  // A hypothesis of step 2: the seed point at lattice node L0 of source s,
  // its patch's offsets mapped by symmetry g; `count` estimates how many
  // points it explains (the histogram).
  struct Hypothesis {
    int source, g;
    Eigen::Vector2i L0;
    int count;
  };

  // Step 2 (identify_hypotheses.cc).
  // The hypotheses of source s from a seed, appended to `out`.
  void Hypotheses(int s, const Seed& seed, std::vector<Hypothesis>* out) const;
  // The candidate poses of the hypotheses of every source, checked in the
  // order of their counts until `clear` says a candidate settles the seed.
  void Candidates(const Seed& seed, std::vector<Hypothesis> hyps, std::vector<Candidate>* out,
                  const std::function<bool(const Candidate&)>& clear) const;
  // The gate of a P3P guess on the seed's patch, in beam spacings.
  static constexpr double kGuessGateSpacings = 0.25;
  // The P3P pose of the seed's cross that fits its patch at (L0, g), or nullptr.
  const PoseRt* BestOnPatch(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                            const std::array<PoseRt, 4>& poses, int num_poses) const;
  // The pose of source s that maps the seed's patch onto the beams L0 + g offset.
  bool PatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g, const PoseRt* guess,
                 PoseRt* pose) const;
  // Appends the observations of a seed's nodes at (L0, g) with Chebyshev
  // radius in (lo, hi] (identify_hypotheses.cc).
  void AppendObservations(int s, const std::vector<std::pair<int, Eigen::Vector2i>>& nodes,
                          const Eigen::Vector2i& L0, int g, int lo, int hi,
                          std::vector<SpotObservation>* obs) const;
  // A grown seed's pose at (L0, g): of the P3P poses of its cross, the one
  // that carries farthest over the grown patch (step 1b); false when none fits.
  bool GrownPatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                      const std::array<PoseRt, 4>& poses, int num_poses, PoseRt* pose) const;
  // `pose`, fitted to the observations `obs` of the seed's patch, carried out
  // to its far nodes ring by ring; the observations of the last fit that held.
  int ExtendPatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                      std::vector<SpotObservation> obs, PoseRt* pose) const;
  // Least squares of the patch's observations that fit `guess`.
  bool FitPatch(const PatternIndex& idx, const std::vector<SpotObservation>& obs, const PoseRt& guess,
                PoseRt* pose) const;
  // Points of source s whose nearest beam under `pose` is within `gate`.
  int Score(int s, const PoseRt& pose, double gate, const Eigen::Matrix3Xd& points) const;

  // Step 3 (identify_refine.cc).
  // Points assigned to beams of source s under scene_from_source within
  // `gate` (and within `radius` nodes of `centre`).
  // `subset`: only these pool indices are considered (nullptr: all).
  Detection Assign(int s, const Rigid3d& scene_from_source, double gate, double sigma,
                   const Eigen::Vector2i& centre = Eigen::Vector2i::Zero(), int radius = 1 << 20,
                   const std::vector<int>* subset = nullptr) const;
  // A candidate grown onto its grid and refined; false when rejected.
  bool Refine(const Candidate& c, Detection* out) const;
  // Angle from point p (scene) to its nearest beam of source s; infinity when none.
  double NearestAngle(int s, const Rigid3d& scene_from_source, const Eigen::Vector3d& p) const;

  // Steps 4 and 5 (identify_rivals.cc).
  // Candidate poses for the alternatives of detection d in the allowed sources.
  std::vector<Candidate> Alternatives(const Detection& d, const std::vector<char>& allowed) const;
  // Truncated chi^2 of a detection's pose over the pool, with a common sigma.
  double Cost(const Detection& d, double sigma) const;

  // Largest noise sigma of an accepted detection of source s, rad.
  double MaxSigma(int s) const {
    return options_.max_sigma_fraction * index_[s].spacing_rad +
           (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
  }

  // Fewest points a detection of source s must explain.
  int MinPoints(int s) const {
    const int beams = static_cast<int>(index_[s].pattern->beams().size());
    return std::max(options_.min_spots, static_cast<int>(std::ceil(options_.min_fraction * beams)));
  }

  double Gate(double sigma, double cap) const {
    double g = options_.assign_gate_sigma * sigma;
    if (options_.directions_nominal) g = std::hypot(g, options_.nominal_tolerance_rad);
    return std::min(g, cap);
  }

  double FinalGate(int s, double sigma) const {
    return Gate(sigma, options_.score_gate_fraction * index_[s].spacing_rad +
                           (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0));
  }

 private:
  const ModuleCalibration& calibration_;
  const IdentifyOptions& options_;
  Pool& pool_;
  const std::vector<std::vector<char>>& reserved_;
  std::vector<PatternIndex> index_;
  mutable PoseNormalEquations patch_problem_;  // FitPatch's scratch (one thread)
  bool local_growth_ = false;
};

}  // namespace identify_internal
}  // namespace opl
