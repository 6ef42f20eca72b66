// Internal to src/uncertainty: what the Monte Carlo reports (monte_carlo.cc,
// calibration_monte_carlo.cc) share to write their text and JSON.
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "opl/uncertainty/monte_carlo.h"

namespace opl::internal {

// Standard deviations from the diagonal of a covariance (negatives from
// rounding read as 0).
inline Eigen::Vector3d StdDevs(const Eigen::Matrix3d& cov) {
  return cov.diagonal().cwiseMax(0.0).cwiseSqrt();
}

// a / b, or 0 when b is not positive (a ratio to a zero prediction).
inline double Ratio(double a, double b) { return b > 0.0 ? a / b : 0.0; }

inline nlohmann::ordered_json VectorJson(const Eigen::Vector3d& v) {
  return nlohmann::ordered_json::array({v.x(), v.y(), v.z()});
}

// [low, high] of a coverage interval, or null when the sample is too small.
inline nlohmann::ordered_json IntervalJson(const SampleSummary& s, const CoverageInterval& c) {
  if (!s.has_interval) return nullptr;
  return nlohmann::ordered_json::array({c.low, c.high});
}

// The keys every Monte Carlo report starts with: format, version 1, the run
// (iterations, succeeded, failed, first_failure when failed > 0, seed) and
// the coverage intervals' probability and kind.
inline nlohmann::ordered_json RunHeaderJson(const char* format, int iterations, int succeeded,
                                            int failed, const std::string& first_failure,
                                            uint64_t seed, double coverage_probability) {
  nlohmann::ordered_json doc;
  doc["format"] = format;
  doc["version"] = 1;
  doc["iterations"] = iterations;
  doc["succeeded"] = succeeded;
  doc["failed"] = failed;
  if (failed > 0) doc["first_failure"] = first_failure;
  doc["seed"] = seed;
  doc["coverage_probability"] = coverage_probability;
  doc["coverage_interval"] = "probabilistically_symmetric";
  return doc;
}

}  // namespace opl::internal
