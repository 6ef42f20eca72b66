// Step 3 of IdentifySpots (opl/identify/identify_spots.h): a candidate pose
// grown from its seed's node onto the whole grid and refined (Refine), the
// assignment of points to beams under a pose (Assign) and the nearest-beam
// angle of a point under a found pose (NearestAngle).
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "identify/identify_spots_internal.h"
#include "opl/locate/locate_source.h"

namespace opl {
namespace identify_internal {

// Assigns points to beams of source s under scene_from_source within
// `gate`; conflicts (two points in one beam's gate) resolved by the chi^2
// margin when sigma > 0, else by the nearest.
Detection Identifier::Assign(int s, const Rigid3d& scene_from_source, double gate, double sigma,
                              const Eigen::Vector2i& centre, int radius, const std::vector<int>* subset) const {
  const PatternIndex& idx = index_[s];
  const Eigen::Matrix3d Rt = scene_from_source.RotationMatrix().transpose();
  const Eigen::Vector3d t = scene_from_source.translation;
  const int nn = idx.n * idx.n;
  std::vector<int> best(nn, -1), second(nn, -1);
  std::vector<double> best_a(nn, 0.0), second_a(nn, 0.0);
  const double reach = idx.PositionReach(gate);
  const int count = subset != nullptr ? static_cast<int>(subset->size()) : pool_.size();
  for (int k = 0; k < count; ++k) {
    const int i = subset != nullptr ? (*subset)[k] : k;
    if (!Eligible(i, s)) continue;
    const Eigen::Vector3d q = Rt * (pool_.p[i] - t);
    if (!(q.x() > 0.0) || !idx.MayBeWithin(q, gate)) continue;
    double angle = 0.0;
    const int node = idx.NearestWithin(q, gate, reach, &angle);
    if (node < 0 || reserved_[s][node]) continue;
    if (std::abs(node % idx.n - centre.x()) > radius || std::abs(node / idx.n - centre.y()) > radius) continue;
    if (best[node] < 0 || angle < best_a[node]) {
      second[node] = best[node];
      second_a[node] = best_a[node];
      best[node] = i;
      best_a[node] = angle;
    } else if (second[node] < 0 || angle < second_a[node]) {
      second[node] = i;
      second_a[node] = angle;
    }
  }
  Detection d;
  d.source = s;
  d.scene_from_source = scene_from_source;
  d.sigma = sigma;
  for (int node = 0; node < nn; ++node) {
    if (best[node] < 0) continue;
    if (second[node] >= 0 && sigma > 0.0) {
      const double margin = (second_a[node] * second_a[node] - best_a[node] * best_a[node]) / (sigma * sigma);
      if (margin < options_.conflict_margin_chi2) {
        ++d.conflicts;
        continue;
      }
    }
    d.point.push_back(best[node]);
    d.beam.push_back(node + 1);
    d.residual.push_back(best_a[node]);
  }
  return d;
}

// Refines a candidate (identify_spots.h, step 3). False when the pose cannot
// be refined or explains too few points.
bool Identifier::Refine(const Candidate& c, Detection* out) const {
  const PatternIndex& idx = index_[c.source];
  const double cap = options_.score_gate_fraction * idx.spacing_rad +
                     (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
  Rigid3d pose(Eigen::Matrix3d(c.pose.R.transpose()), Eigen::Vector3d(-(c.pose.R.transpose() * c.pose.t)));
  double sigma = 0.0;
  double gate = cap;
  // Growth: the region around the seed's node widens stage by stage.
  static constexpr int kRadii[] = {2, 3, 5, 8};
  int stage = c.grow ? 0 : 4;
  auto radius = [&stage]() { return stage < 4 ? kRadii[stage] : 1 << 20; };
  // Large sets: the growth stages (nodes within 8 of the seed's) look only
  // at the points within 1.5 (8 + 2) cross steps of the seed's point, a
  // generous superset on any smooth surface (the steps would have to grow
  // by half within 10 nodes to leave one out).
  std::vector<int> near;
  const std::vector<int>* subset = nullptr;
  if (local_growth_ && c.grow && c.seed_point >= 0 && c.seed_step > 0.0) {
    const Eigen::Vector3d centre = pool_.p[c.seed_point];
    const double reach = 1.5 * (kRadii[3] + 2) * c.seed_step;
    for (int i = 0; i < pool_.size(); ++i) {
      if ((pool_.p[i] - centre).squaredNorm() <= reach * reach) near.push_back(i);
    }
    subset = &near;
  }
  Detection d = Assign(c.source, pose, gate, sigma, c.node, radius(), subset);
  LocateOptions lo;
  lo.ransac_seed = options_.seed;
  // The assigned points are within `cap` of their beams under the initial
  // pose: with that threshold the guess is taken and RANSAC never runs.
  lo.ransac_inlier_threshold_rad = std::min(0.4, 1.01 * cap);
  lo.ransac_max_iterations = 100;
  const double max_sigma = options_.max_sigma_fraction * idx.spacing_rad +
                           (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
  // The gate shrinks from `cap` by halves to the noise gate, so that a pose
  // right only near the seed grows onto the whole grid.
  double schedule = cap;
  for (int iter = 0; iter < 16; ++iter) {
    if (static_cast<int>(d.point.size()) < (stage < 4 ? 6 : std::max(4, options_.min_spots))) return false;
    std::vector<SpotObservation> obs(d.point.size());
    for (size_t k = 0; k < d.point.size(); ++k) {
      obs[k].beam_id = d.beam[k];
      obs[k].point_in_scene = pool_.p[d.point[k]];
    }
    lo.initial_scene_from_source = pose;
    auto located = LocateSource(*idx.pattern, obs, lo);
    if (!located.ok()) return false;
    pose = located->scene_from_source;
    // Robust sigma from the inliers' angles (Rayleigh median = 1.1774 sigma).
    std::vector<double> r;
    const Eigen::Matrix3d Rt = pose.RotationMatrix().transpose();
    for (size_t k = 0; k < obs.size(); ++k) {
      if (located->residuals[k].outlier) continue;
      const Eigen::Vector3d q = (Rt * (obs[k].point_in_scene - pose.translation)).normalized();
      r.push_back((q - idx.pattern->DirectionInSource(obs[k].beam_id)).norm());
    }
    if (r.size() < 4) return false;
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    sigma = std::max(r[r.size() / 2] / std::sqrt(2.0 * std::log(2.0)), options_.min_sigma_rad);
    if (sigma > 2.0 * max_sigma) return false;
    if (stage < 4) {
      ++stage;
      gate = cap;
      d = Assign(c.source, pose, gate, 0.0, c.node, radius(), stage < 4 ? subset : nullptr);
      continue;
    }
    schedule *= 0.5;
    gate = std::max(Gate(sigma, cap), schedule);
    Detection next = Assign(c.source, pose, gate, sigma);
    const bool same = next.point == d.point && next.beam == d.beam;
    d = std::move(next);
    if (same && schedule <= Gate(sigma, cap)) break;
  }
  if (static_cast<int>(d.point.size()) < MinPoints(c.source)) return false;
  // A pose whose spots scatter by more than a small fraction of the beam
  // spacing is not this source's grid (another pattern, a wrong
  // correspondence of a nearly symmetric pattern).
  if (d.sigma > max_sigma) return false;
  *out = std::move(d);
  return true;
}

// Angle from the direction of point p (scene) to its nearest beam of
// source s at `scene_from_source`; infinity when none.
double Identifier::NearestAngle(int s, const Rigid3d& scene_from_source, const Eigen::Vector3d& p) const {
  const Eigen::Vector3d q = scene_from_source.rotation.conjugate() * (p - scene_from_source.translation);
  double angle = std::numeric_limits<double>::infinity();
  if (!(q.x() > 0.0) || index_[s].Nearest(q, &angle) < 0) return std::numeric_limits<double>::infinity();
  return angle;
}

}  // namespace identify_internal
}  // namespace opl
