// Overlays of a run from photographs (opl_measure or opl_calibrate --images
// ... --overlays DIR): every shot drawn with what the front end and the
// identification made of it (report/shot_overlay.h has the legend), for a
// person to check a measurement or a calibration in seconds (docs/images.md,
// "Overlays"). What is shared by both: the front end's findings and one label
// per 3D spot; pipeline/measure_overlays.h and pipeline/calibrate_overlays.h
// give the labels of each kind of run.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/image_front_end.h"
#include "opl/report/shot_overlay.h"

namespace opl {

// What image `image_index` (a shot of the scene) showed: its tags, its kept
// spots and the blobs the spot gates rejected. A kept spot that is a view of
// the front end's 3D spot k is identified with the label `spot_labels[k]`
// ("<source><beam>", e.g. "A61") when that label is not empty, else matched;
// a spot in no 3D spot is detected only. `spot_labels` shorter than the 3D
// spots: the rest are unlabelled. An index out of range gives an empty
// overlay.
ShotOverlay OverlayOfImage(const FrontEndResult& front_end,
                           const std::vector<std::string>& spot_labels, int image_index);

// The overlay file's name for a shot file: "<folder>/<stem>_overlay.jpg"
// ("cam0_A.png" -> "cam0_A_overlay.jpg").
std::string OverlayFileName(const std::string& shot_file);

// Every shot's overlay, drawn over its image read again from `images_dir`
// (vision/shot_image.h) and encoded as JPEG (quality 90): (OverlayFileName,
// bytes) in shot order, made on `threads` threads (0: every core). Errors
// of ReadShotImage (the file, named).
Result<std::vector<std::pair<std::string, std::string>>> RenderOverlays(
    const Scene& scene, const std::string& images_dir, const FrontEndResult& front_end,
    const std::vector<std::string>& spot_labels, int threads = 0);

}  // namespace opl
