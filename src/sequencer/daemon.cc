#include "opl/sequencer/daemon.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/timerfd.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <systemd/sd-daemon.h>

#include "opl/sequencer/clock.h"
#include "opl/sequencer/gpio.h"
#include "opl/sequencer/sequencer.h"
#include "opl/sequencer/sim_chip.h"

namespace opl::sequencer {
namespace {

using nlohmann::json;

constexpr std::uint64_t kTagListen = 1;
constexpr std::uint64_t kTagSignal = 2;
constexpr std::uint64_t kTagTimer = 3;
constexpr std::uint64_t kFirstClientId = 16;
constexpr std::size_t kMaxPendingOutput = 1u << 20;  // bytes queued to one client
constexpr int kMaxReadsPerWakeup = 16;

std::string Dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }
std::string ErrnoText(const std::string& what) { return what + ": " + std::strerror(errno); }

// A file descriptor closed on scope exit.
class Fd {
 public:
  explicit Fd(int fd = -1) : fd_(fd) {}
  ~Fd() { Reset(); }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  void Reset(int fd = -1) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
  }

 private:
  int fd_;
};

// The service manager's side: sd_notify(3) and the watchdog period of
// sd_watchdog_enabled(3) (libsystemd). Outside systemd ($NOTIFY_SOCKET
// unset) both are no-ops.
class SystemdNotifier {
 public:
  SystemdNotifier() {
    std::uint64_t usec = 0;
    // > 0 only when $WATCHDOG_USEC is set and $WATCHDOG_PID is unset or ours.
    if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
      watchdog_interval_ns_ = static_cast<std::int64_t>(usec) * 1000 / 2;  // ping at half the timeout
    }
  }
  void Send(const std::string& state) noexcept { (void)sd_notify(0, state.c_str()); }
  // 0: no watchdog.
  std::int64_t watchdog_interval_ns() const { return watchdog_interval_ns_; }

 private:
  std::int64_t watchdog_interval_ns_ = 0;
};

// A connection beyond config.max_clients takes a reserve slot: it may only
// abort, switch a laser off or ask for status (so a crowd of idle
// connections can never lock out the way to stop a laser), is closed after
// kReserveIdleMs without a request, and when all reserve slots are taken the
// oldest reserve connection gives its slot to the newest.
constexpr double kReserveIdleMs = 2000.0;

struct Client {
  int fd = -1;
  bool reserve = false;    // in a reserve slot (see kReserveClientSlots)
  std::int64_t last_active_ns = 0;  // accept, last request line, or last time it was exempt from the idle timeout
  std::string in;          // bytes of the current, incomplete line
  bool discarding = false; // inside an oversized line: drop bytes up to '\n'
  std::string out;         // bytes not yet sent
  bool subscribed = false;
  bool dead = false;       // disconnect at the end of this wakeup
  bool want_write = false; // EPOLLOUT registered
};

class Daemon {
 public:
  explicit Daemon(const SequencerConfig& config) : config_(config), clock_(std::make_shared<MonotonicClock>()) {}
  ~Daemon();
  int Run(std::string* message);

 private:
  int Fail(int code, const std::string& text, std::string* message) {
    if (message != nullptr) *message = text;
    return code;
  }
  Status OpenChip();
  Status SetUpSocket();
  void ArmTimer();
  void Accept();
  void ReadClient(std::uint64_t id, Client& c);
  void WriteClient(std::uint64_t id, Client& c);
  void Send(std::uint64_t id, Client& c, const json& j);
  void HandleLine(std::uint64_t id, Client& c, const std::string& line);
  json HandleRequest(std::uint64_t id, Client& c, const json& request);
  json StatusJson() const;
  std::string ReserveRefusal() const {
    return "too many clients (max " + std::to_string(config_.max_clients) +
           "): this connection may only abort, switch a laser off or ask for status";
  }
  void DispatchEvents();
  void ReapDeadClients();
  void Disconnect(std::uint64_t id);
  void UpdateEpoll(std::uint64_t id, Client& c);
  // Idle timeout of a client in ms at this moment; 0 = none (subscribed, or
  // the owner of the running sequence or a manual laser).
  double IdleTimeoutMs(std::uint64_t id, const Client& c) const;
  void ExpireIdleClients();
  std::int64_t NextIdleDeadlineNs() const;
  bool Owns(std::uint64_t id) const { return id == sequence_owner_ || id == laser_owner_[0] || id == laser_owner_[1]; }

