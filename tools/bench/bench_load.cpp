// Load and soak against a running ignav-server (tools/bench/bench_load.sh starts one).
//
// load: N DDS clients (each its own participant and client id) send a mix of commands at a steady
//   rate for a while: query, move_target on their own targets, add/remove, slices, and commands
//   the server must refuse (NaN, an unknown id). A separate monitor participant counts every
//   reply on the reply topic, so "exactly one reply per command" is checked outside the client
//   library. Reports throughput, reply latency percentiles per command, and the server's RSS and
//   open file descriptors over time (from /proc).
// soak: one operator repeats a whole insertion: clear, add K targets, lock, approve every motion
//   through the simulated controller to the last retraction, unlock; RSS and fds per cycle.
//
// Exit 0 when every command got exactly one reply and none timed out (load), or every cycle
// reached all its targets (soak); 1 otherwise.
#include <dirent.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include "bench_load.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/protocol/client.hpp"
#include "ignav/protocol/wire/dds.hpp"
#include "ignav/protocol/wire/messages.hpp"

namespace ignav::bench {
namespace {

// ---- load -----------------------------------------------------------------------------------

struct LoadOptions {
  int clients = 20;
  double seconds = 60;
  double rate_hz = 10;  // per client
  int slice_percent = 10;
  int server_pid = 0;
};

struct Sent {
  std::string client_id;
  std::uint64_t request_id;
};

struct ClientResult {
  std::map<std::string, std::vector<double>> latency_ms;  // per command
  std::vector<Sent> sent;                                 // commands on the reply topic
  int timeouts = 0, unexpected = 0, slices_failed = 0;
  std::string first_problem;
};

void runLoadClient(int index, std::uint32_t domain, const std::string& xml,
                   const std::string& robot, const LoadOptions& o, Clock::time_point until,
                   ClientResult& out) {
  const std::string id = "load-" + std::to_string(index);
  Client c(domain, xml, id, nullptr, robot);
  c.setReplySpin(0us);  // 20 polling clients would take the server's cores on a small machine
  if (!c.waitForServer(20s)) {
    out.first_problem = id + ": no server";
    ++out.timeouts;
    return;
  }
  c.waitFor([](const json& s) { return s.contains("registration"); }, 10s);
  std::mt19937 rng(static_cast<unsigned>(1000 + index));
  std::uniform_int_distribution<int> pick(0, 99);
  std::vector<std::uint32_t> mine;
  // From the wall clock in µs, as Client does: a later run with these client ids never repeats
  // this run's request ids, which the server would answer from memory.
  std::uint64_t request =
      static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(
                                     std::chrono::system_clock::now().time_since_epoch())
                                     .count());
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.rate_hz));
  auto next = Clock::now();
  auto problem = [&](const std::string& what) {
    if (out.first_problem.empty()) out.first_problem = id + ": " + what;
  };
  while (Clock::now() < until) {
    std::this_thread::sleep_until(next);
    next += period;
    if (Clock::now() > next) next = Clock::now();  // behind: no burst to catch up
    std::string command;
    CommandArgs args;
    bool expect_accept = true;
    if (pick(rng) < o.slice_percent) {  // a slice through a reachable point (the slice topic)
      ignav::protocol::SliceArgs s;
      s.view = pick(rng) % 2 ? "axial" : "coronal";
      s.size_px = 128;
      s.centre_lps = lpsOf(c.state(), reachablePoint(rng));
      const auto t = Clock::now();
      try {
        const auto r = c.slice(s, 10s);
        out.latency_ms["slice"].push_back(since_ms(t));
        if (!r.ok) {
          ++out.slices_failed;
          problem("slice refused: " + r.message);
        }
      } catch (const ignav::protocol::Timeout&) {
        ++out.timeouts;
        problem("slice timed out");
      }
      continue;
    }
    const int roll = 10 + pick(rng) * 90 / 100;  // the commands on the reply topic
    if (roll < 50) {
      command = "query";
    } else if (roll < 80 && !mine.empty()) {
      command = "move_target";
      args.ids = {mine[rng() % mine.size()]};
      args.points = {lpsOf(c.state(), reachablePoint(rng))};
    } else if (roll < 90) {
      if (mine.size() < 4) {
        command = "add_target";
        args.points = {lpsOf(c.state(), reachablePoint(rng))};
      } else {
        command = "remove_target";
        args.ids = {mine.front()};
      }
    } else if (roll < 95) {  // refused: a NaN click
      command = "add_target";
      args.points = {{std::nan(""), 0.0, 0.0}};
      expect_accept = false;
    } else {  // refused: a target that does not exist
      command = "remove_target";
      args.ids = {4000000000u};
      expect_accept = false;
    }
    const std::uint64_t rid = ++request;
    out.sent.push_back({id, rid});
    const auto t = Clock::now();
    try {
      const auto r = c.send(command, args, 10s, rid);
      out.latency_ms[command + (expect_accept ? "" : " (refused)")].push_back(since_ms(t));
      if (r.accepted != expect_accept) {
        ++out.unexpected;
        problem(command + ": " + (r.accepted ? "accepted" : r.error_code + " " + r.message));
      } else if (r.accepted && command == "add_target") {
        mine.push_back(r.target_id);
      } else if (r.accepted && command == "remove_target") {
        mine.erase(mine.begin());
      }
    } catch (const ignav::protocol::Timeout&) {
      ++out.timeouts;
      problem(command + " " + std::to_string(rid) + " timed out");
    }
    c.poll();  // keep the state mirror (and the registration) current, as a UI would
  }
  // The targets this client still has are removed: a next run against the same server starts
  // from the session this one found (bench_memory.sh's rounds).
  for (const auto target : mine) {
    const std::uint64_t rid = ++request;
    out.sent.push_back({id, rid});
    try {
      if (!c.send("remove_target", {"", {}, {target}}, 10s, rid).accepted) ++out.unexpected;
    } catch (const ignav::protocol::Timeout&) {
      ++out.timeouts;
    }
  }
}

