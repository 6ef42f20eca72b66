// RunClient: the client side of the control protocol, for the opl_sequencer
// client subcommands and for scripts.
//
// Sends one request line and prints the reply line. With `follow`, it then
// stays connected and prints every event line until the thing it started
// has ended: this matters because the daemon aborts a sequence (and switches
// a manual laser off) when the client that started it disconnects.
#ifndef OPL_SEQUENCER_CLIENT_H_
#define OPL_SEQUENCER_CLIENT_H_

#include <iosfwd>
#include <string>

namespace opl::sequencer {

enum class FollowMode {
  kNone,      // print the reply and return
  kSequence,  // until a "done" (kExitOk) or "aborted" / "gpio_error" event
  kLaser,     // until a "laser_off" event for `laser`
};

struct ClientOptions {
  std::string socket_path;       // daemon's Unix socket
  double connect_timeout_ms = 2000.0;
  double reply_timeout_ms = 5000.0;  // for the reply line
  FollowMode follow = FollowMode::kNone;
  std::string laser;  // kLaser: "a" or "b"
  // kSequence: each line read from stdin sends {"cmd":"next_slice"}
  // (an operator presses Enter after moving the screen).
  bool stdin_next_slice = false;
};

// Returns an ExitCode (daemon.h).
int RunClient(const ClientOptions& options, const std::string& request_line,
              std::ostream& out, std::ostream& err);

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_CLIENT_H_
