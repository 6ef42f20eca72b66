#include "opl/sequencer/sequencer.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <sstream>
#include <utility>

#include <nlohmann/json.hpp>

namespace opl::sequencer {
namespace {

constexpr std::size_t kA = static_cast<std::size_t>(LineRole::kLaserA);
constexpr std::size_t kB = static_cast<std::size_t>(LineRole::kLaserB);
constexpr std::size_t kBlocker = static_cast<std::size_t>(LineRole::kBlocker);
constexpr std::size_t kTrigger = static_cast<std::size_t>(LineRole::kTrigger);
constexpr int kMaxSlices = 10000;

std::int64_t SatAdd(std::int64_t a, std::int64_t b) {
  if (b > 0 && a > Sequencer::kNoDeadline - b) return Sequencer::kNoDeadline;
  return a + b;
}

std::string WallTimeUtc() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  tm utc{};
  gmtime_r(&ts.tv_sec, &utc);
  char buf[64];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &utc);
  char frac[32];
  std::snprintf(frac, sizeof frac, ".%06ldZ", static_cast<long>(ts.tv_nsec / 1000));
  return std::string(buf, n) + frac;
}

}  // namespace

// Append-only JSON-lines file, one write(2) per line.
class Sequencer::MetadataFile {
 public:
  static Result<std::unique_ptr<MetadataFile>> Open(const std::string& path) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) return Status(StatusCode::kIoError, "metadata file '" + path + "': " + std::strerror(errno));
    return std::unique_ptr<MetadataFile>(new MetadataFile(fd, path));
  }
  ~MetadataFile() { ::close(fd_); }
  Status Append(const std::string& line) {
    const ssize_t n = ::write(fd_, line.data(), line.size());
    if (n != static_cast<ssize_t>(line.size())) {
      return Status(StatusCode::kIoError, "metadata file '" + path_ + "': write failed: " +
                                              (n < 0 ? std::strerror(errno) : "short write"));
    }
    return Status::Ok();
  }
  const std::string& path() const { return path_; }

 private:
  MetadataFile(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  int fd_;
  std::string path_;
};

const char* SequenceKindName(SequenceKind kind) noexcept {
  switch (kind) {
    case SequenceKind::kMeasurement: return "measurement";
    case SequenceKind::kCalibration: return "calibration";
    case SequenceKind::kManual: return "manual";
  }
  return "unknown";
}

const char* SequencerStateName(SequencerState state) noexcept {
  switch (state) {
    case SequencerState::kIdle: return "idle";
    case SequencerState::kRunning: return "running";
    case SequencerState::kWaitingOperator: return "waiting_operator";
    case SequencerState::kFault: return "fault";
  }
  return "unknown";
}

const char* EventTypeName(EventType type) noexcept {
  switch (type) {
    case EventType::kFrame: return "frame";
    case EventType::kWaitingOperator: return "waiting_operator";
    case EventType::kDone: return "done";
    case EventType::kAborted: return "aborted";
    case EventType::kLaserOff: return "laser_off";
    case EventType::kGpioError: return "gpio_error";
  }
  return "unknown";
}

const std::array<Step, 4>& MeasurementSteps() {
  static const std::array<Step, 4> kSteps = {{
      {"grid_a", true, false, true},
      {"grid_b", false, true, false},
      {"both", true, true, false},
      {"dark", false, false, false},
  }};
  return kSteps;
}

Sequencer::Sequencer(const SequencerConfig& config, std::unique_ptr<GpioChip> chip,
                     std::shared_ptr<const Clock> clock)
    : config_(config), chip_(std::move(chip)), clock_(std::move(clock)) {}

Sequencer::~Sequencer() {
  if (initialized_) {
    AllOff();
    chip_->Release();
  }
}

