#include "opl/sim/surface.h"

#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "opl/geometry/rotation.h"

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;

// Closed-form residuals of each surface's equation, mm (independent of the
// intersection code).
double PlaneResidual(const PlaneSurface& s, const Vec3& p) {
  return s.normal.normalized().dot(p - s.point_mm);
}
double SphereResidual(const SphereSurface& s, const Vec3& p) {
  return (p - s.center_mm).norm() - s.radius_mm;
}
// Distance to the nearest of the three quarter planes (requires the other two
// box coordinates to be >= 0 up to rounding).
double BoxResidual(const BoxCornerSurface& s, const Vec3& p) {
  const Vec3 q = s.scene_from_box.transpose() * (p - s.corner_mm);
  double best = 1e300;
  for (int k = 0; k < 3; ++k) {
    if (q[(k + 1) % 3] >= -1e-9 && q[(k + 2) % 3] >= -1e-9) best = std::min(best, std::abs(q[k]));
  }
  return best;
}
double ParaboloidResidual(const ParaboloidSurface& s, const Vec3& p) {
  const Vec3 a = s.axis.normalized();
  const Vec3 w = p - s.vertex_mm;
  const double z = a.dot(w);
  const double r2 = (w - z * a).squaredNorm();
  return z - 0.5 * s.curvature_per_mm * r2;
}
double Residual(const Surface& surface, const Vec3& p) {
  switch (surface.type()) {
    case SurfaceType::kPlane: return PlaneResidual(std::get<PlaneSurface>(surface.shape()), p);
    case SurfaceType::kSphere: return SphereResidual(std::get<SphereSurface>(surface.shape()), p);
    case SurfaceType::kBoxCorner:
      return BoxResidual(std::get<BoxCornerSurface>(surface.shape()), p);
    case SurfaceType::kParaboloid:
      return ParaboloidResidual(std::get<ParaboloidSurface>(surface.shape()), p);
    case SurfaceType::kPlanes: {
      double best = 1e300;
      for (const PlaneSurface& s : std::get<PlaneListSurface>(surface.shape()).planes) {
        best = std::min(best, std::abs(PlaneResidual(s, p)));
      }
      return best;
    }
  }
  return 1e300;
}

// Distance of p from the ray (o, d), and the ray parameter of p.
double DistanceFromRay(const Vec3& o, const Vec3& d, const Vec3& p) {
  return (p - o).cross(d.normalized()).norm();
}

Vec3 RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  return Vec3(g(rng), g(rng), g(rng)).normalized();
}

Rigid3d RandomPose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Vec3 w(u(rng) * 3.0, u(rng) * 3.0, u(rng) * 3.0);
  return Rigid3d(ExpSO3(w), Vec3(u(rng), u(rng), u(rng)) * 2000.0);
}

std::vector<Surface> AllSurfaces() {
  return {
      Surface(PlaneSurface{Vec3(1000, 20, -30), Vec3(-1, 0.2, 0.1)}),
      Surface(SphereSurface{Vec3(1500, 100, 0), 800.0}),
      Surface(BoxCornerSurface{Vec3(1200, -600, -500), RotationFromXyzAnglesRad(Vec3(0.1, -0.2, 0.7))}),
      Surface(ParaboloidSurface{Vec3(1100, 0, 0), Vec3(-1, 0.05, 0), 1.0 / 1500.0}),
      Surface(PlaneListSurface{{PlaneSurface{Vec3(750, 0, 0), Vec3(-1, 0, 0)},
                                PlaneSurface{Vec3(1050, 0, 0), Vec3(-1, 0, 0.01)},
                                PlaneSurface{Vec3(1350, 0, 0), Vec3(1, 0, 0)}}}),
  };
}

