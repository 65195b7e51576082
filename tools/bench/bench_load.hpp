// What the load and soak runs of bench_load share (bench_load.cpp: load and main;
// bench_soak.cpp: soak): the server's memory and descriptors from /proc, percentiles, a registered
// phantom session, points the paper's robot reaches.
#pragma once

#include <dirent.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "ignav/config/robot_config.hpp"
#include "ignav/protocol/client.hpp"

namespace ignav::bench {

using ignav::protocol::Client;
using ignav::protocol::CommandArgs;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

inline double since_ms(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// The server's resident memory (MiB) and open descriptors, from /proc.
struct ProcessSample {
  double t_s = 0;
  double rss_mib = 0;
  int fds = 0;
};

inline ProcessSample sampleProcess(int pid, Clock::time_point start) {
  ProcessSample s;
  s.t_s = std::chrono::duration<double>(Clock::now() - start).count();
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) s.rss_mib = std::stod(line.substr(6)) / 1024.0;
  }
  if (DIR* d = ::opendir(("/proc/" + std::to_string(pid) + "/fd").c_str())) {
    while (const dirent* e = ::readdir(d))
      if (e->d_name[0] != '.') ++s.fds;
    ::closedir(d);
  }
  return s;
}

struct Percentiles {
  std::size_t n = 0;
  double p50 = 0, p90 = 0, p99 = 0, max = 0;
};

inline Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  p.n = v.size();
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  };
  p.p50 = at(0.50);
  p.p90 = at(0.90);
  p.p99 = at(0.99);
  p.max = v.back();
  return p;
}

// The robot-frame point -> LPS through the registration the server publishes.
inline Eigen::Vector3d lpsOf(const json& state, const Eigen::Vector3d& robot_mm) {
  const Eigen::Matrix4d m =
      ignav::protocol::matrixFromState(state["registration"]["image_to_robot"]);
  return (m.inverse() * robot_mm.homogeneous()).head<3>();
}

// Loads the built-in phantom and registers on its markers, each awaited by its job's outcome.
inline bool registered(Client& c) {
  const auto done = [&](const ignav::protocol::Reply& r, std::chrono::seconds timeout) {
    return r.accepted && c.waitForJobOutcome(r.job, timeout).status == "done";
  };
  if (!done(c.send("load_volume", {"phantom:", {}, {}}), 120s)) return false;
  if (!done(c.send("auto_fiducials"), 30s)) return false;
  // The state that follows the outcomes (the registration's matrix) before it is read.
  c.waitFor(
      [](const json& s) {
        return s.contains("registration") && s["registration"]["status"] == "registered";
      },
      10s);
  return true;
}

// Points the paper's robot reaches (configs/robots/torabi2014.yaml), in the robot frame: drawn
// around the needle axis (within 1 rad of `sector_rad` when given) and kept when the exact inverse
// kinematics reaches them.
inline Eigen::Vector3d reachablePoint(std::mt19937& rng, std::optional<double> sector_rad = {}) {
  static const auto robot = ignav::config::loadRobot(IGNAV_ROBOT_CONFIG).value();
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), near(-1.0, 1.0), radius(5.0, 20.0),
      z(-195.0, -165.0);
  for (;;) {
    const double a = sector_rad ? *sector_rad + near(rng) : angle(rng), r = radius(rng);
    const Eigen::Vector3d p(r * std::cos(a), r * std::sin(a), z(rng));
    const auto ik = robot.kinematics.inverse(p);
    if (ik && ik->reachable()) return p;
  }
}

// soak (bench_soak.cpp): one operator repeats a whole insertion `cycles` times.
int runSoak(std::uint32_t domain, const std::string& xml, int cycles, int targets_per_cycle,
            int server_pid);

}  // namespace ignav::bench