int runLoad(std::uint32_t domain, const std::string& xml, const LoadOptions& o) {
  // The monitor: counts every reply sample by (client id, request id).
  const std::string robot = ignav::protocol::chooseRobot(domain, xml, nullptr, "", 20s);
  ignav::protocol::Participant monitor_participant(domain, xml, nullptr, robot);
  ignav::protocol::Reader<ignav_msg_Reply> monitor(monitor_participant, &ignav_msg_Reply_desc,
                                                   ignav::protocol::topic::kReply,
                                                   ignav::protocol::Qos::kRequest);
  std::map<std::pair<std::string, std::uint64_t>, int> replies;
  std::mutex replies_mutex;
  std::atomic<bool> monitoring{true};
  std::thread monitor_thread([&] {
    while (monitoring) {
      monitor.take([&](const ignav_msg_Reply& r) {
        std::lock_guard<std::mutex> lock(replies_mutex);
        ++replies[{r.client_id ? r.client_id : "", r.request_id}];
      });
      std::this_thread::sleep_for(5ms);  // replies are keyed per request: none is overwritten
    }
  });

  Client setup(domain, xml, "operator", nullptr, robot);
  if (!setup.waitForServer(20s) || !registered(setup)) {
    std::fprintf(stderr, "bench_load: the server did not load and register the phantom\n");
    return 1;
  }
  const auto start = Clock::now();
  std::vector<ProcessSample> process;
  std::atomic<bool> sampling{true};
  std::thread sampler([&] {
    while (sampling) {
      if (o.server_pid > 0) process.push_back(sampleProcess(o.server_pid, start));
      std::this_thread::sleep_for(1s);
    }
  });

  std::vector<ClientResult> results(static_cast<std::size_t>(o.clients));
  // Everyone starts (participants, discovery) first; the clock of the run starts after.
  const auto until =
      Clock::now() +
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.seconds)) + 5s;
  std::vector<std::thread> threads;
  for (int i = 0; i < o.clients; ++i) {
    threads.emplace_back([&, i] {
      try {
        runLoadClient(i, domain, xml, robot, o, until, results[static_cast<std::size_t>(i)]);
      } catch (const std::exception& e) {
        results[static_cast<std::size_t>(i)].first_problem = e.what();
        ++results[static_cast<std::size_t>(i)].timeouts;
      }
    });
  }
  for (auto& t : threads)
    t.join();
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  std::this_thread::sleep_for(1s);  // any late or duplicate reply
  monitoring = false;
  monitor_thread.join();
  sampling = false;
  sampler.join();

  std::map<std::string, std::vector<double>> latency;
  std::vector<double> all;
  int timeouts = 0, unexpected = 0, slices_failed = 0;
  std::size_t commands = 0, missing = 0, duplicated = 0;
  for (const auto& r : results) {
    for (const auto& [k, v] : r.latency_ms) {
      latency[k].insert(latency[k].end(), v.begin(), v.end());
      all.insert(all.end(), v.begin(), v.end());
    }
    timeouts += r.timeouts;
    unexpected += r.unexpected;
    slices_failed += r.slices_failed;
    for (const auto& s : r.sent) {
      ++commands;
      const auto it = replies.find({s.client_id, s.request_id});
      if (it == replies.end()) {
        ++missing;
      } else if (it->second != 1) {
        ++duplicated;
      }
    }
    if (!r.first_problem.empty()) std::printf("problem: %s\n", r.first_problem.c_str());
  }
  // Replies to load clients for requests they never sent.
  std::set<std::pair<std::string, std::uint64_t>> sent;
  for (const auto& r : results)
    for (const auto& s : r.sent)
      sent.insert({s.client_id, s.request_id});
  std::size_t strays = 0;
  for (const auto& [key, n] : replies)
    if (key.first.rfind("load-", 0) == 0 && !sent.count(key)) strays += static_cast<std::size_t>(n);

  std::printf("load: %d clients x %.0f commands/s for %.0f s, %d %% slices\n", o.clients, o.rate_hz,
              o.seconds, o.slice_percent);
  std::printf("%-26s %8s %9s %9s %9s %9s\n", "command", "n", "p50 ms", "p90 ms", "p99 ms",
              "max ms");
  auto row = [](const std::string& name, const Percentiles& p) {
    std::printf("%-26s %8zu %9.2f %9.2f %9.2f %9.2f\n", name.c_str(), p.n, p.p50, p.p90, p.p99,
                p.max);
  };
  for (const auto& [k, v] : latency)
    row(k, percentiles(v));
  row("all", percentiles(all));
  std::printf("throughput: %.1f commands/s (%zu in %.1f s)\n",
              static_cast<double>(all.size()) / elapsed_s, all.size(), elapsed_s);
  std::printf(
      "replies: %zu commands, %zu without a reply, %zu with more than one, %zu stray; %d timed "
      "out, %d answered otherwise than expected, %d slices refused\n",
      commands, missing, duplicated, strays, timeouts, unexpected, slices_failed);
  if (!process.empty()) {
    const auto& first = process.front();
    const auto& last = process.back();
    double peak = 0;
    for (const auto& s : process)
      peak = std::max(peak, s.rss_mib);
    std::printf("server: RSS %.1f MiB at start, %.1f MiB at end, peak %.1f MiB; fds %d -> %d\n",
                first.rss_mib, last.rss_mib, peak, first.fds, last.fds);
    // Growth over the second half, when the start-up allocations are done.
    const auto& mid = process[process.size() / 2];
    if (last.t_s > mid.t_s) {
      std::printf("server: RSS growth over the second half %.3f MiB/min\n",
                  (last.rss_mib - mid.rss_mib) / (last.t_s - mid.t_s) * 60.0);
    }
  }
  const bool ok = missing == 0 && duplicated == 0 && strays == 0 && timeouts == 0 &&
                  unexpected == 0 && slices_failed == 0;
  std::printf("%s\n", ok ? "PASS" : "FAIL");
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace ignav::bench

