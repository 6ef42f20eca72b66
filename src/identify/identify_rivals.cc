// Steps 4 and 5 of IdentifySpots (opl/identify/identify_spots.h): the rivals
// of a detection (its points relabelled by the symmetries of the square, in
// its own and the other sources: Alternatives), the truncated chi^2 that
// ranks detections (Cost), and when two detections give the same
// correspondence (SameCorrespondence).
#include <algorithm>
#include <array>
#include <utility>
#include <vector>

#include "identify/identify_spots_internal.h"

namespace opl {
namespace identify_internal {

// Candidate poses for the alternatives of detection d: its points
// relabelled by each symmetry g of the square about the pattern centre, in
// each allowed source (d's own source without g = identity). The pose of
// each comes from P3P on three well-spread points; it is kept only when it
// puts at least 80% of the relabelled points within 4 max-sigma of their
// beams (an alternative that fits no better than that cannot rival d).
std::vector<Candidate> Identifier::Alternatives(const Detection& d, const std::vector<char>& allowed) const {
  std::vector<Candidate> out;
  const int m = static_cast<int>(d.point.size());
  if (m < 4) return out;
  const int n0 = index_[d.source].n;
  std::vector<Eigen::Vector2i> lattice(m);
  for (int k = 0; k < m; ++k) lattice[k] = Eigen::Vector2i(BeamCol(d.beam[k], n0), BeamRow(d.beam[k], n0));
  // Three well-spread points (in lattice coordinates).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& l : lattice) mean += l.cast<double>();
  mean /= m;
  int a = 0, b = 0, c = 0;
  double best = -1.0;
  for (int k = 0; k < m; ++k) {
    const double v = (lattice[k].cast<double>() - mean).squaredNorm();
    if (v > best) best = v, a = k;
  }
  best = -1.0;
  for (int k = 0; k < m; ++k) {
    const double v = (lattice[k] - lattice[a]).cast<double>().squaredNorm();
    if (v > best) best = v, b = k;
  }
  // c and c2: the largest triangles with a, b on either side of ab.
  int c2 = 0;
  double best2 = 0.0;
  best = 0.0;
  const Eigen::Vector2d ab = (lattice[b] - lattice[a]).cast<double>();
  for (int k = 0; k < m; ++k) {
    const Eigen::Vector2d ak = (lattice[k] - lattice[a]).cast<double>();
    const double v = ab.x() * ak.y() - ab.y() * ak.x();
    if (v > best) best = v, c = k;
    if (-v > best2) best2 = -v, c2 = k;
  }
  if (best <= 0.0 && best2 <= 0.0) return out;
  if (best <= 0.0) c = c2;
  if (best2 <= 0.0) c2 = c;
  // Three triples: a P3P configuration can be near-degenerate (the origin
  // near the triangle's circumscribed cylinder); the best of the three is
  // kept.
  const std::array<std::array<int, 3>, 3> triples = {{{a, b, c}, {a, b, c2}, {c, c2, a}}};
  for (int s = 0; s < static_cast<int>(index_.size()); ++s) {
    if (!allowed[s]) continue;
    const PatternIndex& idx = index_[s];
    if (idx.spacing_rad <= 0.0) continue;
    const double max_sigma = options_.max_sigma_fraction * idx.spacing_rad +
                             (options_.directions_nominal ? options_.nominal_tolerance_rad : 0.0);
    const double gate = 4.0 * max_sigma;
    for (int g = 0; g < 8; ++g) {
      if (s == d.source && g == 0) continue;
      // Relabel: (c, r) -> g ((c, r) - centre0) + centre.
      std::vector<int> node(m, -1);
      const Eigen::Vector2i centre0((n0 - 1) / 2, (n0 - 1) / 2), centre((idx.n - 1) / 2, (idx.n - 1) / 2);
      int valid = 0;
      for (int k = 0; k < m; ++k) {
        const Eigen::Vector2i l = Apply(g, lattice[k] - centre0) + centre;
        if (idx.Has(l.x(), l.y())) node[k] = l.y() * idx.n + l.x(), ++valid;
      }
      if (valid < MinPoints(s) || 5 * valid < 4 * m) continue;
      int best_count = -1;
      PoseRt best_pose;
      for (const auto& tri : triples) {
        if (tri[0] == tri[2] || tri[1] == tri[2] || tri[0] == tri[1]) continue;
        if (node[tri[0]] < 0 || node[tri[1]] < 0 || node[tri[2]] < 0) continue;
        const std::array<Eigen::Vector3d, 3> f = {idx.dir[node[tri[0]]], idx.dir[node[tri[1]]], idx.dir[node[tri[2]]]};
        const std::array<Eigen::Vector3d, 3> X = {pool_.p[d.point[tri[0]]], pool_.p[d.point[tri[1]]],
                                                  pool_.p[d.point[tri[2]]]};
        std::array<PoseRt, 4> poses;
        const int np = SolveP3P(f, X, &poses);
      for (int r = 0; r < np; ++r) {
        if (!poses[r].R.allFinite() || !poses[r].t.allFinite()) continue;
        int count = 0;
        for (int k = 0; k < m; ++k) {
          if (node[k] < 0) continue;
          const Eigen::Vector3d q = poses[r].R * pool_.p[d.point[k]] + poses[r].t;
          if (q.x() > 0.0 && (q.normalized() - idx.dir[node[k]]).norm() < gate) ++count;
        }
        if (count > best_count) best_count = count, best_pose = poses[r];
      }
      }
      if (best_count >= MinPoints(s) && 5 * best_count >= 4 * m) {
        out.push_back({s, best_pose, best_count, Eigen::Vector2i::Zero(), false});
      }
    }
  }
  return out;
}

// Truncated chi^2 of a detection's pose over every point eligible for its
// source, with a common sigma.
double Identifier::Cost(const Detection& d, double sigma) const {
  const PatternIndex& idx = index_[d.source];
  const Eigen::Matrix3d Rt = d.scene_from_source.RotationMatrix().transpose();
  const double G2 = options_.assign_gate_sigma * options_.assign_gate_sigma;
  double cost = 0.0;
  for (int i = 0; i < pool_.size(); ++i) {
    if (pool_.taken[i]) continue;
    double c = G2;
    if (Eligible(i, d.source)) {
      const Eigen::Vector3d q = Rt * (pool_.p[i] - d.scene_from_source.translation);
      double angle = 0.0;
      const int node = q.x() > 0.0 ? idx.Nearest(q, &angle) : -1;
      if (node >= 0 && !reserved_[d.source][node]) c = std::min(G2, angle * angle / (sigma * sigma));
    }
    cost += c;
  }
  return cost;
}

// True when a and b give (mostly) the same correspondence.
bool SameCorrespondence(const Detection& a, const Detection& b) {
  if (a.source != b.source) return false;
  std::vector<std::pair<int, int>> pa, pb;
  for (size_t k = 0; k < a.point.size(); ++k) pa.push_back({a.point[k], a.beam[k]});
  for (size_t k = 0; k < b.point.size(); ++k) pb.push_back({b.point[k], b.beam[k]});
  std::sort(pa.begin(), pa.end());
  std::sort(pb.begin(), pb.end());
  int same = 0, common = 0;
  size_t i = 0, j = 0;
  while (i < pa.size() && j < pb.size()) {
    if (pa[i].first < pb[j].first) {
      ++i;
    } else if (pb[j].first < pa[i].first) {
      ++j;
    } else {
      ++common;
      same += pa[i].second == pb[j].second;
      ++i;
      ++j;
    }
  }
  return common > 0 && 2 * same > common;
}

}  // namespace identify_internal
}  // namespace opl
