#include "opl/pipeline/calibrate_overlays.h"

namespace opl {

std::vector<std::string> SpotLabels(const ImageCalibrationReport& report) {
  std::vector<std::string> labels(report.front_end.spots.size());
  const std::vector<Spot>& assigned = report.identification.spots;
  for (size_t i = 0; i < assigned.size() && i < report.identified_front_end_spots.size(); ++i) {
    const int k = report.identified_front_end_spots[i];
    if (k < 0 || k >= static_cast<int>(labels.size()) || !assigned[i].assigned()) continue;
    labels[static_cast<size_t>(k)] =
        assigned[i].source + std::to_string(assigned[i].observation.beam_id);
  }
  return labels;
}

ShotOverlay OverlayOfImage(const ImageCalibrationReport& report, int image_index) {
  return OverlayOfImage(report.front_end, SpotLabels(report), image_index);
}

Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const ImageCalibrationReport& report,
    int threads) {
  return RenderOverlays(scene, images_dir, report.front_end, SpotLabels(report), threads);
}

}  // namespace opl
