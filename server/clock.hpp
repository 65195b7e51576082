// The server's two clocks. Inputs carry wall-clock time (Unix seconds): journal times and
// approval expiries then mean the same across restarts. Waits, the simulation and uptime use the
// monotonic clock.
#pragma once

#include <chrono>

namespace ignav::server {

using Clock = std::chrono::steady_clock;

inline double wallS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace ignav::server