TEST(Surface, ClosedFormHits) {
  const Vec3 o = Vec3::Zero(), x = Vec3::UnitX();
  // Plane x = 1000.
  const Surface plane = Surface();
  EXPECT_EQ(plane.TypeName(), std::string("plane"));
  EXPECT_TRUE(plane.IntersectRay(o, x)->isApprox(Vec3(1000, 0, 0), 1e-15));
  EXPECT_FALSE(plane.IntersectRay(o, -x).has_value());            // behind
  EXPECT_FALSE(plane.IntersectRay(o, Vec3::UnitY()).has_value());  // parallel
  EXPECT_FALSE(plane.IntersectRay(o, Vec3::Zero()).has_value());   // no direction
  // Direction need not be unit.
  EXPECT_TRUE(plane.IntersectRay(o, Vec3(2, 2, 0))->isApprox(Vec3(1000, 1000, 0), 1e-15));
  // A ray starting on the plane does not hit it at its origin.
  EXPECT_FALSE(plane.IntersectRay(Vec3(1000, 5, 5), x).has_value());

  // Sphere: from outside the near side, from inside the far wall.
  const Surface sphere(SphereSurface{Vec3(2000, 0, 0), 500.0});
  EXPECT_TRUE(sphere.IntersectRay(o, x)->isApprox(Vec3(1500, 0, 0), 1e-15));
  EXPECT_TRUE(sphere.IntersectRay(Vec3(2000, 0, 0), x)->isApprox(Vec3(2500, 0, 0), 1e-15));
  EXPECT_TRUE(sphere.IntersectRay(Vec3(1800, 0, 0), -x)->isApprox(Vec3(1500, 0, 0), 1e-15));
  EXPECT_FALSE(sphere.IntersectRay(o, Vec3::UnitY()).has_value());
  EXPECT_FALSE(sphere.IntersectRay(o, -x).has_value());
  // Grazing at 300 mm off axis: |(1600, 300)| hits (2000 - 400, 300).
  EXPECT_TRUE(sphere.IntersectRay(Vec3(0, 300, 0), x)->isApprox(Vec3(1600, 300, 0), 1e-15));

  // Box corner at the origin, box axes = scene axes; rays from inside the octant.
  const Surface box(BoxCornerSurface{Vec3::Zero(), Eigen::Matrix3d::Identity()});
  EXPECT_TRUE(box.IntersectRay(Vec3(1, 2, 3), -x)->isApprox(Vec3(0, 2, 3), 1e-15));
  EXPECT_TRUE(box.IntersectRay(Vec3(1, 2, 3), Vec3(-1, -1, -1))->isApprox(Vec3(0, 1, 2), 1e-15));
  EXPECT_TRUE(box.IntersectRay(Vec3(3, 2, 1), Vec3(-1, -1, -1))->isApprox(Vec3(2, 1, 0), 1e-15));
  EXPECT_FALSE(box.IntersectRay(Vec3(1, 2, 3), Vec3(1, 1, 1)).has_value());  // out of the open side
  // From outside through a quarter plane's back, and missing the quarter planes.
  EXPECT_TRUE(box.IntersectRay(Vec3(-5, 2, 3), x)->isApprox(Vec3(0, 2, 3), 1e-15));
  EXPECT_FALSE(box.IntersectRay(Vec3(-5, -2, 3), x).has_value());

  // Paraboloid z' = c/2 r'^2 about +X with c = 1/1000.
  const Surface para(ParaboloidSurface{Vec3::Zero(), x, 1e-3});
  EXPECT_LT(para.IntersectRay(Vec3(-500, 0, 0), x)->norm(), 1e-12);
  EXPECT_TRUE(para.IntersectRay(Vec3(-500, 100, 0), x)->isApprox(Vec3(5, 100, 0), 1e-15));
  const double y = std::sqrt(2.0 * 100.0 / 1e-3);
  EXPECT_TRUE(
      para.IntersectRay(Vec3(100, -1000, 0), Vec3::UnitY())->isApprox(Vec3(100, -y, 0), 1e-15));
  // Curvature 0 is a plane through the vertex.
  const Surface flat(ParaboloidSurface{Vec3(700, 0, 0), Vec3(-2, 0, 0), 0.0});
  EXPECT_TRUE(flat.IntersectRay(Vec3(0, 10, 0), x)->isApprox(Vec3(700, 10, 0), 1e-15));

  // Plane list: slices and nearest.
  const Surface list(PlaneListSurface{{PlaneSurface{Vec3(1350, 0, 0), -x},
                                       PlaneSurface{Vec3(750, 0, 0), -x}}});
  EXPECT_EQ(list.num_slices(), 2);
  EXPECT_EQ(sphere.num_slices(), 1);
  EXPECT_TRUE(list.IntersectRaySlice(0, o, x)->isApprox(Vec3(1350, 0, 0), 1e-15));
  EXPECT_TRUE(list.IntersectRaySlice(1, o, x)->isApprox(Vec3(750, 0, 0), 1e-15));
  EXPECT_TRUE(list.IntersectRay(o, x)->isApprox(Vec3(750, 0, 0), 1e-15));
  EXPECT_FALSE(list.IntersectRaySlice(2, o, x).has_value());
  EXPECT_FALSE(list.IntersectRaySlice(-1, o, x).has_value());
  EXPECT_FALSE(sphere.IntersectRaySlice(1, o, x).has_value());
}