Status Sequencer::Init() {
  if (initialized_) return Status(StatusCode::kFailedPrecondition, "sequencer already initialised");
  if (!chip_ || !clock_) return Status(StatusCode::kInvalidArgument, "sequencer: no chip or no clock");
  std::string error;
  if (!config_.IsValid(&error)) return Status(StatusCode::kInvalidArgument, "configuration: " + error);
  std::vector<GpioLineSpec> specs;
  for (std::size_t i = 0; i < kNumLines; ++i) {
    specs.push_back({static_cast<unsigned>(config_.lines[i].offset), config_.lines[i].active_low,
                     LineRoleName(static_cast<LineRole>(i))});
  }
  Status s = chip_->RequestOutputs(specs, config_.consumer);
  if (!s.ok()) return s;
  initialized_ = true;
  active_.fill(false);
  return Status::Ok();
}

Status Sequencer::Set(LineRole role, bool active) {
  const std::size_t i = static_cast<std::size_t>(role);
  Status s = chip_->SetActive(i, active);
  if (s.ok()) active_[i] = active;
  return s;
}

Status Sequencer::AllOff() noexcept {
  Status first;
  if (!initialized_) return first;
  // Lasers first: they are what matters.
  for (std::size_t i : {kA, kB, kTrigger, kBlocker}) {
    Status s = chip_->SetActive(i, false);
    if (s.ok()) {
      active_[i] = false;
    } else if (first.ok()) {
      first = std::move(s);
    }
  }
  manual_pulse_end_ns_ = kNoDeadline;
  if (!active_[kA]) laser_deadline_ns_[0] = kNoDeadline;
  if (!active_[kB]) laser_deadline_ns_[1] = kNoDeadline;
  return first;
}

SequencerEvent Sequencer::MakeEvent(EventType type) const {
  SequencerEvent e;
  e.type = type;
  e.t_ns = clock_->NowNs();
  e.sequence = kind_;
  e.run = run_;
  e.slice = slice_;
  e.slices = slices_;
  e.step_index = step_index_;
  if (step_index_ >= 0 && step_index_ < 4) e.step = MeasurementSteps()[static_cast<std::size_t>(step_index_)].name;
  e.frame = frames_ - 1;
  return e;
}

void Sequencer::EmitLaserOff(std::size_t laser, const std::string& reason, bool manual) {
  SequencerEvent e = MakeEvent(EventType::kLaserOff);
  if (manual) {  // not part of a run: no run context
    e.sequence = SequenceKind::kManual;
    e.run = 0;
    e.slice = -1;
    e.slices = 0;
    e.step_index = -1;
    e.step.clear();
    e.frame = -1;
  }
  e.laser = laser == kA ? "a" : "b";
  e.message = reason;
  events_.push_back(std::move(e));
}

void Sequencer::Fault(const Status& status) {
  const bool was_on[2] = {active_[kA], active_[kB]};
  Status off = AllOff();
  last_error_ = status.ToString();
  if (!off.ok() && off.message() != status.message()) last_error_ += "; while driving lines off: " + off.ToString();
  const bool in_sequence = state_ == SequencerState::kRunning || state_ == SequencerState::kWaitingOperator;
  state_ = SequencerState::kFault;
  phase_ = Phase::kNone;
  phase_deadline_ns_ = kNoDeadline;
  metadata_.reset();
  SequencerEvent e = MakeEvent(EventType::kGpioError);
  e.message = last_error_;
  events_.push_back(e);
  if (in_sequence) {
    SequencerEvent a = MakeEvent(EventType::kAborted);
    a.message = last_error_;
    events_.push_back(std::move(a));
  }
  for (std::size_t l = 0; l < 2; ++l) {
    if (was_on[l]) EmitLaserOff(l == 0 ? kA : kB, "gpio error", !in_sequence);
  }
}

