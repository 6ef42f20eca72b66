// Sequencer: the capture state machine that drives the module's four lines
// (laser A, laser B, blocker, camera trigger) through a GpioChip.
//
// Sequences. A measurement is four frames, in this order:
//
//   step     laser A  laser B  blocker
//   grid_a   on       off      closed   (the blocker hides grid B)
//   grid_b   off      on       open
//   both     on       on       open
//   dark     off      off      open
//
// A calibration runs the same four frames once per slice and, between
// slices, waits (every laser off) for the operator to move the screen and
// call NextSlice(). Manual mode is the idle state: SetLaser (with a time
// limit), SetBlocker and Trigger are accepted only when no sequence runs.
//
// One frame, times from the injected Clock:
//
//   t0            blocker moved if needed, then the step's lasers on
//   t1 >= t0 + max(blocker_settle if the blocker moved,
//                  laser_warmup if a laser is on)
//                 trigger asserted; one metadata JSON line written
//   t1 + pulse    trigger released
//   t1 + exposure every laser off; the next frame starts at once
//
// Every wait is "at least": an action never happens early, a late timer
// makes it late. Each laser-on has a deadline (max_laser_on_ms in sequences,
// the requested limit in manual mode) checked before anything else on every
// OnTime(); past it every line is driven off.
//
// Safety contract: AllOff() is the one path that switches lasers off; it is
// noexcept, tries every line even when one fails, and is called on Abort, on
// any GPIO error (the sequencer then enters kFault and refuses everything but
// Abort and status), on a passed deadline, and by the destructor.
//
// Threading: none. The owner calls OnTime() whenever NextDeadlineNs() has
// passed (the daemon arms a timerfd for it); every call returns quickly.
#ifndef OPL_SEQUENCER_SEQUENCER_H_
#define OPL_SEQUENCER_SEQUENCER_H_

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "opl/sequencer/clock.h"
#include "opl/sequencer/config.h"
#include "opl/sequencer/gpio.h"
#include "opl/sequencer/status.h"

namespace opl::sequencer {

enum class SequenceKind { kMeasurement, kCalibration, kManual };
// "measurement", "calibration", "manual".
const char* SequenceKindName(SequenceKind kind) noexcept;

enum class SequencerState { kIdle, kRunning, kWaitingOperator, kFault };
// "idle", "running", "waiting_operator", "fault".
const char* SequencerStateName(SequencerState state) noexcept;

struct Step {
  const char* name;
  bool laser_a;
  bool laser_b;
  bool blocker_closed;
};
// The four frames of a measurement (and of each calibration slice), in order.
const std::array<Step, 4>& MeasurementSteps();

struct StartRequest {
  SequenceKind kind = SequenceKind::kMeasurement;  // measurement or calibration
  int slices = 1;  // calibration: number of slices, 1 .. 10000; measurement: 1
  // Per-frame metadata file; empty: the configuration's metadata_path.
  std::string metadata_path;
};

enum class EventType {
  kFrame,            // a trigger was asserted (metadata written)
  kWaitingOperator,  // calibration: move the screen, then next_slice
  kDone,             // a sequence completed
  kAborted,          // a sequence stopped early; every laser is off
  kLaserOff,         // a laser went off outside the normal end of a frame
  kGpioError,        // a GPIO write failed; every line driven off; kFault
};
const char* EventTypeName(EventType type) noexcept;

struct SequencerEvent {
  EventType type = EventType::kFrame;
  std::int64_t t_ns = 0;           // Clock time
  SequenceKind sequence = SequenceKind::kManual;
  int run = 0;                     // run number, 1 for the first start
  int slice = -1;                  // slice index, -1 if none
  int slices = 0;                  // number of slices of the run
  int step_index = -1;             // 0..3, -1 if none
  std::string step;                // step name
  int frame = -1;                  // frame number within the run
  std::string laser;               // kLaserOff: "a" or "b"
  std::string message;             // reason or error
};

struct SequencerStatus {
  SequencerState state = SequencerState::kIdle;
  SequenceKind sequence = SequenceKind::kManual;  // of the current or last run
  int run = 0;
  int slice = -1;
  int slices = 0;
  int step_index = -1;
  std::string step;
  int frames = 0;                       // frames triggered in the current or last run
  std::array<bool, kNumLines> active{}; // logical state of each line (LineRole)
  // Time left before each laser's deadline, ms (0 when off).
  std::array<double, 2> laser_remaining_ms{};
  std::string metadata_path;
  std::string last_error;
};

class Sequencer {
 public:
  static constexpr std::int64_t kNoDeadline = std::numeric_limits<std::int64_t>::max();

