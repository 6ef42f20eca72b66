// Step 2 of IdentifySpots (opl/identify/identify_spots.h): the hypotheses
// of a seed (its patch placed on lattice nodes of a source under one of the
// 8 symmetries), their poses (P3P of the seed's cross, refined on the patch)
// and their scores (points within the score gate of a beam); the candidates
// that step 3 refines.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <tuple>
#include <vector>

#include "identify/identify_spots_internal.h"
#include "opl/locate/locate_source.h"

namespace opl {
namespace identify_internal {

// The hypotheses of source s from a seed (identify_spots.h, step 2): for each
// symmetry g, up to 6 nodes L0 with the highest histogram counts (at least
// min_spots), appended to `out`. The histogram of a grown seed is its nodes'
// offsets (no pose); of another, the offsets of the points that the patch
// pose (or, when PatchPose fails, each P3P pose of the seed's cross) maps
// near a node.
void Identifier::Hypotheses(int s, const Seed& seed, std::vector<Hypothesis>* out) const {
  const PatternIndex& idx = index_[s];
  if (idx.spacing_rad <= 0.0) return;
  const int n = idx.n;
  const Eigen::Vector2i L = idx.ref;
  std::vector<Hypothesis>& hist = *out;
  std::vector<int> diff(static_cast<size_t>(n + 1) * (n + 1));
  // The hypotheses of one histogram of offsets from L.
  auto histogram = [&](const std::vector<Eigen::Vector2i>& offsets) {
    for (int g = 0; g < 8; ++g) {
      std::fill(diff.begin(), diff.end(), 0);
      for (const Eigen::Vector2i& o : offsets) {
        const Eigen::Vector2i go = Apply(g, o);
        const int c_lo = std::max(0, -go.x()), c_hi = std::min(n - 1, n - 1 - go.x());
        const int r_lo = std::max(0, -go.y()), r_hi = std::min(n - 1, n - 1 - go.y());
        if (c_lo > c_hi || r_lo > r_hi) continue;
        diff[r_lo * (n + 1) + c_lo] += 1;
        diff[r_lo * (n + 1) + c_hi + 1] -= 1;
        diff[(r_hi + 1) * (n + 1) + c_lo] -= 1;
        diff[(r_hi + 1) * (n + 1) + c_hi + 1] += 1;
      }
      // Prefix sums in place; count at (c, r) = inclusive sum.
      for (int r = 0; r < n; ++r) {
        for (int c = 0; c < n; ++c) {
          int v = diff[r * (n + 1) + c];
          if (r > 0) v += diff[(r - 1) * (n + 1) + c];
          if (c > 0) v += diff[r * (n + 1) + c - 1];
          if (r > 0 && c > 0) v -= diff[(r - 1) * (n + 1) + c - 1];
          diff[r * (n + 1) + c] = v;
        }
      }
      // The best nodes of this histogram and g: up to 6.
      std::array<Hypothesis, 6> top;
      for (auto& t : top) t.count = -1;
      for (int r = 0; r < n; ++r) {
        for (int c = 0; c < n; ++c) {
          const int v = diff[r * (n + 1) + c];
          if (v <= top[5].count) continue;
          if (!idx.Has(c, r)) continue;
          Hypothesis h{s, g, Eigen::Vector2i(c, r), v};
          int k = 5;
          while (k > 0 && top[k - 1].count < v) {
            top[k] = top[k - 1];
            --k;
          }
          top[k] = h;
        }
      }
      for (const auto& t : top) {
        if (t.count >= options_.min_spots) hist.push_back(t);
      }
    }
  };
  std::vector<Eigen::Vector2i> offsets;
  if (!seed.grown.empty()) {
    for (const auto& [i, o] : seed.grown) {
      if (Eligible(i, s)) offsets.push_back(o);
    }
    histogram(offsets);
    return;
  }
  const std::array<Eigen::Vector3d, 3> X = {pool_.p[seed.p0], pool_.p[seed.pa], pool_.p[seed.pb]};
  const std::array<Eigen::Vector3d, 3> f = {idx.Dir(L.x(), L.y()), idx.Dir(L.x() + 1, L.y()),
                                            idx.Dir(L.x(), L.y() + 1)};
  std::array<PoseRt, 4> roots;
  int num_roots = SolveP3P(f, X, &roots);
  if (PatchPose(s, seed, L, 0, BestOnPatch(s, seed, L, 0, roots, num_roots), &roots[0])) num_roots = 1;
  for (int root = 0; root < num_roots; ++root) {
    const PoseRt& P = roots[root];
    if (!P.R.allFinite() || !P.t.allFinite()) continue;
    offsets.clear();
    for (int i = 0; i < pool_.size(); ++i) {
      if (!Eligible(i, s)) continue;
      const Eigen::Vector3d q = P.R * pool_.p[i] + P.t;
      if (!(q.x() > 0.0)) continue;
      const Eigen::Vector2d d = idx.Lattice(q) - L.cast<double>();
      const Eigen::Vector2d rd = d.array().round();
      if ((d - rd).cwiseAbs().maxCoeff() > 0.3 || rd.cwiseAbs().maxCoeff() > 2 * n) continue;
      offsets.push_back(rd.cast<int>());
    }
    histogram(offsets);
  }
}

// Candidate poses from the hypotheses of every source (header comment,
// step 2), checked exactly in the order of their counts (the sources'
// lists merged): per source, those with at least half its highest count,
// at most 48. The counts estimate the exact scores (from above when other
// grids overlap): once the best pose so far scores as many points as the
// next count, or as that source's pattern has beams, the rest are not
// expected to do better, and `clear` is asked whether it settles the seed
// (a clear refinement; a symmetric or cross-source rival is examined in
// step 4 regardless). When it does, the check stops there.
void Identifier::Candidates(const Seed& seed, std::vector<Hypothesis> hyps, std::vector<Candidate>* out,
                            const std::function<bool(const Candidate&)>& clear) const {
  if (hyps.empty()) return;
  std::stable_sort(hyps.begin(), hyps.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.count > b.count; });
  const int num_sources = static_cast<int>(index_.size());
  std::vector<int> max_count(num_sources, -1), checked(num_sources, 0);
  std::vector<Eigen::Matrix3Xd> eligible(num_sources);
  // Large point sets: a hypothesis is scored on an evenly strided subset of
  // at most kScoreSampleSize eligible points, its count scaled by
  // scale[s] = eligible / sampled (an estimate within a few percent, enough
  // to rank hypotheses; refinement and the ambiguity test use every point).
  // Below that size the score is exact, as before.
  std::vector<double> scale(num_sources, 1.0);
  for (const Hypothesis& h : hyps) max_count[h.source] = std::max(max_count[h.source], h.count);
  const std::array<Eigen::Vector3d, 3> X = {pool_.p[seed.p0], pool_.p[seed.pa], pool_.p[seed.pb]};
  int best_score = -1, stop_tried = -1;
  size_t best = 0;  // index in `out` of the best-scoring candidate
  std::vector<std::tuple<int, Eigen::Vector2i, int>> seen;  // (source, L0, g) verified
  for (const Hypothesis& h : hyps) {
    const int s = h.source;
    const PatternIndex& idx = index_[s];
    const int num_beams = static_cast<int>(idx.pattern->beams().size());
    if (best_score >= std::min(h.count, num_beams) && best_score > stop_tried) {
      stop_tried = best_score;
      if (clear(out->at(best))) return;
    }
    if (h.count < 0.5 * max_count[s] || checked[s] >= 48) continue;
    bool dup = false;
    for (const auto& sv : seen) dup |= (std::get<0>(sv) == s && std::get<1>(sv) == h.L0 && std::get<2>(sv) == h.g);
    if (dup) continue;
    seen.emplace_back(s, h.L0, h.g);
    const Eigen::Vector2i e1 = Apply(h.g, Eigen::Vector2i(1, 0)), e2 = Apply(h.g, Eigen::Vector2i(0, 1));
    const Eigen::Vector2i A = h.L0 + e1, B = h.L0 + e2;
    if (!idx.Has(A.x(), A.y()) || !idx.Has(B.x(), B.y())) continue;
    ++checked[s];
    if (eligible[s].cols() == 0) {
      eligible[s].resize(3, pool_.size());
      Eigen::Index m = 0;
      for (int i = 0; i < pool_.size(); ++i) {
        if (Eligible(i, s)) eligible[s].col(m++) = pool_.p[i];
      }
      eligible[s].conservativeResize(3, m);
      if (m > kScoreSampleSize) {
        const Eigen::Index stride = (m + kScoreSampleSize - 1) / kScoreSampleSize;
        Eigen::Index k = 0;
        for (Eigen::Index j = 0; j < m; j += stride) eligible[s].col(k++) = eligible[s].col(j);
        eligible[s].conservativeResize(3, k);
        scale[s] = static_cast<double>(m) / static_cast<double>(k);
      }
    }
    const double gate = options_.score_gate_fraction * idx.spacing_rad +
                        (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
    const std::array<Eigen::Vector3d, 3> fb = {idx.Dir(h.L0.x(), h.L0.y()), idx.Dir(A.x(), A.y()),
                                               idx.Dir(B.x(), B.y())};
    std::array<PoseRt, 4> poses;
    int np = SolveP3P(fb, X, &poses);
    if (seed.grown.empty()) {
      if (PatchPose(s, seed, h.L0, h.g, BestOnPatch(s, seed, h.L0, h.g, poses, np), &poses[0])) np = 1;
    } else {
      PoseRt grown_pose;
      if (GrownPatchPose(s, seed, h.L0, h.g, poses, np, &grown_pose)) poses[0] = grown_pose, np = 1;
    }
    for (int k = 0; k < np; ++k) {
      if (!poses[k].R.allFinite() || !poses[k].t.allFinite()) continue;
      const int score = static_cast<int>(std::lround(Score(s, poses[k], gate, eligible[s]) * scale[s]));
      if (score >= options_.min_spots) {
        if (score > best_score) best = out->size();
        Candidate c{s, poses[k], score, h.L0, true};
        c.seed_point = seed.p0;
        c.seed_step = std::max((X[1] - X[0]).norm(), (X[2] - X[0]).norm());
        out->push_back(c);
      }
      best_score = std::max(best_score, score);
    }
  }
}

// Of the P3P poses of the seed's cross, the one that puts the most patch
// points near their beams L0 + g offset (chord below kGuessGateSpacings
// spacings), when it puts at least 90% of them there: a pose to start
// PatchPose from. nullptr when none does.
const PoseRt* Identifier::BestOnPatch(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                                    const std::array<PoseRt, 4>& poses, int num_poses) const {
  const PatternIndex& idx = index_[s];
  const double gate = kGuessGateSpacings * idx.spacing_rad;
  const PoseRt* best = nullptr;
  int best_count = -1, used = 0;
  for (int k = 0; k < num_poses; ++k) {
    const PoseRt& P = poses[k];
    if (!P.R.allFinite() || !P.t.allFinite()) continue;
    int count = 0;
    used = 0;
    for (const auto& [i, o] : seed.patch) {
      const Eigen::Vector2i l = L0 + Apply(g, o);
      if (!idx.Has(l.x(), l.y()) || !Eligible(i, s)) continue;
      ++used;
      const Eigen::Vector3d q = P.R * pool_.p[i] + P.t;
      if (q.x() > 0.0 && (q.normalized() - idx.Dir(l.x(), l.y())).squaredNorm() < gate * gate) ++count;
    }
    if (count > best_count) {
      best_count = count;
      best = &P;
    }
  }
  return best != nullptr && best_count >= 0.9 * used ? best : nullptr;
}

// The observations of a seed's nodes (point, offset) placed at (L0, g):
// those whose beam L0 + g offset exists, whose point is eligible for s and
// whose offset's Chebyshev radius is in (lo, hi].
void Identifier::AppendObservations(int s, const std::vector<std::pair<int, Eigen::Vector2i>>& nodes,
                                    const Eigen::Vector2i& L0, int g, int lo, int hi,
                                    std::vector<SpotObservation>* obs) const {
  const PatternIndex& idx = index_[s];
  for (const auto& [i, o] : nodes) {
    const int r = o.cwiseAbs().maxCoeff();
    if (r <= lo || r > hi) continue;
    const Eigen::Vector2i l = L0 + Apply(g, o);
    if (!idx.Has(l.x(), l.y()) || !Eligible(i, s)) continue;
    SpotObservation so;
    so.beam_id = idx.Id(l.x(), l.y());
    so.point_in_scene = pool_.p[i];
    obs->push_back(so);
  }
}

// The pose of source s that maps the seed's patch onto the beams
// L0 + g offset; false when it fails. From `guess` (BestOnPatch): a
// least-squares fit of the patch's points that fit the guess within its
// gate (FitPatch). Without a guess: LocateSource over the patch (RANSAC).
bool Identifier::PatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g, const PoseRt* guess,
                         PoseRt* pose) const {
  const PatternIndex& idx = index_[s];
  std::vector<SpotObservation> obs;
  AppendObservations(s, seed.patch, L0, g, -1, std::numeric_limits<int>::max(), &obs);
  if (obs.size() < 6) return false;
  if (guess != nullptr) return FitPatch(idx, obs, *guess, pose);
  LocateOptions lo;
  lo.ransac_seed = options_.seed;
  // The patch's points are nearly all inliers when the hypothesis is
  // right: a few minimal samples suffice; a wrong one fails fast.
  lo.ransac_max_iterations = 20;
  // The pose only has to place the spots to a fraction of the spacing
  // (Score's gate; Refine solves again): 1e-5 of the range is plenty.
  lo.parameter_tolerance = 1e-5;
  lo.ransac_inlier_threshold_rad = 0.05 * idx.spacing_rad;
  auto located = LocateSource(*idx.pattern, obs, lo);
  if (!located.ok()) return false;
  const Eigen::Matrix3d R = located->scene_from_source.RotationMatrix();
  pose->R = R.transpose();
  pose->t = -(R.transpose() * located->scene_from_source.translation);
  return true;
}

// A grown seed (GrowSeed): from every P3P pose of the cross that fits the
// patch (FitPatch), the pose carried out to the far nodes stage by stage
// (ExtendPatchPose); the one that reaches farthest (most observations) is
// kept. Every root is tried: on a small patch a pose and its tilted twin
// fit alike, and only the far nodes tell them apart.
bool Identifier::GrownPatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                                const std::array<PoseRt, 4>& poses, int num_poses, PoseRt* pose) const {
  const PatternIndex& idx = index_[s];
  std::vector<SpotObservation> obs;
  AppendObservations(s, seed.patch, L0, g, -1, std::numeric_limits<int>::max(), &obs);
  if (obs.size() < 6) return false;
  int best = -1;
  for (int k = 0; k < num_poses; ++k) {
    if (!poses[k].R.allFinite() || !poses[k].t.allFinite()) continue;
    PoseRt fitted;
    if (!FitPatch(idx, obs, poses[k], &fitted)) continue;
    const int reached = ExtendPatchPose(s, seed, L0, g, obs, &fitted);
    if (reached > best) {
      best = reached;
      *pose = fitted;
    }
  }
  return best >= 0;
}

