// A program outside the OPL tree: locates a source from exact spots through
// the installed library and headers.
#include <cmath>
#include <cstdio>

#include <opl/locate/locate_source.h>

int main() {
  std::vector<opl::Beam> beams;
  const int n = 5;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      beams.push_back({r * n + c + 1, 0.05 * (c - 2), 0.05 * (2 - r), std::nullopt});
    }
  }
  auto pattern = opl::BeamPattern::Create(n, beams);
  if (!pattern.ok()) return 2;
  const opl::Rigid3d truth(Eigen::Matrix3d::Identity(), Eigen::Vector3d(10, 20, 30));
  std::vector<opl::SpotObservation> spots;
  for (const opl::Beam& b : pattern->beams()) {
    const Eigen::Vector3d d = b.DirectionInSource();
    spots.push_back({b.id, truth * ((1000.0 + 37.0 * b.id) * d), std::nullopt});
  }
  auto result = opl::LocateSource(*pattern, spots);
  if (!result.ok()) {
    std::printf("%s\n", result.status().ToString().c_str());
    return 1;
  }
  const double err = (result->scene_from_source.translation - truth.translation).norm();
  std::printf("origin error %.3g %s\n", err, err < 1e-6 ? "OK" : "BAD");
  return err < 1e-6 ? 0 : 1;
}
