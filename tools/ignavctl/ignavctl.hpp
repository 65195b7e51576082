// What ignavctl's subcommand groups share: the exit codes, ignavctl's own options, the domain and
// the server they reach (connection.cpp), and the work a parsed subcommand leaves for main().
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "ignav/protocol/client.hpp"

namespace ignav::ctl {

// Exit codes: scripts and tests rely on them.
constexpr int kExitRejected = 1;  // refused, failed, or a check found a problem
constexpr int kExitUsage = 2;
constexpr int kExitNoServer = 3;  // nothing answers, or the server's state did not all arrive

// A command line ignavctl cannot act on: exit 2, with the message.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The main app's options (main.cpp): before or after the subcommand.
struct GlobalOptions {
  std::uint32_t domain = 0;
  std::string dds_config = "loopback";
  protocol::DdsSite dds_site;
  std::string client_id;
  bool as_json = false;
  double wait_s = 10.0;
  std::string robot_id;  // empty: the only robot on the domain
  std::string identity;  // a DDS Security identity folder; empty: security off
};

// The DDS domain as the options reach it: for what talks to no one robot (robots, doctor).
struct Domain {
  const GlobalOptions& options;
  std::string xml;  // the Cyclone configuration
  std::optional<protocol::SecurityIdentity> security;
  std::chrono::milliseconds wait;  // --wait-server
  const protocol::SecurityIdentity* identity() const { return security ? &*security : nullptr; }
};

// One robot's server, matched, with its state as far as it arrived.
struct Server {
  protocol::Client& client;
  bool as_json;
  bool present;  // every state topic's present arrived (Client::waitForPresent)

  // Sends a command and prints its reply; the exit code.
  int send(const std::string& command, const protocol::CommandArgs& args = {}) const;
  // Sends a command that starts a background job (load_volume, auto_fiducials, load_confirmation)
  // and waits up to `wait_s` for the job's outcome (JobOutcome, named by the reply's job), then
  // for the state up to the step that took it. The reply is printed when refused, and always
  // without --json; nullopt when refused.
  std::optional<protocol::JobOutcome> sendAndAwaitJob(const std::string& command,
                                                      const protocol::CommandArgs& args,
                                                      double wait_s,
                                                      protocol::Reply* reply = nullptr) const;
  // What a view says when the present did not all arrive: never "none" for "not yet heard"
  // (issue 38). Exit 3.
  int notYetKnown() const;
};

// What a subcommand does with the server; its exit code.
using Work = std::function<int(Server&)>;

// What the parsed subcommand does, set by its CLI11 callback: exactly one of these.
struct Action {
  std::function<int(const GlobalOptions&)> run_alone;  // joins no domain itself (replay)
  std::function<int(const Domain&)> on_domain;         // robots, doctor
  Work on_server;                                      // every other subcommand
};

// The domain the options name: its DDS configuration and security identity (warns when off).
Domain openDomain(const GlobalOptions& options);
// Finds the robot's server, waits for it and for its present, and runs `work` against it.
int withServer(const Domain& domain, const Work& work);

}  // namespace ignav::ctl