  SequencerConfig config_;
  std::shared_ptr<const Clock> clock_;
  std::unique_ptr<Sequencer> seq_;
  std::string chip_description_;
  SystemdNotifier notifier_;
  Fd epoll_, listen_, signal_, timer_;
  bool socket_bound_ = false;
  std::map<std::uint64_t, Client> clients_;
  std::uint64_t next_client_id_ = kFirstClientId;
  std::uint64_t sequence_owner_ = 0;   // client that started the running sequence
  std::uint64_t laser_owner_[2] = {0, 0};  // clients that switched a manual laser on
  std::int64_t next_watchdog_ns_ = Sequencer::kNoDeadline;
  bool stop_ = false;
  std::string stop_reason_;
  sigset_t old_mask_{};
  bool mask_changed_ = false;
};

Daemon::~Daemon() {
  // Lasers off before anything else is torn down.
  if (seq_) seq_->AllOff();
  for (auto& [id, c] : clients_) ::close(c.fd);
  clients_.clear();
  if (socket_bound_) ::unlink(config_.socket_path.c_str());
  seq_.reset();
  if (mask_changed_) pthread_sigmask(SIG_SETMASK, &old_mask_, nullptr);
}

Status Daemon::OpenChip() {
  std::unique_ptr<GpioChip> chip;
  if (config_.backend == "sim") {
    SimChipOptions o;
    o.log_path = config_.sim_log;
    o.fail_write_number = config_.sim_fail_write_number;
    Result<std::unique_ptr<SimChip>> r = SimChip::Open(o, clock_);
    if (!r.ok()) return r.status();
    chip = std::move(r).value();
  } else {
    Result<std::unique_ptr<GpioChip>> r = OpenGpiodChip(config_.chip);
    if (!r.ok()) return r.status();
    chip = std::move(r).value();
  }
  chip_description_ = chip->Describe();
  seq_ = std::make_unique<Sequencer>(config_, std::move(chip), clock_);
  return seq_->Init();
}

