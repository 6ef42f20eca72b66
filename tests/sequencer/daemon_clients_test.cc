// Client slots of the opl_sequencer daemon (issue 19 item 9): idle clients
// are disconnected with a reason, a crowd of connections cannot lock out
// abort and laser off (the reserve slots), and the client prints what the
// daemon said instead of "Broken pipe".
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "opl/sequencer/client.h"
#include "opl/sequencer/daemon.h"

#include "daemon_harness.h"

namespace opl::sequencer {
namespace {

using namespace opl::sequencer::testing;  // NOLINT(build/namespaces)
using json = nlohmann::json;

const json kQuickTimings = {{"laser_warmup", 5}, {"blocker_settle", 5}, {"trigger_pulse", 1}, {"exposure", 5},
                            {"max_laser_on", 60000}};

// Reads lines until one has `event` == name; nullopt on EOF or timeout.
std::optional<json> NextEvent(Conn& c, const std::string& name, int timeout_ms) {
  const std::int64_t end = NowNs() + timeout_ms * kMs;
  for (;;) {
    const std::int64_t left = (end - NowNs()) / kMs;
    if (left <= 0) return std::nullopt;
    std::optional<std::string> line = c.ReadLine(static_cast<int>(left));
    if (!line) return std::nullopt;
    json j = json::parse(*line, nullptr, false);
    if (j.is_object() && j.value("event", "") == name) return j;
  }
}

// A connection in a regular slot (subscribed, which the reserve refuses).
// Retries: the daemon may not yet have reaped a connection closed just
// before (WaitReady's probe), which then still holds a regular slot.
std::unique_ptr<Conn> ConnectRegular(const std::string& socket) {
  for (int attempt = 0; attempt < 50; ++attempt) {
    std::unique_ptr<Conn> c = Conn::Connect(socket);
    if (c && c->Request({{"cmd", "subscribe"}})["ok"].get<bool>()) return c;
    SleepMs(10);
  }
  return nullptr;
}

// True if the daemon closed the connection within timeout_ms.
bool ClosedWithin(Conn& c, int timeout_ms) {
  const std::int64_t end = NowNs() + timeout_ms * kMs;
  while (NowNs() < end) {
    pollfd p{c.fd(), POLLIN, 0};
    if (::poll(&p, 1, 10) <= 0) continue;
    char tmp[4096];
    if (::recv(c.fd(), tmp, sizeof tmp, 0) == 0) return true;
  }
  return false;
}

TEST(SequencerDaemonClients, IdleClientIsToldWhyAndDisconnected) {
  TempDir dir;
  json config = BaseConfig(dir, kQuickTimings);
  config["client_idle_timeout_ms"] = 300;
  DaemonProcess d(dir, config);
  ASSERT_TRUE(d.WaitReady()) << d.log();

  auto idle = Conn::Connect(d.socket());
  auto chatty = Conn::Connect(d.socket());
  auto subscriber = Conn::Connect(d.socket());
  ASSERT_TRUE(idle && chatty && subscriber);
  ASSERT_TRUE(subscriber->Request({{"cmd", "subscribe"}})["ok"].get<bool>());
  const std::int64_t t0 = NowNs();

  // A request every 100 ms keeps a client; silence for 300 ms does not.
  for (int i = 0; i < 8; ++i) {
    SleepMs(100);
    ASSERT_TRUE(chatty->Request({{"cmd", "status"}})["ok"].get<bool>()) << "request " << i;
  }
  std::optional<json> bye = NextEvent(*idle, "disconnect", 2000);
  ASSERT_TRUE(bye) << d.log();
  EXPECT_EQ(bye->value("reason", ""), "idle for 300 ms without a request");
  EXPECT_TRUE(ClosedWithin(*idle, 1000));
  // Late, never early: the disconnect came at least 300 ms after connecting.
  EXPECT_GE(NowNs() - t0, 300 * kMs);

  // The subscriber (silent by design) and the chatty client are still served.
  const json status = subscriber->Request({{"cmd", "status"}});
  ASSERT_TRUE(status["ok"].get<bool>()) << status.dump();
  EXPECT_EQ(status["clients"], 2);
  EXPECT_EQ(status["reserve_clients"], 0);
}

TEST(SequencerDaemonClients, OwnerOfARunningCalibrationIsNeverIdle) {
  TempDir dir;
  json config = BaseConfig(dir, kQuickTimings);
  config["client_idle_timeout_ms"] = 200;
  DaemonProcess d(dir, config);
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto owner = Conn::Connect(d.socket());
  ASSERT_TRUE(owner);
  ASSERT_TRUE(owner->Request({{"cmd", "start"}, {"sequence", "calibration"}, {"slices", 3}})["ok"].get<bool>());
  ASSERT_TRUE(owner->WaitEvent("waiting_operator", 3000)) << d.log();
  SleepMs(700);  // > 3 idle timeouts, waiting for the operator
  auto other = Conn::Connect(d.socket());
  ASSERT_TRUE(other);
  const json status = other->Request({{"cmd", "status"}});
  EXPECT_EQ(status["state"], "waiting_operator") << status.dump();
  EXPECT_EQ(status["clients"], 2);
  ASSERT_TRUE(other->Request({{"cmd", "abort"}})["ok"].get<bool>());
  ASSERT_TRUE(owner->WaitEvent("aborted", 3000));
}

// The finding of issue 19: 16 idle connections from anyone who can open the
// socket locked everyone out, so `client abort` and `laser a off` exited 10
// "Broken pipe" and a running calibration kept running.
TEST(SequencerDaemonClients, ACrowdOfIdleConnectionsCannotLockOutAbortOrLaserOff) {
  TempDir dir;
  json config = BaseConfig(dir, kQuickTimings);
  config["client_idle_timeout_ms"] = 0;  // the worst case: idle clients are never dropped
  DaemonProcess d(dir, config);
  ASSERT_TRUE(d.WaitReady()) << d.log();

  // The operator's calibration owns one slot and a manual laser another.
  auto owner = ConnectRegular(d.socket());
  ASSERT_TRUE(owner);
  ASSERT_TRUE(owner->Request({{"cmd", "start"}, {"sequence", "calibration"}, {"slices", 3}})["ok"].get<bool>());
  ASSERT_TRUE(owner->WaitEvent("waiting_operator", 3000)) << d.log();
  // The calibration holds the lasers: laser off is tested after the abort,
  // on a laser this client switches on.
  auto laser_owner = ConnectRegular(d.socket());
  ASSERT_TRUE(laser_owner);

  // 14 silent, subscribed connections fill the remaining regular slots.
  std::vector<std::unique_ptr<Conn>> crowd;
  for (int i = 0; i < 14; ++i) {
    crowd.push_back(ConnectRegular(d.socket()));
    ASSERT_TRUE(crowd.back()) << "crowd " << i;
  }
  // More connections land in the reserve slots and are told so at once.
  std::vector<std::unique_ptr<Conn>> reserve;
  for (int i = 0; i < kReserveClientSlots; ++i) {
    reserve.push_back(Conn::Connect(d.socket()));
    ASSERT_TRUE(reserve.back());
    std::optional<json> notice = NextEvent(*reserve.back(), "notice", 2000);
    ASSERT_TRUE(notice) << "reserve " << i;
    EXPECT_EQ(notice->value("message", ""),
              "too many clients (max 16): this connection may only abort, switch a laser off or ask for status");
  }
  // One more: the oldest reserve connection gives way to it.
  auto newest = Conn::Connect(d.socket());
  ASSERT_TRUE(newest);
  std::optional<json> evicted = NextEvent(*reserve.front(), "disconnect", 2000);
  ASSERT_TRUE(evicted);
  EXPECT_EQ(evicted->value("reason", ""), "reserve slot taken by a newer connection");
  EXPECT_TRUE(ClosedWithin(*reserve.front(), 1000));

  // A reserve connection may not start anything ...
  const json refused = reserve[1]->Request({{"cmd", "laser"}, {"laser", "a"}, {"on", true}, {"limit_ms", 50}});
  EXPECT_FALSE(refused["ok"].get<bool>());
  EXPECT_NE(refused.value("error", "").find("too many clients (max 16)"), std::string::npos) << refused.dump();
  // ... and the CLI prints the daemon's refusal (exit 1, not 10 "Broken pipe").
  pid_t p = Spawn({"client", "-s", d.socket(), "blocker", "closed"}, dir.File("cli_blocker.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitRefused) << ReadText(dir.File("cli_blocker.log"));
  EXPECT_NE(ReadText(dir.File("cli_blocker.log")).find("opl_sequencer: the daemon refused: too many clients (max 16)"),
            std::string::npos)
      << ReadText(dir.File("cli_blocker.log"));

  // ... but `client status` and `client abort` work, and the calibration stops.
  p = Spawn({"client", "-s", d.socket(), "status"}, dir.File("cli_status.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitOk) << ReadText(dir.File("cli_status.log"));
  EXPECT_NE(ReadText(dir.File("cli_status.log")).find("\"state\":\"waiting_operator\""), std::string::npos)
      << ReadText(dir.File("cli_status.log"));
  p = Spawn({"client", "-s", d.socket(), "abort"}, dir.File("cli_abort.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitOk) << ReadText(dir.File("cli_abort.log"));
  ASSERT_TRUE(owner->WaitEvent("aborted", 3000)) << d.log();

  // A manual laser switched on by a regular client, switched off from the
  // reserve by the CLI.
  ASSERT_TRUE(laser_owner->Request({{"cmd", "laser"}, {"laser", "a"}, {"on", true}, {"limit_ms", 30000}})["ok"].get<bool>());
  ASSERT_GE(d.WaitLine("laser_a", true, 0, 2000), 0);
  const std::int64_t t_off = NowNs();
  p = Spawn({"client", "-s", d.socket(), "laser", "a", "off"}, dir.File("cli_laser.log"));
  EXPECT_EQ(WaitExit(p, 5000), kExitOk) << ReadText(dir.File("cli_laser.log"));
  EXPECT_GE(d.WaitLine("laser_a", false, t_off, 2000), 0) << d.log();
  EXPECT_TRUE(LasersOff(d.FinalState()));
  ASSERT_TRUE(d.Alive()) << d.log();
  ::kill(d.pid(), SIGTERM);
  EXPECT_EQ(d.Exit(5000), 0) << d.log();
}

TEST(SequencerDaemonClients, ReserveConnectionIsClosedAfterTwoSecondsIdle) {
  TempDir dir;
  json config = BaseConfig(dir, kQuickTimings);
  config["max_clients"] = 1;
  config["client_idle_timeout_ms"] = 0;
  DaemonProcess d(dir, config);
  ASSERT_TRUE(d.WaitReady()) << d.log();
  auto regular = ConnectRegular(d.socket());
  ASSERT_TRUE(regular);
  auto extra = Conn::Connect(d.socket());
  ASSERT_TRUE(extra);
  ASSERT_TRUE(NextEvent(*extra, "notice", 2000));
  const std::int64_t t0 = NowNs();
  std::optional<json> bye = NextEvent(*extra, "disconnect", 5000);
  ASSERT_TRUE(bye);
  EXPECT_EQ(bye->value("reason", ""), "reserve slot idle for 2000 ms without a request");
  EXPECT_GE(NowNs() - t0, 1900 * kMs);  // its clock started at accept, a little before t0
  EXPECT_TRUE(regular->Request({{"cmd", "status"}})["ok"].get<bool>());
}

// A daemon (or anything on the socket) that writes its refusal and closes
// before reading the request: the client says what it was told.
TEST(SequencerClient, PrintsTheDaemonsRefusalInsteadOfBrokenPipe) {
  TempDir dir;
  const std::string path = dir.File("fake.sock");
  const int server = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  ASSERT_EQ(::bind(server, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(server, 4), 0);
  std::thread fake([server] {
    const int fd = ::accept(server, nullptr, nullptr);
    const std::string line = "{\"ok\":false,\"error\":\"too many clients (max 16)\"}\n";
    (void)::send(fd, line.data(), line.size(), MSG_NOSIGNAL);
    ::close(fd);
  });
  ClientOptions options;
  options.socket_path = path;
  std::ostringstream out, err;
  // A request larger than the socket buffers, so that sending it fails once
  // the fake has closed: the path that printed only "Broken pipe".
  const std::string request = "{\"cmd\":\"abort\",\"pad\":\"" + std::string(4 << 20, 'x') + "\"}";
  const int code = RunClient(options, request, out, err);
  fake.join();
  ::close(server);
  EXPECT_EQ(code, kExitRefused) << err.str();
  EXPECT_EQ(err.str(), "opl_sequencer: the daemon refused: too many clients (max 16)\n");
  EXPECT_EQ(out.str(), "{\"ok\":false,\"error\":\"too many clients (max 16)\"}\n");
}

}  // namespace
}  // namespace opl::sequencer
