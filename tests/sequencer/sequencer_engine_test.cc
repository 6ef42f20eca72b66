// The Sequencer state machine on a SimChip with a ManualClock: exact frame
// timings, metadata, calibration pauses, laser deadlines and the error paths.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/sequencer/sequencer.h"
#include "opl/sequencer/sim_chip.h"

namespace opl::sequencer {
namespace {

constexpr std::int64_t kMs = 1000000;
constexpr std::int64_t kT0 = 1000 * kMs;

SequencerConfig TestConfig(const std::string& metadata) {
  SequencerConfig c;
  c.backend = "sim";
  c.line(LineRole::kLaserA).offset = 1;
  c.line(LineRole::kLaserB).offset = 2;
  c.line(LineRole::kBlocker).offset = 3;
  c.line(LineRole::kTrigger) = {4, true};
  c.timings.laser_warmup_ms = 30;
  c.timings.blocker_settle_ms = 50;
  c.timings.trigger_pulse_ms = 10;
  c.timings.exposure_ms = 30;
  c.timings.max_laser_on_ms = 500;
  c.metadata_path = metadata;
  return c;
}

struct Change {
  std::int64_t t_ms;  // from kT0
  std::string name;
  bool active;
  bool operator==(const Change& o) const { return t_ms == o.t_ms && name == o.name && active == o.active; }
};
std::ostream& operator<<(std::ostream& os, const Change& c) {
  return os << "{" << c.t_ms << " ms, " << c.name << ", " << c.active << "}";
}

class Harness {
 public:
  explicit Harness(long fail_write_number = 0, SequencerConfig config = TestConfig(MetadataPath()))
      : clock_(std::make_shared<ManualClock>(kT0)) {
    std::remove(MetadataPath().c_str());
    SimChipOptions o;
    o.fail_write_number = fail_write_number;
    auto chip = SimChip::Open(o, clock_);
    sim_ = chip.value().get();
    seq_ = std::make_unique<Sequencer>(config, std::move(chip).value(), clock_);
  }
  ~Harness() { std::remove(MetadataPath().c_str()); }
  static std::string MetadataPath() { return "/tmp/opl_engine_test_" + std::to_string(::getpid()) + ".jsonl"; }

  // Runs the clock from deadline to deadline until nothing is due.
  void RunToEnd(int max_steps = 1000) {
    for (int i = 0; i < max_steps; ++i) {
      const std::int64_t d = seq_->NextDeadlineNs();
      if (d == Sequencer::kNoDeadline) return;
      clock_->SetNs(std::max(d, clock_->NowNs()));
      seq_->OnTime();
    }
  }
  // Actual changes of line state (writes that repeat a value dropped).
  std::vector<Change> Changes() const {
    std::map<std::string, bool> state;
    std::vector<Change> out;
    for (const SimLineEvent& e : sim_->events()) {
      auto it = state.find(e.name);
      if (it != state.end() && it->second == e.active) continue;
      const bool first = it == state.end();
      state[e.name] = e.active;
      if (first) continue;  // the request's initial "inactive"
      out.push_back({(e.t_ns - kT0) / kMs, e.name, e.active});
    }
    return out;
  }
  bool AllOff() const {
    for (std::size_t i = 0; i < kNumLines; ++i) {
      if (sim_->IsActive(i)) return false;
    }
    return true;
  }
  std::vector<EventType> EventTypes() {
    std::vector<EventType> t;
    for (const SequencerEvent& e : seq_->TakeEvents()) t.push_back(e.type);
    return t;
  }