Status Daemon::SetUpSocket() {
  const std::string& path = config_.socket_path;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.data(), path.size());
  struct stat st{};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) return Status(StatusCode::kIoError, "socket path '" + path + "' exists and is not a socket");
    Fd probe(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
    if (probe.get() >= 0 && ::connect(probe.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) {
      return Status(StatusCode::kFailedPrecondition, "another daemon is listening on '" + path + "'");
    }
    ::unlink(path.c_str());  // stale socket of a dead daemon
  }
  listen_.Reset(::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (listen_.get() < 0) return Status(StatusCode::kIoError, ErrnoText("socket"));
  if (::bind(listen_.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    return Status(StatusCode::kIoError, ErrnoText("bind '" + path + "'"));
  }
  socket_bound_ = true;
  ::chmod(path.c_str(), 0660);
  if (::listen(listen_.get(), 16) != 0) return Status(StatusCode::kIoError, ErrnoText("listen '" + path + "'"));
  return Status::Ok();
}

double Daemon::IdleTimeoutMs(std::uint64_t id, const Client& c) const {
  if (c.reserve) return kReserveIdleMs;
  if (c.subscribed || Owns(id)) return 0.0;
  return config_.client_idle_timeout_ms;
}

std::int64_t Daemon::NextIdleDeadlineNs() const {
  std::int64_t next = Sequencer::kNoDeadline;
  for (const auto& [id, c] : clients_) {
    const double ms = IdleTimeoutMs(id, c);
    if (c.dead || ms <= 0) continue;
    next = std::min(next, c.last_active_ns + static_cast<std::int64_t>(ms * 1e6));
  }
  return next;
}

void Daemon::ExpireIdleClients() {
  const std::int64_t now = clock_->NowNs();
  for (auto& [id, c] : clients_) {
    if (c.dead) continue;
    const double ms = IdleTimeoutMs(id, c);
    if (ms <= 0) {
      c.last_active_ns = now;  // its idle time starts when the exemption ends
      continue;
    }
    if (now - c.last_active_ns < static_cast<std::int64_t>(ms * 1e6)) continue;
    std::string ms_text = std::to_string(static_cast<long long>(ms));
    Send(id, c, {{"event", "disconnect"},
                 {"reason", std::string(c.reserve ? "reserve slot " : "") + "idle for " + ms_text + " ms without a request"}});
    c.dead = true;
  }
}

void Daemon::ArmTimer() {
  std::int64_t deadline = std::min({seq_->NextDeadlineNs(), next_watchdog_ns_, NextIdleDeadlineNs()});
  itimerspec its{};
  if (deadline != Sequencer::kNoDeadline) {
    if (deadline <= 0) deadline = 1;
    its.it_value.tv_sec = static_cast<time_t>(deadline / 1000000000LL);
    its.it_value.tv_nsec = static_cast<long>(deadline % 1000000000LL);
  }
  timerfd_settime(timer_.get(), TFD_TIMER_ABSTIME, &its, nullptr);
}

void Daemon::UpdateEpoll(std::uint64_t id, Client& c) {
  const bool want = !c.out.empty();
  if (want == c.want_write) return;
  epoll_event ev{};
  ev.events = EPOLLIN | EPOLLRDHUP | (want ? EPOLLOUT : 0u);
  ev.data.u64 = id;
  epoll_ctl(epoll_.get(), EPOLL_CTL_MOD, c.fd, &ev);
  c.want_write = want;
}

void Daemon::Send(std::uint64_t id, Client& c, const json& j) {
  if (c.dead) return;
  c.out += Dump(j);
  c.out += '\n';
  if (c.out.size() > kMaxPendingOutput) {
    c.dead = true;  // not reading its replies: drop it
    return;
  }
  WriteClient(id, c);
}

void Daemon::WriteClient(std::uint64_t id, Client& c) {
  while (!c.out.empty() && !c.dead) {
    const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      c.out.erase(0, static_cast<std::size_t>(n));
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      break;
    } else {
      c.dead = true;
    }
  }
  if (!c.dead) UpdateEpoll(id, c);
}

void Daemon::Accept() {
  for (;;) {
    const int fd = ::accept4(listen_.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;  // EAGAIN, or a transient error: the loop goes on
    int regular = 0, reserve = 0;
    std::uint64_t oldest_reserve = 0;
    for (const auto& [cid, other] : clients_) {
      if (other.dead) continue;
      if (!other.reserve) {
        ++regular;
      } else if (reserve++ == 0) {
        oldest_reserve = cid;  // ids grow with time: the first is the oldest
      }
    }
    const bool in_reserve = regular >= config_.max_clients;
    if (in_reserve && reserve >= kReserveClientSlots) {
      Client& old = clients_.at(oldest_reserve);
      Send(oldest_reserve, old, {{"event", "disconnect"}, {"reason", "reserve slot taken by a newer connection"}});
      old.dead = true;
    }
    const std::uint64_t id = next_client_id_++;
    epoll_event ev{};
    ev.events = EPOLLIN | EPOLLRDHUP;
    ev.data.u64 = id;
    if (epoll_ctl(epoll_.get(), EPOLL_CTL_ADD, fd, &ev) != 0) {
      ::close(fd);
      continue;
    }
    Client c;
    c.fd = fd;
    c.reserve = in_reserve;
    c.last_active_ns = clock_->NowNs();
    Client& added = clients_.emplace(id, std::move(c)).first->second;
    if (in_reserve) {
      Send(id, added, {{"event", "notice"}, {"message", ReserveRefusal()}});
    }
  }
}

void Daemon::ReadClient(std::uint64_t id, Client& c) {
  char buf[65536];
  for (int reads = 0; reads < kMaxReadsPerWakeup && !c.dead; ++reads) {
    const ssize_t n = ::recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n == 0) {
      c.dead = true;
      return;
    }
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) c.dead = true;
      return;
    }
    std::size_t pos = 0;
    const std::size_t len = static_cast<std::size_t>(n);
    while (pos < len && !c.dead) {
      const char* nl = static_cast<const char*>(std::memchr(buf + pos, '\n', len - pos));
      const std::size_t end = nl != nullptr ? static_cast<std::size_t>(nl - buf) : len;
      if (c.discarding) {
        if (nl != nullptr) c.discarding = false;
      } else {
        c.in.append(buf + pos, end - pos);
        if (c.in.size() > config_.max_message_bytes) {
          Send(id, c, {{"ok", false}, {"error", "message longer than " + std::to_string(config_.max_message_bytes) + " bytes; discarded"}});
          c.in.clear();
          c.in.shrink_to_fit();
          c.discarding = nl == nullptr;
        } else if (nl != nullptr) {
          std::string line;
          line.swap(c.in);
          HandleLine(id, c, line);
          DispatchEvents();
        }
      }
      pos = end + (nl != nullptr ? 1 : 0);
    }
  }
}

