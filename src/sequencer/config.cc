#include "opl/sequencer/config.h"

#include <sys/un.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

namespace opl::sequencer {
namespace {

using nlohmann::json;

constexpr double kLongestTimingMs = 600000.0;  // 10 min

std::string Num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Throws std::runtime_error with a message naming `where`.
class Reader {
 public:
  explicit Reader(std::string where) : where_(std::move(where)) {}
  [[noreturn]] void Fail(const std::string& key, const std::string& what) const {
    throw std::runtime_error(where_ + key + ": " + what);
  }
  void CheckKeys(const json& j, std::initializer_list<const char*> allowed) const {
    if (!j.is_object()) Fail("", "must be an object");
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* k) { return it.key() == k; })) {
        Fail(it.key(), "unknown key");
      }
    }
  }
  std::string String(const json& j, const char* key, const std::string& fallback) const {
    if (!j.contains(key)) return fallback;
    if (!j.at(key).is_string()) Fail(key, "must be a string");
    return j.at(key).get<std::string>();
  }
  bool Bool(const json& j, const char* key, bool fallback) const {
    if (!j.contains(key)) return fallback;
    if (!j.at(key).is_boolean()) Fail(key, "must be true or false");
    return j.at(key).get<bool>();
  }
  double Number(const json& j, const char* key, double fallback) const {
    if (!j.contains(key)) return fallback;
    if (!j.at(key).is_number()) Fail(key, "must be a number");
    return j.at(key).get<double>();
  }
  long long Integer(const json& j, const char* key, long long fallback) const {
    if (!j.contains(key)) return fallback;
    const json& v = j.at(key);
    if (!v.is_number_integer()) Fail(key, "must be an integer");
    if (v.is_number_unsigned() && v.get<unsigned long long>() > 1000000000ULL) Fail(key, "too large");
    return v.get<long long>();
  }
  const std::string& where() const { return where_; }

 private:
  std::string where_;
};

SequencerConfig FromJson(const json& root) {
  SequencerConfig c;
  Reader top("");
  top.CheckKeys(root, {"gpio", "lines", "timings_ms", "socket", "metadata", "max_message_bytes", "max_clients",
                      "client_idle_timeout_ms"});
  if (root.contains("gpio")) {
    Reader r("gpio.");
    const json& g = root.at("gpio");
    r.CheckKeys(g, {"backend", "chip", "consumer", "sim_log", "sim_fail_write_number"});
    c.backend = r.String(g, "backend", c.backend);
    c.chip = r.String(g, "chip", c.chip);
    c.consumer = r.String(g, "consumer", c.consumer);
    c.sim_log = r.String(g, "sim_log", c.sim_log);
    c.sim_fail_write_number = static_cast<long>(r.Integer(g, "sim_fail_write_number", 0));
  }
  if (!root.contains("lines")) top.Fail("lines", "missing (laser_a, laser_b, blocker, trigger offsets are required)");
  {
    Reader r("lines.");
    const json& l = root.at("lines");
    r.CheckKeys(l, {"laser_a", "laser_b", "blocker", "trigger"});
    for (std::size_t i = 0; i < kNumLines; ++i) {
      const char* name = LineRoleName(static_cast<LineRole>(i));
      if (!l.contains(name)) r.Fail(name, "missing");
      Reader rl("lines." + std::string(name) + ".");
      const json& one = l.at(name);
      rl.CheckKeys(one, {"offset", "active_low"});
      if (!one.contains("offset")) rl.Fail("offset", "missing");
      c.lines[i].offset = static_cast<int>(rl.Integer(one, "offset", -1));
      c.lines[i].active_low = rl.Bool(one, "active_low", false);
    }
  }
  if (root.contains("timings_ms")) {
    Reader r("timings_ms.");
    const json& t = root.at("timings_ms");
    r.CheckKeys(t, {"laser_warmup", "blocker_settle", "trigger_pulse", "exposure", "max_laser_on"});
    c.timings.laser_warmup_ms = r.Number(t, "laser_warmup", c.timings.laser_warmup_ms);
    c.timings.blocker_settle_ms = r.Number(t, "blocker_settle", c.timings.blocker_settle_ms);
    c.timings.trigger_pulse_ms = r.Number(t, "trigger_pulse", c.timings.trigger_pulse_ms);
    c.timings.exposure_ms = r.Number(t, "exposure", c.timings.exposure_ms);
    c.timings.max_laser_on_ms = r.Number(t, "max_laser_on", c.timings.max_laser_on_ms);
  }
  c.socket_path = top.String(root, "socket", c.socket_path);
  c.metadata_path = top.String(root, "metadata", c.metadata_path);
  c.max_message_bytes = static_cast<std::size_t>(std::max(0LL, top.Integer(root, "max_message_bytes", 4096)));
  c.max_clients = static_cast<int>(top.Integer(root, "max_clients", c.max_clients));
  c.client_idle_timeout_ms = top.Number(root, "client_idle_timeout_ms", c.client_idle_timeout_ms);
  return c;
}

}  // namespace

const char* LineRoleName(LineRole role) noexcept {
  switch (role) {
    case LineRole::kLaserA: return "laser_a";
    case LineRole::kLaserB: return "laser_b";
    case LineRole::kBlocker: return "blocker";
    case LineRole::kTrigger: return "trigger";
  }
  return "unknown";
}

