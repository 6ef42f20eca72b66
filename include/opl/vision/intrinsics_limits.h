// Plausible camera intrinsics (issue 19 item 6): the limits the scene JSON
// reader holds intrinsics to, beyond CameraIntrinsics::Validate's domain.
#pragma once

#include <string>

#include "opl/vision/camera_model.h"

namespace opl {

// Limits of a plausible camera (docs/formats.md, 'Limits'), checked where
// intrinsics are read from a file (the scene JSON): a value beyond them is a
// corrupt or mistyped field, and would otherwise surface as a failure blamed
// on the images ("no tag is seen in two images").
inline constexpr double kMinFocalPerImageSide = 0.05;  // fx, fy >= 0.05 x max(width, height)
inline constexpr double kMaxFocalPerImageSide = 100.0;  // fx, fy <= 100 x max(width, height)
inline constexpr double kPrincipalPointMargin = 0.5;    // cx in [-0.5 W, 1.5 W], cy likewise
inline constexpr double kMaxRadialScale = 3.0;          // r_d / r at the corner in [1/3, 3]
inline constexpr double kMaxTangential = 0.5;           // |p1|, |p2|

struct IntrinsicsFault {
  std::string field;  // "fx", "cy", "k1", ...
  std::string what;   // e.g. "must be in [51.2, 102400] px ..., got 1e+308"
};

// The first implausible field of `in` (a valid one: CameraIntrinsics::Validate
// is OK), or an empty field when it is plausible: fx, fy within
// [0.05, 100] x the larger image side; the principal point within the image
// widened by half its size on each side; |p1|, |p2| <= 0.5; and the radial
// distortion r_d(r) = r (1 + k1 r^2 + k2 r^4 + k3 r^6) strictly increasing
// (checked on a fine grid) from the centre out to the farthest image corner,
// where it scales r by 1/3 to 3. A fold is blamed on the k term largest there.
IntrinsicsFault FindImplausibleIntrinsics(const CameraIntrinsics& in);

}  // namespace opl