TEST(Surface, RandomHitsLieOnSurfaceAndOnRay) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Surface& surface : AllSurfaces()) {
    int hits = 0;
    double worst_surface = 0.0, worst_ray = 0.0;
    for (int k = 0; k < 4000; ++k) {
      // Rays from around the origin, roughly towards +X, plus some anywhere.
      const Vec3 o = Vec3(u(rng), u(rng), u(rng)) * 100.0;
      const Vec3 d = k % 4 == 0 ? RandomUnit(rng) : Vec3(1.0, 0.6 * u(rng), 0.6 * u(rng));
      for (int slice = 0; slice < surface.num_slices(); ++slice) {
        const auto p = surface.IntersectRaySlice(slice, o, d);
        if (!p) continue;
        ++hits;
        worst_surface = std::max(worst_surface, std::abs(Residual(surface, *p)));
        worst_ray = std::max(worst_ray, DistanceFromRay(o, d, *p));
        EXPECT_GT((*p - o).dot(d), 0.0);
      }
    }
    EXPECT_GT(hits, 2000) << surface.TypeName();
    EXPECT_LT(worst_surface, 1e-9) << surface.TypeName();
    EXPECT_LT(worst_ray, 1e-9) << surface.TypeName();
  }
}

TEST(Surface, FirstHitIsTheNearest) {
  // Sample the ray densely: no point before the returned hit is on the other
  // side of the surface (sign change of the residual), for sphere and paraboloid.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const SphereSurface s{Vec3(1500, 0, 0), 600.0};
  const ParaboloidSurface q{Vec3(900, 0, 0), Vec3(-1, 0, 0), 1.0 / 800.0};
  for (int k = 0; k < 200; ++k) {
    const Vec3 o = Vec3(u(rng), u(rng), u(rng)) * 50.0;
    const Vec3 d = Vec3(1.0, 0.5 * u(rng), 0.5 * u(rng)).normalized();
    if (const auto p = Surface(s).IntersectRay(o, d)) {
      const double t = (*p - o).norm();
      for (int i = 1; i < 100; ++i) {
        EXPECT_GT(SphereResidual(s, o + d * t * i / 100.0), 0.0);  // still outside
      }
    }
    if (const auto p = Surface(q).IntersectRay(o, d)) {
      const double t = (*p - o).norm();
      const double sign0 = ParaboloidResidual(q, o);
      for (int i = 1; i < 100; ++i) {
        EXPECT_GT(ParaboloidResidual(q, o + d * t * i / 100.0) * sign0, 0.0);
      }
    }
  }
  // Box corner from inside: the segment to the hit stays inside the octant.
  const BoxCornerSurface b{Vec3(1000, -500, -400), RotationFromXyzAnglesRad(Vec3(0.3, 0.2, -0.4))};
  int inside_hits = 0;
  for (int k = 0; k < 500; ++k) {
    const Vec3 o = b.corner_mm + b.scene_from_box * Vec3(u(rng) + 1.1, u(rng) + 1.1, u(rng) + 1.1) * 200;
    const auto p = Surface(b).IntersectRay(o, RandomUnit(rng));
    if (!p) continue;
    ++inside_hits;
    const Vec3 mid = b.scene_from_box.transpose() * (0.5 * (o + *p) - b.corner_mm);
    EXPECT_GT(mid.minCoeff(), 0.0);
    EXPECT_LT(BoxResidual(b, *p), 1e-9);
  }
  EXPECT_GT(inside_hits, 300);  // about 7/8 of random directions leave through a wall
}

