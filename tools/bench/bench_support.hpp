// What the DDS benches share: a server brought to planning, and their statistics.
#pragma once

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "ignav/protocol/client.hpp"

namespace ignav::bench {

using Clock = std::chrono::steady_clock;

inline double sinceMs(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// The p-th percentile (0-100) of `v`, nearest rank below; v must not be empty.
inline double percentile(std::vector<double> v, int p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, v.size() * static_cast<std::size_t>(p) / 100)];
}

// Loads `source` (a server-side folder or file, or "phantom:") on the server `c` talks to and
// registers it from its beads, waiting for each; false when the server refuses a step.
inline bool loadAndRegister(protocol::Client& c, const std::string& source) {
  using nlohmann::json;
  c.waitFor([](const json& s) { return s.contains("workflow"); }, std::chrono::seconds(5));
  if (!c.send("load_volume", {source, {}, {}}).accepted) return false;
  c.waitFor([](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; },
            std::chrono::seconds(120));
  // Accepted when the detection starts; the registration follows (issue 22).
  if (!c.send("auto_fiducials").accepted) return false;
  c.waitFor(
      [](const json& s) {
        return s.contains("registration") && s["registration"]["status"] == "registered";
      },
      std::chrono::seconds(60));
  return true;
}

}  // namespace ignav::bench