  std::shared_ptr<ManualClock> clock_;
  SimChip* sim_;
  std::unique_ptr<Sequencer> seq_;
};

TEST(SequencerEngine, MeasurementTimelineIsExact) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.AllOff());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  h.RunToEnd();
  // warm-up 30, settle 50, pulse 10, exposure 30 (ms).
  const std::vector<Change> expected = {
      {0, "blocker", true},   {0, "laser_a", true},   {50, "trigger", true},  {60, "trigger", false},  // grid_a: settle 50
      {80, "laser_a", false}, {80, "blocker", false}, {80, "laser_b", true},                           // grid_b
      {130, "trigger", true}, {140, "trigger", false}, {160, "laser_b", false},
      {160, "laser_a", true}, {160, "laser_b", true},                                                  // both: warm-up 30
      {190, "trigger", true}, {200, "trigger", false}, {220, "laser_a", false}, {220, "laser_b", false},
      {220, "trigger", true}, {230, "trigger", false},                                                 // dark: no wait
  };
  EXPECT_EQ(h.Changes(), expected);
  EXPECT_TRUE(h.AllOff());
  EXPECT_EQ(h.seq_->GetStatus().state, SequencerState::kIdle);
  EXPECT_EQ(h.seq_->GetStatus().frames, 4);
  const std::vector<EventType> events = h.EventTypes();
  ASSERT_EQ(events.size(), 5u);
  EXPECT_EQ(events.back(), EventType::kDone);
  // The sequence ends exposure after the dark trigger.
  EXPECT_EQ(h.clock_->NowNs() - kT0, 250 * kMs);
}

TEST(SequencerEngine, MetadataDescribesEachFrame) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  h.RunToEnd();
  std::ifstream in(Harness::MetadataPath());
  std::vector<nlohmann::json> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(lines.size(), 4u);
  const char* steps[] = {"grid_a", "grid_b", "both", "dark"};
  const bool a[] = {true, false, true, false};
  const bool b[] = {false, true, true, false};
  const char* blocker[] = {"closed", "open", "open", "open"};
  const std::int64_t t_ms[] = {50, 130, 190, 220};
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(lines[i]["step"], steps[i]);
    EXPECT_EQ(lines[i]["step_index"], i);
    EXPECT_EQ(lines[i]["frame"], i);
    EXPECT_EQ(lines[i]["sequence"], "measurement");
    EXPECT_EQ(lines[i]["run"], 1);
    EXPECT_EQ(lines[i]["slice"], 0);
    EXPECT_EQ(lines[i]["lasers"]["a"], a[i]);
    EXPECT_EQ(lines[i]["lasers"]["b"], b[i]);
    EXPECT_EQ(lines[i]["blocker"], blocker[i]);
    EXPECT_EQ(lines[i]["t_ns"].get<std::int64_t>(), kT0 + t_ms[i] * kMs);
    EXPECT_TRUE(lines[i]["time"].is_string());
  }
}

TEST(SequencerEngine, CalibrationWaitsForTheOperatorWithLasersOff) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kCalibration, 3, ""}).ok());
  EXPECT_FALSE(h.seq_->NextSlice().ok());  // not waiting yet
  for (int slice = 0; slice < 3; ++slice) {
    h.RunToEnd();
    if (slice < 2) {
      EXPECT_EQ(h.seq_->GetStatus().state, SequencerState::kWaitingOperator);
      EXPECT_EQ(h.seq_->NextDeadlineNs(), Sequencer::kNoDeadline);
      EXPECT_FALSE(h.seq_->AnyLaserOn());
      EXPECT_FALSE(h.seq_->SetLaser(LineRole::kLaserA, true, 10).ok());
      h.clock_->AdvanceNs(5000 * kMs);  // the operator takes 5 s
      ASSERT_TRUE(h.seq_->NextSlice().ok());
    }
  }
  EXPECT_EQ(h.seq_->GetStatus().state, SequencerState::kIdle);
  EXPECT_EQ(h.seq_->GetStatus().frames, 12);
  int waiting = 0;
  for (const SequencerEvent& e : h.seq_->TakeEvents()) waiting += e.type == EventType::kWaitingOperator;
  EXPECT_EQ(waiting, 2);
  std::ifstream in(Harness::MetadataPath());
  int n = 0;
  for (std::string line; std::getline(in, line); ++n) EXPECT_EQ(nlohmann::json::parse(line)["slice"], n / 4);
  EXPECT_EQ(n, 12);
}

