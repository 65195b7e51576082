// `replay`: a recorded session's states published over DDS as they happened. The server's own
// code publishes them (one implementation of every state topic): ignavctl runs a read-only
// ignav-server in its place, on this client's domain and DDS configuration.
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>

#include "subcommands.hpp"

namespace ignav::ctl {
namespace {

struct ReplayOptions {
  std::string session;
  std::string speed = "1";
  std::uint64_t until = 0;  // 0: to the end
  std::string server_config = "configs/server.yaml";
  std::string server_identity;  // empty: --insecure
};

// ignav-server: $IGNAV_SERVER, else next to this program (installed) or in the build tree.
std::string serverExecutable() {
  if (const char* env = std::getenv("IGNAV_SERVER")) return env;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path();
  for (const auto& candidate : {self / "ignav-server", self / "../../server/ignav-server"}) {
    if (std::filesystem::exists(candidate, ec)) return candidate.lexically_normal().string();
  }
  return "ignav-server";
}

// Returns only when the server could not be run.
int replay(const GlobalOptions& g, const ReplayOptions& o) {
  const std::string server = serverExecutable();
  std::vector<std::string> args{
      server,  "--config", o.server_config,          "--replay",     o.session,   "--speed",
      o.speed, "--domain", std::to_string(g.domain), "--dds-config", g.dds_config};
  if (!g.dds_site.interface.empty()) {
    args.push_back("--dds-interface");
    args.push_back(g.dds_site.interface);
  }
  for (const auto& peer : g.dds_site.peers) {
    args.push_back("--dds-peer");
    args.push_back(peer);
  }
  if (!g.robot_id.empty()) {  // else the server's: its config's robot id with -replay
    args.push_back("--robot-id");
    args.push_back(g.robot_id);
  }
  if (!o.server_identity.empty()) {
    args.push_back("--identity");
    args.push_back(o.server_identity);
  } else {
    args.push_back("--insecure");
  }
  if (o.until != 0) {
    args.push_back("--until");
    args.push_back(std::to_string(o.until));
  }
  std::vector<char*> argv_exec;
  for (auto& a : args)
    argv_exec.push_back(a.data());
  argv_exec.push_back(nullptr);
  ::execvp(server.c_str(), argv_exec.data());
  std::cerr << "ignavctl: cannot run " << server << ": " << std::strerror(errno)
            << " (set IGNAV_SERVER to its path)\n";
  return kExitUsage;
}

}  // namespace

void addReplay(CLI::App& app, Action& chosen) {
  auto o = std::make_shared<ReplayOptions>();
  auto* sub = app.add_subcommand(
      "replay",
      "publish a recorded session's states over DDS as they happened (a read-only "
      "ignav-server)");
  sub->add_option("session", o->session, "the session folder")->required();
  sub->add_option("--speed", o->speed, "1, 10, ... times real time, or max");
  sub->add_option("--until", o->until, "stop at this revision (journal sequence number)");
  sub->add_option("--server-config", o->server_config, "server YAML (robot config)");
  sub->add_option("--server-identity", o->server_identity,
                  "the replaying server's DDS Security identity (a service identity)");
  sub->callback(
      [&chosen, o] { chosen.run_alone = [o](const GlobalOptions& g) { return replay(g, *o); }; });
}

}  // namespace ignav::ctl
