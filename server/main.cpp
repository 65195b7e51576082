// ignav-server --config configs/server.yaml [--domain N] [--session-dir DIR]
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
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
  app.add_option("--dds-config", dds_config, "Cyclone XML (overrides the config)");
  CLI11_PARSE(app, argc, argv);

  // Logs go to stderr: stdout carries the readiness line only.
  spdlog::set_default_logger(spdlog::stderr_color_mt("ignav-server"));
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    auto options = ignav::server::loadServerOptions(config_path);
    if (domain) options.domain_id = *domain;
    if (!session_dir.empty()) options.session_dir = session_dir;
    if (!robot.empty()) options.robot_config = robot;
    if (!dds_config.empty()) options.dds_config = dds_config;
    return ignav::server::runServer(options, g_stop);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
}
