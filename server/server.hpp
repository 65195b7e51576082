// ignav-server: the DDS edge around the workflow reducer. One thread runs the event queue
// (commands, slice requests, finished loads); a loader thread runs volume loads.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

namespace ignav::server {

struct ServerOptions {
  std::string robot_config;
  std::uint32_t domain_id = 0;
  std::string dds_config;    // path of a Cyclone XML file ("" = Cyclone's defaults)
  std::string session_root;  // a session folder is created inside
  std::string session_dir;   // or exactly this folder
};

// Loads `path` (server.yaml); errors name the file and key. CLI options override after.
ServerOptions loadServerOptions(const std::string& path);

// Runs until `stop` becomes true; returns the exit code.
int runServer(const ServerOptions& options, const std::atomic<bool>& stop);

}  // namespace ignav::server