Status Sequencer::Start(const StartRequest& request) {
  if (!initialized_) return Status(StatusCode::kFailedPrecondition, "sequencer not initialised");
  if (state_ == SequencerState::kFault) return Status(StatusCode::kFailedPrecondition, "sequencer in fault state: " + last_error_);
  if (state_ != SequencerState::kIdle) {
    return Status(StatusCode::kFailedPrecondition, std::string("a ") + SequenceKindName(kind_) + " sequence is " + SequencerStateName(state_));
  }
  if (request.kind == SequenceKind::kManual) return Status(StatusCode::kInvalidArgument, "sequence must be measurement or calibration");
  if (request.kind == SequenceKind::kMeasurement && request.slices != 1) {
    return Status(StatusCode::kInvalidArgument, "slices = " + std::to_string(request.slices) + ": a measurement has 1 slice");
  }
  if (request.slices < 1 || request.slices > kMaxSlices) {
    return Status(StatusCode::kInvalidArgument, "slices = " + std::to_string(request.slices) + ": must be 1 .. " + std::to_string(kMaxSlices));
  }
  if (active_[kA] || active_[kB] || manual_pulse_end_ns_ != kNoDeadline) {
    return Status(StatusCode::kFailedPrecondition, "a manual laser or trigger is active; switch it off first");
  }
  const std::string path = request.metadata_path.empty() ? config_.metadata_path : request.metadata_path;
  if (path.empty()) return Status(StatusCode::kInvalidArgument, "no metadata file: give \"metadata\" or set it in the configuration");
  Result<std::unique_ptr<MetadataFile>> file = MetadataFile::Open(path);
  if (!file.ok()) return file.status();
  metadata_ = std::move(file).value();
  metadata_path_ = path;
  kind_ = request.kind;
  ++run_;
  slices_ = request.slices;
  slice_ = 0;
  step_index_ = 0;
  frames_ = 0;
  last_error_.clear();
  state_ = SequencerState::kRunning;
  BeginStep();
  if (state_ == SequencerState::kFault) return Status(StatusCode::kGpioError, last_error_);
  return Status::Ok();
}

Status Sequencer::NextSlice() {
  if (state_ != SequencerState::kWaitingOperator) {
    return Status(StatusCode::kFailedPrecondition, std::string("no calibration is waiting for the operator (state ") +
                                                       SequencerStateName(state_) + ")");
  }
  ++slice_;
  step_index_ = 0;
  state_ = SequencerState::kRunning;
  BeginStep();
  if (state_ == SequencerState::kFault) return Status(StatusCode::kGpioError, last_error_);
  return Status::Ok();
}

void Sequencer::BeginStep() {
  const Step& step = MeasurementSteps()[static_cast<std::size_t>(step_index_)];
  const std::int64_t t_before = clock_->NowNs();
  // Lasers that must be off first, then the blocker, then lasers on.
  const bool want[2] = {step.laser_a, step.laser_b};
  const std::size_t idx[2] = {kA, kB};
  for (int l = 0; l < 2; ++l) {
    if (!want[l] && active_[idx[l]]) {
      Status s = Set(static_cast<LineRole>(idx[l]), false);
      if (!s.ok()) return Fault(s);
    }
  }
  const bool blocker_moved = active_[kBlocker] != step.blocker_closed;
  if (blocker_moved) {
    Status s = Set(LineRole::kBlocker, step.blocker_closed);
    if (!s.ok()) return Fault(s);
  }
  bool any_on = false;
  for (int l = 0; l < 2; ++l) {
    if (!want[l]) continue;
    any_on = true;
    if (!active_[idx[l]]) {
      laser_on_since_ns_[static_cast<std::size_t>(l)] = t_before;
      laser_deadline_ns_[static_cast<std::size_t>(l)] = SatAdd(t_before, MsToNs(config_.timings.max_laser_on_ms));
      Status s = Set(static_cast<LineRole>(idx[l]), true);
      if (!s.ok()) return Fault(s);
    }
  }
  double wait_ms = 0.0;
  if (blocker_moved) wait_ms = std::max(wait_ms, config_.timings.blocker_settle_ms);
  if (any_on) wait_ms = std::max(wait_ms, config_.timings.laser_warmup_ms);
  phase_ = Phase::kWaitTrigger;
  phase_deadline_ns_ = SatAdd(clock_->NowNs(), MsToNs(wait_ms));
}

