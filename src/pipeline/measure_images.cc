#include "opl/pipeline/measure_images.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
#include <sstream>

#include <nlohmann/json.hpp>

#include "opl/core/format.h"
#include "opl/core/message_text.h"
#include "opl/pipeline/projector_measure.h"

namespace opl {

Status ImageMeasureOptions::Validate() const {
  OPL_RETURN_IF_ERROR(front_end.Validate());
  return measure.Validate();
}

const char* ScaleMethodName(ScaleMethod method) {
  return method == ScaleMethod::kAdjustment ? "adjustment" : "two-step";
}

std::string ImageMeasureReport::ToText() const {
  std::ostringstream out;
  out << front_end.ToText();
  for (size_t g = 0; g < identification.size(); ++g) {
    out << "identification, exposure group " << g << ":\n" << identification[g].ToText();
  }
  out << "\nthe two-step measurement (each source located from its triangulated spots):\n"
      << measure.ToText();
  if (shared_components > 0) {
    out << "u(s) = sqrt(own^2 + shared^2): own " << FormatNumber(u_scale_factor_own, 3)
        << " (the spots' own errors), shared " << FormatNumber(u_scale_factor_shared, 3)
        << " (camera poses and datum tags, common to every spot; " << shared_components
        << " components propagated)\n";
  }
  for (const std::string& c : metadata_conflicts) out << "warning: " << c << "\n";
  if (projector) out << "\nthe scale inside the adjustment:\n" << projector->Report();
  out << "\nResult: s = " << FormatPrintf("%.9f", scale_factor) << " +- "
      << FormatPrintf("%.9f", u_scale_factor) << " mm per scene unit ("
      << FormatPrintf("%.1f", u_scale_factor / scale_factor * 1e6) << " ppm, k = 1; U = "
      << FormatPrintf("%.9f", 2.0 * u_scale_factor) << " at k = 2), "
      << (scale_method == ScaleMethod::kAdjustment
              ? std::string("the scale inside the adjustment (the two-step s above for comparison)")
              : "the two-step s above: " + scale_method_note)
      << "\n";
  return out.str();
}

std::string ImageMeasureReport::ToJson() const {
  using nlohmann::ordered_json;
  ordered_json doc;
  doc["format"] = "opl.image_measure_report";
  doc["version"] = 1;
  doc["scale_factor"] = scale_factor;
  doc["u_scale_factor"] = u_scale_factor;
  doc["scale_method"] = ScaleMethodName(scale_method);
  doc["scale_method_note"] = scale_method_note;
  ordered_json images = ordered_json::array();
  for (const ImageFindings& f : front_end.images) {
    images.push_back({{"file", f.file},
                      {"camera", f.camera},
                      {"tags", f.tag_ids},
                      {"spots_detected", f.spots_detected},
                      {"blobs_rejected", f.blobs_rejected},
                      {"spots_matched", f.spots_matched},
                      {"placed", f.placed},
                      {"tag_rms_px", f.tag_rms_px},
                      {"spot_rms_px", f.spot_rms_px},
                      {"tag_model_rms_px", f.tag_model_rms_px},
                      {"spot_model_rms_px", f.spot_model_rms_px},
                      {"spots_saturated", f.spots_saturated},
                      {"lossy_jpeg", f.lossy_jpeg},
                      {"laser_off", f.laser_off},
                      {"dark_frame", f.dark_frame.empty() ? ordered_json(nullptr) : ordered_json(f.dark_frame)},
                      {"dark_frame_gain", f.dark_frame.empty() ? ordered_json(nullptr) : ordered_json(f.dark_frame_gain)},
                      {"notes", f.notes},
                      {"decode_warnings", f.decode_warnings}});
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
    ordered_json group = {{"lasers", front_end.groups[g].lasers}, {"slice", front_end.groups[g].slice}};
    if (!front_end.groups[g].placement.empty()) group["placement"] = front_end.groups[g].placement;
    group["images"] = front_end.groups[g].images;
    group["spots_3d"] = spots_3d;
    group["assigned"] = assigned;
    groups.push_back(std::move(group));
  }
  doc["exposure_groups"] = groups;
  doc["frame_tags"] = front_end.frame_tags;
  doc["rms_reprojection_px"] = front_end.rms_reprojection_px;
  doc["variance_factor"] = front_end.variance_factor;
  doc["spot_variance_factor"] = front_end.spot_variance_factor;
  doc["spot_extra_sigma_px"] = front_end.spot_extra_sigma_px;
  doc["tag_variance_factor"] = front_end.tag_variance_factor;
  doc["tag_extra_sigma_px"] = front_end.tag_extra_sigma_px;
  doc["u_scale_factor_own"] = u_scale_factor_own;
  doc["u_scale_factor_shared"] = u_scale_factor_shared;
  doc["warnings"] = front_end.warnings;
  doc["measure"] = ordered_json::parse(measure.ToJson());
  doc["metadata_conflicts"] = metadata_conflicts;
  if (projector) {
    doc["projector"] = {{"scale_factor", projector->scale_factor},
                        {"u_scale_factor", projector->u_scale_factor},
                        {"datum_length_mm", projector->datum_length_mm},
                        {"u_datum_length_mm", projector->u_datum_length_mm},
                        {"variance_factor", projector->variance_factor},
                        {"rms_tag_px", projector->rms_tag_px},
                        {"rms_spot_px", projector->rms_spot_px}};
  }
  return doc.dump(2) + "\n";
}

Result<ImageMeasureReport> MeasureScaleFromImages(const Scene& scene,
                                                  const std::string& images_dir,
                                                  const ModuleCalibration& calibration,
                                                  const ImageMeasureOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  if (Status st = CheckSceneHasLasers(scene); !st.ok()) {
    return Status::InvalidArgument("scene: " + st.message());
  }
  Result<FrontEndResult> front_end = RunImageFrontEnd(scene, images_dir, options.front_end);
  if (!front_end.ok()) return front_end.status();
  return MeasureScaleFromFrontEnd(std::move(*front_end), calibration, options);
}

Result<ImageMeasureReport> MeasureScaleFromFrontEnd(FrontEndResult front_end,
                                                    const ModuleCalibration& calibration,
                                                    const ImageMeasureOptions& options) {
  OPL_RETURN_IF_ERROR(options.Validate());
  ImageMeasureReport report;
  report.front_end = std::move(front_end);
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
  std::set<std::tuple<std::string, std::string, int>> seen;  // (placement, source, beam)
  for (size_t g = 0; g < fe.groups.size(); ++g) {
    const ExposureGroup& group = fe.groups[g];
    std::vector<size_t> members;
    std::vector<Spot> group_spots;
    for (size_t k = 0; k < fe.spots.size(); ++k) {
      if (fe.spots[k].group != static_cast<int>(g)) continue;
      report.spots[k].placement = group.placement;
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
    // A source whose laser was off in this group's shots was not looked for
    // (one laser on: every spot carries that source) or, with several on,
    // not expected: say so instead of a bare "not found".
    if (!group.lasers.empty()) {
      for (IdentifiedSource& s : identified->sources) {
        if (s.outcome != IdentifyOutcome::kNotFound ||
            std::find(group.lasers.begin(), group.lasers.end(), s.name) != group.lasers.end()) {
          continue;
        }
        s.detail = group.lasers.size() == 1 ? "laser off in these shots: not searched"
                                            : "laser off in these shots";
      }
    }
    for (size_t i = 0; i < members.size(); ++i) {
      const int source = identified->source_index[i];
      if (source < 0) continue;
      const std::string& name = identified->sources[static_cast<size_t>(source)].name;
      const int beam = identified->beam_id[i];
      Spot& spot = report.spots[members[i]];
      if (!group.lasers.empty() &&
          std::find(group.lasers.begin(), group.lasers.end(), name) == group.lasers.end()) {
        report.metadata_conflicts.push_back(spot.where + " identified as source " + QuoteForMessage(name) +
                                            ", which was off in its images: not used");
        continue;
      }
      if (!seen.insert({group.placement, name, beam}).second) {
        report.metadata_conflicts.push_back(spot.where + " is source " + QuoteForMessage(name) + " beam " +
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
  std::vector<size_t> front_end_index;
  for (size_t k = 0; k < report.spots.size(); ++k) {
    if (!report.spots[k].assigned()) continue;
    assigned.push_back(report.spots[k]);
    front_end_index.push_back(k);
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
  // The own / shared split of every assigned spot, when the front end gave it.
  Eigen::Index m = -1;
  bool split = options.propagate_shared_errors;
  for (size_t k : front_end_index) {
    const Eigen::MatrixXd& K = fe.spots[k].shared_factor;
    if (K.size() == 0 || (m >= 0 && K.cols() != m)) split = false;
    m = K.cols();
  }
  if (split) {
    for (size_t i = 0; i < assigned.size(); ++i) {
      assigned[i].observation.cov_in_scene = fe.spots[front_end_index[i]].own_covariance;
    }
  }
  Result<MeasureReport> measure = MeasureScale(calibration, assigned, options.measure);
  if (!measure.ok()) return measure.status();
  if (split && m > 0) {
    // g_k = ds / dz_k by central differences at one standard deviation (s
    // is linear in z to far better than that: a shared component moves the
    // spots by a fraction of their own scatter).
    ScaleResult& scale = measure->scale;
    double shared2 = 0.0;
    std::vector<double> photo2(scale.lengths.size(), 0.0), scale2(scale.lengths.size(), 0.0);
    report.scale_shared_gradient = Eigen::VectorXd::Zero(m);
    for (Eigen::Index k = 0; k < m; ++k) {
      std::array<ScaleResult, 2> moved;
      for (int side = 0; side < 2; ++side) {
        std::vector<Spot> perturbed = assigned;
        const double sign = side == 0 ? 1.0 : -1.0;
        for (size_t i = 0; i < perturbed.size(); ++i) {
          perturbed[i].observation.point_in_scene +=
              sign * fe.spots[front_end_index[i]].shared_factor.col(k);
        }
        Result<MeasureReport> r = MeasureScale(calibration, perturbed, options.measure);
        if (!r.ok()) {
          return Status(r.status().code(), "propagating the spots' shared errors (component " +
                                               std::to_string(k + 1) + " of " +
                                               std::to_string(m) + "): " + r.status().message());
        }
        if (r->scale.lengths.size() != scale.lengths.size()) {
          return Status::NoSolution(
              "propagating the spots' shared errors (component " + std::to_string(k + 1) +
              "): a one-sigma move of the cameras changed which sources were located");
        }
        moved[static_cast<size_t>(side)] = r->scale;
      }
      const double g = 0.5 * (moved[0].scale_factor - moved[1].scale_factor);
      shared2 += g * g;
      report.scale_shared_gradient[k] = g;
      for (size_t l = 0; l < scale.lengths.size(); ++l) {
        const double gp = 0.5 * (moved[0].lengths[l].photo - moved[1].lengths[l].photo);
        const double gs = 0.5 * (moved[0].lengths[l].scale - moved[1].lengths[l].scale);
        photo2[l] += gp * gp;
        scale2[l] += gs * gs;
      }
    }
    report.u_scale_factor_own = scale.u_scale_factor;
    report.u_scale_factor_shared = std::sqrt(shared2);
    report.shared_components = static_cast<int>(m);
    scale.u_scale_factor = std::hypot(scale.u_scale_factor, report.u_scale_factor_shared);
    for (size_t l = 0; l < scale.lengths.size(); ++l) {
      scale.lengths[l].u_photo = std::sqrt(scale.lengths[l].u_photo * scale.lengths[l].u_photo + photo2[l]);
      scale.lengths[l].u_scale = std::sqrt(scale.lengths[l].u_scale * scale.lengths[l].u_scale + scale2[l]);
    }
  }
  report.measure = std::move(*measure);
  report.scale_factor = report.measure.scale.scale_factor;
  report.u_scale_factor = report.measure.scale.u_scale_factor;
  report.scale_method = ScaleMethod::kTwoStep;
  if (!options.front_end.scale_in_adjustment) {
    report.scale_method_note = "the scale inside the adjustment was not asked for";
  } else if (report.front_end.adjustment.cameras.empty()) {
    report.scale_method_note =
        "the scale inside the adjustment needs the front end's own adjustment, which the COLMAP "
        "path does not keep";
  } else {
    ProjectorAdjustmentOptions projector_options;
    projector_options.num_threads = std::max(1, options.front_end.num_threads);
    Result<ProjectorAdjustmentResult> projector =
        AdjustScaleWithProjector(report, calibration, projector_options, options.projector_tag_lengths);
    if (projector.ok()) {
      report.projector = std::move(*projector);
      report.scale_factor = report.projector->scale_factor;
      report.u_scale_factor = report.projector->u_scale_factor;
      report.scale_method = ScaleMethod::kAdjustment;
    } else {
      report.projector_status = projector.status();
      report.scale_method_note = "the scale inside the adjustment failed (" +
                                 projector.status().message() + ")";
      report.front_end.warnings.push_back(report.scale_method_note + "; s is the two-step s");
    }
  }
  return report;
}

}  // namespace opl
