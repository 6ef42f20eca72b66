// The calibration session of examples/calibration_session_small.json in the
// harder virtual lab (issue 17; docs/images.md, "Calibration sessions", "On
// the harder lab"): colour JPEG 90 (4:2:0, as the shot writer makes it), a
// photograph of fruit as the wall (the image's background, so behind the
// screen's spots too), an ambient ramp, vignetting, mild defocus, 40
// distractors per camera, and one laser-off shot per camera per slice (the
// screen moves between slices, so each slice has its own dark frames). The
// noisy variant adds speckle and shot and read noise; the noise-free one
// keeps everything else. Also: the check of a calibration's identified
// spots against the renderer's truth.
#pragma once

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/scene.h"
#include "opl/pipeline/calibrate_images.h"
#include "support/scene_images.h"

namespace opl::test {

// The file of a laser-off shot: "s<slice>_off_<camera>.jpg".
inline std::string LaserOffFile(int slice, const std::string& camera) {
  return "s" + std::to_string(slice) + "_off_" + camera + ".jpg";
}

// The session as scene JSON (the example with its module and the wall
// texture as absolute paths), for the tools; `source_dir` is the source
// tree.
inline nlohmann::json HarderSessionJson(bool noisy, const std::string& source_dir = SourceDir()) {
  std::ifstream in(source_dir + "/examples/calibration_session_small.json");
  nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  EXPECT_FALSE(j.is_discarded()) << source_dir << ": no examples/calibration_session_small.json";
  if (j.is_discarded()) return nlohmann::json::object();
  j["module"] = source_dir + "/examples/calibration_session_small_module.json";
  nlohmann::json& image = j["image"];
  image["bit_depth"] = 8;
  image["color"] = true;
  image["wall_texture"] = source_dir + "/tests/data/textures/fruits.jpg";
  image["wall_texture_contrast"] = 1.0;
  image["ambient_gradient"] = 0.1;
  image["ambient_angle_deg"] = 20.0;
  image["vignetting"] = 0.3;
  image["defocus_sigma_px"] = 0.5;
  image["distractors"] = 40;
  image["format"] = "jpeg";
  image["jpeg_quality"] = 90;
  image["read_noise"] = noisy ? 0.004 : 0.0;
  image["gain_e_per_dn"] = noisy ? 20.0 : 0.0;
  j["spots"]["speckle_contrast"] = noisy ? 0.1 : 0.0;
  std::set<int> slices;
  for (nlohmann::json& shot : j["shots"]) {
    const std::string file = shot["file"];
    shot["file"] = file.substr(0, file.rfind('.')) + ".jpg";
    slices.insert(shot.value("slice", 0));
  }
  for (int slice : slices) {
    for (const nlohmann::json& camera : nlohmann::json(j["cameras"])) {
      j["shots"].push_back({{"camera", camera["name"]},
                            {"file", LaserOffFile(slice, camera["name"])},
                            {"lasers", nlohmann::json::array()},
                            {"slice", slice}});
    }
  }
  return j;
}

inline Scene HarderSession(bool noisy, const std::string& source_dir = SourceDir()) {
  Result<Scene> scene =
      ParseSceneJson(HarderSessionJson(noisy, source_dir).dump(), "harder session");
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  return scene.ok() ? std::move(scene).value() : Scene();
}

// The same session as lossless PNG (16 bit when noise-free), the rest kept.
inline Scene AsPng(Scene s) {
  s.image.format = "png";
  if (s.image.read_noise == 0.0 && s.image.gain_e_per_dn == 0.0) s.image.bit_depth = 16;
  for (SceneShot& shot : s.shots) shot.file = shot.file.substr(0, shot.file.rfind('.')) + ".png";
  return s;
}

// The identified spots against the truth: a spot is wrong when its 3D point
// (scaled by the artifact) is farther than wrong_mm from the true hit of
// the beam it was identified as, on its exposure group's slice (beams are
// 19 mm or more apart on the nearest screen).
struct SessionTruthCheck {
  int identified = 0;
  int wrong = 0;
};

inline SessionTruthCheck CheckAgainstTruth(const ImageCalibrationReport& report,
                                           const SceneRenderer& truth, double wrong_mm = 5.0) {
  std::map<std::tuple<std::string, int, int>, Eigen::Vector3d> true_point;
  for (const SceneSpotTruth& t : truth.spots()) true_point[{t.source, t.beam, t.slice}] = t.point_in_scene;
  SessionTruthCheck c;
  const auto& ids = report.identification.spots;
  for (size_t k = 0; k < ids.size(); ++k) {
    ++c.identified;
    const FrontEndSpot& spot =
        report.front_end.spots.at(static_cast<size_t>(report.identified_front_end_spots.at(k)));
    const int slice = report.front_end.groups.at(static_cast<size_t>(spot.group)).slice;
    const auto found = true_point.find({ids[k].source, ids[k].observation.beam_id, slice});
    if (found == true_point.end() ||
        (report.scaling.scale * spot.point_in_scene - found->second).norm() > wrong_mm) {
      ++c.wrong;
    }
  }
  return c;
}

}  // namespace opl::test