TEST(SequencerEngine, ManualLaserGoesOffAtItsLimit) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  EXPECT_FALSE(h.seq_->SetLaser(LineRole::kLaserA, true, 501).ok());  // > max_laser_on
  EXPECT_FALSE(h.seq_->SetLaser(LineRole::kLaserA, true, 0).ok());
  EXPECT_FALSE(h.AllOff() && h.seq_->AnyLaserOn());
  ASSERT_TRUE(h.seq_->SetLaser(LineRole::kLaserA, true, 100).ok());
  EXPECT_EQ(h.seq_->NextDeadlineNs(), kT0 + 100 * kMs);
  h.clock_->SetNs(kT0 + 100 * kMs - 1);
  h.seq_->OnTime();
  EXPECT_TRUE(h.seq_->AnyLaserOn());
  h.clock_->SetNs(kT0 + 100 * kMs);
  h.seq_->OnTime();
  EXPECT_FALSE(h.seq_->AnyLaserOn());
  const std::vector<SequencerEvent> ev = h.seq_->TakeEvents();
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].type, EventType::kLaserOff);
  EXPECT_EQ(ev[0].laser, "a");
  EXPECT_EQ(ev[0].message, "limit");
}

TEST(SequencerEngine, RenewedLaserOnCannotExceedMaxLaserOn) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->SetLaser(LineRole::kLaserB, true, 400).ok());
  h.clock_->SetNs(kT0 + 300 * kMs);
  ASSERT_TRUE(h.seq_->SetLaser(LineRole::kLaserB, true, 400).ok());
  EXPECT_EQ(h.seq_->NextDeadlineNs(), kT0 + 500 * kMs);  // not 700
  h.RunToEnd();
  EXPECT_FALSE(h.seq_->AnyLaserOn());
  EXPECT_EQ(h.clock_->NowNs(), kT0 + 500 * kMs);
}

TEST(SequencerEngine, LateTimerCutsTheLaserAtItsDeadlineBeforeTriggering) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  h.clock_->SetNs(kT0 + 10000 * kMs);  // the loop stalled for 10 s
  h.seq_->OnTime();
  EXPECT_TRUE(h.AllOff());
  EXPECT_EQ(h.seq_->GetStatus().state, SequencerState::kIdle);
  for (const Change& c : h.Changes()) EXPECT_FALSE(c.name == "trigger") << c;
  const std::vector<EventType> ev = h.EventTypes();
  ASSERT_FALSE(ev.empty());
  EXPECT_EQ(ev.front(), EventType::kAborted);
}

TEST(SequencerEngine, GpioErrorDrivesEverythingOffAndFaults) {
  Harness h(/*fail_write_number=*/3);  // writes: blocker, laser_a, trigger <- fails
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  EXPECT_TRUE(h.seq_->AnyLaserOn());
  h.RunToEnd();
  EXPECT_TRUE(h.seq_->faulted());
  EXPECT_TRUE(h.AllOff());
  EXPECT_FALSE(h.seq_->AnyLaserOn());
  EXPECT_NE(h.seq_->GetStatus().last_error.find("injected failure of write 3"), std::string::npos);
  const std::vector<EventType> ev = h.EventTypes();
  ASSERT_GE(ev.size(), 2u);
  EXPECT_EQ(ev[0], EventType::kGpioError);
  EXPECT_EQ(ev[1], EventType::kAborted);
  EXPECT_FALSE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  EXPECT_FALSE(h.seq_->SetLaser(LineRole::kLaserA, true, 10).ok());
}

TEST(SequencerEngine, GpioErrorInsideStartIsReturned) {
  Harness h(/*fail_write_number=*/2);  // writes: blocker, laser_a <- fails
  ASSERT_TRUE(h.seq_->Init().ok());
  EXPECT_EQ(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).code(), StatusCode::kGpioError);
  EXPECT_TRUE(h.seq_->faulted());
  EXPECT_TRUE(h.AllOff());
}

