// The server's options (server.yaml, then the command line): what they are, how server.yaml is
// read, and what is checked (configs/server.yaml is the example; docs/PROTOCOL.md, "The server").
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ignav/anatomy/site.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/protocol/config.hpp"
#include "ignav/protocol/security.hpp"

namespace ignav::server {

// The motor controller the server drives (server.yaml `controller:`).
struct ControllerOptions {
  std::string kind = "simulated";  // simulated | galil
  std::string host = "127.0.0.1";  // galil
  int port = 23;                   // galil
  double speed_steps_s = 2000.0;   // every motor (SP; the simulation's axes)
  double acceleration_steps_s2 = 8000.0;
  int control_period_ms = 10;  // how often a moving robot is polled and its state published
  int timeout_ms = 1000;       // galil: connecting, and each reply; then it is a fault
};

// DDS Security (server.yaml `security:`, docs/SECURITY.md). Without an identity the server runs
// unauthenticated and unencrypted, for local development only, and says so loudly.
struct SecurityOptions {
  std::string identity;  // an identity folder (configs/security/make-test-pki.sh writes them)
  std::string plugins;   // folder of Cyclone's libdds_security_*.so ("" = Debian's)
};

// The identity `o.identity` names, with `o.plugins` applied (the identity must be set). Throws
// protocol::DdsError naming a missing file.
protocol::SecurityIdentity securityIdentity(const SecurityOptions& o);

// The OpenIGTLink bridge for 3D Slicer (server.yaml `openigtlink:`, docs/OPENIGTLINK.md).
struct OpenIgtlinkOptions {
  bool enabled = false;
  std::string address = "127.0.0.1";  // loopback unless a site opens it
  int port = 18944;                   // 0: any free port (printed on the ready line)
  double timeout_s = 5.0;             // a dropped or stalled client is let go after this
  // OpenIGTLink has no authentication: MOVE_TO_TARGET over it releases motion only if a site
  // says so here (the server then says so loudly, in its log and in the workflow state).
  bool allow_motion_approval = false;
  // The BRP revision its clients speak (docs/OPENIGTLINK.md): "slicer" (the current 3D Slicer
  // module) or "brp2013" (the 2013 revision as its reference robots write it).
  std::string protocol = "slicer";
  // The needle tip told during motion this many times a second: TRANSFORM to every client, TDATA
  // to those that asked for it (STT_TDATA), each stamped with when the position was read.
  double tip_rate_hz = 20.0;
  // The largest scan (IMAGE ConfirmationCT / IntermittentCT) a client may send, in MiB of body; a
  // client holds at most one while it arrives. 0: none taken.
  std::uint64_t max_scan_mb = 1024;
};

// The largest DDS domain id: RTPS's default port mapping (7400 + 250 x id + 11) stays a UDP port.
constexpr std::uint32_t kMaxDomainId = 232;
constexpr std::uint32_t kMaxSecureDomainId = 230;  // Cyclone's governance parser's limit

struct ServerOptions {
  ControllerOptions controller;
  OpenIgtlinkOptions openigtlink;
  SecurityOptions security;
  std::vector<std::string> approvers;  // client ids allowed to approve motion
  double approval_expiry_s = 120.0;
  std::string tissue_profiles;                  // configs/tissues.yaml
  std::string tissue_name;                      // "" = no deflection prediction
  std::optional<config::TissueProfile> tissue;  // loaded by runServer
  // The site's roles for the patient's structures (configs/sites/*.yaml); "": none.
  std::string site_path;
  std::optional<anatomy::Site> site;      // loaded by runServer
  std::size_t max_targets = 100;          // per insertion, at most 100 (paper §V)
  double max_total_rotation_deg = 360.0;  // the cannula's rotation over one insertion
  std::string robot_config;
  // This robot's name on the DDS domain: the server's topics are in its partition (topics.hpp),
  // so several robots share a domain; two servers with one id never both serve (DEPLOYMENT.md).
  std::string robot_id = "robot-1";
  // Before it serves, how long a starting server listens for another one with its robot id (0:
  // not at start; only once serving, within a second).
  int robot_id_check_ms = 1000;
  std::uint32_t domain_id = 0;
  std::string dds_config;      // path of a Cyclone XML file ("" = Cyclone's defaults)
  protocol::DdsSite dds_site;  // what a site configuration leaves open: interface, peers
  std::string dds_config_xml;  // dds_config read and filled in (runServer)
  std::string session_root;    // a session folder is created inside
  std::string session_dir;     // or exactly this folder
  // Replay instead of serving: publish a recorded session's states as they happened.
  std::string replay_session;      // its folder (read only)
  double replay_speed = 1.0;       // 1, 10, ... times real time; 0 = as fast as possible
  std::uint64_t replay_until = 0;  // stop after this revision (0 = the whole journal)
};

// Loads `path` (server.yaml); errors name the file and key. CLI options override after.
ServerOptions loadServerOptions(const std::string& path);
// What is wrong with the options ("controller.port: ...", "robot_id: ..."), if anything.
std::optional<std::string> checkServerOptions(const ServerOptions& options);

}  // namespace ignav::server
