#include "opl/sequencer/client.h"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "opl/sequencer/daemon.h"

namespace opl::sequencer {
namespace {

using nlohmann::json;

class LineReader {
 public:
  explicit LineReader(int fd) : fd_(fd) {}
  // 1: a line; 0: EOF; -1: timeout; -2: error.
  int Next(std::string* line, int timeout_ms) {
    for (;;) {
      const std::size_t nl = buf_.find('\n');
      if (nl != std::string::npos) {
        *line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return 1;
      }
      if (eof_) return 0;
      pollfd p{fd_, POLLIN, 0};
      const int r = ::poll(&p, 1, timeout_ms);
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) return -2;
      if (r == 0) return -1;
      if (!Fill()) return buf_.empty() ? 0 : -2;
    }
  }
  // Reads what is available; false on EOF or error.
  bool Fill() {
    char tmp[4096];
    const ssize_t n = ::read(fd_, tmp, sizeof tmp);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) return true;
    if (n <= 0) {
      eof_ = true;
      return false;
    }
    buf_.append(tmp, static_cast<std::size_t>(n));
    return true;
  }
  bool HasLine() const { return buf_.find('\n') != std::string::npos; }
  int fd() const { return fd_; }

 private:
  int fd_;
  std::string buf_;
  bool eof_ = false;
};

bool SendAll(int fd, const std::string& data) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::send(fd, data.data() + done, data.size() - done, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

// What a daemon line tells a person: the "error" of a refusal, the "reason"
// of a disconnect or the "message" of a notice; empty for anything else.
std::string DaemonText(const json& j) {
  if (!j.is_object()) return "";
  for (const char* key : {"error", "reason", "message"}) {
    if (j.contains(key) && j.at(key).is_string()) return j.at(key).get<std::string>();
  }
  return "";
}

// "the daemon closed the connection", with the last thing it said.
std::string Closed(const std::string& said) {
  return "opl_sequencer: the daemon closed the connection" + (said.empty() ? std::string() : ": " + said) + "\n";
}

int ToMs(double ms) { return ms <= 0 || !std::isfinite(ms) ? 0 : ms > 1e9 ? 1000000000 : static_cast<int>(ms); }

}  // namespace

int RunClient(const ClientOptions& options, const std::string& request_line, std::ostream& out, std::ostream& err) {
  if (options.socket_path.empty() || options.socket_path.size() >= sizeof(sockaddr_un{}.sun_path)) {
    err << "opl_sequencer: socket path '" << options.socket_path << "' is empty or too long\n";
    return kExitUsage;
  }
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    err << "opl_sequencer: socket: " << std::strerror(errno) << "\n";
    return kExitNoDaemon;
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, options.socket_path.data(), options.socket_path.size());
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    err << "opl_sequencer: cannot connect to the daemon at '" << options.socket_path << "': " << std::strerror(errno) << "\n";
    return kExitNoDaemon;
  }
  LineReader reader(fd);
  std::string line;
  std::string said;  // the daemon's last notice, disconnect reason or error
  if (!SendAll(fd, request_line + "\n")) {
    const std::string why = std::strerror(errno);
    // The daemon may have written why it closed the connection ("too many
    // clients", an idle timeout) before closing it: say that, not EPIPE.
    while (reader.Next(&line, 200) == 1) {
      json j = json::parse(line, nullptr, false);
      if (!DaemonText(j).empty()) said = DaemonText(j);
      if (j.is_object() && j.contains("ok") && j.at("ok").is_boolean() && !j.at("ok").get<bool>()) {
        out << line << "\n" << std::flush;
        err << "opl_sequencer: the daemon refused: " << said << "\n";
        return kExitRefused;
      }
    }
    err << "opl_sequencer: sending the request failed: " << why << (said.empty() ? "" : " (the daemon said: " + said + ")") << "\n";
    return kExitNoDaemon;
  }
  // The reply: the first line that is not an event.
  for (;;) {
    const int r = reader.Next(&line, ToMs(options.reply_timeout_ms));
    if (r == -1) {
      err << "opl_sequencer: no reply within " << options.reply_timeout_ms << " ms\n";
      return kExitNoDaemon;
    }
    if (r != 1) {
      err << Closed(said);
      return kExitNoDaemon;
    }
    out << line << "\n" << std::flush;
    json j = json::parse(line, nullptr, false);
    if (!DaemonText(j).empty()) said = DaemonText(j);
    if (j.is_object() && j.contains("event")) continue;
    if (!j.is_object() || !j.contains("ok") || !j.at("ok").is_boolean()) {
      err << "opl_sequencer: unexpected reply\n";
      return kExitNoDaemon;
    }
    if (!j.at("ok").get<bool>()) {
      err << "opl_sequencer: the daemon refused: " << said << "\n";
      return kExitRefused;
    }
    break;
  }
  if (options.follow == FollowMode::kNone) return kExitOk;

  bool watch_stdin = options.follow == FollowMode::kSequence && options.stdin_next_slice;
  std::string stdin_buf;
  for (;;) {
    while (reader.HasLine()) {
      reader.Next(&line, 0);
      out << line << "\n" << std::flush;
      json j = json::parse(line, nullptr, false);
      if (!DaemonText(j).empty()) said = DaemonText(j);
      if (!j.is_object() || !j.contains("event") || !j.at("event").is_string()) continue;
      const std::string ev = j.at("event").get<std::string>();
      if (ev == "shutdown" || ev == "gpio_error") return kExitSequenceFailed;
      if (options.follow == FollowMode::kSequence) {
        if (ev == "done") return kExitOk;
        if (ev == "aborted") return kExitSequenceFailed;
        if (ev == "waiting_operator" && watch_stdin) {
          err << "Move the screen to the next slice, then press Enter.\n";
        }
      } else if (ev == "laser_off" && j.value("laser", std::string()) == options.laser) {
        return j.value("message", std::string()) == "limit" || j.value("message", std::string()) == "requested"
                   ? kExitOk
                   : kExitSequenceFailed;
      }
    }
    pollfd p[2] = {{fd, POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}};
    const int r = ::poll(p, watch_stdin ? 2 : 1, -1);
    if (r < 0) {
      if (errno == EINTR) continue;
      err << "opl_sequencer: poll: " << std::strerror(errno) << "\n";
      return kExitNoDaemon;
    }
    if (p[0].revents != 0 && !reader.Fill() && !reader.HasLine()) {
      err << Closed(said);
      return kExitNoDaemon;
    }
    if (watch_stdin && p[1].revents != 0) {
      char tmp[256];
      const ssize_t n = ::read(STDIN_FILENO, tmp, sizeof tmp);
      if (n <= 0) {
        watch_stdin = false;
      } else {
        stdin_buf.append(tmp, static_cast<std::size_t>(n));
        std::size_t nl;
        while ((nl = stdin_buf.find('\n')) != std::string::npos) {
          stdin_buf.erase(0, nl + 1);
          if (!SendAll(fd, "{\"cmd\":\"next_slice\"}\n")) {
            err << Closed(said);
            return kExitNoDaemon;
          }
        }
      }
    }
  }
}

}  // namespace opl::sequencer
