// Test harness for the opl_sequencer daemon: a child-process daemon with the
// simulated chip (DaemonProcess), a raw protocol connection (Conn), the
// host-stall monitor that tells the machine's stalls from the daemon's
// lateness, and small helpers. Shared by daemon_test.cc and
// daemon_clients_test.cc; needs OPL_SEQUENCER_BIN defined to the binary.
#ifndef OPL_TESTS_SEQUENCER_DAEMON_HARNESS_H_
#define OPL_TESTS_SEQUENCER_DAEMON_HARNESS_H_

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
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "opl/sequencer/clock.h"
#include "opl/sequencer/sim_chip.h"

namespace opl::sequencer::testing {

using json = nlohmann::json;
constexpr std::int64_t kMs = 1000000;

inline std::int64_t NowNs() { return MonotonicClock().NowNs(); }
inline void SleepMs(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

// The host's scheduling stalls, to tell them from the daemon's lateness.
// Two threads (one per core of the 2-core CI machine) sleep 1 ms at a time
// and record every sleep that overran by more than 1 ms; the worst overrun
// of a sleep that overlapped an interval is the host's stall there. A
// stopped vCPU or a full run queue delays the daemon and these threads
// alike; a daemon late on its own (a bug) is late while these sleeps are on
// time, and still fails.
class HostStallMonitor {
 public:
  HostStallMonitor() {
    for (int i = 0; i < 2; ++i) threads_.emplace_back([this] { Run(); });
  }
  ~HostStallMonitor() {
    stop_ = true;
    for (std::thread& t : threads_) t.join();
  }
  HostStallMonitor(const HostStallMonitor&) = delete;
  HostStallMonitor& operator=(const HostStallMonitor&) = delete;

  // Worst overrun [ms] of a sleep that overlapped [from_ns, to_ns].
  double WorstMs(std::int64_t from_ns, std::int64_t to_ns) const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::int64_t worst = 0;
    for (const Stall& s : stalls_) {
      if (s.end_ns >= from_ns && s.start_ns <= to_ns) worst = std::max(worst, s.overrun_ns);
    }
    return static_cast<double>(worst) / 1e6;
  }

 private:
  struct Stall {
    std::int64_t start_ns, end_ns, overrun_ns;
  };
  void Run() {
    while (!stop_) {
      const std::int64_t start = MonotonicClock().NowNs();
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      const std::int64_t end = MonotonicClock().NowNs();
      const std::int64_t overrun = end - start - 1000000;
      if (overrun > 1000000) {
        std::lock_guard<std::mutex> lock(mutex_);
        stalls_.push_back({start, end, overrun});
      }
    }
  }
  std::atomic<bool> stop_{false};
  mutable std::mutex mutex_;
  std::vector<Stall> stalls_;
  std::vector<std::thread> threads_;
};

class TempDir {
 public:
  TempDir() {
    char tmpl[] = "/tmp/opl-seq-XXXXXX";
    path_ = ::mkdtemp(tmpl) != nullptr ? tmpl : "/tmp";
  }
  ~TempDir() {
    if (path_ != "/tmp" && std::getenv("OPL_KEEP_TEST_FILES") == nullptr) {
      (void)std::system(("rm -rf '" + path_ + "'").c_str());
    }
  }
  std::string File(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

inline json BaseConfig(const TempDir& dir, json timings) {
  return {{"gpio", {{"backend", "sim"}, {"sim_log", dir.File("sim.jsonl")}}},
          {"lines",
           {{"laser_a", {{"offset", 17}}},
            {"laser_b", {{"offset", 27}}},
            {"blocker", {{"offset", 22}}},
            {"trigger", {{"offset", 23}, {"active_low", true}}}}},
          {"timings_ms", timings},
          {"socket", dir.File("s.sock")},
          {"metadata", dir.File("frames.jsonl")}};
}

// Spawns `opl_sequencer <args>` with stdout/stderr to files.
inline pid_t Spawn(const std::vector<std::string>& args, const std::string& out_path,
            const std::vector<std::string>& env = {}) {
  std::vector<std::string> env_copy = env;  // putenv keeps the pointer
  std::vector<char*> argv;
  std::string bin = OPL_SEQUENCER_BIN;
  argv.push_back(bin.data());
  std::vector<std::string> copy = args;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int in = ::open("/dev/null", O_RDONLY);
    if (out >= 0) {
      ::dup2(out, 1);
      ::dup2(out, 2);
    }
    if (in >= 0) ::dup2(in, 0);
    for (std::string& e : env_copy) ::putenv(e.data());
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  return pid;
}

// Exit code, -signal, or -1000 on timeout (the child is then killed).
inline int WaitExit(pid_t pid, int timeout_ms) {
  const std::int64_t end = NowNs() + timeout_ms * kMs;
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
    if (r < 0) return -2000;
    if (NowNs() > end) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      return -1000;
    }
    SleepMs(1);
  }
}

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class Conn {
 public:
  static std::unique_ptr<Conn> Connect(const std::string& path) {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
      ::close(fd);
      return nullptr;
    }
    return std::unique_ptr<Conn>(new Conn(fd));
  }
  ~Conn() { Close(); }
  void Close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  int fd() const { return fd_; }
  bool Send(const std::string& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n <= 0) return false;
      done += static_cast<std::size_t>(n);
    }
    return true;
  }
  std::optional<std::string> ReadLine(int timeout_ms) {
    const std::int64_t end = NowNs() + timeout_ms * kMs;
    for (;;) {
      const std::size_t nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return line;
      }
      const std::int64_t left = (end - NowNs()) / kMs;
      if (left <= 0) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      char tmp[65536];
      const ssize_t n = ::recv(fd_, tmp, sizeof tmp, 0);
      if (n <= 0) return std::nullopt;
      buf_.append(tmp, static_cast<std::size_t>(n));
    }
  }
  // Sends a request; returns its reply, keeping events for WaitEvent.
  json Request(const json& request, int timeout_ms = 5000) {
    if (!Send(request.dump() + "\n")) return {{"ok", false}, {"error", "send failed"}};
    for (;;) {
      std::optional<std::string> line = ReadLine(timeout_ms);
      if (!line) return {{"ok", false}, {"error", "no reply"}};
      json j = json::parse(*line);
      if (j.contains("event")) {
        events_.push_back(j);
        continue;
      }
      return j;
    }
  }
  std::optional<json> WaitEvent(const std::string& name, int timeout_ms) {
    const std::int64_t end = NowNs() + timeout_ms * kMs;
    for (;;) {
      while (!events_.empty()) {
        json e = events_.front();
        events_.pop_front();
        seen_.push_back(e);
        if (e.value("event", "") == name) return e;
      }
      const std::int64_t left = (end - NowNs()) / kMs;
      if (left <= 0) return std::nullopt;
      std::optional<std::string> line = ReadLine(static_cast<int>(left));
      if (!line) return std::nullopt;
      events_.push_back(json::parse(*line));
    }
  }
  const std::vector<json>& seen() const { return seen_; }

 private:
  explicit Conn(int fd) : fd_(fd) {}
  int fd_;
  std::string buf_;
  std::deque<json> events_;
  std::vector<json> seen_;
};

