// Test helpers that judge a measurement from images against the virtual
// lab's truth, independently of the pipeline: the similarity (Umeyama) from
// the identified 3D spots to their true points (the true scale of the
// measured frame, and the spots identified as the wrong beam), and the
// detection's recall and false spots per image against the truth's pixels.
#pragma once

#include <cmath>
#include <map>
#include <tuple>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "opl/lab/render_scene.h"
#include "opl/pipeline/measure_images.h"

namespace opl::test {

struct TruthFit {
  double scale = 0.0;   // mm per scene unit: s_true
  double rms_mm = 0.0;  // residual of the fit
  int points = 0;       // identified spots with a true point
  int wrong = 0;        // of those, farther than wrong_mm from it after the fit
};

inline TruthFit FitToTruth(const ImageMeasureReport& report, const SceneRenderer& truth,
                           double wrong_mm = 5.0) {
  // (placement, source, beam): a module placement's grid is a grid of its own.
  std::map<std::tuple<std::string, std::string, int>, Eigen::Vector3d> true_point;
  for (const SceneSpotTruth& s : truth.spots()) true_point[{s.placement, s.source, s.beam}] = s.point_in_scene;
  std::vector<Eigen::Vector3d> measured, truths;
  for (const Spot& spot : report.spots) {
    if (!spot.assigned()) continue;
    const auto found = true_point.find({spot.placement, spot.source, spot.observation.beam_id});
    if (found == true_point.end()) continue;
    measured.push_back(spot.observation.point_in_scene);
    truths.push_back(found->second);
  }
  TruthFit fit;
  fit.points = static_cast<int>(measured.size());
  if (fit.points < 4) return fit;
  Eigen::Matrix3Xd src(3, fit.points), dst(3, fit.points);
  for (int i = 0; i < fit.points; ++i) {
    src.col(i) = measured[static_cast<size_t>(i)];
    dst.col(i) = truths[static_cast<size_t>(i)];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
  fit.scale = t.topLeftCorner<3, 3>().col(0).norm();
  double sum = 0.0;
  for (int i = 0; i < fit.points; ++i) {
    const Eigen::Vector3d r =
        t.topLeftCorner<3, 3>() * src.col(i) + t.topRightCorner<3, 1>() - dst.col(i);
    sum += r.squaredNorm();
    fit.wrong += r.norm() > wrong_mm ? 1 : 0;
  }
  fit.rms_mm = std::sqrt(sum / fit.points);
  return fit;
}

struct SpotCounts {
  int visible = 0;      // true spots inside the lit images
  int found = 0;        // of those, with a kept detection within 1 px
  int false_spots = 0;  // kept detections farther than 1 px from every drawn true spot
};

// Over the lit shots of the renderer's scene (each rendered again for its
// truth), against the front end's kept spots of each image.
inline SpotCounts CountSpots(const SceneRenderer& truth, const ImageMeasureReport& report) {
  SpotCounts c;
  for (size_t i = 0; i < truth.scene().shots.size(); ++i) {
    if (truth.scene().shots[i].lasers.empty()) continue;
    Result<RenderedShot> shot = truth.RenderShot(static_cast<int>(i));
    EXPECT_TRUE(shot.ok());
    if (!shot.ok()) continue;
    const std::vector<DetectedSpot>& kept = report.front_end.images[i].spots;
    for (const SpotView& v : shot->spots) {
      if (!v.visible) continue;
      ++c.visible;
      for (const DetectedSpot& d : kept) {
        if ((Eigen::Vector2d(d.u_px, d.v_px) - v.center_px).norm() < 1.0) {
          ++c.found;
          break;
        }
      }
    }
    for (const DetectedSpot& d : kept) {
      bool near = false;
      for (const SpotView& v : shot->spots) {
        near = near || (v.center_px.allFinite() &&
                        (Eigen::Vector2d(d.u_px, d.v_px) - v.center_px).norm() < 1.0);
      }
      c.false_spots += near ? 0 : 1;
    }
  }
  return c;
}

}  // namespace opl::test
