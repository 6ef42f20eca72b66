#include "opl/lab/scene.h"

#include <cmath>
#include <map>
#include <set>
#include <string>

#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/geometry/rotation.h"

namespace opl {
namespace {

constexpr int kMaxTagId = 586;  // tag36h11

bool Finite(double x) { return std::isfinite(x); }

bool FinitePose(const Rigid3d& pose) {
  return pose.rotation.coeffs().allFinite() && pose.translation.allFinite() &&
         std::abs(pose.rotation.norm() - 1.0) < 1e-9;
}

Status Bad(const std::string& field, const std::string& what) {
  return Status::InvalidArgument(field + ": " + what);
}

Status BadNumber(const std::string& field, double value, const std::string& rule) {
  return Bad(field, FormatNumber(value) + ": " + rule);
}

Status CheckLooks(const SpotLook& spots, const ImageLook& image) {
  if (!(Finite(spots.diameter_mm) && spots.diameter_mm > 0.0)) {
    return BadNumber("spots.diameter_mm", spots.diameter_mm, "must be finite and > 0");
  }
  if (!(Finite(spots.peak_fraction) && spots.peak_fraction > 0.0 && spots.peak_fraction <= 100.0)) {
    return BadNumber("spots.peak_fraction", spots.peak_fraction, "must be in (0, 100]");
  }
  if (!(spots.speckle_contrast >= 0.0 && spots.speckle_contrast <= 1.0)) {
    return BadNumber("spots.speckle_contrast", spots.speckle_contrast, "must be in [0, 1]");
  }
  if (!(spots.speckle_grain_px > 0.0 && spots.speckle_grain_px <= 100.0)) {
    return BadNumber("spots.speckle_grain_px", spots.speckle_grain_px, "must be in (0, 100]");
  }
  if (image.bit_depth != 8 && image.bit_depth != 16) {
    return BadNumber("image.bit_depth", image.bit_depth, "must be 8 or 16");
  }
  const std::pair<const char*, double> levels[] = {{"image.background_level", image.background_level},
                                                   {"image.black_level", image.black_level},
                                                   {"image.white_level", image.white_level}};
  for (const auto& [field, value] : levels) {
    if (!(value >= 0.0 && value <= 1.0)) return BadNumber(field, value, "must be in [0, 1]");
  }
  if (!(image.blur_sigma_px >= 0.0 && image.blur_sigma_px <= 10.0)) {
    return BadNumber("image.blur_sigma_px", image.blur_sigma_px, "must be in [0, 10]");
  }
  if (!(image.read_noise >= 0.0 && image.read_noise <= 1.0)) {
    return BadNumber("image.read_noise", image.read_noise, "must be in [0, 1]");
  }
  if (!(Finite(image.gain_e_per_dn) && image.gain_e_per_dn >= 0.0)) {
    return BadNumber("image.gain_e_per_dn", image.gain_e_per_dn,
                     "must be finite and >= 0 (0: no shot noise)");
  }
  if (image.subpixels_per_axis < 1 || image.subpixels_per_axis > 8) {
    return BadNumber("image.subpixels_per_axis", image.subpixels_per_axis, "must be in [1, 8]");
  }
  for (int c = 0; c < 3; ++c) {
    const double r = image.laser_response_rgb[static_cast<size_t>(c)];
    if (!(r >= 0.0 && r <= 1.0)) {
      return BadNumber("image.laser_response_rgb[" + std::to_string(c) + "]", r, "must be in [0, 1]");
    }
  }
  if (image.bayer && !image.color) return Bad("image.bayer", "needs \"color\": true");
  if (!(image.wall_texture_contrast >= 0.0 && image.wall_texture_contrast <= 1.0)) {
    return BadNumber("image.wall_texture_contrast", image.wall_texture_contrast, "must be in [0, 1]");
  }
  if (!(image.ambient_gradient >= 0.0 && image.ambient_gradient <= 1.0)) {
    return BadNumber("image.ambient_gradient", image.ambient_gradient, "must be in [0, 1]");
  }
  if (!Finite(image.ambient_angle_deg)) {
    return BadNumber("image.ambient_angle_deg", image.ambient_angle_deg, "must be finite");
  }
  if (!(image.vignetting >= 0.0 && image.vignetting <= 0.9)) {
    return BadNumber("image.vignetting", image.vignetting, "must be in [0, 0.9]");
  }
  if (!(image.defocus_sigma_px >= 0.0 && image.defocus_sigma_px <= 10.0)) {
    return BadNumber("image.defocus_sigma_px", image.defocus_sigma_px, "must be in [0, 10]");
  }
  if (image.distractors < 0 || image.distractors > 1000) {
    return BadNumber("image.distractors", image.distractors, "must be in [0, 1000]");
  }
  if (image.format != "png" && image.format != "jpeg") {
    return Bad("image.format", QuoteForMessage(image.format, 40) + ": must be \"png\" or \"jpeg\"");
  }
  if (image.format == "jpeg" && image.bit_depth != 8) {
    return Bad("image.format", "\"jpeg\" needs \"bit_depth\": 8");
  }
  if (image.jpeg_quality < 1 || image.jpeg_quality > 100) {
    return BadNumber("image.jpeg_quality", image.jpeg_quality, "must be in [1, 100]");
  }
  if (image.exif_orientation < 0 || image.exif_orientation > 8) {
    return BadNumber("image.exif_orientation", image.exif_orientation,
                     "must be 0 (none) or an EXIF orientation 1..8");
  }
  if (image.exif_orientation != 0 && image.format != "jpeg") {
    return Bad("image.exif_orientation", "only with \"format\": \"jpeg\"");
  }
  return Status::Ok();
}

}  // namespace

Status Scene::Validate() const {
  if (cameras.empty()) return Bad("cameras", "at least one camera is needed");
  std::map<std::string, size_t> camera_index;
  for (size_t k = 0; k < cameras.size(); ++k) {
    const std::string path = "cameras[" + std::to_string(k) + "]";
    const SceneCamera& c = cameras[k];
    if (c.name.empty()) return Bad(path + ".name", "must not be empty");
    const auto [it, inserted] = camera_index.emplace(c.name, k);
    if (!inserted) {
      return Bad(path + ".name", "duplicate camera name '" + c.name + "' (also cameras[" +
                                     std::to_string(it->second) + "])");
    }
    if (Status s = c.intrinsics.Validate(); !s.ok()) return Bad(path + ".intrinsics", s.message());
    if (c.cam_from_scene && !FinitePose(*c.cam_from_scene)) {
      return Bad(path + ".cam_from_scene", "not finite or not a unit quaternion");
    }
  }

  if (tags.family != "tag36h11") {
    return Bad("tags.family", QuoteForMessage(tags.family, 40) + ": only 'tag36h11' is supported");
  }
  if (!(Finite(tags.size_mm) && tags.size_mm > 0.0)) {
    return BadNumber("tags.size_mm", tags.size_mm, "must be finite and > 0");
  }
  std::map<int, size_t> tag_index;
  for (size_t k = 0; k < tags.tags.size(); ++k) {
    const std::string path = "tags.tags[" + std::to_string(k) + "]";
    const SceneTag& t = tags.tags[k];
    if (t.id < 0 || t.id > kMaxTagId) {
      return Bad(path + ".id", std::to_string(t.id) + ": must be in [0, 586] (tag36h11)");
    }
    const auto [it, inserted] = tag_index.emplace(t.id, k);
    if (!inserted) {
      return Bad(path + ".id", "duplicate tag id " + std::to_string(t.id) + " (also tags.tags[" +
                                   std::to_string(it->second) + "])");
    }
    if (!FinitePose(t.scene_from_tag)) {
      return Bad(path + ".scene_from_tag", "not finite or not a unit quaternion");
    }
  }
  // A measured scene may leave its tags unlisted (the front end finds them in
  // the images); listed, they must hold the frame and artifact tags.
  auto check_tag = [&](const std::string& field, int id) {
    if (id < 0 || id > kMaxTagId) {
      return Bad(field, std::to_string(id) + ": must be in [0, 586] (tag36h11)");
    }
    if (!tags.tags.empty() && tag_index.count(id) == 0) {
      return Bad(field, "tag " + std::to_string(id) + " is not among the scene's tags");
    }
    return Status::Ok();
  };
  if (frame) {
    OPL_RETURN_IF_ERROR(check_tag("frame.origin_tag", frame->origin_tag));
    OPL_RETURN_IF_ERROR(check_tag("frame.axis_tag", frame->axis_tag));
    OPL_RETURN_IF_ERROR(check_tag("frame.plane_tag", frame->plane_tag));
    if (frame->origin_tag == frame->axis_tag || frame->origin_tag == frame->plane_tag ||
        frame->axis_tag == frame->plane_tag) {
      return Bad("frame", "origin_tag, axis_tag and plane_tag must be three distinct tags, got " +
                              std::to_string(frame->origin_tag) + ", " +
                              std::to_string(frame->axis_tag) + ", " +
                              std::to_string(frame->plane_tag));
    }
  }
  if (artifact) {
    OPL_RETURN_IF_ERROR(check_tag("artifact.tag_1", artifact->tag_1));
    OPL_RETURN_IF_ERROR(check_tag("artifact.tag_2", artifact->tag_2));
    if (artifact->tag_1 == artifact->tag_2) {
      return Bad("artifact.tag_2", "must differ from tag_1 (" + std::to_string(artifact->tag_1) + ")");
    }
    if (!(Finite(artifact->length_mm) && artifact->length_mm > 0.0)) {
      return BadNumber("artifact.length_mm", artifact->length_mm, "must be finite and > 0");
    }
    if (!(Finite(artifact->length_sigma_mm) && artifact->length_sigma_mm >= 0.0)) {
      return BadNumber("artifact.length_sigma_mm", artifact->length_sigma_mm,
                       "must be finite and >= 0");
    }
  }
  if (module) {
    if (Status s = module->Validate(); !s.ok()) return Bad("module", s.message());
  }
  OPL_RETURN_IF_ERROR(CheckLooks(spots, image));

  std::map<std::string, size_t> placement_index;
  for (size_t k = 0; k < module_placements.size(); ++k) {
    const std::string path = "module_placements[" + std::to_string(k) + "]";
    const SceneModulePlacement& p = module_placements[k];
    if (p.name.empty()) return Bad(path + ".name", "must not be empty");
    const auto [it, inserted] = placement_index.emplace(p.name, k);
    if (!inserted) {
      return Bad(path + ".name", "duplicate placement name '" + p.name + "' (also module_placements[" +
                                     std::to_string(it->second) + "])");
    }
    if (!p.rotation_deg.allFinite() || p.rotation_deg.cwiseAbs().maxCoeff() > 360.0) {
      return Bad(path + ".rotation_deg", "each angle must be finite and within [-360, 360] deg");
    }
    if (!p.translation_mm.allFinite() || p.translation_mm.cwiseAbs().maxCoeff() > 1e9) {
      return Bad(path + ".translation_mm", "must be finite and within 1e9 mm of the origin");
    }
  }
  std::map<std::string, size_t> check_index;
  for (size_t k = 0; k < check_lengths.size(); ++k) {
    const std::string path = "check_lengths[" + std::to_string(k) + "]";
    const SceneCheckLength& c = check_lengths[k];
    if (c.name.empty()) return Bad(path + ".name", "must not be empty");
    const auto [it, inserted] = check_index.emplace(c.name, k);
    if (!inserted) {
      return Bad(path + ".name", "duplicate check length name '" + c.name + "' (also check_lengths[" +
                                     std::to_string(it->second) + "])");
    }
    OPL_RETURN_IF_ERROR(check_tag(path + ".tag_1", c.tag_1));
    OPL_RETURN_IF_ERROR(check_tag(path + ".tag_2", c.tag_2));
    if (c.tag_1 == c.tag_2) {
      return Bad(path + ".tag_2", "must differ from tag_1 (" + std::to_string(c.tag_1) + ")");
    }
    if (!(Finite(c.length_mm) && c.length_mm > 0.0)) {
      return BadNumber(path + ".length_mm", c.length_mm, "must be finite and > 0");
    }
    if (!(Finite(c.length_sigma_mm) && c.length_sigma_mm >= 0.0)) {
      return BadNumber(path + ".length_sigma_mm", c.length_sigma_mm, "must be finite and >= 0");
    }
  }

  if (shots.empty()) return Bad("shots", "at least one shot is needed");
  std::map<std::string, size_t> file_index;
  for (size_t k = 0; k < shots.size(); ++k) {
    const std::string path = "shots[" + std::to_string(k) + "]";
    const SceneShot& s = shots[k];
    if (FindCamera(s.camera) == nullptr) {
      return Bad(path + ".camera", "no camera named " + QuoteForMessage(s.camera));
    }
    if (s.file.empty()) return Bad(path + ".file", "must not be empty");
    const auto [it, inserted] = file_index.emplace(s.file, k);
    if (!inserted) {
      return Bad(path + ".file", QuoteForMessage(s.file) + " is also the file of shots[" +
                                     std::to_string(it->second) + "]");
    }
    std::set<std::string> lit;
    for (size_t l = 0; l < s.lasers.size(); ++l) {
      const std::string field = path + ".lasers[" + std::to_string(l) + "]";
      if (!lit.insert(s.lasers[l]).second) {
        return Bad(field, "laser '" + s.lasers[l] + "' listed twice");
      }
      if (module && module->FindSource(s.lasers[l]) == nullptr) {
        std::string names;
        for (const SourceDesign& src : module->sources) names += (names.empty() ? "" : ", ") + src.name;
        return Bad(field, "no source named '" + s.lasers[l] + "' in the module (it has " + names + ")");
      }
    }
    if (!s.placement.empty() && placement_index.count(s.placement) == 0) {
      return Bad(path + ".placement",
                 module_placements.empty()
                     ? QuoteForMessage(s.placement) + ": the scene lists no module_placements"
                     : "no module placement named " + QuoteForMessage(s.placement));
    }
    if (s.placement.empty() && !module_placements.empty() && !s.lasers.empty()) {
      return Bad(path + ".placement",
                 "missing: the scene lists module_placements, so a shot with a laser on must "
                 "name the placement it shows");
    }
    if (s.slice < 0) return Bad(path + ".slice", std::to_string(s.slice) + ": must be >= 0");
    if (!(s.exposure > 0.0 && s.exposure <= 10.0)) {
      return BadNumber(path + ".exposure", s.exposure, "must be in (0, 10]");
    }
    if (module && s.slice >= module->surface.num_slices()) {
      return Bad(path + ".slice", std::to_string(s.slice) + ": the module's surface has " +
                                      std::to_string(module->surface.num_slices()) +
                                      " slice(s), 0.." +
                                      std::to_string(module->surface.num_slices() - 1));
    }
  }
  return Status::Ok();
}

Status Scene::ValidateForRendering() const {
  OPL_RETURN_IF_ERROR(Validate());
  for (size_t k = 0; k < cameras.size(); ++k) {
    if (!cameras[k].cam_from_scene) {
      return Bad("cameras[" + std::to_string(k) + "]",
                 "camera '" + cameras[k].name +
                     "' has no pose (rendering needs every camera's true pose)");
    }
  }
  if (!module) return Bad("module", "missing (rendering needs the module and its surface)");
  if (!image.HasSceneLook()) {
    for (size_t k = 0; k < shots.size(); ++k) {
      if (shots[k].exposure != 1.0) {
        return Bad("shots[" + std::to_string(k) + "].exposure",
                   FormatNumber(shots[k].exposure) +
                       ": the plain lab renders every shot at exposure 1; a shot's exposure "
                       "needs the harder lab (an image field such as color, wall_texture, "
                       "vignetting or distractors)");
      }
    }
  }
  return Status::Ok();
}

const SceneCamera* Scene::FindCamera(const std::string& name) const {
  for (const SceneCamera& c : cameras) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

int Scene::FindModulePlacement(const std::string& name) const {
  for (size_t k = 0; k < module_placements.size(); ++k) {
    if (module_placements[k].name == name) return static_cast<int>(k);
  }
  return -1;
}

Rigid3d SceneModulePlacement::SceneFromDesign(const ModuleDesign& design) const {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const SourceDesign& s : design.sources) centroid += s.scene_from_source.translation;
  if (!design.sources.empty()) centroid /= static_cast<double>(design.sources.size());
  const Eigen::Matrix3d R = RotationFromXyzAnglesRad(rotation_deg * (M_PI / 180.0));
  // x -> R (x - c) + c + t
  return Rigid3d(R, centroid - R * centroid + translation_mm);
}

const SceneTag* Scene::FindTag(int id) const {
  for (const SceneTag& t : tags.tags) {
    if (t.id == id) return &t;
  }
  return nullptr;
}

}  // namespace opl
