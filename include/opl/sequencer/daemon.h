// RunDaemon: the opl_sequencer daemon as a library function, and the exit
// codes of the opl_sequencer program.
//
// One thread, one epoll loop over: the listening Unix socket, the clients, a
// signalfd (SIGTERM, SIGINT, SIGHUP) and one timerfd (CLOCK_MONOTONIC,
// absolute) armed at the earliest of the sequencer's next action, the laser
// deadlines and the systemd watchdog ping. Signals are therefore handled
// between two GPIO writes, never inside one.
//
// Control protocol (docs/sequencer.md): line-delimited JSON over the Unix
// socket; each request line gets exactly one reply line
// {"ok":true,...} or {"ok":false,"error":"..."} (with the request's "id"
// echoed when it had one); asynchronous {"event":...} lines go to the client
// that owns the running sequence or a manual laser, and to subscribers.
//
// Clients: at most max_clients regular ones, plus kReserveClientSlots
// reserve ones (below). A regular client that sends no request line for
// client_idle_timeout_ms (and is neither subscribed nor the owner of the
// running sequence or a manual laser) gets {"event":"disconnect","reason":...}
// and is closed.
//
// Safety: every line is driven off at start, on SIGTERM/SIGINT/SIGHUP (then
// the daemon exits 0), when the owner of a sequence or of a manual laser
// disconnects, when a laser deadline passes, on abort, and on a GPIO error
// (then the daemon exits kExitGpioRuntime so that systemd restarts it).
#ifndef OPL_SEQUENCER_DAEMON_H_
#define OPL_SEQUENCER_DAEMON_H_

#include <string>

#include "opl/sequencer/config.h"

namespace opl::sequencer {

// Connections accepted beyond SequencerConfig::max_clients: each may only
// abort, switch a laser off or ask for status, and is closed after 2 s
// without a request; when all are taken, the oldest gives way to the newest.
// So a crowd of idle connections never locks out stopping the lasers.
inline constexpr int kReserveClientSlots = 4;

// Exit codes of opl_sequencer (daemon and client subcommands).
enum ExitCode : int {
  kExitOk = 0,              // daemon: stopped by a signal, every line off;
                            // client: request accepted / sequence done
  kExitRefused = 1,         // client: the daemon replied {"ok":false}
  kExitUsage = 2,           // bad command line
  kExitConfig = 3,          // configuration unreadable or invalid
  kExitGpioSetup = 4,       // daemon: chip could not be opened / lines requested
  kExitSocket = 5,          // daemon: socket in use by another daemon, or bind/listen failed
  kExitGpioRuntime = 6,     // daemon: a GPIO write failed while running; lines driven off
  kExitInternal = 7,        // daemon: epoll/timerfd/signalfd failure
  kExitNoDaemon = 10,       // client: cannot connect, or the daemon closed the connection
  kExitSequenceFailed = 11, // client: the followed sequence was aborted / laser cut by error
};

// Runs the daemon until a terminating signal or a fatal error. Blocks
// SIGTERM, SIGINT and SIGHUP for the calling thread (they are read through a
// signalfd) and ignores SIGPIPE. Returns an ExitCode; `message` (optional)
// receives a one-line explanation of a non-zero code.
int RunDaemon(const SequencerConfig& config, std::string* message);

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_DAEMON_H_
