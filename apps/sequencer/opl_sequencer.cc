// opl_sequencer: GPIO sequencer daemon for the laser module, and its client.
//
//   opl_sequencer daemon --config /etc/opl/sequencer.json
//   opl_sequencer check-config --config /etc/opl/sequencer.json
//   opl_sequencer client status
//   opl_sequencer client start measurement [--metadata frames.jsonl]
//   opl_sequencer client start calibration --slices 5      (Enter = next slice)
//   opl_sequencer client next-slice | abort
//   opl_sequencer client laser a on --limit-ms 500          (blocks until off)
//   opl_sequencer client laser a off
//   opl_sequencer client blocker closed|open
//   opl_sequencer client trigger [--metadata frames.jsonl]
//   opl_sequencer client send '{"cmd":"status","id":1}'
//
// Exit codes: see opl/sequencer/daemon.h and docs/sequencer.md.
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "opl/sequencer/client.h"
#include "opl_version_git.h"  // generated: OPL_VERSION_NUMBER, OPL_GIT_DESCRIBE
#include "opl/sequencer/config.h"
#include "opl/sequencer/daemon.h"

namespace seq = opl::sequencer;

int main(int argc, char** argv) {
  CLI::App app{"OPL laser-module GPIO sequencer: daemon and client"};
  app.set_version_flag("--version", std::string("opl_sequencer ") + OPL_VERSION_NUMBER + " (commit " +
                                         OPL_GIT_DESCRIBE + ")",
                       "Print the version and the commit it was built from, and exit");
  app.require_subcommand(1);

  std::string config_path;
  CLI::App* daemon = app.add_subcommand("daemon", "Run the sequencer daemon (every laser off on start and exit)");
  daemon->add_option("-c,--config", config_path, "Configuration file (JSON)")->required();

  CLI::App* check = app.add_subcommand("check-config", "Validate a configuration file and exit");
  check->add_option("-c,--config", config_path, "Configuration file (JSON)")->required();

  CLI::App* client = app.add_subcommand("client", "Send a request to the running daemon");
  client->require_subcommand(1);
  std::string socket_path;
  std::string client_config;
  double timeout_ms = 5000.0;
  client->add_option("-s,--socket", socket_path, "Daemon socket (default: from --config, else /run/opl-sequencer/sequencer.sock)");
  client->add_option("-c,--config", client_config, "Read the socket path from this configuration file");
  client->add_option("--timeout-ms", timeout_ms, "Wait at most this long for the reply, ms")->check(CLI::PositiveNumber);

  client->add_subcommand("status", "Print the daemon's state");
  client->add_subcommand("abort", "Abort the sequence and switch every laser off");
  client->add_subcommand("next-slice", "Calibration: the screen was moved, capture the next slice");

  std::string sequence;
  int slices = 1;
  std::string metadata;
  bool no_stdin = false;
  CLI::App* start = client->add_subcommand("start", "Run a sequence; stays connected until it ends (disconnecting aborts it)");
  start->add_option("sequence", sequence, "measurement or calibration")->required()->check(CLI::IsMember({"measurement", "calibration"}));
  start->add_option("--slices", slices, "Calibration: number of slices")->check(CLI::Range(1, 10000));
  start->add_option("--metadata", metadata, "Per-frame metadata JSON-lines file (default: from the daemon's configuration)");
  start->add_flag("--no-stdin", no_stdin, "Do not read Enter from stdin for next slice");

  std::string laser;
  std::string on_off;
  double limit_ms = 0.0;
  CLI::App* laser_cmd = client->add_subcommand("laser", "Manual laser on (with a time limit; blocks until off) or off");
  laser_cmd->add_option("laser", laser, "a or b")->required()->check(CLI::IsMember({"a", "b"}));
  laser_cmd->add_option("state", on_off, "on or off")->required()->check(CLI::IsMember({"on", "off"}));
  laser_cmd->add_option("--limit-ms", limit_ms, "On: switch off after this many ms (<= max_laser_on)")->check(CLI::PositiveNumber);

  std::string blocker_state;
  CLI::App* blocker = client->add_subcommand("blocker", "Manual blocker: closed (hides grid B) or open");
  blocker->add_option("state", blocker_state, "closed or open")->required()->check(CLI::IsMember({"closed", "open"}));

  std::string trigger_metadata;
  CLI::App* trigger = client->add_subcommand("trigger", "Manual camera trigger pulse, with a metadata line");
  trigger->add_option("--metadata", trigger_metadata, "Metadata JSON-lines file (default: from the daemon's configuration)");

  std::string raw;
  CLI::App* send = client->add_subcommand("send", "Send one raw JSON request line, print the reply");
  send->add_option("json", raw, "Request, e.g. '{\"cmd\":\"status\"}'")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);  // prints the version on stdout, returns 0
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return seq::kExitUsage;
  }

  if (daemon->parsed() || check->parsed()) {
    opl::sequencer::Result<seq::SequencerConfig> config = seq::LoadConfig(config_path);
    if (!config.ok()) {
      std::cerr << "opl_sequencer: " << config.status().message() << "\n";
      return seq::kExitConfig;
    }
    if (check->parsed()) {
      std::cout << "configuration '" << config_path << "' is valid\n";
      return seq::kExitOk;
    }
    std::string message;
    const int code = seq::RunDaemon(config.value(), &message);
    if (code != seq::kExitOk) {
      std::cerr << "opl_sequencer: " << message << "\n";
    } else if (!message.empty()) {
      std::cerr << "opl_sequencer: " << message << "\n";
    }
    return code;
  }

  // Client.
  seq::ClientOptions options;
  options.reply_timeout_ms = timeout_ms;
  if (!socket_path.empty()) {
    options.socket_path = socket_path;
  } else if (!client_config.empty()) {
    opl::sequencer::Result<seq::SequencerConfig> config = seq::LoadConfig(client_config);
    if (!config.ok()) {
      std::cerr << "opl_sequencer: " << config.status().message() << "\n";
      return seq::kExitConfig;
    }
    options.socket_path = config.value().socket_path;
  } else {
    options.socket_path = seq::SequencerConfig().socket_path;
  }

  nlohmann::json request;
  std::string line;
  if (client->got_subcommand("status")) {
    request = {{"cmd", "status"}};
  } else if (client->got_subcommand("abort")) {
    request = {{"cmd", "abort"}};
  } else if (client->got_subcommand("next-slice")) {
    request = {{"cmd", "next_slice"}};
  } else if (start->parsed()) {
    request = {{"cmd", "start"}, {"sequence", sequence}};
    if (sequence == "calibration") request["slices"] = slices;
    if (!metadata.empty()) request["metadata"] = metadata;
    options.follow = seq::FollowMode::kSequence;
    options.stdin_next_slice = !no_stdin;
  } else if (laser_cmd->parsed()) {
    request = {{"cmd", "laser"}, {"laser", laser}, {"on", on_off == "on"}};
    if (on_off == "on") {
      if (limit_ms <= 0.0) {
        std::cerr << "opl_sequencer: laser on needs --limit-ms\n";
        return seq::kExitUsage;
      }
      request["limit_ms"] = limit_ms;
      options.follow = seq::FollowMode::kLaser;
      options.laser = laser;
    }
  } else if (blocker->parsed()) {
    request = {{"cmd", "blocker"}, {"closed", blocker_state == "closed"}};
  } else if (trigger->parsed()) {
    request = {{"cmd", "trigger"}};
    if (!trigger_metadata.empty()) request["metadata"] = trigger_metadata;
  } else if (send->parsed()) {
    line = raw;
  }
  if (line.empty()) line = request.dump();
  return seq::RunClient(options, line, std::cout, std::cerr);
}