void Daemon::HandleLine(std::uint64_t id, Client& c, const std::string& raw) {
  c.last_active_ns = clock_->NowNs();
  std::string line = raw;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  json reply;
  json request;
  bool parsed = false;
  try {
    request = json::parse(line);
    parsed = true;
  } catch (const json::exception& e) {
    reply = {{"ok", false}, {"error", std::string("invalid JSON: ") + e.what()}};
  }
  if (parsed) {
    try {
      reply = HandleRequest(id, c, request);
    } catch (const std::exception& e) {
      // Only JSON type errors can land here: the request is rejected, the
      // sequencer's state is unchanged.
      reply = {{"ok", false}, {"error", std::string("bad request: ") + e.what()}};
    }
    if (request.is_object() && request.contains("id")) {
      const json& rid = request.at("id");
      if (rid.is_string() || rid.is_number() || rid.is_null() || rid.is_boolean()) reply["id"] = rid;
    }
  }
  Send(id, c, reply);
}

json Daemon::StatusJson() const {
  const SequencerStatus s = seq_->GetStatus();
  json j;
  j["ok"] = true;
  j["state"] = SequencerStateName(s.state);
  j["sequence"] = SequenceKindName(s.sequence);
  j["run"] = s.run;
  j["slice"] = s.slice >= 0 ? json(s.slice) : json(nullptr);
  j["slices"] = s.slices;
  j["step"] = s.step.empty() ? json(nullptr) : json(s.step);
  j["frames"] = s.frames;
  j["lasers"] = {{"a", static_cast<bool>(s.active[0])}, {"b", static_cast<bool>(s.active[1])}};
  j["laser_remaining_ms"] = {{"a", s.laser_remaining_ms[0]}, {"b", s.laser_remaining_ms[1]}};
  j["blocker"] = s.active[2] ? "closed" : "open";
  j["trigger"] = static_cast<bool>(s.active[3]);
  j["metadata"] = s.metadata_path;
  j["last_error"] = s.last_error;
  j["clients"] = std::count_if(clients_.begin(), clients_.end(), [](const auto& kv) { return !kv.second.reserve; });
  j["reserve_clients"] = std::count_if(clients_.begin(), clients_.end(), [](const auto& kv) { return kv.second.reserve; });
  j["chip"] = chip_description_;
  return j;
}