TEST(SequencerEngine, AbortMidFrameSwitchesEverythingOff) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  h.clock_->SetNs(kT0 + 55 * kMs);
  h.seq_->OnTime();  // trigger asserted, laser A and blocker active
  EXPECT_TRUE(h.sim_->IsActive(3));
  ASSERT_TRUE(h.seq_->Abort("test").ok());
  EXPECT_TRUE(h.AllOff());
  EXPECT_EQ(h.seq_->NextDeadlineNs(), Sequencer::kNoDeadline);
  EXPECT_EQ(h.seq_->GetStatus().last_error, "test");
}

TEST(SequencerEngine, ManualAndSequenceExcludeEachOther) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->SetLaser(LineRole::kLaserA, true, 100).ok());
  EXPECT_EQ(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(h.seq_->SetLaser(LineRole::kLaserA, false, 0).ok());
  ASSERT_TRUE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  EXPECT_FALSE(h.seq_->SetBlocker(true).ok());
  EXPECT_FALSE(h.seq_->Trigger("").ok());
  EXPECT_FALSE(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).ok());
  // "Laser off" is always accepted; during a sequence it aborts it.
  ASSERT_TRUE(h.seq_->SetLaser(LineRole::kLaserB, false, 0).ok());
  EXPECT_EQ(h.seq_->GetStatus().state, SequencerState::kIdle);
  EXPECT_TRUE(h.AllOff());
}

TEST(SequencerEngine, ManualTriggerPulsesAndWritesMetadata) {
  Harness h;
  ASSERT_TRUE(h.seq_->Init().ok());
  ASSERT_TRUE(h.seq_->SetBlocker(true).ok());
  ASSERT_TRUE(h.seq_->Trigger("").ok());
  EXPECT_TRUE(h.sim_->IsActive(3));
  EXPECT_EQ(h.seq_->NextDeadlineNs(), kT0 + 10 * kMs);
  h.RunToEnd();
  EXPECT_FALSE(h.sim_->IsActive(3));
  std::ifstream in(Harness::MetadataPath());
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  const nlohmann::json j = nlohmann::json::parse(line);
  EXPECT_EQ(j["sequence"], "manual");
  EXPECT_EQ(j["blocker"], "closed");
  EXPECT_TRUE(j["slice"].is_null());
}

TEST(SequencerEngine, StartNeedsAMetadataFile) {
  Harness h(0, TestConfig(""));
  ASSERT_TRUE(h.seq_->Init().ok());
  EXPECT_EQ(h.seq_->Start({SequenceKind::kMeasurement, 1, ""}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(h.seq_->Start({SequenceKind::kMeasurement, 1, "/nonexistent-dir/x.jsonl"}).code(), StatusCode::kIoError);
  EXPECT_EQ(h.seq_->Start({SequenceKind::kCalibration, 0, Harness::MetadataPath()}).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(h.AllOff());
}

TEST(SequencerEngine, DestructorDrivesEveryLineOff) {
  auto clock = std::make_shared<ManualClock>(kT0);
  auto chip = SimChip::Open({}, clock);
  SimChip* sim = chip.value().get();
  std::shared_ptr<SimChip> keep;  // the chip dies with the sequencer; read its log via a file instead
  SimChipOptions o;
  o.log_path = "/tmp/opl_engine_dtor_" + std::to_string(::getpid()) + ".jsonl";
  auto logged = SimChip::Open(o, clock);
  (void)sim;
  {
    Sequencer s(TestConfig(Harness::MetadataPath()), std::move(logged).value(), clock);
    ASSERT_TRUE(s.Init().ok());
    ASSERT_TRUE(s.SetLaser(LineRole::kLaserA, true, 100).ok());
  }
  auto events = ReadSimLog(o.log_path);
  ASSERT_TRUE(events.ok());
  ASSERT_FALSE(events.value().empty());
  std::map<std::string, bool> last;
  for (const SimLineEvent& e : events.value()) last[e.name] = e.active;
  EXPECT_FALSE(last["laser_a"]);
  EXPECT_FALSE(last["laser_b"]);
  std::remove(o.log_path.c_str());
}

}  // namespace
}  // namespace opl::sequencer
