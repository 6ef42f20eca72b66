#include "opl/sim/simulate_spots.h"

#include "opl/core/format.h"

#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <utility>

#include "opl/sim/random.h"

namespace opl {
namespace {

struct Candidate {
  const SourceDesign* source = nullptr;
  int beam_id = 0;
  int slice = 0;
  Eigen::Vector3d true_point = Eigen::Vector3d::Zero();
  Eigen::Vector3d ray_direction = Eigen::Vector3d::UnitX();  // unit, scene
  Eigen::Vector3d perpendicular = Eigen::Vector3d::UnitY();  // unit, scene, _|_ ray
};

// A unit vector perpendicular to unit `d` (deterministic).
Eigen::Vector3d AnyPerpendicular(const Eigen::Vector3d& d) {
  int k = 0;
  d.cwiseAbs().minCoeff(&k);
  return d.cross(Eigen::Vector3d::Unit(k)).normalized();
}

}  // namespace

Status SpotSimulationOptions::Validate() const {
  if (!(missing_fraction >= 0.0 && missing_fraction <= 1.0)) {
    return Status::InvalidArgument("missing_fraction must be in [0, 1], got " +
                                   FormatNumber(missing_fraction));
  }
  if (!(outlier_fraction >= 0.0 && outlier_fraction <= 1.0)) {
    return Status::InvalidArgument("outlier_fraction must be in [0, 1], got " +
                                   FormatNumber(outlier_fraction));
  }
  if (!(std::isfinite(outlier_distance_mm) && outlier_distance_mm > 0.0)) {
    return Status::InvalidArgument("outlier_distance_mm must be finite and > 0, got " +
                                   FormatNumber(outlier_distance_mm));
  }
  return Status::Ok();
}

Result<std::vector<SimulatedSpot>> SimulateSpots(const ModuleDesign& design,
                                                 const SpotSimulationOptions& options) {
  OPL_RETURN_IF_ERROR(design.Validate());
  OPL_RETURN_IF_ERROR(options.Validate());

  // Candidates: every beam's hit on every slice.
  std::vector<Candidate> candidates;
  for (const SourceDesign& source : design.sources) {
    Result<BeamPattern> pattern = MakePattern(source);
    if (!pattern.ok()) return pattern.status();
    const Eigen::Matrix3d R = source.scene_from_source.RotationMatrix();
    const Eigen::Vector3d& t = source.scene_from_source.translation;
    for (int slice = 0; slice < design.surface.num_slices(); ++slice) {
      for (const Beam& beam : pattern->beams()) {
        const Eigen::Vector3d d_source = beam.DirectionInSource();
        const Eigen::Vector3d d = (R * d_source).normalized();
        const std::optional<Eigen::Vector3d> hit = design.surface.IntersectRaySlice(slice, t, d);
        if (!hit) continue;
        // The outlier basis is fixed in the source frame so that moving the
        // whole design moves its outliers with it.
        candidates.push_back({&source, beam.id, slice, *hit, d, R * AnyPerpendicular(d_source)});
      }
    }
  }
  if (candidates.empty()) {
    return Status::NoSolution("no beam of any source hits the surface (" +
                              std::string(design.surface.TypeName()) + ")");
  }
  const size_t n = candidates.size();

  SplitMix64 seeder(options.seed);
  std::mt19937_64 missing_rng(seeder.Next());
  std::mt19937_64 outlier_rng(seeder.Next());
  std::mt19937_64 noise_rng(seeder.Next());

  // 1. Missing.
  const size_t num_missing = static_cast<size_t>(std::llround(options.missing_fraction * n));
  std::vector<char> missing(n, 0);
  for (size_t index : SampleWithoutReplacement(n, num_missing, missing_rng)) missing[index] = 1;
  std::vector<size_t> kept;
  kept.reserve(n - num_missing);
  for (size_t i = 0; i < n; ++i) {
    if (!missing[i]) kept.push_back(i);
  }

  // 3. Outliers (chosen now; applied below).
  const size_t num_outliers =
      static_cast<size_t>(std::llround(options.outlier_fraction * kept.size()));
  std::vector<char> outlier(n, 0);
  for (size_t k : SampleWithoutReplacement(kept.size(), num_outliers, outlier_rng)) {
    outlier[kept[k]] = 1;
  }

  // 2. Noise for every candidate (kept or not), in candidate order.
  const Eigen::Matrix3d Rn = design.noise_frame_rotation;
  const Eigen::Matrix3d cov = design.SpotCovarianceMm2();
  NormalGenerator normal;
  std::vector<SimulatedSpot> out;
  out.reserve(kept.size());
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d z(normal(noise_rng), normal(noise_rng), normal(noise_rng));
    if (missing[i]) continue;
    const Candidate& c = candidates[i];
    Eigen::Vector3d point = c.true_point + Rn * design.spot_noise_mm.cwiseProduct(z);
    if (outlier[i]) {
      const Eigen::Vector3d& e1 = c.perpendicular;
      const Eigen::Vector3d e2 = c.ray_direction.cross(e1);
      const double phi = 2.0 * kPi * Uniform01(outlier_rng);
      point += options.outlier_distance_mm * (std::cos(phi) * e1 + std::sin(phi) * e2);
    }
    SimulatedSpot s;
    s.spot.source = c.source->name;
    s.spot.observation.beam_id = c.beam_id;
    s.spot.observation.point_in_scene = point;
    if (options.attach_covariance) s.spot.observation.cov_in_scene = cov;
    s.spot.where = "simulated";
    s.true_point_in_scene = c.true_point;
    s.slice = c.slice;
    s.outlier = outlier[i] != 0;
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<Spot> SpotsOf(const std::vector<SimulatedSpot>& simulated) {
  std::vector<Spot> spots;
  spots.reserve(simulated.size());
  for (const SimulatedSpot& s : simulated) spots.push_back(s.spot);
  return spots;
}

}  // namespace opl
