// ignav-web: the browser viewer's gateway (docs/WEB.md). Prints one ready line with the URL.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <thread>

#include "gateway.hpp"
#include "ignav/protocol/client.hpp"
#include "ignav/protocol/config.hpp"
#include "ignav/protocol/security.hpp"

namespace {
std::atomic<bool> g_stop_requested{false};  // lock-free, so a signal handler may set it
void requestStop(int) {
  g_stop_requested = true;
}
// Installed (the Debian package): <prefix>/share/ignav/web beside <prefix>/bin; else the build's.
std::string defaultAppDir() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto installed = exe.parent_path() / "../share/ignav/web";
    if (std::filesystem::exists(installed / "index.html", ec)) {
      return installed.lexically_normal().string();
    }
  }
  return IGNAV_WEB_APP_DIR;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ignav-web: the web viewer's gateway to ignav-server"};
  ignav::web::GatewayOptions options;
  options.app_dir = defaultAppDir();
  std::string dds_config = "loopback";
  ignav::protocol::DdsSite dds_site;
  std::string identity;
  app.add_option("--listen", options.listen_address, "HTTP address (loopback by default)");
  app.add_option("--port", options.port, "HTTP port (0: any free port)");
  app.add_option("--app-dir", options.app_dir, "the built browser app");
  app.add_option("--domain", options.domain, "DDS domain id");
  app.add_option("--dds-config", dds_config,
                 "Cyclone XML, or a name: loopback, site-multicast, site-unicast ('' = Cyclone's "
                 "defaults)");
  app.add_option("--dds-interface", dds_site.interface,
                 "the network interface a site configuration uses");
  app.add_option("--dds-peer", dds_site.peers, "a unicast discovery peer, once per host");
  std::string robot;
  double wait_s = 10.0;
  app.add_option("--robot", robot,
                 "the robot to serve (its robot_id); by default the only one on the domain")
      ->envname("IGNAV_ROBOT");
  app.add_option("--wait-server", wait_s,
                 "without --robot: seconds to wait for a server to appear on the domain");
  app.add_option("--client-id", options.client_id,
                 "the DDS client id every browser of this gateway acts as");
  app.add_option("--identity", identity,
                 "DDS Security identity folder; without one, security is off")
      ->envname("IGNAV_IDENTITY");
  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr: stdout carries the ready line only.
  spdlog::set_default_logger(spdlog::stderr_color_mt("ignav-web"));

  try {
    options.dds_config_xml = ignav::protocol::loadToolDdsConfig(dds_config, dds_site);
    if (!identity.empty()) {
      options.identity = ignav::protocol::identityFromFolder(identity);
    } else {
      spdlog::warn("DDS Security is off (no --identity): for local development only");
    }
    // One robot per gateway, chosen now: a viewer never shows one robot and commands another.
    options.robot_id = ignav::protocol::chooseRobot(
        options.domain, options.dds_config_xml, options.identity ? &*options.identity : nullptr,
        robot, std::chrono::milliseconds(static_cast<long>(wait_s * 1000)));
    if (options.listen_address != "127.0.0.1" && options.listen_address != "::1") {
      spdlog::warn("listening on {}, not loopback: anyone who reaches it acts as '{}'",
                   options.listen_address, options.client_id);
    }
    ignav::web::Gateway gateway(options);
    std::cout << "ignav-web ready url=http://" << options.listen_address << ":" << gateway.port()
              << "/ client_id=" << options.client_id << " robot=" << options.robot_id
              << " security=" << (options.identity ? "on" : "OFF") << std::endl;
    // SIGINT/SIGTERM end the serving loop; the gateway closes its sockets and participant. (A
    // handler, not a blocked mask and sigwait: some of Cyclone's threads unblock every signal.)
    std::signal(SIGINT, requestStop);
    std::signal(SIGTERM, requestStop);
    std::atomic<bool> served{false};
    std::thread watcher([&] {
      while (!g_stop_requested && !served)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      gateway.stop();
    });
    gateway.run();
    served = true;
    watcher.join();
    spdlog::info("stopped");
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "ignav-web: " << e.what() << "\n";
    return 1;
  }
}