class DaemonProcess {
 public:
  DaemonProcess(const TempDir& dir, const json& config, const std::string& tag = "daemon",
                const std::vector<std::string>& env = {})
      : dir_(dir) {
    config_path_ = dir.File(tag + ".json");
    std::ofstream(config_path_) << config.dump(2);
    socket_ = config.at("socket").get<std::string>();
    sim_log_ = config.at("gpio").value("sim_log", "");
    log_ = dir.File(tag + ".log");
    pid_ = Spawn({"daemon", "--config", config_path_}, log_, env);
  }
  ~DaemonProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      int status;
      ::waitpid(pid_, &status, 0);
    }
  }
  // True once the socket accepts connections.
  bool WaitReady(int timeout_ms = 5000) {
    const std::int64_t end = NowNs() + timeout_ms * kMs;
    while (NowNs() < end) {
      if (Conn::Connect(socket_)) return true;
      int status;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return false;
      }
      SleepMs(2);
    }
    return false;
  }
  int Exit(int timeout_ms) {
    const int code = WaitExit(pid_, timeout_ms);
    pid_ = -1;
    return code;
  }
  bool Alive() {
    int status;
    return pid_ > 0 && ::waitpid(pid_, &status, WNOHANG) == 0;
  }
  pid_t pid() const { return pid_; }
  const std::string& socket() const { return socket_; }
  std::string log() const { return ReadText(log_); }
  std::vector<SimLineEvent> SimLog() const {
    auto r = ReadSimLog(sim_log_);
    return r.ok() ? r.value() : std::vector<SimLineEvent>{};
  }
  // Waits until the sim log has a write of `name` to `active` at or after
  // `after_ns`; returns its time or -1.
  std::int64_t WaitLine(const std::string& name, bool active, std::int64_t after_ns, int timeout_ms) const {
    const std::int64_t end = NowNs() + timeout_ms * kMs;
    for (;;) {
      for (const SimLineEvent& e : SimLog()) {
        if (e.name == name && e.active == active && e.t_ns >= after_ns) return e.t_ns;
      }
      if (NowNs() > end) return -1;
      SleepMs(1);
    }
  }
  // Last written state of each line.
  std::map<std::string, bool> FinalState() const {
    std::map<std::string, bool> s;
    for (const SimLineEvent& e : SimLog()) s[e.name] = e.active;
    return s;
  }

 private:
  const TempDir& dir_;
  std::string config_path_, socket_, sim_log_, log_;
  pid_t pid_ = -1;
};

struct Change {
  std::int64_t t_ns;
  std::string name;
  bool active;
};

// Actual changes (repeated values dropped), after the request's initial
// inactive writes.
inline std::vector<Change> Changes(const std::vector<SimLineEvent>& log) {
  std::map<std::string, bool> state;
  std::vector<Change> out;
  for (const SimLineEvent& e : log) {
    auto it = state.find(e.name);
    const bool first = it == state.end();
    if (!first && it->second == e.active) continue;
    state[e.name] = e.active;
    if (!first) out.push_back({e.t_ns, e.name, e.active});
  }
  return out;
}

inline bool LasersOff(const std::map<std::string, bool>& s) {
  auto off = [&](const char* n) { auto it = s.find(n); return it == s.end() || !it->second; };
  return off("laser_a") && off("laser_b");
}

inline double Ms(std::int64_t ns) { return static_cast<double>(ns) / 1e6; }

}  // namespace opl::sequencer::testing

#endif  // OPL_TESTS_SEQUENCER_DAEMON_HARNESS_H_