json Daemon::HandleRequest(std::uint64_t id, Client& c, const json& request) {
  auto error = [](const std::string& text) { return json{{"ok", false}, {"error", text}}; };
  auto from_status = [&](const Status& s) { return s.ok() ? json{{"ok", true}} : error(s.message()); };
  if (!request.is_object()) return error("request must be a JSON object");
  if (!request.contains("cmd") || !request.at("cmd").is_string()) return error("request needs \"cmd\" (a string)");
  const std::string cmd = request.at("cmd").get<std::string>();
  if (c.reserve) {
    const bool laser_off = cmd == "laser" && request.contains("on") && request.at("on").is_boolean() &&
                           !request.at("on").get<bool>();
    if (cmd != "abort" && cmd != "status" && !laser_off) return error(ReserveRefusal());
  }
  auto check_keys = [&](std::initializer_list<const char*> allowed) -> std::string {
    for (auto it = request.begin(); it != request.end(); ++it) {
      if (it.key() == "cmd" || it.key() == "id") continue;
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* k) { return it.key() == k; })) {
        return "unknown field \"" + it.key() + "\" for " + cmd;
      }
    }
    return "";
  };
  std::string bad;
  if (cmd == "status") {
    if (!(bad = check_keys({})).empty()) return error(bad);
    return StatusJson();
  }
  if (cmd == "subscribe") {
    if (!(bad = check_keys({})).empty()) return error(bad);
    c.subscribed = true;
    return {{"ok", true}};
  }
  if (cmd == "abort") {
    if (!(bad = check_keys({})).empty()) return error(bad);
    return from_status(seq_->Abort("abort requested by a client"));
  }
  if (cmd == "next_slice") {
    if (!(bad = check_keys({})).empty()) return error(bad);
    return from_status(seq_->NextSlice());
  }
  if (cmd == "start") {
    if (!(bad = check_keys({"sequence", "slices", "metadata"})).empty()) return error(bad);
    StartRequest r;
    if (!request.contains("sequence") || !request.at("sequence").is_string()) {
      return error("start needs \"sequence\": \"measurement\" or \"calibration\"");
    }
    const std::string kind = request.at("sequence").get<std::string>();
    if (kind == "measurement") {
      r.kind = SequenceKind::kMeasurement;
    } else if (kind == "calibration") {
      r.kind = SequenceKind::kCalibration;
    } else {
      return error("sequence must be \"measurement\" or \"calibration\"");
    }
    if (request.contains("slices")) {
      const json& s = request.at("slices");
      if (!s.is_number_integer() || (s.is_number_unsigned() && s.get<std::uint64_t>() > 1000000u) ||
          (!s.is_number_unsigned() && (s.get<std::int64_t>() < -1000000 || s.get<std::int64_t>() > 1000000))) {
        return error("slices must be an integer 1 .. 10000");
      }
      r.slices = static_cast<int>(s.get<std::int64_t>());
    }
    if (request.contains("metadata")) {
      if (!request.at("metadata").is_string()) return error("metadata must be a string (a file path)");
      r.metadata_path = request.at("metadata").get<std::string>();
    }
    const Status s = seq_->Start(r);
    if (!s.ok()) return error(s.message());
    sequence_owner_ = id;
    return {{"ok", true}, {"run", seq_->GetStatus().run}};
  }
  if (cmd == "laser") {
    if (!(bad = check_keys({"laser", "on", "limit_ms"})).empty()) return error(bad);
    if (!request.contains("laser") || !request.at("laser").is_string()) return error("laser needs \"laser\": \"a\" or \"b\"");
    const std::string which = request.at("laser").get<std::string>();
    if (which != "a" && which != "b") return error("laser must be \"a\" or \"b\"");
    if (!request.contains("on") || !request.at("on").is_boolean()) return error("laser needs \"on\": true or false");
    const bool on = request.at("on").get<bool>();
    double limit_ms = 0.0;
    if (on) {
      if (!request.contains("limit_ms") || !request.at("limit_ms").is_number()) {
        return error("laser on needs \"limit_ms\" (a number, ms)");
      }
      limit_ms = request.at("limit_ms").get<double>();
    }
    const LineRole role = which == "a" ? LineRole::kLaserA : LineRole::kLaserB;
    const Status s = seq_->SetLaser(role, on, limit_ms);
    if (!s.ok()) return error(s.message());
    if (on) laser_owner_[which == "a" ? 0 : 1] = id;
    return {{"ok", true}};
  }
  if (cmd == "blocker") {
    if (!(bad = check_keys({"closed"})).empty()) return error(bad);
    if (!request.contains("closed") || !request.at("closed").is_boolean()) return error("blocker needs \"closed\": true or false");
    return from_status(seq_->SetBlocker(request.at("closed").get<bool>()));
  }
  if (cmd == "trigger") {
    if (!(bad = check_keys({"metadata"})).empty()) return error(bad);
    std::string path;
    if (request.contains("metadata")) {
      if (!request.at("metadata").is_string()) return error("metadata must be a string (a file path)");
      path = request.at("metadata").get<std::string>();
    }
    return from_status(seq_->Trigger(path));
  }
  return error("unknown cmd \"" + cmd + "\" (status, start, abort, next_slice, laser, blocker, trigger, subscribe)");
}

