// Test support: random scenes for spot identification (tests/identify,
// tests/benchmarks/identify_bench.cc). A module of several 11 x 11 sources
// whose grids partly overlap, at a random pose (any rotation), throwing its
// spots on a random surface (plane, sphere from outside or inside, box
// corner, paraboloid); spots missing, anisotropic noise, spurious points
// (some uniform in the scene's box, some 0.5-3 mm from a real spot); all
// points shuffled and stripped of source and beam. The truth is kept.
//
// The calibration handed to IdentifySpots holds the patterns the spots were
// made with: designed patterns (equal-angle or grating) with every beam's
// direction perturbed by `perturbation_rad` per component, as a real
// calibrated module differs from its design.
#pragma once

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "opl/geometry/rotation.h"
#include "opl/model/module_calibration.h"
#include "opl/model/spot.h"
#include "opl/sim/pattern_models.h"
#include "opl/sim/surface.h"
#include "support/synthetic_source.h"

namespace opl::test {

struct IdentifySceneOptions {
  int sources = 3;
  int beams_per_side = 11;
  double full_angle_deg = 29.0;
  double perturbation_rad = 2e-3;  // per beam and component; 0: the exact design
  double max_missing = 0.3;        // missing fraction drawn in [0, max_missing]
  double max_spurious = 0.1;       // spurious points drawn in [0, max_spurious] * real
  double near_fraction = 0.5;      // of the spurious points: 0.5-3 mm from a real spot
  Eigen::Vector3d noise_mm = Eigen::Vector3d(0.110, 0.073, 0.073);  // scene axes
  int surface = -1;                // 0 plane, 1 sphere out, 2 sphere in, 3 box corner, 4 paraboloid; -1 random
  double min_distance_mm = 400.0, max_distance_mm = 3000.0;
  bool random_pose = true;         // module at a random pose (else at the scene origin looking +X)
  double roll_rad = 0.0;           // extra roll of every source about its central beam
};

struct IdentifyScene {
  ModuleCalibration calibration;
  std::vector<Spot> spots;          // unassigned: source "", beam 0; where "scene:<i>"
  std::vector<int> true_source;     // index into calibration.sources, -1 for spurious
  std::vector<int> true_beam;       // 0 for spurious
  std::vector<Rigid3d> scene_from_source;
  std::string surface;
  int real = 0, spurious = 0;
};

inline BeamPattern PerturbedPattern(const BeamPattern& pattern, double sigma_rad, std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Beam> beams = pattern.beams();
  for (Beam& b : beams) {
    b.az_rad += sigma_rad * g(rng);
    b.el_rad += sigma_rad * g(rng);
  }
  return BeamPattern(pattern.beams_per_side(), beams);
}

inline IdentifyScene MakeIdentifyScene(uint64_t seed, const IdentifySceneOptions& o = IdentifySceneOptions()) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  auto uni = [&](double a, double b) { return a + (b - a) * u01(rng); };
  IdentifyScene scene;

  // Module frame: sources side by side along Y, 55 mm apart, yawed apart so
  // that neighbouring grids overlap partly.
  const double full = o.full_angle_deg * M_PI / 180.0;
  const double yaw_step = uni(0.3, 0.8) * full;
  std::vector<Rigid3d> module_from_source;
  for (int k = 0; k < o.sources; ++k) {
    SourceCalibration s;
    s.name = std::string(1, static_cast<char>('A' + k));
    const bool grating = u01(rng) < 0.5;
    const BeamPattern design = grating ? MakeGratingPattern(o.beams_per_side, full, 658.0)
                                       : MakeEqualAnglePattern(o.beams_per_side, full);
    s.pattern = o.perturbation_rad > 0.0 ? PerturbedPattern(design, o.perturbation_rad, rng) : design;
    const double c = k - 0.5 * (o.sources - 1);
    const Eigen::Vector3d xyz(o.roll_rad + uni(-0.1, 0.1), uni(-0.05, 0.05), c * yaw_step + uni(-0.05, 0.05));
    const Rigid3d pose(RotationFromXyzAnglesRad(xyz), Eigen::Vector3d(uni(-2, 2), -55.0 * c, uni(-5, 5)));
    s.calibration_from_source = pose;
    module_from_source.push_back(pose);
    scene.calibration.sources.push_back(s);
  }
  scene.calibration.separations = ModuleCalibration::SeparationsFromOrigins(scene.calibration.sources);

