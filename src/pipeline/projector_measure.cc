#include "opl/pipeline/projector_measure.h"

#include <algorithm>
#include <array>
#include <map>
#include <set>

#include "opl/pipeline/measure_images.h"

namespace opl {

Result<ProjectorAdjustmentData> ProjectorDataFromTwoStep(
    const ImageMeasureReport& two_step, const ModuleCalibration& calibration,
    ProjectorAdjustmentOptions* options, const std::vector<std::pair<int, int>>& tag_lengths) {
  const FrontEndResult& fe = two_step.front_end;
  const BundleData& adj = fe.adjustment;
  if (adj.cameras.empty() || fe.tag_first_point.empty()) {
    return Status::InvalidArgument(
        "scale_in_adjustment: the front end kept no adjustment data (the COLMAP path does not "
        "support the projector adjustment)");
  }
  const double s0 = two_step.measure.scale.scale_factor;
  if (!(s0 > 0.0)) return Status::NoSolution("scale_in_adjustment: the two-step s is not positive");
  if (two_step.measure.sources.empty()) {
    return Status::NoSolution("scale_in_adjustment: no source was located by the two-step path");
  }
  ProjectorAdjustmentData data;
  data.calibration = calibration;
  data.bundle.intrinsics = adj.intrinsics;
  for (BundleIntrinsics& k : data.bundle.intrinsics) k.constant = true;
  data.bundle.cameras = adj.cameras;
  for (BundleCamera& c : data.bundle.cameras) c.cam_from_scene.translation *= s0;
  // Tag points that are adjusted (a tag dropped by the front end is constant
  // and unobserved), renumbered.
  std::vector<int> observed(static_cast<size_t>(fe.first_spot_point), 0);
  for (const BundleObservation& ob : adj.observations) {
    if (ob.point < fe.first_spot_point) observed[static_cast<size_t>(ob.point)] = 1;
  }
  std::vector<int> new_index(static_cast<size_t>(fe.first_spot_point), -1);
  for (int j = 0; j < fe.first_spot_point; ++j) {
    const BundlePoint& p = adj.points[static_cast<size_t>(j)];
    if (p.constant || !observed[static_cast<size_t>(j)]) continue;
    new_index[static_cast<size_t>(j)] = static_cast<int>(data.bundle.points.size());
    BundlePoint q = p;
    q.point_in_scene *= s0;
    data.bundle.points.push_back(q);
  }
  // One placement per module placement of the two-step's located sources
  // (order of first appearance), each started from its first located source.
  const Eigen::Vector3d centre = data.ModuleOriginInCalibration();
  const MeasureReport& measured = two_step.measure;
  std::map<std::string, int> placement_index;
  std::map<std::pair<std::string, std::string>, std::set<int>> outliers;  // (placement, source)
  for (size_t k = 0; k < measured.sources.size(); ++k) {
    const auto& [name, located] = measured.sources[k];
    const std::string placement_name =
        k < measured.source_placements.size() ? measured.source_placements[k] : "";
    for (int b : located.OutlierBeamIds()) outliers[{placement_name, name}].insert(b);
    if (placement_index.count(placement_name)) continue;
    const SourceCalibration* first = calibration.FindSource(name);
    if (first == nullptr) {
      return Status::InvalidArgument("scale_in_adjustment: located source '" + name +
                                     "' is not in the calibration");
    }
    Rigid3d scene_from_source = located.scene_from_source;
    scene_from_source.translation *= s0;
    const Rigid3d module_from_source(first->calibration_from_source.rotation,
                                     first->calibration_from_source.translation - centre);
    ProjectorPlacement placement;
    placement.name = placement_name.empty() ? "all shots" : placement_name;
    placement.scene_from_module = scene_from_source * module_from_source.Inverse();
    placement_index[placement_name] = static_cast<int>(data.placements.size());
    data.placements.push_back(placement);
  }

  std::vector<int> spot_of_point(adj.points.size(), -1);
  for (size_t k = 0; k < two_step.spots.size(); ++k) {
    const Spot& spot = two_step.spots[k];
    if (!spot.assigned() || outliers[{spot.placement, spot.source}].count(spot.observation.beam_id)) {
      continue;
    }
    const auto placement = placement_index.find(spot.placement);
    if (placement == placement_index.end()) continue;  // its source was not located there
    const SourceCalibration* src = calibration.FindSource(spot.source);
    if (src == nullptr || src->pattern.Find(spot.observation.beam_id) == nullptr) continue;
    const Rigid3d scene_from_src =
        data.placements[static_cast<size_t>(placement->second)].scene_from_module *
        Rigid3d(src->calibration_from_source.rotation, src->calibration_from_source.translation - centre);
    const Eigen::Vector3d beam = scene_from_src.rotation * src->pattern.DirectionInSource(spot.observation.beam_id);
    ProjectorSpot ps;
    ps.placement = placement->second;
    ps.source = spot.source;
    ps.beam_id = spot.observation.beam_id;
    ps.depth_mm = std::max(1.0, beam.dot(s0 * spot.observation.point_in_scene - scene_from_src.translation));
    spot_of_point[static_cast<size_t>(fe.first_spot_point) + k] = static_cast<int>(data.spots.size());
    data.spots.push_back(ps);
  }
  if (data.spots.empty()) {
    return Status::InvalidArgument("scale_in_adjustment: no identified spot to adjust");
  }
  for (const BundleObservation& ob : adj.observations) {
    if (ob.point < fe.first_spot_point) {
      const int j = new_index[static_cast<size_t>(ob.point)];
      if (j < 0) continue;
      BundleObservation o = ob;
      o.point = j;
      data.bundle.observations.push_back(o);
      continue;
    }
    const int k = spot_of_point[static_cast<size_t>(ob.point)];
    if (k < 0) continue;
    data.spots[static_cast<size_t>(k)].observations.push_back({ob.camera, ob.pixel_px, ob.covariance_px2});
  }
  // The datum: the frame tags' corners.
  for (size_t a = 0; a < 3; ++a) {
    const auto found = fe.tag_first_point.find(fe.frame_tags[a]);
    if (found == fe.tag_first_point.end()) {
      return Status::InvalidArgument("scale_in_adjustment: frame tag " + std::to_string(fe.frame_tags[a]) +
                                     " is not in the adjustment");
    }
    options->datum_point_sets[a].clear();
    for (int q = 0; q < 4; ++q) {
      const int j = new_index[static_cast<size_t>(found->second + q)];
      if (j >= 0) options->datum_point_sets[a].push_back(j);
    }
  }
  // The requested tag-to-tag lengths: each tag's four corners.
  options->length_point_sets.clear();
  auto corners_of = [&](int id, std::vector<int>* set) -> Status {
    const auto found = fe.tag_first_point.find(id);
    if (found != fe.tag_first_point.end()) {
      for (int q = 0; q < 4; ++q) {
        const int j = new_index[static_cast<size_t>(found->second + q)];
        if (j >= 0) set->push_back(j);
      }
    }
    if (set->empty()) {
      return Status::InvalidArgument("scale_in_adjustment: tag " + std::to_string(id) +
                                     " is not in the adjustment (not seen from two camera positions)");
    }
    return Status::Ok();
  };
  for (const auto& [a, b] : tag_lengths) {
    std::array<std::vector<int>, 2> ends;
    OPL_RETURN_IF_ERROR(corners_of(a, &ends[0]));
    OPL_RETURN_IF_ERROR(corners_of(b, &ends[1]));
    options->length_point_sets.push_back(std::move(ends));
  }
  options->unscaled_datum_length =
      (fe.tag_centers.at(fe.frame_tags[1]) - fe.tag_centers.at(fe.frame_tags[0])).norm();
  return data;
}

Result<ProjectorAdjustmentResult> AdjustScaleWithProjector(
    const ImageMeasureReport& two_step, const ModuleCalibration& calibration,
    ProjectorAdjustmentOptions options, const std::vector<std::pair<int, int>>& tag_lengths) {
  Result<ProjectorAdjustmentData> data =
      ProjectorDataFromTwoStep(two_step, calibration, &options, tag_lengths);
  if (!data.ok()) return data.status();
  Result<ProjectorAdjustmentResult> r = ProjectorAdjust(*data, options);
  if (!r.ok()) return Status(r.status().code(), "scale_in_adjustment: " + r.status().message());
  return r;
}

}  // namespace opl