// A grown seed (GrowSeed): the patch pose carried out to the far nodes
// stage by stage, the Chebyshev radius doubling from 4 (each stage's
// prediction reaches twice as far as the points it was fitted to, well
// within FitPatch's guess gate); a stage that fails leaves the pose of the
// last one that fitted.
int Identifier::ExtendPatchPose(int s, const Seed& seed, const Eigen::Vector2i& L0, int g,
                                std::vector<SpotObservation> obs, PoseRt* pose) const {
  int fitted = static_cast<int>(obs.size());
  const PatternIndex& idx = index_[s];
  int reach = 0;
  for (const auto& f : seed.far) reach = std::max(reach, f.second.cwiseAbs().maxCoeff());
  for (int lo = 2, hi = 4; lo < reach; lo = hi, hi *= 2) {
    const size_t before = obs.size();
    AppendObservations(s, seed.far, L0, g, lo, hi, &obs);
    if (obs.size() == before) continue;
    PoseRt next;
    if (!FitPatch(idx, obs, *pose, &next)) return fitted;
    *pose = next;
    fitted = static_cast<int>(obs.size());
  }
  return fitted;
}

// Least squares of the angle residuals (PoseNormalEquations, unweighted)
// over the observations within the guess gate of `guess`; then, as
// LocateSource does, the observations beyond 5 robust sigmas of the fitted
// pose are left out and the fit repeated until that set is stable (at most
// 6 fits). The pose only places spots to a fraction of the spacing for
// Score and seeds Refine, which solves again: a step below 1e-5 of the
// range ends each solve. False when fewer than 6 observations, or under
// half of them, remain, or a solve fails.
bool Identifier::FitPatch(const PatternIndex& idx, const std::vector<SpotObservation>& obs, const PoseRt& guess,
                        PoseRt* pose) const {
  Eigen::Matrix3d R = guess.R.transpose();  // scene_from_source
  Eigen::Vector3d t = -(R * guess.t);
  const int m = static_cast<int>(obs.size());
  std::vector<char> use(m), next(m);
  std::vector<double> chord(m);
  auto chords = [&]() {
    const Eigen::Matrix3d Rt = R.transpose();
    for (int k = 0; k < m; ++k) {
      const Eigen::Vector3d q = Rt * (obs[k].point_in_scene - t);
      chord[k] = q.x() > 0.0 ? (q.normalized() - idx.pattern->DirectionInSource(obs[k].beam_id)).norm()
                             : std::numeric_limits<double>::infinity();
    }
  };
  chords();
  const double guess_gate = kGuessGateSpacings * idx.spacing_rad;
  for (int k = 0; k < m; ++k) use[k] = chord[k] < guess_gate;
  std::vector<double> inlier;
  for (int round = 0; round < 6; ++round) {
    int used = 0;
    double D = 0.0;
    for (int k = 0; k < m; ++k) {
      if (use[k]) ++used, D += (obs[k].point_in_scene - t).norm();
    }
    if (used < 6 || 2 * used < m) return false;
    D /= used;
    const Eigen::Vector3d offset(D, 0.0, 0.0);
    patch_problem_.Reset(R, t - offset, D);
    for (int k = 0; k < m; ++k) {
      if (!use[k]) continue;
      patch_problem_.AddSpot(obs[k].point_in_scene,
                             BeamAngles::FromDirection(idx.pattern->DirectionInSource(obs[k].beam_id)),
                             Eigen::Matrix2d::Identity());
    }
    Eigen::Matrix<double, 6, 1> x;
    x << 0.0, 0.0, 0.0, offset;
    PoseSolverOptions so;
    so.max_num_iterations = 20;
    so.function_tolerance = std::numeric_limits<double>::min();  // step test only
    so.parameter_tolerance = 1e-5;
    so.cost_threshold = 0.0;
    so.initial_trust_region_radius = 1e12;  // close to Gauss-Newton (as LocateSource)
    const PoseSolverSummary summary = SolvePoseLevenbergMarquardt(patch_problem_, so, &x);
    if (summary.evaluation_failed || !x.allFinite() || !std::isfinite(summary.final_cost)) return false;
    R = patch_problem_.Rotation(x.data());
    t = patch_problem_.Origin(x.data());
    // Outliers as LocateSource flags them: beyond 5 robust sigmas (the
    // median chord of a 2D Gaussian is 1.1774 sigma).
    chords();
    inlier.clear();
    for (int k = 0; k < m; ++k) {
      if (use[k]) inlier.push_back(chord[k]);
    }
    std::nth_element(inlier.begin(), inlier.begin() + inlier.size() / 2, inlier.end());
    const double gate = std::max(5.0 * inlier[inlier.size() / 2] / 1.1774100225154747, 1e-7);
    for (int k = 0; k < m; ++k) next[k] = chord[k] <= gate;
    if (next == use) break;
    use = next;
  }
  pose->R = R.transpose();
  pose->t = -(R.transpose() * t);
  return pose->R.allFinite() && pose->t.allFinite();
}

// Points of source s whose nearest beam under `pose` is within `gate`.
// `points`: the points eligible for s (3 x m).
int Identifier::Score(int s, const PoseRt& pose, double gate, const Eigen::Matrix3Xd& points) const {
  const PatternIndex& idx = index_[s];
  int count = 0;
  const double reach = idx.PositionReach(gate);
  const Eigen::Matrix3Xd Q = (pose.R * points).colwise() + pose.t;
  for (Eigen::Index i = 0; i < Q.cols(); ++i) {
    const Eigen::Vector3d q = Q.col(i);
    if (!(q.x() > 0.0) || !idx.MayBeWithin(q, gate)) continue;
    if (idx.AnyWithin(q, gate, reach)) ++count;
  }
  return count;
}

}  // namespace identify_internal
}  // namespace opl