  // Surface in the module frame, the module looking along +X.
  const double D = uni(o.min_distance_mm, o.max_distance_mm);
  const int type = o.surface >= 0 ? o.surface : static_cast<int>(u01(rng) * 5.0) % 5;
  Surface surface;
  switch (type) {
    case 0: {
      const double tilt = uni(0.0, 60.0) * M_PI / 180.0, phi = uni(0.0, 2.0 * M_PI);
      surface = PlaneSurface{Eigen::Vector3d(D, 0, 0),
                             Eigen::Vector3d(-std::cos(tilt), std::sin(tilt) * std::cos(phi),
                                             std::sin(tilt) * std::sin(phi))};
      scene.surface = "plane";
      break;
    }
    case 1: {
      const double R = uni(0.5, 3.0) * D;
      surface = SphereSurface{Eigen::Vector3d(D + R, uni(-0.1, 0.1) * D, uni(-0.1, 0.1) * D), R};
      scene.surface = "sphere (outside)";
      break;
    }
    case 2: {
      const double R = uni(1.2, 3.0) * D;
      surface = SphereSurface{Eigen::Vector3d(D - R, uni(-0.1, 0.1) * D, uni(-0.1, 0.1) * D), R};
      scene.surface = "sphere (inside)";
      break;
    }
    case 3: {
      // Open octant towards the module: (1,1,1) of the box points along -X.
      const Eigen::Quaterniond align =
          Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(1, 1, 1).normalized(), -Eigen::Vector3d::UnitX());
      const Eigen::Matrix3d B =
          (Eigen::AngleAxisd(uni(0.0, 2.0 * M_PI), Eigen::Vector3d::UnitX()) * align).toRotationMatrix();
      surface = BoxCornerSurface{Eigen::Vector3d(D, uni(-0.15, 0.15) * D, uni(-0.15, 0.15) * D), B};
      scene.surface = "box corner";
      break;
    }
    default: {
      const double c = (u01(rng) < 0.5 ? 1.0 : -1.0) / (uni(1.0, 5.0) * D);
      surface = ParaboloidSurface{Eigen::Vector3d(D, 0, 0),
                                  Eigen::Vector3d(-1.0, uni(-0.2, 0.2), uni(-0.2, 0.2)), c};
      scene.surface = "paraboloid";
      break;
    }
  }

  const Rigid3d scene_from_module =
      o.random_pose ? Rigid3d(RandomRotation(rng), Eigen::Vector3d(uni(-1000, 1000), uni(-1000, 1000), uni(-1000, 1000)))
                    : Rigid3d();
  struct Pt {
    Eigen::Vector3d p;
    int source, beam;
  };
  std::vector<Pt> points;
  const double missing = uni(0.0, o.max_missing);
  for (int k = 0; k < o.sources; ++k) {
    const SourceCalibration& s = scene.calibration.sources[k];
    const Rigid3d& module_pose = module_from_source[k];
    scene.scene_from_source.push_back(scene_from_module * module_pose);
    for (const Beam& b : s.pattern.beams()) {
      const Eigen::Vector3d d = module_pose.rotation * s.pattern.DirectionInSource(b.id);
      auto hit = surface.IntersectRay(module_pose.translation, d);
      if (!hit) continue;
      if (u01(rng) < missing) continue;
      Eigen::Vector3d p = scene_from_module * *hit;
      p += Eigen::Vector3d(o.noise_mm.x() * g(rng), o.noise_mm.y() * g(rng), o.noise_mm.z() * g(rng));
      points.push_back({p, k, b.id});
    }
  }
  scene.real = static_cast<int>(points.size());
  if (points.empty()) return scene;
  Eigen::Vector3d lo = points[0].p, hi = points[0].p;
  for (const Pt& p : points) {
    lo = lo.cwiseMin(p.p);
    hi = hi.cwiseMax(p.p);
  }
  const int spurious = static_cast<int>(std::lround(uni(0.0, o.max_spurious) * scene.real));
  for (int k = 0; k < spurious; ++k) {
    Eigen::Vector3d p;
    if (u01(rng) < o.near_fraction) {
      const Pt& real = points[static_cast<size_t>(u01(rng) * scene.real) % scene.real];
      const Eigen::Vector3d dir = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
      p = real.p + uni(0.5, 3.0) * dir;
    } else {
      p = Eigen::Vector3d(uni(lo.x(), hi.x()), uni(lo.y(), hi.y()), uni(lo.z(), hi.z()));
    }
    points.push_back({p, -1, 0});
  }
  scene.spurious = spurious;
  std::shuffle(points.begin(), points.end(), rng);
  for (size_t i = 0; i < points.size(); ++i) {
    Spot s;
    s.observation.point_in_scene = points[i].p;
    s.where = "scene:" + std::to_string(i);
    scene.spots.push_back(s);
    scene.true_source.push_back(points[i].source);
    scene.true_beam.push_back(points[i].beam);
  }
  return scene;
}

}  // namespace opl::test
