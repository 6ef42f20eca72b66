// IdentifySpots (opl/identify/identify_spots.h): the search that drives the
// steps of identify_internal (seeds, hypotheses, refinement, rivals) over
// the pool of points, decides found / ambiguous / not found per source, and
// unassigns the points that overlapping found grids share.
#include "opl/identify/identify_spots.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "identify/identify_spots_internal.h"
#include "identify/nearest_neighbours.h"
#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/geometry/rotation.h"

namespace opl {
namespace {

using identify_internal::Candidate;
using identify_internal::DerivedSeeds;
using identify_internal::Detection;
using identify_internal::FindSeeds;
using identify_internal::Identifier;
using identify_internal::NearestNeighbours;
using identify_internal::Pool;
using identify_internal::SameCorrespondence;
using identify_internal::Seed;

std::string Where(const Spot& s, size_t i) {
  return s.where.empty() ? "spot " + std::to_string(i) : s.where;
}

}  // namespace

Result<IdentifyResult> IdentifySpots(const ModuleCalibration& calibration, const std::vector<Spot>& spots,
                                     const IdentifyOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  {
    Status s = calibration.Validate();
    if (!s.ok()) return Status::InvalidArgument("calibration: " + s.message());
  }
  if (calibration.sources.empty()) return Status::InvalidArgument("calibration: no sources");
  const int num_sources = static_cast<int>(calibration.sources.size());
  // The orientation prior, by source index (identity-free when absent).
  std::vector<const Eigen::Matrix3d*> expected(num_sources, nullptr);
  for (const auto& [name, r] : options.expected_rotation) {
    bool known = false;
    for (int s = 0; s < num_sources; ++s) {
      if (calibration.sources[s].name == name) {
        expected[s] = &r;
        known = true;
      }
    }
    if (!known) {
      return Status::InvalidArgument("IdentifyOptions.expected_rotation: unknown source " + QuoteForMessage(name) + "");
    }
  }
  std::vector<const Eigen::Vector3d*> expected_origin(num_sources, nullptr);
  for (const auto& [name, o] : options.expected_origin) {
    bool known = false;
    for (int s = 0; s < num_sources; ++s) {
      if (calibration.sources[s].name == name) {
        expected_origin[s] = &o;
        known = true;
      }
    }
    if (!known) {
      return Status::InvalidArgument("IdentifyOptions.expected_origin: unknown source " + QuoteForMessage(name) + "");
    }
  }
  const double prior_tolerance_rad = options.expected_rotation_tolerance_deg * kPi / 180.0;
  auto against_prior = [&](const Detection& d) {
    const bool rotation_off =
        expected[d.source] != nullptr &&
        RotationAngleBetweenRad(*expected[d.source], d.scene_from_source.RotationMatrix()) >
            prior_tolerance_rad;
    const bool origin_off =
        expected_origin[d.source] != nullptr &&
        (d.scene_from_source.translation - *expected_origin[d.source]).norm() >
            options.expected_origin_tolerance;
    return rotation_off || origin_off;
  };

  IdentifyResult result;
  result.source_index.assign(spots.size(), -1);
  result.beam_id.assign(spots.size(), 0);
  for (const SourceCalibration& s : calibration.sources) {
    IdentifiedSource is;
    is.name = s.name;
    result.sources.push_back(is);
  }
  std::vector<std::vector<char>> reserved(num_sources);
  for (int s = 0; s < num_sources; ++s) {
    const int n = calibration.sources[s].pattern.beams_per_side();
    reserved[s].assign(static_cast<size_t>(n) * n + 1, 0);
  }

  Pool pool;
  for (size_t i = 0; i < spots.size(); ++i) {
    const Spot& spot = spots[i];
    if (!spot.observation.point_in_scene.allFinite()) {
      return Status::InvalidArgument(Where(spot, i) + ": point is not finite");
    }
    if (spot.observation.beam_id < 0) {
      return Status::InvalidArgument(Where(spot, i) + ": beam id " + std::to_string(spot.observation.beam_id) +
                                     " is negative");
    }
    int source = -1;
    if (!spot.source.empty()) {
      for (int s = 0; s < num_sources; ++s) {
        if (calibration.sources[s].name == spot.source) source = s;
      }
      if (source < 0) {
        std::string names;
        for (const auto& s : calibration.sources) names += (names.empty() ? "" : ", ") + s.name;
        return Status::InvalidArgument(Where(spot, i) + ": unknown source " + QuoteForMessage(spot.source) +
                                       " (the calibration has " + names + ")");
      }
    }
    if (source >= 0 && spot.observation.beam_id > 0) {
      const BeamPattern& pattern = calibration.sources[source].pattern;
      if (pattern.Find(spot.observation.beam_id) == nullptr) {
        return Status::InvalidArgument(Where(spot, i) + ": beam " + std::to_string(spot.observation.beam_id) +
                                       " is not in the pattern of source " + QuoteForMessage(spot.source) + "");
      }
      result.source_index[i] = source;
      result.beam_id[i] = spot.observation.beam_id;
      reserved[source][spot.observation.beam_id - 1] = 1;
      ++result.passed_through;
      continue;
    }
    pool.p.push_back(spot.observation.point_in_scene);
    pool.spot.push_back(static_cast<int>(i));
    pool.only_source.push_back(source);
  }
  pool.taken.assign(pool.p.size(), 0);
  pool.blocked.assign(pool.p.size(), 0);

  Identifier identifier(calibration, options, &pool, reserved);
  std::vector<char> done(num_sources, 0);
  IdentifyProgress progress;
  progress.num_sources = num_sources;
  progress.points = pool.size();
  auto report_progress = [&]() {
    if (options.progress) options.progress(progress);
  };
  report_progress();
  std::vector<std::string> ambiguity(num_sources);
  for (int s = 0; s < num_sources; ++s) {
    if (identifier.index(s).spacing_rad <= 0.0) {
      done[s] = 1;
      result.sources[s].detail = "the pattern has no lattice node with a row and a column neighbour";
    }
  }

  // One index of the points for the seeds' nearest neighbours (step 1) and
  // the growth's radius queries (step 1b).
  const NearestNeighbours neighbours(pool.p, options.neighbours);
  const std::vector<Seed> seeds = FindSeeds(pool, neighbours, options.num_threads);
  // Large sets: seeds grown over their grids before they are tried (step 1b).
  const bool grow = pool.size() > identify_internal::kGrowPoolSize;
  identify_internal::GrowthScale growth_scale;
  int max_extent = 0;
  if (grow) {
    growth_scale = identify_internal::MakeGrowthScale(seeds, pool);
    identifier.set_local_growth(true);
    for (const SourceCalibration& s : calibration.sources) {
      max_extent = std::max(max_extent, s.pattern.beams_per_side() - 1);
    }
  }
  int tried = 0, tried_derived = 0;
  auto usable = [&](const Seed& seed) {
    bool skip = pool.taken[seed.p0] || pool.taken[seed.pa] || pool.taken[seed.pb];
    return !(skip || pool.blocked[seed.p0]);
  };
  // Adds d to `detections` unless one with the same correspondence is there
  // (the one with more points, then the lower sigma, is kept).
  auto add_to = [](std::vector<Detection>* detections, Detection d) {
    for (Detection& e : *detections) {
      if (SameCorrespondence(d, e)) {
        if (d.point.size() > e.point.size() || (d.point.size() == e.point.size() && d.sigma < e.sigma)) {
          e = std::move(d);
        }
        return;
      }
    }
    detections->push_back(std::move(d));
  };
  // The refined detections of one seed (header comment, steps 2-3).
  auto seed_detections = [&](const Seed& seed, std::vector<Detection>* out) {
    const int sp[3] = {seed.p0, seed.pa, seed.pb};
    std::vector<Identifier::Hypothesis> hypotheses;
    for (int s = 0; s < num_sources; ++s) {
      if (done[s]) continue;
      bool allowed = true;
      for (int i : sp) allowed &= pool.only_source[i] < 0 || pool.only_source[i] == s;
      if (allowed) identifier.Hypotheses(s, seed, &hypotheses);
    }
    std::vector<Candidate> candidates;
    // A candidate that refines clearly (noise well below the acceptance
    // limit) is the grid: its symmetric and cross-source alternatives are
    // examined next (step 4), so no other candidate needs refining.
    std::optional<Detection> settled;
    identifier.Candidates(seed, std::move(hypotheses), &candidates, [&](const Candidate& c) {
      Detection d;
      if (!identifier.Refine(c, &d) || d.sigma > 0.25 * identifier.MaxSigma(d.source)) return false;
      settled = std::move(d);
      return true;
    });
    if (candidates.empty()) return;
    // Best score first; among equal scores, by source, then in the order
    // each source's hypotheses were checked.
    std::stable_sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
      return a.score > b.score || (a.score == b.score && a.source < b.source);
    });
    // Distinct poses only (the same hypothesis is reached from several
    // symmetries, nodes and roots), the best-scoring first.
    std::vector<const Candidate*> distinct;
    for (const Candidate& c : candidates) {
      if (static_cast<int>(distinct.size()) >= options.max_refined) break;
      if (c.score * 2 < candidates.front().score) break;
      const Eigen::Vector3d origin = -(c.pose.R.transpose() * c.pose.t);
      const double range = (pool.p[seed.p0] - origin).norm();
      bool same = false;
      for (const Candidate* e : distinct) {
        if (e->source != c.source) continue;
        const Eigen::Vector3d eo = -(e->pose.R.transpose() * e->pose.t);
        same |= RotationAngleBetweenRad(e->pose.R, c.pose.R) < 0.02 && (eo - origin).norm() < 0.02 * range;
      }
      if (!same) distinct.push_back(&c);
    }
    auto add = [&](Detection d) { add_to(out, std::move(d)); };
    if (settled) {
      distinct.clear();
      add(std::move(*settled));
    }
    for (const Candidate* cp : distinct) {
      Detection d;
      const bool ok = identifier.Refine(*cp, &d);
      // A detection whose noise is well below the acceptance limit is the
      // grid; its symmetric and cross-source alternatives are examined next
      // (step 4), so the remaining candidates need not be refined.
      const bool clear = ok && d.sigma <= 0.25 * identifier.MaxSigma(d.source);
      if (ok) add(std::move(d));
      if (clear) break;
    }
  };
  auto clear = [&](const std::vector<Detection>& detections) {
    for (const Detection& d : detections) {
      if (d.sigma <= 0.25 * identifier.MaxSigma(d.source)) return true;
    }
    return false;
  };
  // One seed (header comment, steps 2-5): false when it explains nothing
  // (no detection survives), true when it found a source or made one
  // ambiguous. With `derived`, when the seed gives no clear detection (noise
  // well below the acceptance limit), the detections of its derived crosses
  // (DerivedSeeds; header comment, step 1) compete with its own: a cross
  // mixing two interleaved grids can fit a wrong pose to a few dozen points
  // of their union (a sheared or rotated lattice) that no other seed
  // contradicts.
  // `defer`: a decision on a detection that is not clear (noise above a
  // quarter of the acceptance limit) is put off: the seed counts as
  // explaining nothing and changes nothing (no point taken or blocked).
  bool deferred_one = false;
  auto try_seed = [&](const Seed& seed, bool derived, bool defer) -> bool {
    deferred_one = false;
    std::vector<Detection> detections;
    seed_detections(seed, &detections);
    if (derived && !clear(detections)) {
      for (const Seed& d : DerivedSeeds(seed)) {
        if (tried_derived >= options.max_seeds) break;
        if (!usable(d)) continue;
        ++tried_derived;
        seed_detections(d, &detections);
        if (clear(detections)) break;
      }
    }
    if (detections.empty()) return false;
    // Common sigma: the smallest among the detections that explain nearly as
    // many points as the most; the best detection has the lowest cost.
    auto rank = [&]() {
      size_t max_points = 0;
      for (const Detection& d : detections) max_points = std::max(max_points, d.point.size());
      double sigma = std::numeric_limits<double>::infinity();
      for (const Detection& d : detections) {
        if (d.point.size() * 5 >= max_points * 4) sigma = std::min(sigma, d.sigma);
      }
      for (Detection& d : detections) d.cost = identifier.Cost(d, sigma);
      std::stable_sort(detections.begin(), detections.end(),
                       [](const Detection& x, const Detection& y) { return x.cost < y.cost; });
    };
    rank();
    detections.resize(1);
    // The alternatives of the first detection: its points relabelled by every
    // symmetry of the square about the pattern centre, in every unfound
    // source allowed for them (header comment, step 4).
    {
      std::vector<char> allowed(num_sources, 0);
      for (int s = 0; s < num_sources; ++s) {
        bool ok = !done[s];
        for (int i : detections[0].point) ok = ok && (pool.only_source[i] < 0 || pool.only_source[i] == s);
        allowed[s] = ok;
      }
      const std::vector<Candidate> alternatives = identifier.Alternatives(detections[0], allowed);
      for (const Candidate& c : alternatives) {
        Detection d;
        if (identifier.Refine(c, &d)) add_to(&detections, std::move(d));
      }
    }
    detections.erase(std::remove_if(detections.begin(), detections.end(), against_prior),
                     detections.end());
    rank();
    if (detections.empty()) return false;
    size_t best = 0;
    for (size_t k = 1; k < detections.size(); ++k) {
      if (detections[k].cost < detections[best].cost) best = k;
    }
    const Detection& b = detections[best];
    if (defer && !(b.sigma <= 0.25 * identifier.MaxSigma(b.source))) {
      deferred_one = true;
      return false;
    }
    std::vector<size_t> rivals;
    for (size_t k = 0; k < detections.size(); ++k) {
      if (k != best && detections[k].cost - b.cost < options.ambiguity_chi2) rivals.push_back(k);
    }
    if (rivals.empty()) {
      IdentifiedSource& out = result.sources[b.source];
      out.outcome = IdentifyOutcome::kFound;
      out.detail.clear();
      out.scene_from_source = b.scene_from_source;
      out.assigned = static_cast<int>(b.point.size());
      out.sigma_rad = b.sigma;
      double ss = 0.0;
      for (size_t k = 0; k < b.point.size(); ++k) {
        const int i = b.point[k];
        pool.taken[i] = 1;
        result.source_index[pool.spot[i]] = b.source;
        result.beam_id[pool.spot[i]] = b.beam[k];
        ss += b.residual[k] * b.residual[k];
      }
      out.rms_residual_rad = std::sqrt(ss / (2.0 * std::max<size_t>(1, b.point.size())));
      done[b.source] = 1;
      ++progress.sources_found;
      progress.points_assigned += out.assigned;
      return true;
    }
    // Ambiguous: say why, for every source involved.
    for (int i : b.point) pool.blocked[i] = 1;
    const Detection& r = detections[rivals.front()];
    std::ostringstream why;
    if (r.source == b.source) {
      const double angle = RotationAngleBetweenRad(b.scene_from_source.RotationMatrix(),
                                                   r.scene_from_source.RotationMatrix());
      why << b.point.size() << " points fit two correspondences as well (the other pose rotated by "
          << FormatNumber(angle * 180.0 / kPi, 4) << " deg; chi2 difference "
          << FormatNumber(r.cost - b.cost, 3) << " < " << FormatNumber(options.ambiguity_chi2, 3)
          << "): the pattern is symmetric to within the noise";
      ambiguity[b.source] = why.str();
      done[b.source] = 1;
    } else {
      why << "a grid of " << b.point.size() << " points fits sources " << calibration.sources[b.source].name
          << " and " << calibration.sources[r.source].name << " as well (chi2 difference "
          << FormatNumber(r.cost - b.cost, 3) << " < " << FormatNumber(options.ambiguity_chi2, 3) << ")";
      ambiguity[b.source] = why.str();
      ambiguity[r.source] = why.str();
    }
    return true;
  };
  auto all_done = [&done]() { return std::all_of(done.begin(), done.end(), [](char d) { return d != 0; }); };
  // A detection that is not clear is decided only after kDeferrals such
  // seeds: interleaved grids (spots of the other grid a fraction of a step
  // away) can give a wrong pose of a whole grid whose noise, far above the
  // spots', is still below the acceptance limit, while a later seed finds
  // the grid clearly.
  constexpr int kDeferrals = 16;
  int deferrals = 0;
  // The seeds of `list` in order, each counted in *counter (at most
  // max_seeds); then, when a decision was put off and sources remain, the
  // same seeds again deciding on every detection.
  auto run = [&](const std::vector<Seed>& list, int* counter) {
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {
        if (deferrals == 0 || all_done()) break;
        deferrals = kDeferrals;
        *counter = 0;
      }
      for (const Seed& seed : list) {
        if (all_done() || *counter >= options.max_seeds) break;
        if (!usable(seed)) continue;
        ++*counter;
        const int derived_before = tried_derived;
        if (grow) {
          Seed grown = seed;
          identify_internal::GrowSeed(pool, neighbours, growth_scale, max_extent, &grown);
          try_seed(grown, true, deferrals < kDeferrals);
        } else {
          try_seed(seed, true, deferrals < kDeferrals);
        }
        deferrals += deferred_one;
        progress.seeds_tried += 1 + (tried_derived - derived_before);
        report_progress();
      }
    }
  };
  run(seeds, &tried);
  // Sources still to find after a source was found: seeds again, from the
  // points still free only (a grid interleaved with a found one: its
  // points' crosses used the found grid's points), with a budget of
  // max_seeds.
  int reseeded = 0;
  if (!all_done() && std::any_of(pool.taken.begin(), pool.taken.end(), [](char t) { return t != 0; })) {
    Pool rest;
    std::vector<int> back;
    for (int i = 0; i < pool.size(); ++i) {
      if (pool.taken[i]) continue;
      rest.p.push_back(pool.p[i]);
      back.push_back(i);
    }
    std::vector<Seed> more = FindSeeds(rest, NearestNeighbours(rest.p, options.neighbours), options.num_threads);
    for (Seed& seed : more) {
      seed.p0 = back[seed.p0];
      seed.pa = back[seed.pa];
      seed.pb = back[seed.pb];
      for (auto& entry : seed.patch) entry.first = back[entry.first];
    }
    deferrals = 0;
    run(more, &reseeded);
  }

  // Overlapping grids: a point assigned to one found source that also lies
  // within the gate of a beam of another found source could be either's
  // spot (e.g. a spot of one grid where the other's is missing): refuse it.
  for (int i = 0; i < pool.size(); ++i) {
    const int spot = pool.spot[i];
    const int s = result.source_index[spot];
    if (s < 0) continue;
    for (int o = 0; o < num_sources; ++o) {
      if (o == s || result.sources[o].outcome != IdentifyOutcome::kFound) continue;
      if (pool.only_source[i] >= 0 && pool.only_source[i] != o) continue;
      const double angle = identifier.NearestAngle(o, result.sources[o].scene_from_source, pool.p[i]);
      if (angle < identifier.FinalGate(o, result.sources[o].sigma_rad)) {
        const double r = identifier.NearestAngle(s, result.sources[s].scene_from_source, pool.p[i]);
        IdentifiedSource& src = result.sources[s];
        const double ss = src.rms_residual_rad * src.rms_residual_rad * 2.0 * src.assigned - r * r;
        --src.assigned;
        src.rms_residual_rad = std::sqrt(std::max(0.0, ss) / (2.0 * std::max(1, src.assigned)));
        result.source_index[spot] = -1;
        result.beam_id[spot] = 0;
        break;
      }
    }
  }

  progress.sources_found = 0;
  progress.points_assigned = 0;
  for (const IdentifiedSource& source : result.sources) {
    if (source.outcome != IdentifyOutcome::kFound) continue;
    ++progress.sources_found;
    progress.points_assigned += source.assigned;
  }
  progress.finished = true;
  report_progress();

  for (int s = 0; s < num_sources; ++s) {
    IdentifiedSource& out = result.sources[s];
    if (out.outcome == IdentifyOutcome::kFound) continue;
    if (!ambiguity[s].empty()) {
      out.outcome = IdentifyOutcome::kAmbiguous;
      out.detail = ambiguity[s];
    } else if (out.detail.empty()) {
      out.outcome = IdentifyOutcome::kNotFound;
      if (pool.size() < options.min_spots) {
        out.detail = "too few points to identify: " + std::to_string(pool.size()) + " (at least " +
                     std::to_string(options.min_spots) + " needed)";
      } else if (seeds.empty()) {
        out.detail = "no lattice-like group of points (a point with two pairs of opposite neighbours)";
      } else {
        out.detail = "no pose explains at least " + std::to_string(identifier.MinPoints(s)) + " points (" +
                     std::to_string(tried) + " seeds tried, " + std::to_string(tried_derived) +
                     " derived crosses, " + std::to_string(reseeded) + " seeds of the free points)";
      }
    }
  }
  return result;
}

}  // namespace opl