Status Sequencer::WriteFrameMetadata(std::int64_t t_ns, const std::string& step, int step_index) {
  if (!metadata_) return Status(StatusCode::kFailedPrecondition, "no metadata file open");
  nlohmann::json j;
  j["t_ns"] = t_ns;
  j["time"] = WallTimeUtc();
  j["sequence"] = SequenceKindName(kind_);
  j["run"] = run_;
  j["slice"] = slice_ >= 0 ? nlohmann::json(slice_) : nlohmann::json(nullptr);
  j["step"] = step;
  j["step_index"] = step_index >= 0 ? nlohmann::json(step_index) : nlohmann::json(nullptr);
  j["frame"] = frames_;
  j["lasers"] = {{"a", static_cast<bool>(active_[kA])}, {"b", static_cast<bool>(active_[kB])}};
  j["blocker"] = active_[kBlocker] ? "closed" : "open";
  return metadata_->Append(j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

void Sequencer::AdvancePhase() {
  const Timings& t = config_.timings;
  switch (phase_) {
    case Phase::kNone:
      phase_deadline_ns_ = kNoDeadline;
      return;
    case Phase::kWaitTrigger: {
      const std::int64_t t_before = clock_->NowNs();
      Status s = Set(LineRole::kTrigger, true);
      if (!s.ok()) return Fault(s);
      trigger_time_ns_ = t_before;
      const Step& step = MeasurementSteps()[static_cast<std::size_t>(step_index_)];
      Status m = WriteFrameMetadata(t_before, step.name, step_index_);
      ++frames_;
      if (!m.ok()) {
        FinishSequence(true, m.ToString());
        return;
      }
      SequencerEvent e = MakeEvent(EventType::kFrame);
      e.t_ns = t_before;
      events_.push_back(std::move(e));
      phase_ = Phase::kWaitPulseEnd;
      // Pulse width counts from the trigger write, metadata write included.
      phase_deadline_ns_ = SatAdd(t_before, MsToNs(t.trigger_pulse_ms));
      return;
    }
    case Phase::kWaitPulseEnd: {
      Status s = Set(LineRole::kTrigger, false);
      if (!s.ok()) return Fault(s);
      phase_ = Phase::kWaitFrameEnd;
      // Exposure counts from the trigger's rising edge.
      phase_deadline_ns_ = SatAdd(trigger_time_ns_, MsToNs(t.exposure_ms));
      phase_deadline_ns_ = std::max(phase_deadline_ns_, clock_->NowNs());
      return;
    }
    case Phase::kWaitFrameEnd: {
      for (std::size_t i : {kA, kB}) {
        if (active_[i]) {
          Status s = Set(static_cast<LineRole>(i), false);
          if (!s.ok()) return Fault(s);
          laser_deadline_ns_[i == kA ? 0 : 1] = kNoDeadline;
        }
      }
      ++step_index_;
      if (step_index_ < static_cast<int>(MeasurementSteps().size())) {
        BeginStep();
        return;
      }
      if (kind_ == SequenceKind::kCalibration && slice_ + 1 < slices_) {
        phase_ = Phase::kNone;
        phase_deadline_ns_ = kNoDeadline;
        state_ = SequencerState::kWaitingOperator;
        step_index_ = -1;
        SequencerEvent e = MakeEvent(EventType::kWaitingOperator);
        e.slice = slice_ + 1;  // the slice to be captured next
        events_.push_back(std::move(e));
        return;
      }
      FinishSequence(false, "");
      return;
    }
  }
}

void Sequencer::FinishSequence(bool aborted, const std::string& reason) {
  const bool was_on[2] = {active_[kA], active_[kB]};
  Status off = AllOff();
  phase_ = Phase::kNone;
  phase_deadline_ns_ = kNoDeadline;
  metadata_.reset();
  if (!off.ok()) {
    Fault(off);
    return;
  }
  state_ = SequencerState::kIdle;
  SequencerEvent e = MakeEvent(aborted ? EventType::kAborted : EventType::kDone);
  e.message = reason;
  if (aborted) last_error_ = reason;
  events_.push_back(std::move(e));
  for (std::size_t l = 0; l < 2; ++l) {
    if (was_on[l]) EmitLaserOff(l == 0 ? kA : kB, aborted ? reason : "sequence done", false);
  }
}

Status Sequencer::Abort(const std::string& reason) {
  if (!initialized_) return Status::Ok();
  if (state_ == SequencerState::kRunning || state_ == SequencerState::kWaitingOperator) {
    FinishSequence(true, reason);
    return state_ == SequencerState::kFault ? Status(StatusCode::kGpioError, last_error_) : Status::Ok();
  }
  const bool was_on[2] = {active_[kA], active_[kB]};
  Status off = AllOff();
  if (!off.ok()) {
    if (state_ != SequencerState::kFault) Fault(off);
    return off;
  }
  for (std::size_t l = 0; l < 2; ++l) {
    if (was_on[l]) EmitLaserOff(l == 0 ? kA : kB, reason, true);
  }
  return Status::Ok();
}

Status Sequencer::SetLaser(LineRole laser, bool on, double limit_ms) {
  if (laser != LineRole::kLaserA && laser != LineRole::kLaserB) return Status(StatusCode::kInvalidArgument, "not a laser line");
  if (!initialized_) return Status(StatusCode::kFailedPrecondition, "sequencer not initialised");
  const std::size_t i = static_cast<std::size_t>(laser);
  const std::size_t l = i == kA ? 0 : 1;
  if (!on) {
    if (state_ == SequencerState::kRunning || state_ == SequencerState::kWaitingOperator) {
      return Abort(std::string("laser ") + (l == 0 ? "a" : "b") + " off requested during the sequence");
    }
    if (!active_[i]) return Status::Ok();
    Status s = Set(laser, false);
    if (!s.ok()) {
      Fault(s);
      return s;
    }
    laser_deadline_ns_[l] = kNoDeadline;
    EmitLaserOff(i, "requested", true);
    return Status::Ok();
  }
  if (state_ != SequencerState::kIdle) {
    return Status(StatusCode::kFailedPrecondition, std::string("manual laser control needs the idle state (state ") +
                                                       SequencerStateName(state_) + ")");
  }
  if (!std::isfinite(limit_ms) || limit_ms <= 0.0 || limit_ms > config_.timings.max_laser_on_ms) {
    std::ostringstream msg;
    msg << "limit_ms = " << limit_ms << ": must be > 0 and <= max_laser_on (" << config_.timings.max_laser_on_ms << " ms)";
    return Status(StatusCode::kInvalidArgument, msg.str());
  }
  const std::int64_t t_before = clock_->NowNs();
  if (!active_[i]) laser_on_since_ns_[l] = t_before;
  // A repeated "on" renews the limit but never beyond max_laser_on of
  // continuous light.
  laser_deadline_ns_[l] = std::min(SatAdd(t_before, MsToNs(limit_ms)),
                                   SatAdd(laser_on_since_ns_[l], MsToNs(config_.timings.max_laser_on_ms)));
  if (!active_[i]) {
    Status s = Set(laser, true);
    if (!s.ok()) {
      Fault(s);
      return s;
    }
  }
  return Status::Ok();
}

Status Sequencer::SetBlocker(bool closed) {
  if (!initialized_) return Status(StatusCode::kFailedPrecondition, "sequencer not initialised");
  if (state_ != SequencerState::kIdle) {
    return Status(StatusCode::kFailedPrecondition, std::string("manual blocker control needs the idle state (state ") +
                                                       SequencerStateName(state_) + ")");
  }
  if (active_[kBlocker] == closed) return Status::Ok();
  Status s = Set(LineRole::kBlocker, closed);
  if (!s.ok()) Fault(s);
  return s;
}

Status Sequencer::Trigger(const std::string& metadata_path) {
  if (!initialized_) return Status(StatusCode::kFailedPrecondition, "sequencer not initialised");
  if (state_ != SequencerState::kIdle) {
    return Status(StatusCode::kFailedPrecondition, std::string("manual trigger needs the idle state (state ") +
                                                       SequencerStateName(state_) + ")");
  }
  if (manual_pulse_end_ns_ != kNoDeadline) return Status(StatusCode::kFailedPrecondition, "a trigger pulse is in progress");
  const std::string path = metadata_path.empty() ? config_.metadata_path : metadata_path;
  if (path.empty()) return Status(StatusCode::kInvalidArgument, "no metadata file: give \"metadata\" or set it in the configuration");
  Result<std::unique_ptr<MetadataFile>> file = MetadataFile::Open(path);
  if (!file.ok()) return file.status();
  metadata_ = std::move(file).value();
  metadata_path_ = path;
  kind_ = SequenceKind::kManual;
  ++run_;
  slice_ = -1;
  slices_ = 0;
  step_index_ = -1;
  frames_ = 0;
  const std::int64_t t_before = clock_->NowNs();
  Status s = Set(LineRole::kTrigger, true);
  if (!s.ok()) {
    metadata_.reset();
    Fault(s);
    return s;
  }
  Status m = WriteFrameMetadata(t_before, "manual", -1);
  metadata_.reset();
  ++frames_;
  manual_pulse_end_ns_ = SatAdd(clock_->NowNs(), MsToNs(config_.timings.trigger_pulse_ms));
  SequencerEvent e = MakeEvent(EventType::kFrame);
  e.t_ns = t_before;
  e.step = "manual";
  events_.push_back(std::move(e));
  return m;
}

void Sequencer::OnTime() {
  if (!initialized_ || state_ == SequencerState::kFault) return;
  // Bounded: each pass does at least one action or stops.
  for (int pass = 0; pass < 64; ++pass) {
    const std::int64_t now = clock_->NowNs();
    // Laser deadlines before anything else.
    for (std::size_t l = 0; l < 2; ++l) {
      const std::size_t i = l == 0 ? kA : kB;
      if (active_[i] && now >= laser_deadline_ns_[l]) {
        const std::string reason = std::string("laser ") + (l == 0 ? "a" : "b") + " reached its on-time limit";
        if (state_ == SequencerState::kRunning || state_ == SequencerState::kWaitingOperator) {
          FinishSequence(true, reason);
        } else {
          const bool was_on[2] = {active_[kA], active_[kB]};
          Status off = AllOff();
          if (!off.ok()) return Fault(off);
          for (std::size_t k = 0; k < 2; ++k) {
            if (was_on[k]) EmitLaserOff(k == 0 ? kA : kB, k == l ? "limit" : reason, true);
          }
        }
        if (state_ == SequencerState::kFault) return;
      }
    }
    if (manual_pulse_end_ns_ != kNoDeadline && now >= manual_pulse_end_ns_) {
      manual_pulse_end_ns_ = kNoDeadline;
      Status s = Set(LineRole::kTrigger, false);
      if (!s.ok()) return Fault(s);
    }
    if (state_ == SequencerState::kRunning && now >= phase_deadline_ns_) {
      AdvancePhase();
      if (state_ == SequencerState::kFault) return;
      continue;
    }
    return;
  }
}

std::int64_t Sequencer::NextDeadlineNs() const {
  if (!initialized_ || state_ == SequencerState::kFault) return kNoDeadline;
  std::int64_t d = manual_pulse_end_ns_;
  if (state_ == SequencerState::kRunning) d = std::min(d, phase_deadline_ns_);
  if (active_[kA]) d = std::min(d, laser_deadline_ns_[0]);
  if (active_[kB]) d = std::min(d, laser_deadline_ns_[1]);
  return d;
}

bool Sequencer::AnyLaserOn() const { return active_[kA] || active_[kB]; }

SequencerStatus Sequencer::GetStatus() const {
  SequencerStatus s;
  s.state = state_;
  s.sequence = kind_;
  s.run = run_;
  s.slice = slice_;
  s.slices = slices_;
  s.step_index = state_ == SequencerState::kRunning ? step_index_ : -1;
  if (s.step_index >= 0 && s.step_index < 4) s.step = MeasurementSteps()[static_cast<std::size_t>(s.step_index)].name;
  s.frames = frames_;
  s.active = active_;
  const std::int64_t now = clock_->NowNs();
  for (std::size_t l = 0; l < 2; ++l) {
    const std::size_t i = l == 0 ? kA : kB;
    if (active_[i] && laser_deadline_ns_[l] != kNoDeadline) {
      s.laser_remaining_ms[l] = std::max<double>(0.0, static_cast<double>(laser_deadline_ns_[l] - now) / 1e6);
    }
  }
  s.metadata_path = metadata_path_;
  s.last_error = last_error_;
  return s;
}

std::vector<SequencerEvent> Sequencer::TakeEvents() {
  std::vector<SequencerEvent> out;
  out.swap(events_);
  return out;
}

}  // namespace opl::sequencer
