// Surfaces the simulated spots land on (method.md, "Simulation models";
// docs/simulation.md, "Surfaces").
//
// A Surface is a value: one of five shapes, all given in the scene frame,
// millimetres.
//
//   PlaneSurface       n . (p - point_mm) = 0. `normal` need not be unit.
//   SphereSurface      |p - center_mm| = radius_mm. A ray from outside hits the
//                      near side first; a ray from inside hits the far wall
//                      (the first intersection ahead of the origin either way).
//   BoxCornerSurface   a concave corner of three mutually orthogonal planes
//                      (e.g. two walls and a floor seen from inside a room).
//                      In box coordinates p' = B^T (p - corner_mm), where the
//                      columns of B = scene_from_box are the box axes in the
//                      scene, the surface is the union of the three quarter
//                      planes {p'_k = 0, the other two coordinates >= 0}. The
//                      corner's octant (all p' >= 0) is the open side. A ray
//                      hits the first quarter plane it reaches.
//   ParaboloidSurface  in its own frame (origin at vertex_mm, z' along `axis`)
//                      z' = curvature_per_mm / 2 * r'^2, r'^2 = x'^2 + y'^2.
//                      `axis` need not be unit; curvature 0 is the plane
//                      through the vertex normal to the axis; negative
//                      curvature opens towards -axis.
//   PlaneListSurface   several planes (calibration slices at several depths);
//                      each plane is a "slice" and gives its own set of spots.
//
// Intersection contract: IntersectRay(origin, direction) returns the first
// point origin + t * d, d = direction / |direction|, with t > kMinHitDistanceMm,
// that lies on the surface, or nullopt when there is none (the ray misses, is
// parallel to a plane, or the direction is zero or not finite). Hits closer
// than kMinHitDistanceMm are ignored so that a ray starting on a surface does
// not hit it at its own origin. For a PlaneListSurface IntersectRay returns the
// nearest hit over all planes, and IntersectRaySlice(k, ...) the hit with plane
// k alone; for the other shapes slice 0 is the surface itself. Results are
// accurate to rounding: residuals of the surface equation are ~1e-13 mm at
// metre scale (tested < 1e-9 mm).
#pragma once

#include <optional>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "opl/core/status.h"
#include "opl/geometry/rigid3.h"

namespace opl {

struct PlaneSurface {
  Eigen::Vector3d point_mm = Eigen::Vector3d::Zero();  // any point of the plane, scene
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();   // non-zero, scene; sign irrelevant
};

struct SphereSurface {
  Eigen::Vector3d center_mm = Eigen::Vector3d::Zero();  // scene
  double radius_mm = 1000.0;                            // > 0
};

struct BoxCornerSurface {
  Eigen::Vector3d corner_mm = Eigen::Vector3d::Zero();  // the corner point, scene
  // Rotation whose columns are the box axes in the scene (proper, orthonormal).
  Eigen::Matrix3d scene_from_box = Eigen::Matrix3d::Identity();
};

struct ParaboloidSurface {
  Eigen::Vector3d vertex_mm = Eigen::Vector3d::Zero();  // scene
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();      // non-zero, scene; z' direction
  double curvature_per_mm = 0.0;                        // c in z' = c/2 r'^2, 1/mm
};

struct PlaneListSurface {
  std::vector<PlaneSurface> planes;  // slice k = planes[k]; at least one
};

enum class SurfaceType { kPlane, kSphere, kBoxCorner, kParaboloid, kPlanes };

class Surface {
 public:
  using Shape = std::variant<PlaneSurface, SphereSurface, BoxCornerSurface, ParaboloidSurface,
                             PlaneListSurface>;

  // Hits nearer than this to the ray's origin are ignored, mm.
  static constexpr double kMinHitDistanceMm = 1e-9;

  // The plane x = 1000 mm, normal -X: a screen one metre ahead of a source at
  // the origin looking along +X.
  Surface() : shape_(PlaneSurface{Eigen::Vector3d(1000.0, 0.0, 0.0), -Eigen::Vector3d::UnitX()}) {}
  Surface(PlaneSurface s) : shape_(std::move(s)) {}       // NOLINT: implicit by design
  Surface(SphereSurface s) : shape_(std::move(s)) {}      // NOLINT
  Surface(BoxCornerSurface s) : shape_(std::move(s)) {}   // NOLINT
  Surface(ParaboloidSurface s) : shape_(std::move(s)) {}  // NOLINT
  Surface(PlaneListSurface s) : shape_(std::move(s)) {}   // NOLINT

  const Shape& shape() const { return shape_; }
  SurfaceType type() const { return static_cast<SurfaceType>(shape_.index()); }
  // "plane", "sphere", "box_corner", "paraboloid", "planes" (the JSON names).
  const char* TypeName() const;

  // Every number finite; normals and axis non-zero; radius > 0;
  // scene_from_box orthonormal with determinant +1 (to 1e-9); at least one
  // plane in a list. The message names the field, e.g. "planes[2].normal is zero".
  Status Validate() const;

  // Number of slices: the number of planes of a PlaneListSurface, else 1.
  int num_slices() const;

  // First hit ahead of `origin` (see the contract above), scene frame, mm.
  std::optional<Eigen::Vector3d> IntersectRay(const Eigen::Vector3d& origin,
                                              const Eigen::Vector3d& unit_direction) const;
  // The hit with slice `slice` alone; nullopt when slice is out of range.
  std::optional<Eigen::Vector3d> IntersectRaySlice(int slice, const Eigen::Vector3d& origin,
                                                   const Eigen::Vector3d& unit_direction) const;

  // The same surface expressed in another frame: every point p of the result
  // is new_from_old * p_old (moves the surface rigidly).
  Surface Transformed(const Rigid3d& new_from_old) const;

 private:
  Shape shape_;
};

}  // namespace opl