json EventJson(const SequencerEvent& e) {
  json j;
  j["event"] = EventTypeName(e.type);
  j["t_ns"] = e.t_ns;
  j["sequence"] = SequenceKindName(e.sequence);
  j["run"] = e.run;
  if (e.slice >= 0) j["slice"] = e.slice;
  if (e.slices > 0) j["slices"] = e.slices;
  if (e.type == EventType::kFrame) {
    j["step"] = e.step;
    if (e.step_index >= 0) j["step_index"] = e.step_index;
    j["frame"] = e.frame;
  }
  if (!e.laser.empty()) j["laser"] = e.laser;
  if (!e.message.empty()) j["message"] = e.message;
  return j;
}

void Daemon::DispatchEvents() {
  if (!seq_) return;
  const std::vector<SequencerEvent> events = seq_->TakeEvents();
  for (const SequencerEvent& e : events) {
    const json j = EventJson(e);
    for (auto& [cid, c] : clients_) {
      if (c.subscribed || cid == sequence_owner_ || cid == laser_owner_[0] || cid == laser_owner_[1]) Send(cid, c, j);
    }
  }
  const SequencerStatus s = seq_->GetStatus();
  if (s.state != SequencerState::kRunning && s.state != SequencerState::kWaitingOperator) sequence_owner_ = 0;
  if (!s.active[0]) laser_owner_[0] = 0;
  if (!s.active[1]) laser_owner_[1] = 0;
}

void Daemon::Disconnect(std::uint64_t id) {
  auto it = clients_.find(id);
  if (it == clients_.end()) return;
  epoll_ctl(epoll_.get(), EPOLL_CTL_DEL, it->second.fd, nullptr);
  ::close(it->second.fd);
  clients_.erase(it);
  if (id == sequence_owner_) {
    seq_->Abort("the client that started the sequence disconnected");
  } else if (id == laser_owner_[0] || id == laser_owner_[1]) {
    seq_->Abort("the client that switched the laser on disconnected");
  }
  DispatchEvents();
}

void Daemon::ReapDeadClients() {
  for (;;) {
    std::uint64_t dead = 0;
    for (auto& [id, c] : clients_) {
      if (c.dead) {
        dead = id;
        break;
      }
    }
    if (dead == 0) return;
    Disconnect(dead);
  }
}

