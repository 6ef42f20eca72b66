// Overlays of a measurement from photographs: every shot drawn with what the
// front end and the identification made of it (report/shot_overlay.h has
// the legend), for a person to check a measurement in seconds
// (`opl_measure --images ... --overlays DIR`; docs/images.md, "Overlays").
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/measure_images.h"
#include "opl/report/shot_overlay.h"

namespace opl {

// What image `image_index` (a shot of the scene) showed: its tags, its kept
// spots (identified: "<source><beam>"; matched in a 3D spot; or detected
// only) and the blobs the spot gates rejected. An index out of range gives
// an empty overlay.
ShotOverlay OverlayOfImage(const ImageMeasureReport& report, int image_index);

// The overlay file's name for a shot file: "<folder>/<stem>_overlay.jpg"
// ("cam0_A.png" -> "cam0_A_overlay.jpg").
std::string OverlayFileName(const std::string& shot_file);

// Every shot's overlay, drawn over its image read again from `images_dir`
// (vision/shot_image.h) and encoded as JPEG (quality 90): (OverlayFileName,
// bytes) in shot order, made on `threads` threads (0: every core). Errors
// of ReadShotImage (the file, named).
Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const ImageMeasureReport& report,
    int threads = 0);

}  // namespace opl
