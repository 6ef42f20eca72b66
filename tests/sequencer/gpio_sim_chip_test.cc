// SimChip: records every write with the injected clock, applies active-low,
// appends JSON lines that ReadSimLog reads back, and injects one failure.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "opl/sequencer/sim_chip.h"

namespace opl::sequencer {
namespace {

std::vector<GpioLineSpec> FourLines() {
  return {{3, false, "laser_a"}, {4, false, "laser_b"}, {5, false, "blocker"}, {6, true, "trigger"}};
}

std::string TempPath(const std::string& name) {
  return "/tmp/opl_sim_chip_test_" + std::to_string(::getpid()) + "_" + name;
}

TEST(SimChip, RequestDrivesEveryLineInactiveAndRecordsIt) {
  auto clock = std::make_shared<ManualClock>(1000);
  auto chip = SimChip::Open({}, clock);
  ASSERT_TRUE(chip.ok()) << chip.status().ToString();
  ASSERT_TRUE(chip.value()->RequestOutputs(FourLines(), "test").ok());
  const auto& ev = chip.value()->events();
  ASSERT_EQ(ev.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_FALSE(ev[i].active);
    EXPECT_EQ(ev[i].t_ns, 1000);
    EXPECT_FALSE(chip.value()->IsActive(i));
  }
  // Active-low trigger: inactive is the high level.
  EXPECT_EQ(ev[3].value, 1);
  EXPECT_EQ(ev[0].value, 0);
}

TEST(SimChip, RecordsEachWriteWithTheClockAndActiveLow) {
  auto clock = std::make_shared<ManualClock>(0);
  auto chip = SimChip::Open({}, clock);
  ASSERT_TRUE(chip.ok());
  SimChip& c = *chip.value();
  ASSERT_TRUE(c.RequestOutputs(FourLines(), "test").ok());
  clock->SetNs(5000);
  ASSERT_TRUE(c.SetActive(0, true).ok());
  clock->SetNs(7500);
  ASSERT_TRUE(c.SetActive(3, true).ok());
  ASSERT_EQ(c.events().size(), 6u);
  EXPECT_EQ(c.events()[4].t_ns, 5000);
  EXPECT_EQ(c.events()[4].offset, 3u);
  EXPECT_TRUE(c.events()[4].active);
  EXPECT_EQ(c.events()[4].value, 1);
  EXPECT_EQ(c.events()[5].t_ns, 7500);
  EXPECT_EQ(c.events()[5].name, "trigger");
  EXPECT_EQ(c.events()[5].value, 0);  // active-low asserted = low
  EXPECT_TRUE(c.IsActive(0));
  EXPECT_FALSE(c.SetActive(4, true).ok());  // no such index
}

TEST(SimChip, LogFileRoundTrips) {
  const std::string path = TempPath("log.jsonl");
  auto clock = std::make_shared<ManualClock>(42);
  {
    SimChipOptions o;
    o.log_path = path;
    auto chip = SimChip::Open(o, clock);
    ASSERT_TRUE(chip.ok()) << chip.status().ToString();
    ASSERT_TRUE(chip.value()->RequestOutputs(FourLines(), "test").ok());
    clock->SetNs(99);
    ASSERT_TRUE(chip.value()->SetActive(1, true).ok());
  }
  // A partial last line (writer killed mid-write) is ignored.
  { std::ofstream(path, std::ios::app) << "{\"t_ns\":1"; }
  auto events = ReadSimLog(path);
  ASSERT_TRUE(events.ok()) << events.status().ToString();
  ASSERT_EQ(events.value().size(), 5u);
  EXPECT_EQ(events.value()[4].t_ns, 99);
  EXPECT_EQ(events.value()[4].offset, 4u);
  EXPECT_EQ(events.value()[4].name, "laser_b");
  EXPECT_TRUE(events.value()[4].active);
  std::remove(path.c_str());
}

TEST(SimChip, InjectedFailureHitsExactlyTheNthWrite) {
  auto clock = std::make_shared<ManualClock>(0);
  SimChipOptions o;
  o.fail_write_number = 2;
  auto chip = SimChip::Open(o, clock);
  ASSERT_TRUE(chip.ok());
  SimChip& c = *chip.value();
  ASSERT_TRUE(c.RequestOutputs(FourLines(), "test").ok());
  EXPECT_TRUE(c.SetActive(0, true).ok());
  Status s = c.SetActive(1, true);
  EXPECT_EQ(s.code(), StatusCode::kGpioError);
  EXPECT_FALSE(c.IsActive(1));  // a failed write changes nothing
  EXPECT_TRUE(c.SetActive(1, true).ok());
  EXPECT_TRUE(c.IsActive(1));
}

TEST(SimChip, RejectsOffsetsBeyondTheChipAndDuplicates) {
  auto clock = std::make_shared<ManualClock>(0);
  SimChipOptions o;
  o.num_lines = 8;
  auto chip = SimChip::Open(o, clock);
  ASSERT_TRUE(chip.ok());
  EXPECT_EQ(chip.value()->RequestOutputs({{8, false, "laser_a"}}, "t").code(), StatusCode::kNotFound);
  EXPECT_FALSE(chip.value()->RequestOutputs({{1, false, "a"}, {1, false, "b"}}, "t").ok());
  EXPECT_TRUE(chip.value()->events().empty());
}

TEST(SimChip, UnwritableLogIsAnError) {
  SimChipOptions o;
  o.log_path = "/nonexistent-dir/opl/sim.jsonl";
  auto chip = SimChip::Open(o, std::make_shared<ManualClock>(0));
  EXPECT_EQ(chip.status().code(), StatusCode::kIoError);
}

}  // namespace
}  // namespace opl::sequencer
