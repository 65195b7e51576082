// ignav-server --config configs/server.yaml [--domain N] [--session-dir DIR] [--controller C]
//              [--igtl-port N]
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <optional>

#include "server.hpp"

namespace {
std::atomic<bool> g_stop{false};
void onSignal(int) {
  g_stop.store(true);
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ignav-server: the image-guided navigation server over DDS"};
  std::string config_path = "configs/server.yaml";
  std::optional<std::uint32_t> domain;
  std::string session_dir, robot, dds_config;
  app.add_option("--config", config_path, "server YAML");
  app.add_option("--domain", domain, "DDS domain id (overrides the config)");
  app.add_option("--session-dir", session_dir, "the session folder (default: a new one)");
  app.add_option("--robot", robot, "robot YAML (overrides the config)");
  app.add_option("--dds-config", dds_config,
                 "Cyclone XML, or a name: loopback, site-multicast, site-unicast (overrides the "
                 "config)");
  std::string dds_interface;
  app.add_option("--dds-interface", dds_interface,
                 "the network interface a site configuration uses (overrides dds.interface)");
  std::vector<std::string> dds_peers;
  app.add_option("--dds-peer", dds_peers,
                 "a unicast discovery peer, once per host (site-unicast; overrides dds.peers)");
  std::string robot_id;
  app.add_option("--robot-id", robot_id,
                 "this robot's id on the DDS domain (overrides the config; a replay's default "
                 "is the config's with -replay)");
  std::optional<int> robot_id_check_ms;
  app.add_option("--robot-id-check-ms", robot_id_check_ms,
                 "how long to listen for another server with this robot id before serving");
  std::string controller;
  std::optional<double> speed;
  std::optional<int> controller_timeout;
  app.add_option("--controller-timeout-ms", controller_timeout,
                 "a controller reply (or connection) that takes longer is a fault (galil; "
                 "overrides the config)");
  std::vector<std::string> approvers;
  std::string site;
  app.add_option("--site", site,
                 "the site's roles for the patient's structures (configs/sites/*.yaml; 'none': "
                 "none); overrides server.yaml site:");
  std::string tissue;
  app.add_option("--tissue", tissue,
                 "tissue profile for deflection predictions (configs/tissues.yaml; 'none' is "
                 "the plain model)");
  std::string replay, speed_text = "1";
  std::uint64_t until = 0;
  app.add_option("--replay", replay,
                 "publish this recorded session's states as they happened, then keep serving them");
  app.add_option("--speed", speed_text, "replay speed: 1, 10, ... or max");
  app.add_option("--until", until, "replay up to this revision (journal sequence number)");
  app.add_option("--controller", controller,
                 "simulated, or galil:HOST:PORT (overrides the config)");
  app.add_option("--controller-speed", speed,
                 "steps/s of every motor; acceleration 10x per second (overrides the config)");
  app.add_option("--approver", approvers,
                 "a client id allowed to approve motion (repeatable; "
                 "replaces the config's list)");
  std::string identity;
  app.add_option("--identity", identity,
                 "DDS Security identity folder (cert.pem, key.pem, permissions.p7s, "
                 "governance.p7s, identity_ca.pem, permissions_ca.pem); overrides the config");
  std::optional<int> igtl_port;
  app.add_option("--igtl-port", igtl_port,
                 "serve OpenIGTLink (3D Slicer, BRP protocol) on this loopback port; 0 = any "
                 "free port (overrides the config and turns the bridge on)");
  std::optional<double> igtl_timeout;
  app.add_option("--igtl-timeout", igtl_timeout,
                 "seconds after which a dropped or stalled OpenIGTLink client is let go "
                 "(overrides the config)");
  std::string igtl_protocol;
  app.add_option("--igtl-protocol", igtl_protocol,
                 "the BRP revision OpenIGTLink clients speak: slicer or brp2013 (overrides the "
                 "config)");
  std::optional<double> igtl_tip_rate;
  app.add_option("--igtl-tip-rate", igtl_tip_rate,
                 "the needle tip told to OpenIGTLink clients this many times a second during "
                 "motion (TRANSFORM; TDATA to those that ask; overrides the config)");
  bool igtl_off = false, igtl_approval = false;
  app.add_flag("--no-igtl", igtl_off, "no OpenIGTLink bridge whatever the config says");
  app.add_flag("--igtl-allow-approval", igtl_approval,
               "let MOVE_TO_TARGET over OpenIGTLink release motion (unauthenticated: loopback "
               "sites only; said loudly in the log and the workflow state)");
  bool insecure = false;
  app.add_flag("--insecure", insecure,
               "DDS Security off even if the config names an identity (local development only)");
  CLI11_PARSE(app, argc, argv);

  // Logs go to stderr: stdout carries the readiness line only.
  spdlog::set_default_logger(spdlog::stderr_color_mt("ignav-server"));
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  // A file over the size limit is an error to report (the journal refuses the change), not a
  // reason to die.
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    auto options = ignav::server::loadServerOptions(config_path);
    if (domain) options.domain_id = *domain;
    if (!session_dir.empty()) options.session_dir = session_dir;
    if (!robot.empty()) options.robot_config = robot;
    if (!dds_config.empty()) {
      // A name is looked up beside the config file first, then where tools look.
      std::vector<std::string> dirs{
          (std::filesystem::path(config_path).parent_path() / "dds").string()};
      for (auto& d : ignav::protocol::ddsConfigDirs())
        dirs.push_back(std::move(d));
      options.dds_config = ignav::protocol::resolveDdsConfig(dds_config, dirs);
    }
    if (!dds_interface.empty()) options.dds_site.interface = dds_interface;
    if (!dds_peers.empty()) options.dds_site.peers = dds_peers;
    if (!robot_id.empty()) {
      options.robot_id = robot_id;
    } else if (!replay.empty()) {
      options.robot_id += "-replay";  // beside the live robot, not in its place
    }
    if (robot_id_check_ms) options.robot_id_check_ms = *robot_id_check_ms;
    if (!identity.empty()) options.security.identity = identity;
    if (insecure) options.security.identity.clear();
    if (igtl_port) {
      options.openigtlink.enabled = true;
      options.openigtlink.port = *igtl_port;
    }
    if (igtl_approval) options.openigtlink.allow_motion_approval = true;
    if (igtl_timeout) options.openigtlink.timeout_s = *igtl_timeout;
    if (igtl_tip_rate) options.openigtlink.tip_rate_hz = *igtl_tip_rate;
    if (!igtl_protocol.empty()) options.openigtlink.protocol = igtl_protocol;
    if (igtl_off) options.openigtlink.enabled = false;
    if (controller == "simulated") {
      options.controller.kind = controller;
    } else if (controller.rfind("galil:", 0) == 0) {
      const auto colon = controller.rfind(':');
      options.controller.kind = "galil";
      options.controller.host = controller.substr(6, colon - 6);
      options.controller.port = std::stoi(controller.substr(colon + 1));
    } else if (!controller.empty()) {
      spdlog::error("--controller: '{}' is not simulated or galil:HOST:PORT", controller);
      return 2;
    }
    if (speed) {
      options.controller.speed_steps_s = *speed;
      options.controller.acceleration_steps_s2 = 10.0 * *speed;
    }
    if (controller_timeout) options.controller.timeout_ms = *controller_timeout;
    if (!approvers.empty()) options.approvers = approvers;
    if (!tissue.empty()) options.tissue_name = tissue;
    if (site == "none")
      options.site_path.clear();
    else if (!site.empty())
      options.site_path = site;
    if (!replay.empty()) {
      options.replay_session = replay;
      options.replay_until = until;
      char* end = nullptr;
      const double replay_speed = speed_text == "max" ? 0.0 : std::strtod(speed_text.c_str(), &end);
      if (speed_text != "max" &&
          (end == speed_text.c_str() || *end != '\0' || !(replay_speed > 0))) {
        spdlog::error("--speed: '{}' is not a positive number or max", speed_text);
        return 2;
      }
      options.replay_speed = replay_speed;
    }
    if (auto bad = ignav::server::checkServerOptions(options)) {
      spdlog::error("{}", *bad);
      return 2;
    }
    return ignav::server::runServer(options, g_stop);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
}