int main(int argc, char** argv) {
  CLI::App app{"Load and soak against a running ignav-server"};
  std::uint32_t domain = 0;
  std::string config;
  ignav::bench::LoadOptions load;
  int soak_cycles = 0, targets_per_cycle = 5;
  app.add_option("--domain", domain, "DDS domain id")->required();
  app.add_option("--dds-config", config, "Cyclone XML (configs/dds/loopback.xml)")->required();
  app.add_option("--clients", load.clients, "concurrent clients")->check(CLI::Range(1, 200));
  app.add_option("--seconds", load.seconds, "length of the load run")->check(CLI::Range(1, 86400));
  app.add_option("--rate", load.rate_hz, "commands per second per client")
      ->check(CLI::Range(0.1, 1000.0));
  app.add_option("--slices", load.slice_percent, "percent of requests that are slices")
      ->check(CLI::Range(0, 100));
  app.add_option("--server-pid", load.server_pid, "track this process's RSS and fds");
  app.add_option("--soak", soak_cycles, "instead of load: this many insertion cycles");
  app.add_option("--targets-per-cycle", targets_per_cycle, "soak: targets per insertion")
      ->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  try {
    const std::string xml = ignav::protocol::readConfigFile(config);
    if (soak_cycles > 0)
      return ignav::bench::runSoak(domain, xml, soak_cycles, targets_per_cycle, load.server_pid);
    return ignav::bench::runLoad(domain, xml, load);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_load: %s\n", e.what());
    return 1;
  }
}