TEST(Surface, TransformedMovesSurfaceRigidly) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Surface& surface : AllSurfaces()) {
    const Rigid3d T = RandomPose(rng);
    const Surface moved = surface.Transformed(T);
    EXPECT_EQ(moved.type(), surface.type());
    EXPECT_EQ(moved.num_slices(), surface.num_slices());
    int compared = 0;
    for (int k = 0; k < 500; ++k) {
      const Vec3 o = Vec3(u(rng), u(rng), u(rng)) * 100.0;
      const Vec3 d = Vec3(1.0, 0.6 * u(rng), 0.6 * u(rng));
      for (int slice = 0; slice < surface.num_slices(); ++slice) {
        const auto p = surface.IntersectRaySlice(slice, o, d);
        const auto q = moved.IntersectRaySlice(slice, T * o, T.rotation * d);
        ASSERT_EQ(p.has_value(), q.has_value());
        if (!p) continue;
        ++compared;
        EXPECT_LT((*q - T * *p).norm(), 1e-9) << surface.TypeName();
        EXPECT_LT(std::abs(Residual(moved, *q)), 1e-9) << surface.TypeName();
      }
    }
    EXPECT_GT(compared, 250) << surface.TypeName();
  }
}

TEST(Surface, ValidateNamesTheProblem) {
  for (const Surface& s : AllSurfaces()) EXPECT_TRUE(s.Validate().ok()) << s.TypeName();
  EXPECT_EQ(Surface(PlaneSurface{Vec3::Zero(), Vec3::Zero()}).Validate().message(),
            "normal is zero");
  EXPECT_EQ(Surface(PlaneSurface{Vec3(NAN, 0, 0), Vec3::UnitX()}).Validate().message(),
            "point_mm is not finite");
  EXPECT_EQ(Surface(SphereSurface{Vec3::Zero(), 0.0}).Validate().code(),
            StatusCode::kInvalidArgument);
  Eigen::Matrix3d not_rotation = Eigen::Matrix3d::Identity();
  not_rotation(0, 0) = -1.0;  // a reflection
  EXPECT_EQ(Surface(BoxCornerSurface{Vec3::Zero(), not_rotation}).Validate().message(),
            "box rotation is not a proper rotation");
  EXPECT_EQ(Surface(ParaboloidSurface{Vec3::Zero(), Vec3::Zero(), 1.0}).Validate().message(),
            "axis is zero");
  EXPECT_EQ(Surface(ParaboloidSurface{Vec3::Zero(), Vec3::UnitX(), INFINITY}).Validate().message(),
            "curvature_per_mm is not finite");
  EXPECT_EQ(Surface(PlaneListSurface{}).Validate().message(), "planes is empty");
  EXPECT_EQ(Surface(PlaneListSurface{{PlaneSurface{}, PlaneSurface{Vec3::Zero(), Vec3::Zero()}}})
                .Validate()
                .message(),
            "planes[1].normal is zero");
}

}  // namespace
}  // namespace opl
