// E-stop and query latency with a slow motor controller (issue 22.1). Starts its own Galil
// look-alike (dmc-emulator), a proxy that holds every controller reply for --delay-ms
// (tests/support/delay_proxy.hpp; it also records when each command reached it, "on the wire"),
// and an ignav-server driving the look-alike through the proxy. Then, per round: approve a slow
// move (the replies prompt), wait until BG has gone out, slow the replies down, wait a random
// 0.3-1.5 s (so the emergency stop meets the driver at every point of a poll), emergency-stop,
// and time
//   e-stop -> AB at the controller (the proxy's clock), and e-stop -> the DDS reply;
// meanwhile another client sends `query` every 20 ms, timed while the controller is slow.
// Prints median, p95, p99 and max in milliseconds.
//   bench_slow_controller [--delay-ms 900] [--domain 96] [--rounds 20]
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/LU>

#include "child_process.hpp"
#include "ignav/protocol/client.hpp"
#include "support/delay_proxy.hpp"

extern char** environ;

namespace {

using ignav::bench::Child;
using ignav::protocol::Client;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

double ms(Clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

struct Stats {
  std::vector<double> v;
  void print(const char* name) {
    if (v.empty()) {
      std::printf("%-48s (no samples)\n", name);
      return;
    }
    std::sort(v.begin(), v.end());
    auto at = [&](double q) {
      return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
    };
    std::printf("%-48s median %8.2f ms  p95 %8.2f ms  p99 %8.2f ms  max %8.2f ms  (%zu)\n", name,
                at(0.5), at(0.95), at(0.99), v.back(), v.size());
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_slow_controller: e-stop and query latency with a slow motor controller"};
  int delay_ms = 900, rounds = 20;
  std::uint32_t domain = 96;
  std::string server_exe = IGNAV_SERVER_EXE, emulator_exe = DMC_EMULATOR_EXE;
  std::string source = IGNAV_SOURCE_DIR;
  app.add_option("--delay-ms", delay_ms, "how long every controller reply is held");
  app.add_option("--domain", domain, "DDS domain id");
  app.add_option("--rounds", rounds, "emergency stops to time");
  app.add_option("--server", server_exe, "ignav-server");
  app.add_option("--emulator", emulator_exe, "dmc-emulator");
  CLI11_PARSE(app, argc, argv);

  const auto dir =
      std::filesystem::temp_directory_path() / ("ignav_bench_slow_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  try {
    Child emulator({emulator_exe, "--port", "0"}, "listening", (dir / "emulator.log").string());
    const int dmc_port = std::stoi(emulator.line().substr(emulator.line().rfind(':') + 1));
    ignav::test::DelayProxy proxy(dmc_port);
    Child server(
        {server_exe, "--config", source + "/configs/server.yaml", "--domain",
         std::to_string(domain), "--dds-config", source + "/configs/dds/loopback.xml",
         "--session-dir", (dir / "session").string(), "--no-igtl", "--insecure", "--controller",
         "galil:127.0.0.1:" + std::to_string(proxy.port()), "--controller-speed", "2000"},
        "ignav-server ready", (dir / "server.log").string());
    const std::string xml = ignav::protocol::readConfigFile(source + "/configs/dds/loopback.xml");
    const std::string robot = ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s);
    Client op(domain, xml, "operator", nullptr, robot);
    if (!op.waitForServer(10s)) throw std::runtime_error("no server");
    op.waitFor([](const json& s) { return s.contains("workflow"); }, 10s);
    op.send("load_volume", {"phantom:", {}, {}});
    op.waitFor(
        [](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; },
        60s);
    if (!op.send("auto_fiducials").accepted) throw std::runtime_error("auto_fiducials refused");
    op.waitFor(
        [](const json& s) {
          return s.contains("registration") && s["registration"]["status"] == "registered";
        },
        10s);
    const Eigen::Matrix4d to_robot =
        ignav::protocol::matrixFromState(op.state()["registration"]["image_to_robot"]);
    const Eigen::Vector3d lps = (to_robot.inverse() * Eigen::Vector4d(-10, 15, -190, 1)).head<3>();
    if (!op.send("add_target", {"", {lps}, {}}).accepted) throw std::runtime_error("add_target");
    if (!op.send("lock_plan").accepted) throw std::runtime_error("lock_plan refused");

    // Queries from another client, the whole time; those sent while the replies are held count.
    std::atomic<bool> slow{false}, done{false};
    std::atomic<int> query_timeouts{0};
    Stats query_slow, query_prompt;
    std::mutex stats_mutex;
    std::thread watcher([&] {
      Client w(domain, xml, "watcher", nullptr, robot);
      w.waitForServer(10s);
      while (!done) {
        const bool was_slow = slow;
        const auto t = Clock::now();
        try {
          w.send("query", {}, 10s);
        } catch (const ignav::protocol::Timeout&) {
          ++query_timeouts;  // counted at the 10 s it waited
        }
        const double took = ms(Clock::now() - t);
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          (was_slow && slow ? query_slow : query_prompt).v.push_back(took);
        }
        std::this_thread::sleep_for(20ms);
      }
    });

    struct Join {  // the watcher ends with this scope, thrown out of or not
      std::atomic<bool>& done;
      std::thread& thread;
      ~Join() {
        done = true;
        if (thread.joinable()) thread.join();
      }
    } join{done, watcher};
    Stats wire, reply;
    std::mt19937 random(22);
    std::uniform_int_distribution<int> wait_ms(300, 1500);
    for (int round = 0; round < rounds; ++round) {
      op.waitFor([](const json& s) { return s["approval"]["status"] == "pending"; }, 20s);
      const json shown = op.state()["approval"];
      const auto approved = Clock::now();
      if (!op.approve(shown["plan_id"], shown["digest"]).accepted) {
        throw std::runtime_error("approval refused");
      }
      if (!proxy.waitFor("BG", approved, 20s)) throw std::runtime_error("the move never started");
      proxy.setDelay(std::chrono::milliseconds(delay_ms));
      slow = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(wait_ms(random)));
      const auto sent = Clock::now();
      const auto r = op.emergencyStop(10s);
      const auto answered = Clock::now();
      if (!r.accepted) throw std::runtime_error("emergency stop refused: " + r.message);
      const auto ab = proxy.waitFor("AB", sent, 10s);
      if (!ab) throw std::runtime_error("AB never reached the controller");
      wire.v.push_back(ms(*ab - sent));
      reply.v.push_back(ms(answered - sent));
      // Prompt again: at rest, reset, resume (a new approval request), next round.
      slow = false;
      proxy.setDelay(0ms);
      op.waitFor([](const json& s) { return s["motion"]["state"] == "idle"; }, 30s);
      for (const char* command : {"reset_emergency", "resume"}) {
        const auto answer = op.send(command, {}, 10s);
        if (!answer.accepted) {
          throw std::runtime_error(std::string(command) + " refused: " + answer.message);
        }
      }
      std::fprintf(stderr, "round %d: AB after %.2f ms, reply after %.2f ms\n", round + 1,
                   wire.v.back(), reply.v.back());
    }
    done = true;
    watcher.join();
    std::lock_guard<std::mutex> lock(stats_mutex);
    std::printf("controller replies held %d ms; %d emergency stops mid-move\n", delay_ms, rounds);
    wire.print("emergency stop -> AB at the controller");
    reply.print("emergency stop -> DDS reply");
    query_slow.print("query -> reply, controller slow");
    query_prompt.print("query -> reply, controller prompt");
    if (query_timeouts > 0)
      std::printf("queries unanswered after 10 s: %d\n", query_timeouts.load());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_slow_controller: %s\n", e.what());
    std::filesystem::remove_all(dir);
    return 1;
  }
  std::filesystem::remove_all(dir);
  return 0;
}
