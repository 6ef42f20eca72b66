// Integration and fuzz tests of the real opl_sequencer daemon, run as a child
// process with the simulated chip ("backend": "sim"). The sim chip appends
// every line write to a JSON-lines file with CLOCK_MONOTONIC timestamps,
// which this process reads with the same clock.
//
// Timing tolerance: an action may be late, never early. Durations are
// asserted within [configured - 0.5 ms, configured + 50 ms] (the -0.5 ms is
// the gap between the daemon's clock read and the sim chip's timestamp of
// the same write; +50 ms because on a 2-core machine with 4 busy processes
// the daemon's wake-ups were measured up to 26 ms late, while on an idle
// machine they are < 4 ms late); the order of line changes is asserted
// exactly. The 100 ms laser-off requirement is asserted as such. On top of
// both, an assertion allows the host's own stall over the same interval
// (HostStallMonitor): on a shared virtual machine a vCPU can be stopped for
// tens of ms (7-26 % CPU steal measured on the build machine, where 3 of 7
// runs failed by 118 ms of lateness or 193 ms of laser-off latency), which
// no daemon can help.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/sequencer/clock.h"
#include "opl/sequencer/daemon.h"
#include "opl/sequencer/sim_chip.h"

#include "daemon_harness.h"

namespace opl::sequencer {
namespace {

using namespace opl::sequencer::testing;  // NOLINT(build/namespaces)
using json = nlohmann::json;
constexpr double kLateToleranceMs = 50.0;
constexpr double kEarlyToleranceMs = 0.5;
constexpr std::int64_t kLaserOffRequirementNs = 100 * kMs;

// ---------------------------------------------------------------------------

TEST(SequencerDaemon, MeasurementOrderTimingsAndMetadata) {
  HostStallMonitor host;
  TempDir dir;
  const json timings = {{"laser_warmup", 30}, {"blocker_settle", 50}, {"trigger_pulse", 10}, {"exposure", 30}, {"max_laser_on", 500}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  // Every line driven inactive at start.
  const std::vector<SimLineEvent> start_log = d.SimLog();
  ASSERT_EQ(start_log.size(), 4u);
  for (const SimLineEvent& e : start_log) EXPECT_FALSE(e.active) << e.name;

  auto c = Conn::Connect(d.socket());
  ASSERT_TRUE(c);
  const json reply = c->Request({{"cmd", "start"}, {"sequence", "measurement"}, {"id", "m1"}});
  ASSERT_TRUE(reply.value("ok", false)) << reply.dump();
  EXPECT_EQ(reply["id"], "m1");
  ASSERT_TRUE(c->WaitEvent("done", 5000)) << d.log();
  int frames = 0;
  for (const json& e : c->seen()) frames += e["event"] == "frame";
  EXPECT_EQ(frames, 4);

  const std::vector<Change> ch = Changes(d.SimLog());
  const std::vector<std::pair<std::string, bool>> expected = {
      {"blocker", true},  {"laser_a", true},  {"trigger", true},  {"trigger", false}, {"laser_a", false},  // grid_a
      {"blocker", false}, {"laser_b", true},  {"trigger", true},  {"trigger", false}, {"laser_b", false},  // grid_b
      {"laser_a", true},  {"laser_b", true},  {"trigger", true},  {"trigger", false},                      // both
      {"laser_a", false}, {"laser_b", false}, {"trigger", true},  {"trigger", false}};                     // dark
  ASSERT_EQ(ch.size(), expected.size());
  for (std::size_t i = 0; i < ch.size(); ++i) {
    EXPECT_EQ(ch[i].name, expected[i].first) << "change " << i;
    EXPECT_EQ(ch[i].active, expected[i].second) << "change " << i;
  }
  // Durations: (from change, to change, configured ms).
  struct Span {
    int from, to;
    double ms;
    const char* what;
  };
  const Span spans[] = {
      {0, 2, 50, "grid_a blocker -> trigger (settle)"}, {1, 2, 50, "grid_a laser on -> trigger (max(settle, warm-up))"},
      {2, 3, 10, "grid_a pulse"},                       {2, 4, 30, "grid_a exposure"},
      {5, 7, 50, "grid_b blocker -> trigger (settle)"}, {7, 8, 10, "grid_b pulse"},
      {7, 9, 30, "grid_b exposure"},                    {11, 12, 30, "both laser on -> trigger (warm-up)"},
      {12, 13, 10, "both pulse"},                       {12, 15, 30, "both exposure"},
      {15, 16, 0, "dark: no wait"},                     {16, 17, 10, "dark pulse"},
  };
  double worst_late_ms = 0.0;
  for (const Span& s : spans) {
    const std::int64_t from_ns = ch[static_cast<std::size_t>(s.from)].t_ns;
    const std::int64_t to_ns = ch[static_cast<std::size_t>(s.to)].t_ns;
    const double got = Ms(to_ns - from_ns);
    const double stall = host.WorstMs(from_ns, to_ns);
    EXPECT_GE(got, s.ms - kEarlyToleranceMs) << s.what;
    EXPECT_LE(got, s.ms + kLateToleranceMs + stall) << s.what << " (host stall " << stall << " ms)";
    worst_late_ms = std::max(worst_late_ms, got - s.ms);
    if (std::getenv("OPL_VERBOSE_TIMING") != nullptr) std::cout << "  " << s.what << ": " << got << " ms\n";
  }
  std::cout << "[ timing   ] worst lateness over " << std::size(spans) << " spans: " << worst_late_ms << " ms\n";
  ::testing::Test::RecordProperty("worst_lateness_us", static_cast<int>(worst_late_ms * 1000));

  // Metadata: one line per trigger, matching the lines' state.
  std::ifstream in(dir.File("frames.jsonl"));
  std::vector<json> meta;
  for (std::string line; std::getline(in, line);) meta.push_back(json::parse(line));
  ASSERT_EQ(meta.size(), 4u);
  const int trigger_change[] = {2, 7, 12, 16};
  const char* steps[] = {"grid_a", "grid_b", "both", "dark"};
  const bool la[] = {true, false, true, false}, lb[] = {false, true, true, false};
  const char* blocker[] = {"closed", "open", "open", "open"};
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(meta[i]["sequence"], "measurement");
    EXPECT_EQ(meta[i]["step"], steps[i]);
    EXPECT_EQ(meta[i]["frame"], static_cast<int>(i));
    EXPECT_EQ(meta[i]["lasers"]["a"], la[i]);
    EXPECT_EQ(meta[i]["lasers"]["b"], lb[i]);
    EXPECT_EQ(meta[i]["blocker"], blocker[i]);
    const std::int64_t dt = ch[static_cast<std::size_t>(trigger_change[i])].t_ns - meta[i]["t_ns"].get<std::int64_t>();
    EXPECT_GE(dt, 0) << "metadata time after the trigger edge";
    EXPECT_LT(dt, 1 * kMs) << "metadata time vs trigger edge";
  }
  EXPECT_TRUE(LasersOff(d.FinalState()));
  ::kill(d.pid(), SIGTERM);
  EXPECT_EQ(d.Exit(3000), 0);
}

TEST(SequencerDaemon, ClientKilledMidSequenceLeavesEveryLaserOffWithin100ms) {
  HostStallMonitor host;
  TempDir dir;
  const json timings = {{"laser_warmup", 300}, {"blocker_settle", 10}, {"trigger_pulse", 5}, {"exposure", 20}, {"max_laser_on", 1000}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  std::vector<double> latencies_ms;
  for (int rep = 0; rep < 6; ++rep) {
    const std::int64_t t_start = NowNs();
    const pid_t client = Spawn({"client", "-s", d.socket(), "start", "measurement", "--no-stdin"},
                               dir.File("client" + std::to_string(rep) + ".log"));
    // Kill during grid_a (laser A on) or grid_b (laser B on).
    const std::string laser = rep % 2 == 0 ? "laser_a" : "laser_b";
    const std::int64_t t_on = d.WaitLine(laser, true, t_start, 5000);
    ASSERT_GT(t_on, 0) << d.log() << ReadText(dir.File("client" + std::to_string(rep) + ".log"));
    SleepMs(20);
    const std::int64_t t_kill = NowNs();
    ASSERT_EQ(::kill(client, SIGKILL), 0);
    EXPECT_EQ(WaitExit(client, 2000), -SIGKILL);
    const std::int64_t t_off = d.WaitLine(laser, false, t_on, 2000);
    ASSERT_GT(t_off, 0);
    latencies_ms.push_back(Ms(t_off - t_kill));
    const double stall = host.WorstMs(t_kill, t_off);
    EXPECT_LT(Ms(t_off - t_kill), Ms(kLaserOffRequirementNs) + stall)
        << "laser off " << Ms(t_off - t_kill) << " ms after the client was killed (host stall " << stall
        << " ms)";
    EXPECT_TRUE(LasersOff(d.FinalState()));
    auto c = Conn::Connect(d.socket());
    ASSERT_TRUE(c);
    const json s = c->Request({{"cmd", "status"}});
    EXPECT_EQ(s["state"], "idle");
    EXPECT_EQ(s["lasers"]["a"], false);
    EXPECT_EQ(s["lasers"]["b"], false);
    EXPECT_NE(s["last_error"].get<std::string>().find("disconnected"), std::string::npos) << s.dump();
  }
  const double worst = *std::max_element(latencies_ms.begin(), latencies_ms.end());
  std::cout << "[ latency  ] laser off after client SIGKILL, ms:";
  for (double l : latencies_ms) std::cout << " " << l;
  std::cout << " (worst " << worst << ")\n";
  ::testing::Test::RecordProperty("worst_client_kill_latency_us", static_cast<int>(worst * 1000));
  EXPECT_TRUE(d.Alive());
}

class SequencerDaemonSignal : public ::testing::TestWithParam<int> {};

TEST_P(SequencerDaemonSignal, LeavesEveryLaserOffAndExitsCleanly) {
  const int sig = GetParam();
  HostStallMonitor host;
  TempDir dir;
  const json timings = {{"laser_warmup", 300}, {"blocker_settle", 10}, {"trigger_pulse", 5}, {"exposure", 20}, {"max_laser_on", 1000}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto c = Conn::Connect(d.socket());
  ASSERT_TRUE(c);
  ASSERT_TRUE(c->Request({{"cmd", "start"}, {"sequence", "measurement"}})["ok"].get<bool>());
  const std::int64_t t_on = d.WaitLine("laser_a", true, 0, 3000);
  ASSERT_GT(t_on, 0);
  SleepMs(20);
  const std::int64_t t_sig = NowNs();
  ASSERT_EQ(::kill(d.pid(), sig), 0);
  EXPECT_EQ(d.Exit(3000), 0) << "exit status after " << strsignal(sig);
  const std::int64_t t_off = d.WaitLine("laser_a", false, t_on, 1000);
  ASSERT_GT(t_off, 0);
  EXPECT_LT(Ms(t_off - t_sig), Ms(kLaserOffRequirementNs) + host.WorstMs(t_sig, t_off))
      << "host stall " << host.WorstMs(t_sig, t_off) << " ms";
  std::cout << "[ latency  ] laser off after " << strsignal(sig) << ": " << Ms(t_off - t_sig) << " ms\n";
  const auto final_state = d.FinalState();
  for (const auto& [name, active] : final_state) EXPECT_FALSE(active) << name;
  // The client was told, then the connection closed; the socket is gone.
  EXPECT_TRUE(c->WaitEvent("aborted", 1000));
  EXPECT_TRUE(c->WaitEvent("shutdown", 1000));
  struct stat st{};
  EXPECT_NE(::stat(d.socket().c_str(), &st), 0);
}

INSTANTIATE_TEST_SUITE_P(Sequencer, SequencerDaemonSignal, ::testing::Values(SIGTERM, SIGINT, SIGHUP),
                         [](const ::testing::TestParamInfo<int>& param_info) {
                           const int s = param_info.param;
                           return std::string(s == SIGTERM ? "SIGTERM" : s == SIGINT ? "SIGINT" : "SIGHUP");
                         });

TEST(SequencerDaemon, LaserHeldPastItsLimitIsSwitchedOff) {
  HostStallMonitor host;
  TempDir dir;
  const json timings = {{"laser_warmup", 10}, {"blocker_settle", 10}, {"trigger_pulse", 5}, {"exposure", 20}, {"max_laser_on", 200}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto c = Conn::Connect(d.socket());
  ASSERT_TRUE(c);
  // Over the configured maximum: refused, nothing switched on.
  json r = c->Request({{"cmd", "laser"}, {"laser", "a"}, {"on", true}, {"limit_ms", 250}});
  EXPECT_FALSE(r["ok"].get<bool>());
  EXPECT_TRUE(Changes(d.SimLog()).empty());
  // Without a limit: refused.
  EXPECT_FALSE(c->Request({{"cmd", "laser"}, {"laser", "a"}, {"on", true}})["ok"].get<bool>());

  r = c->Request({{"cmd", "laser"}, {"laser", "a"}, {"on", true}, {"limit_ms", 80}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  auto ev = c->WaitEvent("laser_off", 2000);
  ASSERT_TRUE(ev);
  EXPECT_EQ((*ev)["laser"], "a");
  EXPECT_EQ((*ev)["message"], "limit");
  std::vector<Change> ch = Changes(d.SimLog());
  ASSERT_EQ(ch.size(), 2u);
  const double on_ms = Ms(ch[1].t_ns - ch[0].t_ns);
  EXPECT_GE(on_ms, 80 - kEarlyToleranceMs);
  EXPECT_LE(on_ms, 80 + kLateToleranceMs + host.WorstMs(ch[0].t_ns, ch[1].t_ns));
  std::cout << "[ timing   ] manual laser with an 80 ms limit was on for " << on_ms << " ms\n";

  // Renewing "on" cannot stretch continuous light past max_laser_on (200 ms):
  // renewed after 60 ms for 190 ms more, it still goes off at 200 ms. (The
  // renewal must arrive before the first 190 ms run out: a host stall of
  // over 130 ms in between would break that premise, and is reported.)
  ASSERT_TRUE(c->Request({{"cmd", "laser"}, {"laser", "b"}, {"on", true}, {"limit_ms", 190}})["ok"].get<bool>());
  const std::int64_t t_first_on = NowNs();
  SleepMs(60);
  ASSERT_TRUE(c->Request({{"cmd", "laser"}, {"laser", "b"}, {"on", true}, {"limit_ms", 190}})["ok"].get<bool>());
  const std::int64_t t_renewed = NowNs();
  ASSERT_TRUE(c->WaitEvent("laser_off", 2000));
  ch = Changes(d.SimLog());
  ASSERT_EQ(ch.size(), 4u) << "host stall between the first request and the renewal: "
                           << host.WorstMs(t_first_on, t_renewed) << " ms";
  EXPECT_EQ(ch[3].name, "laser_b");
  const double b_ms = Ms(ch[3].t_ns - ch[2].t_ns);
  EXPECT_GE(b_ms, 200 - kEarlyToleranceMs);
  EXPECT_LE(b_ms, 200 + kLateToleranceMs + host.WorstMs(ch[2].t_ns, ch[3].t_ns));

  // The owner of a manual laser disconnects: off within 100 ms.
  ASSERT_TRUE(c->Request({{"cmd", "laser"}, {"laser", "a"}, {"on", true}, {"limit_ms", 190}})["ok"].get<bool>());
  const std::int64_t t_on = d.WaitLine("laser_a", true, ch[3].t_ns, 1000);
  ASSERT_GT(t_on, 0);
  const std::int64_t t_close = NowNs();
  c->Close();
  const std::int64_t t_off = d.WaitLine("laser_a", false, t_on, 1000);
  ASSERT_GT(t_off, 0);
  EXPECT_LT(Ms(t_off - t_close), Ms(kLaserOffRequirementNs) + host.WorstMs(t_close, t_off));
  EXPECT_LT(t_off - t_on, 150 * kMs) << "switched off by the disconnect, not by its 190 ms limit";
  EXPECT_TRUE(d.Alive());
}

TEST(SequencerDaemon, CalibrationWaitsForNextSliceFromAnotherClient) {
  TempDir dir;
  // A frame keeps a laser on ~10 ms. This test checks the flow, not the
  // on-time limit (LaserHeldPastItsLimitIsSwitchedOff does): a limit far
  // above a frame keeps a stall of the shared host from aborting the run
  // (a 100 ms limit did, once: "laser a reached its on-time limit").
  const json timings = {{"laser_warmup", 5}, {"blocker_settle", 5}, {"trigger_pulse", 1}, {"exposure", 5}, {"max_laser_on", 2000}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto owner = Conn::Connect(d.socket());
  ASSERT_TRUE(owner);
  const std::string meta = dir.File("calib.jsonl");
  ASSERT_TRUE(owner->Request({{"cmd", "start"}, {"sequence", "calibration"}, {"slices", 2}, {"metadata", meta}})["ok"].get<bool>());
  auto wait = owner->WaitEvent("waiting_operator", 3000);
  ASSERT_TRUE(wait);
  EXPECT_EQ((*wait)["slice"], 1);
  auto op = Conn::Connect(d.socket());
  ASSERT_TRUE(op);
  json s = op->Request({{"cmd", "status"}});
  EXPECT_EQ(s["state"], "waiting_operator");
  EXPECT_EQ(s["lasers"]["a"], false);
  EXPECT_EQ(s["lasers"]["b"], false);
  SleepMs(150);  // nothing may be on while waiting (the 2 s limit would not cut it yet)
  EXPECT_TRUE(LasersOff(d.FinalState()));
  ASSERT_TRUE(op->Request({{"cmd", "next_slice"}})["ok"].get<bool>());
  ASSERT_TRUE(owner->WaitEvent("done", 3000));
  std::ifstream in(meta);
  int n = 0;
  for (std::string line; std::getline(in, line); ++n) EXPECT_EQ(json::parse(line)["slice"], n / 4);
  EXPECT_EQ(n, 8);
}

TEST(SequencerDaemon, OwnerDisconnectWhileWaitingForTheOperatorAbortsTheCalibration) {
  TempDir dir;
  const json timings = {{"laser_warmup", 5}, {"blocker_settle", 5}, {"trigger_pulse", 1}, {"exposure", 5}, {"max_laser_on", 100}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto owner = Conn::Connect(d.socket());
  auto other = Conn::Connect(d.socket());
  ASSERT_TRUE(owner && other);
  ASSERT_TRUE(owner->Request({{"cmd", "start"}, {"sequence", "calibration"}, {"slices", 3}})["ok"].get<bool>());
  ASSERT_TRUE(owner->WaitEvent("waiting_operator", 3000));
  other->Close();  // not the owner: nothing happens
  SleepMs(20);
  auto check = Conn::Connect(d.socket());
  ASSERT_TRUE(check);
  EXPECT_EQ(check->Request({{"cmd", "status"}})["state"], "waiting_operator");
  owner->Close();
  SleepMs(50);
  const json s = check->Request({{"cmd", "status"}});
  EXPECT_EQ(s["state"], "idle");
  EXPECT_NE(s["last_error"].get<std::string>().find("disconnected"), std::string::npos) << s.dump();
  EXPECT_FALSE(check->Request({{"cmd", "next_slice"}})["ok"].get<bool>());
  EXPECT_TRUE(LasersOff(d.FinalState()));
}

TEST(SequencerDaemon, CliClientRunsAMeasurementAndReportsExitCodes) {
  TempDir dir;
  // A frame keeps a laser on ~10 ms. This test checks the flow, not the
  // on-time limit (LaserHeldPastItsLimitIsSwitchedOff does): a limit far
  // above a frame keeps a stall of the shared host from aborting the run
  // (a 100 ms limit did, once: "laser a reached its on-time limit").
  const json timings = {{"laser_warmup", 5}, {"blocker_settle", 5}, {"trigger_pulse", 1}, {"exposure", 5}, {"max_laser_on", 2000}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  pid_t p = Spawn({"client", "-s", d.socket(), "start", "measurement", "--no-stdin"}, dir.File("cli1.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitOk) << ReadText(dir.File("cli1.log"));
  EXPECT_NE(ReadText(dir.File("cli1.log")).find("\"event\":\"done\""), std::string::npos);
  p = Spawn({"client", "-s", d.socket(), "next-slice"}, dir.File("cli2.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitRefused);
  p = Spawn({"client", "-s", d.socket(), "laser", "b", "on", "--limit-ms", "30"}, dir.File("cli3.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitOk) << ReadText(dir.File("cli3.log"));
  p = Spawn({"client", "-s", dir.File("nothing.sock"), "status"}, dir.File("cli4.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitNoDaemon);
  p = Spawn({"client", "-s", d.socket(), "laser", "c", "on"}, dir.File("cli5.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitUsage);
  EXPECT_TRUE(LasersOff(d.FinalState()));
}

TEST(SequencerDaemon, GpioErrorDrivesLinesOffAndExitsWithCode6) {
  TempDir dir;
  const json timings = {{"laser_warmup", 30}, {"blocker_settle", 10}, {"trigger_pulse", 5}, {"exposure", 20}, {"max_laser_on", 500}};
  json config = BaseConfig(dir, timings);
  config["gpio"]["sim_fail_write_number"] = 3;  // blocker, laser_a, trigger <- fails with laser A on
  DaemonProcess d(dir, config);
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto c = Conn::Connect(d.socket());
  ASSERT_TRUE(c);
  ASSERT_TRUE(c->Request({{"cmd", "start"}, {"sequence", "measurement"}})["ok"].get<bool>());
  EXPECT_TRUE(c->WaitEvent("gpio_error", 3000));
  EXPECT_EQ(d.Exit(3000), kExitGpioRuntime);
  const auto final_state = d.FinalState();
  for (const auto& [name, active] : final_state) EXPECT_FALSE(active) << name;
  const std::vector<Change> ch = Changes(d.SimLog());
  ASSERT_GE(ch.size(), 3u);
  EXPECT_EQ(ch[1].name, "laser_a");
  EXPECT_TRUE(ch[1].active);
  for (const Change& x : ch) EXPECT_NE(x.name, "trigger") << "the failed trigger write changed nothing";
}

TEST(SequencerDaemon, StartUpErrorsHaveTheirExitCodes) {
  TempDir dir;
  const json timings = {{"laser_warmup", 5}, {"blocker_settle", 5}, {"trigger_pulse", 1}, {"exposure", 5}, {"max_laser_on", 100}};
  DaemonProcess first(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(first.WaitReady()) << first.log();
  // Same socket, another sim log: refused with kExitSocket, the first one unharmed.
  json second_config = BaseConfig(dir, timings);
  second_config["gpio"]["sim_log"] = dir.File("sim2.jsonl");
  DaemonProcess second(dir, second_config, "second");
  EXPECT_EQ(second.Exit(5000), kExitSocket) << second.log();
  EXPECT_NE(second.log().find("another daemon"), std::string::npos) << second.log();
  EXPECT_TRUE(first.Alive());
  auto c = Conn::Connect(first.socket());
  ASSERT_TRUE(c);
  EXPECT_TRUE(c->Request({{"cmd", "status"}})["ok"].get<bool>());
  // Invalid configuration.
  json bad = BaseConfig(dir, timings);
  bad["timings_ms"]["max_laser_on"] = 1;
  DaemonProcess third(dir, bad, "third");
  EXPECT_EQ(third.Exit(5000), kExitConfig) << third.log();
  EXPECT_NE(third.log().find("max_laser_on"), std::string::npos);
  // GPIO set-up: no such chip (libgpiod backend).
  json gpiod = BaseConfig(dir, timings);
  gpiod["gpio"] = {{"backend", "gpiod"}, {"chip", "opl-no-such-chip"}};
  gpiod["socket"] = dir.File("g.sock");
  DaemonProcess fourth(dir, gpiod, "fourth");
  EXPECT_EQ(fourth.Exit(5000), kExitGpioSetup) << fourth.log();
}

TEST(SequencerDaemon, NotifiesSystemdAndPingsTheWatchdogAtHalfItsPeriod) {
  TempDir dir;
  const std::string notify_path = dir.File("notify.sock");
  const int ns = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, notify_path.c_str(), sizeof addr.sun_path - 1);
  ASSERT_EQ(::bind(ns, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  const json timings = {{"laser_warmup", 5}, {"blocker_settle", 5}, {"trigger_pulse", 1}, {"exposure", 5}, {"max_laser_on", 100}};
  DaemonProcess d(dir, BaseConfig(dir, timings), "daemon", {"NOTIFY_SOCKET=" + notify_path, "WATCHDOG_USEC=100000"});
  int ready = 0, pings = 0, stopping = 0;
  std::int64_t first_ping = 0, last_ping = 0;
  auto drain = [&](int ms) {
    const std::int64_t end = NowNs() + ms * kMs;
    while (NowNs() < end) {
      pollfd p{ns, POLLIN, 0};
      if (::poll(&p, 1, 10) <= 0) continue;
      char buf[512];
      const ssize_t n = ::recv(ns, buf, sizeof buf, 0);
      if (n <= 0) continue;
      const std::string msg(buf, static_cast<std::size_t>(n));
      ready += msg.rfind("READY=1", 0) == 0;
      stopping += msg == "STOPPING=1";
      if (msg == "WATCHDOG=1") {
        if (pings++ == 0) first_ping = NowNs();
        last_ping = NowNs();
      }
    }
  };
  ASSERT_TRUE(d.WaitReady()) << d.log();
  drain(100);
  EXPECT_EQ(ready, 1);
  pings = 0;  // measure the cadence from here, nothing queued
  drain(600);
  // 100 ms watchdog: a ping every 50 ms.
  ASSERT_GE(pings, 6);
  const double period_ms = Ms(last_ping - first_ping) / (pings - 1);
  EXPECT_GT(period_ms, 45.0);
  EXPECT_LT(period_ms, 60.0);
  ::kill(d.pid(), SIGTERM);
  EXPECT_EQ(d.Exit(3000), 0);
  drain(50);
  EXPECT_EQ(stopping, 1);
  ::close(ns);
}

// ---------------------------------------------------------------------------
// Fuzz: at least 10000 seeded random / malformed / oversized messages.

std::string Dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

struct FuzzMessage {
  std::string bytes;       // without the trailing newline; never contains '\n'
  bool must_fail = false;  // the reply must be {"ok":false,...}
  long id = -1;            // "id" the reply must echo, -1 if none
};

class FuzzGenerator {
 public:
  FuzzGenerator(std::uint32_t seed, std::string metadata_path) : rng_(seed), metadata_(std::move(metadata_path)) {}

  FuzzMessage Next(long index) {
    const int kind = Uniform(0, 99);
    FuzzMessage m;
    if (kind < 20) {  // random bytes
      m.bytes = RandomBytes(Uniform(0, 300));
      m.must_fail = !LooksLikeObject(m.bytes);
    } else if (kind < 28) {  // valid JSON, not an object
      json v = json::array({RandomValue(2), RandomValue(1)});
      m.bytes = Uniform(0, 1) ? Dump(v) : Dump(RandomValue(2));
      if (!m.bytes.empty() && m.bytes[0] == '{') m.bytes = "[" + m.bytes + "]";
      m.must_fail = true;
    } else if (kind < 36) {  // object without a string "cmd"
      json o = RandomObject(3);
      o.erase("cmd");
      if (Uniform(0, 1)) o["cmd"] = RandomNonString();
      m.bytes = Dump(o);
      m.must_fail = true;
    } else if (kind < 44) {  // unknown command
      m.bytes = Dump(json{{"cmd", RandomString(12) + "_x"}, {"id", index}});
      m.id = index;
      m.must_fail = true;
    } else if (kind < 74) {  // known command, random fields and types
      json o = RandomCommand();
      if (Uniform(0, 1)) {
        o["id"] = index;
        m.id = index;
      }
      m.bytes = Dump(o);
    } else if (kind < 82) {  // truncated valid request
      const std::string full = Dump(RandomCommand());
      m.bytes = full.substr(0, static_cast<std::size_t>(Uniform(0, static_cast<int>(full.size()) - 1)));
      m.must_fail = true;
    } else if (kind < 86) {  // oversized
      const int n = Uniform(0, 9) == 0 ? Uniform(100000, 300000) : Uniform(4097, 20000);
      m.bytes = "{\"cmd\":\"status\",\"pad\":\"" + std::string(static_cast<std::size_t>(n), 'x') + "\"}";
      m.must_fail = true;
    } else if (kind < 90) {  // deep nesting
      const int depth = Uniform(100, 2000);
      m.bytes = std::string(static_cast<std::size_t>(depth), '[') + std::string(static_cast<std::size_t>(depth), ']');
      m.must_fail = true;
    } else if (kind < 94) {  // invalid UTF-8 in a string
      m.bytes = "{\"cmd\":\"status\",\"id\":\"\xff\xfe" + RandomBytes(5) + "\"}";
      m.must_fail = true;
    } else {  // number edge cases in a start / laser request
      static const char* kNumbers[] = {"1e400", "-1e400", "NaN", "Infinity", "-0", "1e-400", "18446744073709551616",
                                       "-9223372036854775809", "0.0000001", "99999999999999999999999"};
      const std::string num = kNumbers[Uniform(0, 9)];
      m.bytes = Uniform(0, 1) ? "{\"cmd\":\"start\",\"sequence\":\"calibration\",\"slices\":" + num + "}"
                              : "{\"cmd\":\"laser\",\"laser\":\"a\",\"on\":true,\"limit_ms\":" + num + "}";
    }
    return m;
  }

 private:
  int Uniform(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  static bool LooksLikeObject(const std::string& s) { return s.find('{') != std::string::npos; }
  std::string RandomBytes(int n) {
    std::string s;
    for (int i = 0; i < n; ++i) {
      char c = static_cast<char>(Uniform(0, 255));
      if (c == '\n') c = ' ';
      s.push_back(c);
    }
    return s;
  }
  std::string RandomString(int max_len) {
    static const char kChars[] = "abcdefghijklmnopqrstuvwxyz_\"\\/{}[]:, \t\x01\xc3\xa9";
    std::string s;
    const int n = Uniform(0, max_len);
    for (int i = 0; i < n; ++i) s.push_back(kChars[Uniform(0, static_cast<int>(sizeof kChars) - 2)]);
    return s;
  }
  json RandomNonString() {
    switch (Uniform(0, 5)) {
      case 0: return nullptr;
      case 1: return Uniform(0, 1) == 1;
      case 2: return Uniform(-1000000, 1000000);
      case 3: return std::uniform_real_distribution<double>(-1e6, 1e6)(rng_);
      case 4: return json::array({1, "a"});
      default: return json::object({{"k", 1}});
    }
  }
  json RandomValue(int depth) {
    const int k = Uniform(0, depth > 0 ? 7 : 5);
    if (k <= 4) return RandomNonString().is_structured() ? json(Uniform(0, 9)) : RandomNonString();
    if (k == 5) return RandomString(20);
    if (k == 6) {
      json a = json::array();
      for (int i = Uniform(0, 3); i > 0; --i) a.push_back(RandomValue(depth - 1));
      return a;
    }
    return RandomObject(depth - 1);
  }
  json RandomObject(int depth) {
    json o = json::object();
    for (int i = Uniform(0, 4); i > 0; --i) o[RandomString(8)] = RandomValue(depth);
    return o;
  }
  // A known command with fields that are sometimes right, sometimes not.
  // Metadata paths stay inside the test directory.
  json RandomCommand() {
    static const char* kCmds[] = {"status", "start", "abort", "next_slice", "laser", "blocker", "trigger", "subscribe"};
    const std::string cmd = kCmds[Uniform(0, 7)];
    json o = {{"cmd", cmd}};
    auto maybe = [&](const char* key, json good) {
      const int r = Uniform(0, 9);
      if (r < 6) {
        o[key] = std::move(good);
      } else if (r < 9) {
        o[key] = RandomNonString();
      }
    };
    if (cmd == "start") {
      static const char* kSeq[] = {"measurement", "calibration", "manual", ""};
      maybe("sequence", kSeq[Uniform(0, 3)]);
      maybe("slices", Uniform(-2, 4));
      maybe("metadata", metadata_);
    } else if (cmd == "laser") {
      static const char* kLaser[] = {"a", "b", "c", "A"};
      maybe("laser", kLaser[Uniform(0, 3)]);
      maybe("on", Uniform(0, 1) == 1);
      maybe("limit_ms", std::uniform_real_distribution<double>(-10, 120)(rng_));
    } else if (cmd == "blocker") {
      maybe("closed", Uniform(0, 1) == 1);
    } else if (cmd == "trigger") {
      maybe("metadata", metadata_);
    }
    if (Uniform(0, 19) == 0) o[RandomString(6) + "_extra"] = 1;  // unknown field
    return o;
  }

  std::mt19937 rng_;
  std::string metadata_;
};

TEST(SequencerDaemonFuzz, TenThousandSeededMessagesGetRepliesAndLeaveEverythingOff) {
  TempDir dir;
  const json timings = {{"laser_warmup", 2}, {"blocker_settle", 2}, {"trigger_pulse", 1}, {"exposure", 3}, {"max_laser_on", 120}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();

  constexpr int kMessages = 12000;
  FuzzGenerator gen(20261122u, dir.File("fuzz-meta.jsonl"));
  std::vector<FuzzMessage> messages;
  std::string wire;
  for (long i = 0; i < kMessages; ++i) {
    messages.push_back(gen.Next(i));
    wire += messages.back().bytes;
    wire += '\n';
  }
  // One line of 1 MiB as well.
  messages.push_back({std::string(1u << 20, 'z'), true, -1});
  wire += messages.back().bytes + "\n";

  auto c = Conn::Connect(d.socket());
  ASSERT_TRUE(c);
  ::fcntl(c->fd(), F_SETFL, ::fcntl(c->fd(), F_GETFL) | O_NONBLOCK);
  std::size_t sent = 0;
  std::string in;
  std::vector<json> replies;
  int events = 0;
  const std::int64_t end = NowNs() + 90000 * kMs;
  while (replies.size() < messages.size() && NowNs() < end) {
    pollfd p{c->fd(), static_cast<short>(POLLIN | (sent < wire.size() ? POLLOUT : 0)), 0};
    if (::poll(&p, 1, 1000) <= 0) continue;
    if ((p.revents & POLLOUT) && sent < wire.size()) {
      const ssize_t n = ::send(c->fd(), wire.data() + sent, std::min<std::size_t>(65536, wire.size() - sent), MSG_NOSIGNAL);
      if (n > 0) sent += static_cast<std::size_t>(n);
    }
    if (p.revents & (POLLIN | POLLHUP | POLLERR)) {
      char tmp[65536];
      const ssize_t n = ::recv(c->fd(), tmp, sizeof tmp, 0);
      ASSERT_GT(n, 0) << "daemon closed the connection after " << replies.size() << " replies\n" << d.log();
      in.append(tmp, static_cast<std::size_t>(n));
      std::size_t nl;
      while ((nl = in.find('\n')) != std::string::npos) {
        const std::string line = in.substr(0, nl);
        in.erase(0, nl + 1);
        json j = json::parse(line, nullptr, false);
        ASSERT_FALSE(j.is_discarded()) << "reply is not JSON: " << line.substr(0, 200);
        if (j.contains("event")) {
          ++events;
          continue;
        }
        ASSERT_TRUE(j.contains("ok") && j["ok"].is_boolean()) << line.substr(0, 200);
        replies.push_back(std::move(j));
      }
    }
  }
  ASSERT_EQ(replies.size(), messages.size()) << "every line gets exactly one reply";
  int failed = 0, must_fail = 0;
  for (std::size_t i = 0; i < messages.size(); ++i) {
    const bool ok = replies[i]["ok"].get<bool>();
    failed += !ok;
    if (messages[i].must_fail) {
      ++must_fail;
      EXPECT_FALSE(ok) << "message " << i << ": " << messages[i].bytes.substr(0, 200);
      if (!ok) {
        EXPECT_FALSE(replies[i].value("error", "").empty());
      }
    }
    if (messages[i].id >= 0) {
      EXPECT_EQ(replies[i].value("id", -2L), messages[i].id) << "reply " << i << " out of order";
    }
  }
  std::cout << "[ fuzz     ] " << messages.size() << " messages, " << failed << " error replies (" << must_fail
            << " required), " << events << " events\n";

  // Connections that die in the middle of a line, and too many at once.
  for (int i = 0; i < 100; ++i) {
    auto p = Conn::Connect(d.socket());
    ASSERT_TRUE(p);
    p->Send("{\"cmd\":\"laser\",\"laser\":\"a\",\"on\":tr");
  }
  // max_clients is 16 and the fuzz connection is still open: of 20 more,
  // the last ones are told "too many clients" and closed.
  std::vector<std::unique_ptr<Conn>> crowd;
  for (int i = 0; i < 20; ++i) crowd.push_back(Conn::Connect(d.socket()));
  int turned_away = 0;
  for (auto& one : crowd) {
    if (!one) continue;
    std::optional<std::string> line = one->ReadLine(30);
    if (line && line->find("too many clients") != std::string::npos) ++turned_away;
  }
  EXPECT_GE(turned_away, 4);
  crowd.clear();

  // Close the fuzz connection (anything it owned is aborted), then check.
  c->Close();
  SleepMs(150);  // > max_laser_on: even a laser owned by someone else is off now
  ASSERT_TRUE(d.Alive()) << d.log();
  auto check = Conn::Connect(d.socket());
  ASSERT_TRUE(check);
  const json s = check->Request({{"cmd", "status"}});
  ASSERT_TRUE(s["ok"].get<bool>()) << s.dump();
  EXPECT_EQ(s["lasers"]["a"], false);
  EXPECT_EQ(s["lasers"]["b"], false);
  EXPECT_NE(s["state"], "running");
  EXPECT_TRUE(LasersOff(d.FinalState()));
  ::kill(d.pid(), SIGTERM);
  EXPECT_EQ(d.Exit(5000), 0) << d.log();
}

TEST(SequencerDaemonFuzz, LineLengthBoundary) {
  TempDir dir;
  const json timings = {{"laser_warmup", 2}, {"blocker_settle", 2}, {"trigger_pulse", 1}, {"exposure", 3}, {"max_laser_on", 120}};
  DaemonProcess d(dir, BaseConfig(dir, timings));
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto c = Conn::Connect(d.socket());
  ASSERT_TRUE(c);
  const std::string base = "{\"cmd\":\"status\"}";
  const std::string at_limit = base + std::string(4096 - base.size(), ' ');
  ASSERT_EQ(at_limit.size(), 4096u);
  ASSERT_TRUE(c->Send(at_limit + "\n"));
  json r = json::parse(*c->ReadLine(3000));
  EXPECT_TRUE(r["ok"].get<bool>()) << r.dump();
  ASSERT_TRUE(c->Send(at_limit + " \n"));
  r = json::parse(*c->ReadLine(3000));
  EXPECT_FALSE(r["ok"].get<bool>());
  EXPECT_NE(r["error"].get<std::string>().find("longer than 4096"), std::string::npos);
  // The rest of the oversized line is discarded, the next line is served.
  ASSERT_TRUE(c->Send(std::string(10000, 'x')));
  r = json::parse(*c->ReadLine(3000));
  EXPECT_FALSE(r["ok"].get<bool>());
  ASSERT_TRUE(c->Send(std::string(10000, 'y') + "\n{\"cmd\":\"status\",\"id\":7}\n"));
  r = json::parse(*c->ReadLine(3000));
  EXPECT_TRUE(r["ok"].get<bool>()) << r.dump();
  EXPECT_EQ(r["id"], 7);
}

}  // namespace
}  // namespace opl::sequencer
