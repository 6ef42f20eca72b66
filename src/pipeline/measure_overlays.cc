#include "opl/pipeline/measure_overlays.h"

namespace opl {

std::vector<std::string> SpotLabels(const ImageMeasureReport& report) {
  std::vector<std::string> labels(report.front_end.spots.size());
  for (size_t k = 0; k < labels.size() && k < report.spots.size(); ++k) {
    const Spot& spot = report.spots[k];
    if (spot.assigned()) labels[k] = spot.source + std::to_string(spot.observation.beam_id);
  }
  return labels;
}

ShotOverlay OverlayOfImage(const ImageMeasureReport& report, int image_index) {
  return OverlayOfImage(report.front_end, SpotLabels(report), image_index);
}

Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const ImageMeasureReport& report,
    int threads) {
  return RenderOverlays(scene, images_dir, report.front_end, SpotLabels(report), threads);
}

}  // namespace opl
