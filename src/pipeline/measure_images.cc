#include "opl/pipeline/measure_images.h"

#include <algorithm>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

namespace opl {

Status ImageMeasureOptions::Validate() const {
  OPL_RETURN_IF_ERROR(front_end.Validate());
  return measure.Validate();
}

std::string ImageMeasureReport::ToText() const {
  std::ostringstream out;
  out << front_end.ToText();
  for (size_t g = 0; g < identification.size(); ++g) {
    out << "identification, exposure group " << g << ":\n" << identification[g].ToText();
  }
  out << "\n" << measure.ToText();
  for (const std::string& c : metadata_conflicts) out << "warning: " << c << "\n";
  return out.str();
}

std::string ImageMeasureReport::ToJson() const {
  using nlohmann::ordered_json;
  ordered_json doc;
  doc["format"] = "opl.image_measure_report";
  doc["version"] = 1;
  ordered_json images = ordered_json::array();
  for (const ImageFindings& f : front_end.images) {
    images.push_back({{"file", f.file},
                      {"camera", f.camera},
                      {"tags", f.tag_ids},
                      {"spots_detected", f.spots_detected},
                      {"spots_matched", f.spots_matched},
                      {"placed", f.placed},
                      {"tag_rms_px", f.tag_rms_px},
                      {"spot_rms_px", f.spot_rms_px},
                      {"notes", f.notes}});
  }
  doc["images"] = images;
  ordered_json groups = ordered_json::array();
  for (size_t g = 0; g < front_end.groups.size(); ++g) {
    int spots_3d = 0, assigned = 0;
    for (size_t k = 0; k < front_end.spots.size(); ++k) {
      if (front_end.spots[k].group != static_cast<int>(g)) continue;
      ++spots_3d;
      assigned += spots[k].assigned() ? 1 : 0;
    }
    groups.push_back({{"lasers", front_end.groups[g].lasers},
                      {"slice", front_end.groups[g].slice},
                      {"images", front_end.groups[g].images},
                      {"spots_3d", spots_3d},
                      {"assigned", assigned}});
  }
  doc["exposure_groups"] = groups;
  doc["frame_tags"] = front_end.frame_tags;
  doc["rms_reprojection_px"] = front_end.rms_reprojection_px;
  doc["variance_factor"] = front_end.variance_factor;
  doc["warnings"] = front_end.warnings;
  doc["measure"] = ordered_json::parse(measure.ToJson());
  doc["metadata_conflicts"] = metadata_conflicts;
  return doc.dump(2) + "\n";
}

Result<ImageMeasureReport> MeasureScaleFromImages(const Scene& scene,
                                                  const std::string& images_dir,
                                                  const ModuleCalibration& calibration,
                                                  const ImageMeasureOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  Result<FrontEndResult> front_end = RunImageFrontEnd(scene, images_dir, options.front_end);
  if (!front_end.ok()) return front_end.status();
  ImageMeasureReport report;
  report.front_end = std::move(*front_end);
  const FrontEndResult& fe = report.front_end;
  for (size_t k = 0; k < fe.spots.size(); ++k) {
    const FrontEndSpot& s = fe.spots[k];
    Spot spot;
    spot.observation.point_in_scene = s.point_in_scene;
    spot.observation.cov_in_scene = s.covariance;
    spot.where = "spot " + std::to_string(k + 1) + " (group " + std::to_string(s.group) + ", " +
                 std::to_string(s.views.size()) + " views)";
    report.spots.push_back(spot);
  }

  // Identification, one exposure group at a time: the spots of different
  // exposures are different point sets (two grids shot separately may
  // interleave in space, which a joint identification would have to
  // untangle for nothing).
  std::set<std::pair<std::string, int>> seen;
  for (size_t g = 0; g < fe.groups.size(); ++g) {
    const ExposureGroup& group = fe.groups[g];
    std::vector<size_t> members;
    std::vector<Spot> group_spots;
    for (size_t k = 0; k < fe.spots.size(); ++k) {
      if (fe.spots[k].group != static_cast<int>(g)) continue;
      Spot spot = report.spots[k];
      // One laser on: its spots can only be that source's.
      if (group.lasers.size() == 1 && calibration.FindSource(group.lasers[0]) != nullptr) {
        spot.source = group.lasers[0];
      }
      members.push_back(k);
      group_spots.push_back(spot);
    }
    if (group_spots.empty()) {
      report.identification.emplace_back();
      continue;
    }
    Result<IdentifyResult> identified =
        IdentifySpots(calibration, group_spots, options.measure.identify);
    if (!identified.ok()) {
      return Status(identified.status().code(), "identifying the spots of exposure group " +
                                                    std::to_string(g) + ": " +
                                                    identified.status().message());
    }
    for (size_t i = 0; i < members.size(); ++i) {
      const int source = identified->source_index[i];
      if (source < 0) continue;
      const std::string& name = identified->sources[static_cast<size_t>(source)].name;
      const int beam = identified->beam_id[i];
      Spot& spot = report.spots[members[i]];
      if (!group.lasers.empty() &&
          std::find(group.lasers.begin(), group.lasers.end(), name) == group.lasers.end()) {
        report.metadata_conflicts.push_back(spot.where + " identified as source '" + name +
                                            "', which was off in its images: not used");
        continue;
      }
      if (!seen.insert({name, beam}).second) {
        report.metadata_conflicts.push_back(spot.where + " is source '" + name + "' beam " +
                                            std::to_string(beam) +
                                            " again (another exposure group has it): not used");
        continue;
      }
      spot.source = name;
      spot.observation.beam_id = beam;
    }
    report.identification.push_back(std::move(*identified));
  }
  std::vector<Spot> assigned;
  for (const Spot& s : report.spots) {
    if (s.assigned()) assigned.push_back(s);
  }
  if (assigned.empty()) {
    std::string what;
    for (size_t g = 0; g < report.identification.size(); ++g) {
      for (const IdentifiedSource& s : report.identification[g].sources) {
        if (!s.detail.empty()) what += "; group " + std::to_string(g) + ": " + s.name + " " + s.detail;
      }
    }
    return Status::NoSolution("no spot was identified in any exposure group" + what);
  }
  Result<MeasureReport> measure = MeasureScale(calibration, assigned, options.measure);
  if (!measure.ok()) return measure.status();
  report.measure = std::move(*measure);
  return report;
}

}  // namespace opl
