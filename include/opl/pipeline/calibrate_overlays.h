// Overlays of a calibration from photographs (`opl_calibrate --images ...
// --overlays DIR`; docs/images.md, "Overlays"): the shared drawing of
// pipeline/shot_overlays.h with the calibration's identification. A session
// has many slices (screen positions) and grids, one exposure group each;
// every image shows its own group's spots, labelled with the source and beam
// the calibration used them as.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/calibrate_images.h"
#include "opl/pipeline/shot_overlays.h"

namespace opl {

// One label per front-end 3D spot: "<source><beam>" for a spot the session's
// identification assigned (and the calibration used), else empty.
std::vector<std::string> SpotLabels(const ImageCalibrationReport& report);

// OverlayOfImage (pipeline/shot_overlays.h) with SpotLabels(report).
ShotOverlay OverlayOfImage(const ImageCalibrationReport& report, int image_index);

// RenderOverlays (pipeline/shot_overlays.h) with SpotLabels(report).
Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const ImageCalibrationReport& report,
    int threads = 0);

}  // namespace opl