int Daemon::Run(std::string* message) {
  // Signals first, so that a SIGTERM arriving during start-up is not lost
  // and cannot kill the process between two GPIO writes.
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGTERM);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGHUP);
  if (pthread_sigmask(SIG_BLOCK, &mask, &old_mask_) != 0) return Fail(kExitInternal, "cannot block signals", message);
  mask_changed_ = true;
  ::signal(SIGPIPE, SIG_IGN);
  signal_.Reset(::signalfd(-1, &mask, SFD_NONBLOCK | SFD_CLOEXEC));
  if (signal_.get() < 0) return Fail(kExitInternal, ErrnoText("signalfd"), message);

  std::string invalid;
  if (!config_.IsValid(&invalid)) return Fail(kExitConfig, "configuration: " + invalid, message);

  // GPIO next: every line is driven off as part of the request.
  const Status chip = OpenChip();
  if (!chip.ok()) return Fail(kExitGpioSetup, chip.ToString(), message);

  const Status sock = SetUpSocket();
  if (!sock.ok()) return Fail(kExitSocket, sock.ToString(), message);

  timer_.Reset(::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC));
  epoll_.Reset(::epoll_create1(EPOLL_CLOEXEC));
  if (timer_.get() < 0 || epoll_.get() < 0) return Fail(kExitInternal, ErrnoText("timerfd/epoll"), message);
  for (auto [fd, tag] : {std::pair<int, std::uint64_t>{listen_.get(), kTagListen}, {signal_.get(), kTagSignal}, {timer_.get(), kTagTimer}}) {
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = tag;
    if (epoll_ctl(epoll_.get(), EPOLL_CTL_ADD, fd, &ev) != 0) return Fail(kExitInternal, ErrnoText("epoll_ctl"), message);
  }

  if (notifier_.watchdog_interval_ns() > 0) next_watchdog_ns_ = clock_->NowNs() + notifier_.watchdog_interval_ns();
  notifier_.Send("READY=1\nSTATUS=idle, every laser off\nMAINPID=" + std::to_string(::getpid()));

  int code = kExitOk;
  std::string why;
  epoll_event events[64];
  while (!stop_) {
    seq_->OnTime();
    DispatchEvents();
    ExpireIdleClients();
    ReapDeadClients();
    if (seq_->faulted()) {
      code = kExitGpioRuntime;
      why = "GPIO error, every line driven off: " + seq_->GetStatus().last_error;
      break;
    }
    if (next_watchdog_ns_ != Sequencer::kNoDeadline && clock_->NowNs() >= next_watchdog_ns_) {
      notifier_.Send("WATCHDOG=1");
      // Fixed cadence; after a stall, restart it from now.
      next_watchdog_ns_ += notifier_.watchdog_interval_ns();
      if (next_watchdog_ns_ <= clock_->NowNs()) next_watchdog_ns_ = clock_->NowNs() + notifier_.watchdog_interval_ns();
    }
    ArmTimer();
    const int n = ::epoll_wait(epoll_.get(), events, 64, -1);
    if (n < 0) {
      if (errno == EINTR) continue;
      code = kExitInternal;
      why = ErrnoText("epoll_wait");
      break;
    }
    for (int k = 0; k < n; ++k) {
      const std::uint64_t tag = events[k].data.u64;
      if (tag == kTagListen) {
        Accept();
      } else if (tag == kTagSignal) {
        signalfd_siginfo si{};
        while (::read(signal_.get(), &si, sizeof si) == static_cast<ssize_t>(sizeof si)) {
          stop_ = true;
          stop_reason_ = si.ssi_signo == SIGTERM ? "SIGTERM" : si.ssi_signo == SIGINT ? "SIGINT" : "SIGHUP";
        }
      } else if (tag == kTagTimer) {
        std::uint64_t expirations = 0;
        (void)::read(timer_.get(), &expirations, sizeof expirations);
      } else {
        auto it = clients_.find(tag);
        if (it == clients_.end()) continue;
        Client& c = it->second;
        if (events[k].events & (EPOLLIN | EPOLLRDHUP | EPOLLHUP | EPOLLERR)) ReadClient(tag, c);
        if (events[k].events & (EPOLLHUP | EPOLLERR)) c.dead = true;
        if (!c.dead && (events[k].events & EPOLLOUT)) WriteClient(tag, c);
      }
      // Deadlines are checked between any two events of a wakeup.
      seq_->OnTime();
      if (stop_) break;
    }
  }

  // Stopping: every line off first, then tell the clients and systemd.
  const Status off = seq_->Abort(stop_ ? "daemon stopping on " + stop_reason_ : "daemon stopping: " + why);
  DispatchEvents();
  notifier_.Send("STOPPING=1");
  const json bye = {{"event", "shutdown"}, {"reason", stop_ ? stop_reason_ : why}};
  for (auto& [cid, c] : clients_) Send(cid, c, bye);
  if (code == kExitOk && !off.ok()) {
    code = kExitGpioRuntime;
    why = "GPIO error while driving lines off: " + off.ToString();
  }
  if (code != kExitOk) return Fail(code, why, message);
  if (message != nullptr) *message = "stopped on " + stop_reason_ + ", every line off";
  return kExitOk;
}

}  // namespace

int RunDaemon(const SequencerConfig& config, std::string* message) {
  try {
    Daemon daemon(config);
    return daemon.Run(message);
  } catch (const std::exception& e) {
    // Out of memory or a library bug. The Daemon destructor has already
    // driven every line off while unwinding.
    if (message != nullptr) *message = std::string("internal error: ") + e.what();
    return kExitInternal;
  }
}

}  // namespace opl::sequencer
