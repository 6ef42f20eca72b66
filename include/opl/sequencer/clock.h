// Clock: the monotonic time source of the sequencer, injectable for tests.
//
// Every time in the sequencer is an int64 count of nanoseconds of one clock.
// The daemon uses MonotonicClock (CLOCK_MONOTONIC), the same clock its
// timerfd runs on, so that the simulated chip's log, the per-frame metadata
// and a test process reading clock_gettime(CLOCK_MONOTONIC) share one time
// base. Unit tests use ManualClock and advance time by hand.
#ifndef OPL_SEQUENCER_CLOCK_H_
#define OPL_SEQUENCER_CLOCK_H_

#include <cstdint>

namespace opl::sequencer {

class Clock {
 public:
  virtual ~Clock() = default;
  // Nanoseconds since an arbitrary fixed origin; never decreases.
  virtual std::int64_t NowNs() const noexcept = 0;
};

// CLOCK_MONOTONIC.
class MonotonicClock final : public Clock {
 public:
  std::int64_t NowNs() const noexcept override;
};

// A clock that moves only when told to (unit tests).
class ManualClock final : public Clock {
 public:
  explicit ManualClock(std::int64_t start_ns = 0) : now_ns_(start_ns) {}
  std::int64_t NowNs() const noexcept override { return now_ns_; }
  void SetNs(std::int64_t now_ns) { now_ns_ = now_ns; }
  void AdvanceNs(std::int64_t delta_ns) { now_ns_ += delta_ns; }

 private:
  std::int64_t now_ns_;
};

// Milliseconds (a configuration unit) to nanoseconds, rounded to nearest.
std::int64_t MsToNs(double ms) noexcept;

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_CLOCK_H_
