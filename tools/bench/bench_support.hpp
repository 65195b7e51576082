// What the DDS benches share: a server brought to planning, and their statistics.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <thread>
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

// The built-in phantom on a server that has just started, waited for: its CT loaded and
// registered, its anatomy loaded. Says on stderr what did not happen.
inline bool phantomWithAnatomy(protocol::Client& c, std::uint32_t domain) {
  if (!c.waitForServer(std::chrono::seconds(10)) || !loadAndRegister(c, "phantom:")) {
    std::fprintf(stderr, "no server on domain %u, or the phantom did not register\n", domain);
    return false;
  }
  const auto loaded = c.send("load_structures", {"phantom:", {}, {}});
  if (loaded.accepted &&
      c.waitForJobOutcome(loaded.job, std::chrono::seconds(120)).status == "done")
    return true;
  std::fprintf(stderr, "the phantom's anatomy did not load\n");
  return false;
}

// Pings from a client of its own every 5 ms until stopped; the round trips (ms).
class Pinger {
 public:
  Pinger(std::uint32_t domain, const std::string& xml) {
    thread_ = std::thread([this, domain, xml] {
      ignav::protocol::Client c(
          domain, xml, "bench-ping", nullptr,
          ignav::protocol::chooseRobot(domain, xml, nullptr, "", std::chrono::seconds(10)));
      if (!c.waitForServer(std::chrono::seconds(10))) return;
      ready_ = true;
      while (!stop_) {
        const auto t = Clock::now();
        c.send("ping");
        const double ms = sinceMs(t);
        if (recording_) samples_.push_back(ms);
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
    });
    while (!ready_)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ~Pinger() {
    stop_ = true;
    thread_.join();
  }
  void record(bool on) { recording_ = on; }
  // Only between record(false) and the next record(true).
  std::vector<double> take() {
    std::vector<double> out;
    out.swap(samples_);
    return out;
  }

 private:
  std::atomic<bool> stop_{false}, ready_{false}, recording_{false};
  std::vector<double> samples_;
  std::thread thread_;
};

inline void print(const char* name, const std::vector<double>& v) {
  if (v.empty()) {
    std::printf("%-40s no samples\n", name);
    return;
  }
  std::printf("%-40s median %7.2f ms   p95 %7.2f   p99 %7.2f   worst %7.2f   (n %zu)\n", name,
              percentile(v, 50), percentile(v, 95), percentile(v, 99),
              *std::max_element(v.begin(), v.end()), v.size());
}

// A background job's command sent `rounds` times, each awaited, while a Pinger times `ping`s
// (2 s idle first): the jobs' durations, the pings idle and during, the last outcome. `send`
// returns the reply naming the job; a refusal or a failed job ends the rounds.
struct JobsWhilePinging {
  std::vector<double> jobs_ms, idle_ms, during_ms;
  std::string last;  // "done: ..." or why not
  bool refused = false;
};
inline JobsWhilePinging timeJobsWhilePinging(protocol::Client& c, std::uint32_t domain,
                                             const std::string& xml, int rounds,
                                             const std::function<protocol::Reply()>& send,
                                             const std::function<void()>& between = {}) {
  JobsWhilePinging out;
  Pinger pinger(domain, xml);
  pinger.record(true);
  std::this_thread::sleep_for(std::chrono::seconds(2));
  pinger.record(false);
  out.idle_ms = pinger.take();
  pinger.record(true);
  for (int r = 0; r < rounds; ++r) {
    if (between && r > 0) between();  // untimed: what the round before leaves to tidy
    const auto t = Clock::now();
    const auto sent = send();
    if (!sent.accepted) {
      out.refused = true;
      out.last = "refused: " + sent.message;
      break;
    }
    const auto outcome = c.waitForJobOutcome(sent.job, std::chrono::seconds(300));
    out.jobs_ms.push_back(sinceMs(t));
    out.last = outcome.status + ": " + outcome.message;
    if (outcome.status != "done") break;
  }
  pinger.record(false);
  out.during_ms = pinger.take();
  return out;
}

// What timeJobsWhilePinging measured, for a person: `command`'s durations and the pings idle and
// `while` it ran; false (said on stderr) when the command was refused.
inline bool printJobsWhilePinging(const JobsWhilePinging& run, const std::string& command,
                                  const std::string& what, const std::string& during) {
  if (run.refused) {
    std::fprintf(stderr, "%s %s\n", command.c_str(), run.last.c_str());
    return false;
  }
  std::printf("%s: %s\n", what.c_str(), run.last.c_str());
  print((command + " -> its outcome").c_str(), run.jobs_ms);
  print("ping -> reply, idle", run.idle_ms);
  print(("ping -> reply, while " + during).c_str(), run.during_ms);
  return true;
}

}  // namespace ignav::bench
