// Overlays of a measurement from photographs (`opl_measure --images ...
// --overlays DIR`; docs/images.md, "Overlays"): the shared drawing of
// pipeline/shot_overlays.h with the measurement's identification.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/pipeline/shot_overlays.h"

namespace opl {

// One label per front-end 3D spot: "<source><beam>" for a spot the
// measurement identified (report.spots[k]), else empty.
std::vector<std::string> SpotLabels(const ImageMeasureReport& report);

// OverlayOfImage (pipeline/shot_overlays.h) with SpotLabels(report).
ShotOverlay OverlayOfImage(const ImageMeasureReport& report, int image_index);

// RenderOverlays (pipeline/shot_overlays.h) with SpotLabels(report).
Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const ImageMeasureReport& report,
    int threads = 0);

}  // namespace opl
