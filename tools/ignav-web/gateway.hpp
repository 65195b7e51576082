// ignav-web's gateway (docs/WEB.md): serves the browser app over HTTP and relays its WebSocket to
// ignav-server as one ordinary DDS client. No workflow logic: every browser request becomes one
// command (or approval, emergency stop, slice) and the server's answer goes back to that browser;
// state changes go to every browser.
//
// Threads: one runs the HTTP/WebSocket side (Boost.Beast, every socket), one owns the DDS client
// (protocol::Client is single-threaded). They meet only through the job queue and posted
// completions, so neither ever waits on the other's I/O.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "ignav/protocol/security.hpp"

namespace ignav::web {

struct GatewayOptions {
  std::string listen_address = "127.0.0.1";
  std::uint16_t port = 8080;  // 0: any free port (port() tells which)
  std::string app_dir;        // index.html, app.js, app.css
  std::uint32_t domain = 0;
  std::string dds_config_xml;  // the XML itself ("" = Cyclone's defaults)
  std::string client_id = "web";
  std::string robot_id;  // the one robot this gateway serves (protocol::chooseRobot finds it)
  std::optional<protocol::SecurityIdentity> identity;
  // How long a request waits for the server's answer before the browser gets "timeout".
  std::chrono::milliseconds reply_timeout = std::chrono::seconds(10);
};

class Gateway {
 public:
  // Binds the listening socket and creates the DDS participant; throws naming what failed (the
  // address, the identity folder, ...).
  explicit Gateway(GatewayOptions options);
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  std::uint16_t port() const;
  // Serves until stop(); then closes every connection.
  void run();
  // From any thread (a signal handler's asio::signal_set, a test).
  void stop();

  struct Impl;  // gateway.cpp's (its sessions need to name it)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ignav::web
