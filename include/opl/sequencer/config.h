// SequencerConfig: the daemon's configuration file (JSON), see
// examples/sequencer/sequencer.json and docs/sequencer.md.
//
//   {
//     "gpio": {"backend": "gpiod", "chip": "gpiochip0", "consumer": "opl-sequencer"},
//     "lines": {
//       "laser_a": {"offset": 17, "active_low": false},
//       "laser_b": {"offset": 27, "active_low": false},
//       "blocker": {"offset": 22, "active_low": false},
//       "trigger": {"offset": 23, "active_low": true}
//     },
//     "timings_ms": {"laser_warmup": 50, "blocker_settle": 80,
//                    "trigger_pulse": 1, "exposure": 30, "max_laser_on": 1000},
//     "socket": "/run/opl-sequencer/sequencer.sock",
//     "metadata": "/var/lib/opl/sequencer/frames.jsonl"
//   }
//
// Unknown keys are errors (a misspelt "max_laser_on" must not silently fall
// back to a default). Every field has a default except the line offsets.
#ifndef OPL_SEQUENCER_CONFIG_H_
#define OPL_SEQUENCER_CONFIG_H_

#include <cstddef>
#include <string>

#include "opl/sequencer/status.h"

namespace opl::sequencer {

// The four roles of the module's GPIO lines; the value is the index of the
// line in every per-line array of the library.
enum class LineRole : std::size_t { kLaserA = 0, kLaserB = 1, kBlocker = 2, kTrigger = 3 };
inline constexpr std::size_t kNumLines = 4;
// "laser_a", "laser_b", "blocker", "trigger".
const char* LineRoleName(LineRole role) noexcept;

struct LineConfig {
  int offset = -1;          // line offset on the chip; required, >= 0
  bool active_low = false;  // true: on / closed / asserted is the low level
};

struct Timings {
  // Laser warm-up: time from switching a laser on to the trigger, ms.
  double laser_warmup_ms = 50.0;
  // Blocker settle: time from moving the blocker to the trigger, ms.
  double blocker_settle_ms = 80.0;
  // Width of the camera trigger pulse, ms. > 0.
  double trigger_pulse_ms = 1.0;
  // Exposure: time from the trigger's rising edge to switching the lasers
  // off at the end of a frame, ms. >= trigger_pulse_ms.
  double exposure_ms = 30.0;
  // Longest a laser may stay on, in a sequence, ms; a manual "laser on" asks
  // for its own limit, which may not exceed this. A frame's laser-on time,
  // max(laser_warmup, blocker_settle) + exposure, must be below it.
  double max_laser_on_ms = 1000.0;
};

struct SequencerConfig {
  // "gpiod" (libgpiod, real hardware) or "sim" (SimChip, tests / dry runs).
  std::string backend = "gpiod";
  // gpiod: chip name, path, label or number (gpiod_chip_open_lookup).
  std::string chip = "gpiochip0";
  // Consumer label shown by gpioinfo.
  std::string consumer = "opl-sequencer";
  // sim: JSON-lines file of every line change (see sim_chip.h); may be empty.
  std::string sim_log;
  // sim, tests only: the n-th GPIO write fails (0: none).
  long sim_fail_write_number = 0;

  LineConfig lines[kNumLines];  // indexed by LineRole
  Timings timings;

  // Unix socket of the control protocol.
  std::string socket_path = "/run/opl-sequencer/sequencer.sock";
  // Default per-frame metadata JSON-lines file; a start or trigger command
  // may name another. Empty: the command must name one.
  std::string metadata_path;
  // Longest request line, bytes, newline excluded; longer lines get an error
  // reply and are discarded. 64 .. 1 MiB.
  std::size_t max_message_bytes = 4096;
  // Most clients connected at once. A connection beyond them takes one of
  // kReserveClientSlots reserve slots (daemon.h), which accept only abort,
  // laser off and status.
  int max_clients = 16;

  // A client that has sent no request line for this long is told why and
  // disconnected, unless it is subscribed or owns the running sequence or a
  // manual laser (its silence is then expected). 0: never. 0 or 100 .. 86400000.
  double client_idle_timeout_ms = 60000.0;

  const LineConfig& line(LineRole role) const { return lines[static_cast<std::size_t>(role)]; }
  LineConfig& line(LineRole role) { return lines[static_cast<std::size_t>(role)]; }

  // True if usable; else false with `error` naming the field, its value and
  // the broken constraint.
  bool IsValid(std::string* error) const;
};

// Parses and validates a configuration from JSON text.
Result<SequencerConfig> ParseConfig(const std::string& json_text);
// Reads, parses and validates a configuration file.
Result<SequencerConfig> LoadConfig(const std::string& path);

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_CONFIG_H_