bool SequencerConfig::IsValid(std::string* error) const {
  auto fail = [&](const std::string& msg) {
    if (error != nullptr) *error = msg;
    return false;
  };
  if (backend != "gpiod" && backend != "sim") return fail("gpio.backend = '" + backend + "': must be 'gpiod' or 'sim'");
  if (backend == "gpiod" && chip.empty()) return fail("gpio.chip is empty: name the GPIO chip (e.g. gpiochip0)");
  if (consumer.empty() || consumer.size() > 31) return fail("gpio.consumer = '" + consumer + "': must be 1 to 31 characters");
  if (sim_fail_write_number < 0) return fail("gpio.sim_fail_write_number = " + std::to_string(sim_fail_write_number) + ": must be >= 0");
  for (std::size_t i = 0; i < kNumLines; ++i) {
    const std::string name = LineRoleName(static_cast<LineRole>(i));
    if (lines[i].offset < 0 || lines[i].offset > 65535) {
      return fail("lines." + name + ".offset = " + std::to_string(lines[i].offset) + ": must be 0 .. 65535");
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (lines[j].offset == lines[i].offset) {
        return fail("lines." + name + ".offset = " + std::to_string(lines[i].offset) + ": same line as lines." +
                    LineRoleName(static_cast<LineRole>(j)));
      }
    }
  }
  const Timings& t = timings;
  const std::pair<const char*, double> all[] = {{"laser_warmup", t.laser_warmup_ms}, {"blocker_settle", t.blocker_settle_ms},
                                                {"trigger_pulse", t.trigger_pulse_ms}, {"exposure", t.exposure_ms},
                                                {"max_laser_on", t.max_laser_on_ms}};
  for (const auto& [name, v] : all) {
    if (!std::isfinite(v) || v < 0.0 || v > kLongestTimingMs) {
      return fail(std::string("timings_ms.") + name + " = " + Num(v) + ": must be 0 .. " + Num(kLongestTimingMs) + " ms");
    }
  }
  if (t.trigger_pulse_ms <= 0.0) return fail("timings_ms.trigger_pulse = " + Num(t.trigger_pulse_ms) + ": must be > 0 ms");
  if (t.exposure_ms < t.trigger_pulse_ms) {
    return fail("timings_ms.exposure = " + Num(t.exposure_ms) + ": must be >= trigger_pulse (" + Num(t.trigger_pulse_ms) + " ms)");
  }
  const double frame_on_ms = std::max(t.laser_warmup_ms, t.blocker_settle_ms) + t.exposure_ms;
  if (!(t.max_laser_on_ms > frame_on_ms)) {
    return fail("timings_ms.max_laser_on = " + Num(t.max_laser_on_ms) +
                ": must exceed a frame's laser-on time max(laser_warmup, blocker_settle) + exposure = " + Num(frame_on_ms) + " ms");
  }
  if (socket_path.empty() || socket_path.size() >= sizeof(sockaddr_un{}.sun_path)) {
    return fail("socket = '" + socket_path + "': must be 1 to " + std::to_string(sizeof(sockaddr_un{}.sun_path) - 1) + " characters");
  }
  if (max_message_bytes < 64 || max_message_bytes > (1u << 20)) {
    return fail("max_message_bytes = " + std::to_string(max_message_bytes) + ": must be 64 .. 1048576");
  }
  if (max_clients < 1 || max_clients > 1024) return fail("max_clients = " + std::to_string(max_clients) + ": must be 1 .. 1024");
  if (!(client_idle_timeout_ms == 0 || (client_idle_timeout_ms >= 100 && client_idle_timeout_ms <= 86400000))) {
    return fail("client_idle_timeout_ms = " + Num(client_idle_timeout_ms) + ": must be 0 (never) or 100 .. 86400000");
  }
  return true;
}

namespace {

// A message made one safe line of bounded length (issue 19 item 7): JSON's
// "; last read: '...'" (an echo of up to a whole line of the file) is left
// out, control characters are escaped as \xHH, and the text is cut at 300
// bytes.
std::string SafeMessage(std::string message) {
  if (const size_t at = message.find("; last read: "); at != std::string::npos) message.resize(at);
  constexpr size_t kMaxBytes = 300;
  std::string out;
  for (const char c : message) {
    if (out.size() >= kMaxBytes) {
      out += "...";
      break;
    }
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      static const char* kHex = "0123456789abcdef";
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 15];
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

Result<SequencerConfig> ParseConfig(const std::string& json_text) {
  SequencerConfig config;
  try {
    config = FromJson(json::parse(json_text));
  } catch (const std::exception& e) {
    return Status(StatusCode::kInvalidArgument, "configuration: " + SafeMessage(e.what()));
  }
  std::string error;
  if (!config.IsValid(&error)) {
    return Status(StatusCode::kInvalidArgument, "configuration: " + SafeMessage(error));
  }
  return config;
}

Result<SequencerConfig> LoadConfig(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status(StatusCode::kNotFound, "configuration file '" + path + "' cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  Result<SequencerConfig> r = ParseConfig(ss.str());
  if (!r.ok()) return Status(r.status().code(), "'" + path + "': " + r.status().message());
  return r;
}

}  // namespace opl::sequencer
