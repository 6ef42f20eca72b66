#include "opl/model/beam_pattern.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/LU>

#include "opl/geometry/spherical.h"

namespace opl {

Eigen::Vector3d Beam::DirectionInSource() const { return DirectionFromAzElRad(az_rad, el_rad); }

std::string BeamsPerSideProblem(long long n) {
  if (n >= 3 && n <= kMaxBeamsPerSide && n % 2 != 0) return "";
  return "must be odd and in [3, " + std::to_string(kMaxBeamsPerSide) + "], got " +
         std::to_string(n);
}

Status CheckBeamsPerSide(int beams_per_side) {
  const std::string problem = BeamsPerSideProblem(beams_per_side);
  if (problem.empty()) return Status::Ok();
  return Status::InvalidArgument("beams_per_side " + problem);
}

BeamPattern::BeamPattern(int beams_per_side, std::vector<Beam> beams)
    : beams_per_side_(beams_per_side), beams_(std::move(beams)) {
  std::sort(beams_.begin(), beams_.end(),
            [](const Beam& a, const Beam& b) { return a.id < b.id; });
  // An invalid n (Validate refuses it) gets no index rather than a huge one.
  const int n2 = beams_per_side_ > 0 && beams_per_side_ <= kMaxBeamsPerSide
                     ? beams_per_side_ * beams_per_side_
                     : 0;
  index_by_id_.assign(static_cast<size_t>(n2) + 1, -1);
  directions_.reserve(beams_.size());
  for (const Beam& b : beams_) directions_.push_back(b.DirectionInSource());
  for (size_t i = 0; i < beams_.size(); ++i) {
    const int id = beams_[i].id;
    if (id >= 1 && id <= n2 && index_by_id_[id] < 0) index_by_id_[id] = static_cast<int>(i);
  }
}

Result<BeamPattern> BeamPattern::Create(int beams_per_side, std::vector<Beam> beams) {
  BeamPattern pattern(beams_per_side, std::move(beams));
  Status status = pattern.Validate();
  if (!status.ok()) return status;
  return pattern;
}

Status BeamPattern::Validate() const {
  OPL_RETURN_IF_ERROR(CheckBeamsPerSide(beams_per_side_));
  const int n2 = beams_per_side_ * beams_per_side_;
  for (size_t i = 0; i < beams_.size(); ++i) {
    const Beam& b = beams_[i];
    if (b.id < 1 || b.id > n2) {
      return Status::InvalidArgument("beam id " + std::to_string(b.id) + " is outside 1.." +
                                     std::to_string(n2));
    }
    if (i > 0 && beams_[i - 1].id == b.id) {
      return Status::InvalidArgument("duplicate beam id " + std::to_string(b.id));
    }
    if (!std::isfinite(b.az_rad) || !std::isfinite(b.el_rad)) {
      return Status::InvalidArgument("beam " + std::to_string(b.id) + ": angle is not finite");
    }
    if (std::abs(b.el_rad) >= 0.5 * M_PI || std::abs(b.az_rad) > M_PI) {
      return Status::InvalidArgument("beam " + std::to_string(b.id) +
                                     ": angle out of range (|az| <= pi, |el| < pi/2)");
    }
    if (b.cov_azel_rad2) {
      const Eigen::Matrix2d& C = *b.cov_azel_rad2;
      if (!C.allFinite() || std::abs(C(0, 1) - C(1, 0)) > 1e-12 * (1.0 + C.norm()) ||
          C(0, 0) < 0 || C(1, 1) < 0 || C.determinant() < -1e-30) {
        return Status::InvalidArgument("beam " + std::to_string(b.id) +
                                       ": covariance is not symmetric positive semi-definite");
      }
    }
  }
  return Status::Ok();
}

const Beam* BeamPattern::Find(int id) const {
  if (id < 1 || id >= static_cast<int>(index_by_id_.size())) return nullptr;
  const int index = index_by_id_[id];
  return index < 0 ? nullptr : &beams_[index];
}

}  // namespace opl
