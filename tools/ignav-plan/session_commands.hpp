// ignav-plan replay: a recorded session re-derived offline from its journal, every record
// checked against what the server recorded (the determinism check).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "cli_common.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::plan {

struct ReplayArgs {
  std::string session_dir;
  std::string robot_path;  // the robot config the server ran with
};
nlohmann::json replaySession(const ReplayArgs& args);
// The session its journal describes (every record checked), and how many records it took;
// CliError naming what is wrong.
struct ReplayedSession {
  workflow::Session session;
  std::size_t records = 0;
  bool torn_tail_dropped = false;
};
ReplayedSession replayedSession(const ReplayArgs& args);

}  // namespace ignav::plan
