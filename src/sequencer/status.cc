#include "opl/sequencer/status.h"

#include <cmath>
#include <ctime>

#include "opl/sequencer/clock.h"

namespace opl::sequencer {

const char* StatusCodeName(StatusCode code) noexcept {
  switch (code) {
    case StatusCode::kOk: return "OK";
    case StatusCode::kInvalidArgument: return "INVALID_ARGUMENT";
    case StatusCode::kFailedPrecondition: return "FAILED_PRECONDITION";
    case StatusCode::kNotFound: return "NOT_FOUND";
    case StatusCode::kIoError: return "IO_ERROR";
    case StatusCode::kGpioError: return "GPIO_ERROR";
    case StatusCode::kInternal: return "INTERNAL";
  }
  return "UNKNOWN";
}

std::string Status::ToString() const {
  if (ok()) return "OK";
  return std::string(StatusCodeName(code_)) + ": " + message_;
}

std::int64_t MonotonicClock::NowNs() const noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

std::int64_t MsToNs(double ms) noexcept {
  if (!std::isfinite(ms) || ms <= 0.0) return 0;
  if (ms > 9.0e9) ms = 9.0e9;  // ~104 days; keeps the product far from overflow
  return static_cast<std::int64_t>(std::llround(ms * 1.0e6));
}

}  // namespace opl::sequencer