  // `config` must be valid (SequencerConfig::IsValid).
  Sequencer(const SequencerConfig& config, std::unique_ptr<GpioChip> chip,
            std::shared_ptr<const Clock> clock);
  // Drives every line off and releases the chip.
  ~Sequencer();
  Sequencer(const Sequencer&) = delete;
  Sequencer& operator=(const Sequencer&) = delete;

  // Requests the four lines as outputs, all inactive (every laser off).
  Status Init();

  Status Start(const StartRequest& request);
  // Calibration, kWaitingOperator only: captures the next slice.
  Status NextSlice();
  // Drives every line off and ends the current sequence, if any. Always
  // allowed; the returned status is that of the GPIO writes.
  Status Abort(const std::string& reason);
  // Manual: laser kLaserA / kLaserB on for at most `limit_ms` (0 <
  // limit_ms <= max_laser_on_ms; a repeated "on" cannot extend a laser's
  // continuous on-time beyond max_laser_on_ms), or off. "Off" is always
  // allowed; during a sequence it aborts the sequence.
  Status SetLaser(LineRole laser, bool on, double limit_ms);
  // Manual, idle only.
  Status SetBlocker(bool closed);
  // Manual, idle only: one trigger pulse and one metadata line (sequence
  // "manual"). `metadata_path` empty: the configuration's.
  Status Trigger(const std::string& metadata_path);

  // Performs every action that is due by the clock's now.
  void OnTime();
  // Clock time of the next due action, or kNoDeadline.
  std::int64_t NextDeadlineNs() const;

  // Drives every line inactive, each attempted even if another fails. Never
  // throws. Returns the first failure.
  Status AllOff() noexcept;

  SequencerStatus GetStatus() const;
  bool AnyLaserOn() const;
  bool faulted() const { return state_ == SequencerState::kFault; }
  // Events since the last call, oldest first.
  std::vector<SequencerEvent> TakeEvents();

 private:
  enum class Phase { kNone, kWaitTrigger, kWaitPulseEnd, kWaitFrameEnd };
  class MetadataFile;

  Status Set(LineRole role, bool active);
  void Fault(const Status& status);
  void BeginStep();
  void AdvancePhase();
  void FinishSequence(bool aborted, const std::string& reason);
  Status WriteFrameMetadata(std::int64_t t_ns, const std::string& step, int step_index);
  SequencerEvent MakeEvent(EventType type) const;
  void EmitLaserOff(std::size_t laser, const std::string& reason, bool manual);

  SequencerConfig config_;
  std::unique_ptr<GpioChip> chip_;
  std::shared_ptr<const Clock> clock_;
  bool initialized_ = false;

  SequencerState state_ = SequencerState::kIdle;
  std::array<bool, kNumLines> active_{};
  std::array<std::int64_t, 2> laser_deadline_ns_{kNoDeadline, kNoDeadline};
  std::array<std::int64_t, 2> laser_on_since_ns_{0, 0};

  SequenceKind kind_ = SequenceKind::kManual;
  int run_ = 0;
  int slice_ = -1;
  int slices_ = 0;
  int step_index_ = -1;
  int frames_ = 0;
  Phase phase_ = Phase::kNone;
  std::int64_t phase_deadline_ns_ = kNoDeadline;
  std::int64_t trigger_time_ns_ = 0;
  std::int64_t manual_pulse_end_ns_ = kNoDeadline;
  std::unique_ptr<MetadataFile> metadata_;
  std::string metadata_path_;
  std::string last_error_;
  std::vector<SequencerEvent> events_;
};

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_SEQUENCER_H_
