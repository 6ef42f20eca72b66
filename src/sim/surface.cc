#include "opl/sim/surface.h"

#include <cmath>
#include <string>

namespace opl {
namespace {

using Vec3 = Eigen::Vector3d;

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

constexpr double kMin = Surface::kMinHitDistanceMm;

// Keeps the smaller of the admissible ray parameters.
void Consider(double t, std::optional<double>* best) {
  if (std::isfinite(t) && t > kMin && (!*best || t < **best)) *best = t;
}

// Real roots of a t^2 + b t + c = 0, numerically stable (no cancellation).
// Adds the admissible ones to `best`.
void QuadraticRoots(double a, double b, double c, std::optional<double>* best) {
  if (a == 0.0) {
    if (b != 0.0) Consider(-c / b, best);
    return;
  }
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  if (q == 0.0) {  // b == 0 and c == 0: double root at 0
    Consider(0.0, best);
    return;
  }
  Consider(q / a, best);
  Consider(c / q, best);
}

std::optional<double> HitPlane(const PlaneSurface& s, const Vec3& o, const Vec3& d) {
  const double denom = s.normal.dot(d);
  if (denom == 0.0) return std::nullopt;
  std::optional<double> best;
  Consider(s.normal.dot(s.point_mm - o) / denom, &best);
  return best;
}

std::optional<double> HitSphere(const SphereSurface& s, const Vec3& o, const Vec3& d) {
  const Vec3 oc = o - s.center_mm;
  std::optional<double> best;
  // |oc + t d|^2 = r^2 with |d| = 1.
  QuadraticRoots(1.0, 2.0 * d.dot(oc), oc.squaredNorm() - s.radius_mm * s.radius_mm, &best);
  return best;
}

std::optional<double> HitBoxCorner(const BoxCornerSurface& s, const Vec3& o, const Vec3& d) {
  const Eigen::Matrix3d Bt = s.scene_from_box.transpose();
  const Vec3 p = Bt * (o - s.corner_mm);
  const Vec3 v = Bt * d;
  std::optional<double> best;
  for (int k = 0; k < 3; ++k) {
    if (v[k] == 0.0) continue;
    const double t = -p[k] / v[k];
    if (!(std::isfinite(t) && t > kMin)) continue;
    const Vec3 h = p + t * v;
    const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
    // An edge belongs to two faces; accept rounding-level negatives.
    const double tol = 1e-12 * (1.0 + h.cwiseAbs().maxCoeff());
    if (h[k1] >= -tol && h[k2] >= -tol) Consider(t, &best);
  }
  return best;
}

std::optional<double> HitParaboloid(const ParaboloidSurface& s, const Vec3& o, const Vec3& d) {
  const Vec3 a = s.axis.normalized();
  const double c = s.curvature_per_mm;
  const Vec3 w = o - s.vertex_mm;
  const double wa = a.dot(w), da = a.dot(d);
  const Vec3 wp = w - wa * a, dp = d - da * a;
  // wa + t da = c/2 |wp + t dp|^2
  std::optional<double> best;
  QuadraticRoots(0.5 * c * dp.squaredNorm(), c * wp.dot(dp) - da, 0.5 * c * wp.squaredNorm() - wa,
                 &best);
  return best;
}

std::optional<double> HitSlice(const Surface::Shape& shape, int slice, const Vec3& o,
                               const Vec3& d) {
  return std::visit(
      Overloaded{
          [&](const PlaneSurface& s) { return slice == 0 ? HitPlane(s, o, d) : std::nullopt; },
          [&](const SphereSurface& s) { return slice == 0 ? HitSphere(s, o, d) : std::nullopt; },
          [&](const BoxCornerSurface& s) {
            return slice == 0 ? HitBoxCorner(s, o, d) : std::nullopt;
          },
          [&](const ParaboloidSurface& s) {
            return slice == 0 ? HitParaboloid(s, o, d) : std::nullopt;
          },
          [&](const PlaneListSurface& s) -> std::optional<double> {
            if (slice < 0 || slice >= static_cast<int>(s.planes.size())) return std::nullopt;
            return HitPlane(s.planes[slice], o, d);
          }},
      shape);
}

Status CheckVector(const Vec3& v, const std::string& name, bool nonzero) {
  if (!v.allFinite()) return Status::InvalidArgument(name + " is not finite");
  if (nonzero && v.norm() == 0.0) return Status::InvalidArgument(name + " is zero");
  return Status::Ok();
}

Status CheckPlane(const PlaneSurface& s, const std::string& prefix) {
  OPL_RETURN_IF_ERROR(CheckVector(s.point_mm, prefix + "point_mm", false));
  return CheckVector(s.normal, prefix + "normal", true);
}

}  // namespace

const char* Surface::TypeName() const {
  switch (type()) {
    case SurfaceType::kPlane: return "plane";
    case SurfaceType::kSphere: return "sphere";
    case SurfaceType::kBoxCorner: return "box_corner";
    case SurfaceType::kParaboloid: return "paraboloid";
    case SurfaceType::kPlanes: return "planes";
  }
  return "unknown";
}

Status Surface::Validate() const {
  return std::visit(
      Overloaded{
          [](const PlaneSurface& s) { return CheckPlane(s, ""); },
          [](const SphereSurface& s) {
            OPL_RETURN_IF_ERROR(CheckVector(s.center_mm, "center_mm", false));
            if (!(std::isfinite(s.radius_mm) && s.radius_mm > 0.0)) {
              return Status::InvalidArgument("radius_mm must be finite and > 0, got " +
                                             std::to_string(s.radius_mm));
            }
            return Status::Ok();
          },
          [](const BoxCornerSurface& s) {
            OPL_RETURN_IF_ERROR(CheckVector(s.corner_mm, "corner_mm", false));
            const Eigen::Matrix3d& B = s.scene_from_box;
            if (!B.allFinite()) return Status::InvalidArgument("box rotation is not finite");
            if ((B.transpose() * B - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
                std::abs(B.determinant() - 1.0) > 1e-9) {
              return Status::InvalidArgument("box rotation is not a proper rotation");
            }
            return Status::Ok();
          },
          [](const ParaboloidSurface& s) {
            OPL_RETURN_IF_ERROR(CheckVector(s.vertex_mm, "vertex_mm", false));
            OPL_RETURN_IF_ERROR(CheckVector(s.axis, "axis", true));
            if (!std::isfinite(s.curvature_per_mm)) {
              return Status::InvalidArgument("curvature_per_mm is not finite");
            }
            return Status::Ok();
          },
          [](const PlaneListSurface& s) {
            if (s.planes.empty()) return Status::InvalidArgument("planes is empty");
            for (size_t k = 0; k < s.planes.size(); ++k) {
              OPL_RETURN_IF_ERROR(CheckPlane(s.planes[k], "planes[" + std::to_string(k) + "]."));
            }
            return Status::Ok();
          }},
      shape_);
}

int Surface::num_slices() const {
  if (const auto* list = std::get_if<PlaneListSurface>(&shape_)) {
    return static_cast<int>(list->planes.size());
  }
  return 1;
}

std::optional<Eigen::Vector3d> Surface::IntersectRaySlice(
    int slice, const Eigen::Vector3d& origin, const Eigen::Vector3d& unit_direction) const {
  const double norm = unit_direction.norm();
  if (!origin.allFinite() || !std::isfinite(norm) || norm == 0.0) return std::nullopt;
  const Vec3 d = unit_direction / norm;
  const std::optional<double> t = HitSlice(shape_, slice, origin, d);
  if (!t) return std::nullopt;
  return Vec3(origin + *t * d);
}

std::optional<Eigen::Vector3d> Surface::IntersectRay(const Eigen::Vector3d& origin,
                                                     const Eigen::Vector3d& unit_direction) const {
  std::optional<Eigen::Vector3d> best;
  double best_distance = 0.0;
  for (int k = 0; k < num_slices(); ++k) {
    const std::optional<Eigen::Vector3d> hit = IntersectRaySlice(k, origin, unit_direction);
    if (!hit) continue;
    const double distance = (*hit - origin).norm();
    if (!best || distance < best_distance) {
      best = hit;
      best_distance = distance;
    }
  }
  return best;
}

Surface Surface::Transformed(const Rigid3d& new_from_old) const {
  const Eigen::Matrix3d R = new_from_old.RotationMatrix();
  auto plane = [&](const PlaneSurface& s) {
    return PlaneSurface{new_from_old * s.point_mm, R * s.normal};
  };
  return std::visit(
      Overloaded{
          [&](const PlaneSurface& s) { return Surface(plane(s)); },
          [&](const SphereSurface& s) {
            return Surface(SphereSurface{new_from_old * s.center_mm, s.radius_mm});
          },
          [&](const BoxCornerSurface& s) {
            return Surface(BoxCornerSurface{new_from_old * s.corner_mm, R * s.scene_from_box});
          },
          [&](const ParaboloidSurface& s) {
            return Surface(
                ParaboloidSurface{new_from_old * s.vertex_mm, R * s.axis, s.curvature_per_mm});
          },
          [&](const PlaneListSurface& s) {
            PlaneListSurface out;
            for (const PlaneSurface& p : s.planes) out.planes.push_back(plane(p));
            return Surface(std::move(out));
          }},
      shape_);
}

}  // namespace opl
