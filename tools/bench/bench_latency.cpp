// Round trips to a running ignav-server (tools/bench/bench_latency.sh starts one):
//   refused : a command refused (remove_target of a target that does not exist) -> reply
//   query   : command -> reply
//   move    : move_target (a click) -> reply, with the journal fsync
//   click   : move_target -> the target's new state sample arrives
//   approve : approval -> the MotionState sample showing the robot moving
//   e-stop  : emergency stop mid-move -> reply (the controller is aborted before the reply) and
//             -> the MotionState sample showing it at rest
// Prints median and p99 in microseconds.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/LU>

#include "bench_support.hpp"
#include "ignav/protocol/client.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

struct Stats {
  double median_us, p99_us;
};

Stats stats(const std::vector<double>& v) {
  return {ignav::bench::percentile(v, 50), ignav::bench::percentile(v, 99)};
}

double since_us(Clock::time_point t) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_latency DOMAIN DDS_CONFIG_XML [ROUNDS] [IDENTITY_DIR]\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const int rounds = argc > 3 ? std::stoi(argv[3]) : 2000;
  // "operator": an approver in configs/server.yaml. With an identity folder: DDS Security on.
  std::optional<ignav::protocol::SecurityIdentity> identity;
  if (argc > 4) identity = ignav::protocol::identityFromFolder(argv[4]);
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const auto* secure = identity ? &*identity : nullptr;
  ignav::protocol::Client c(
      domain, xml, "operator", secure,
      ignav::protocol::chooseRobot(domain, xml, secure, "", std::chrono::seconds(10)));
  if (!c.waitForServer(std::chrono::seconds(10))) {
    std::fprintf(stderr, "no server on domain %u\n", domain);
    return 3;
  }
  // Planning needs a CT and a registration.
  if (!ignav::bench::loadAndRegister(c, "phantom:")) return 4;
  const auto added = c.send("add_target", {"", {{0.0, 10.0, -30.0}}, {}});
  const std::string id = std::to_string(added.target_id);

  std::vector<double> refused, query, move, click;
  for (int i = 0; i < rounds / 10; ++i)
    c.send("query");  // warm-up
  for (int i = 0; i < rounds; ++i) {
    auto t = Clock::now();
    if (c.send("remove_target", {"", {}, {999999}}).accepted) return 9;
    refused.push_back(since_us(t));
  }
  for (int i = 0; i < rounds; ++i) {
    auto t = Clock::now();
    c.send("query");
    query.push_back(since_us(t));
  }
  for (int i = 0; i < rounds; ++i) {
    const Eigen::Vector3d p(0.001 * (i % 100), 10.0, -30.0);
    auto t = Clock::now();
    c.send("move_target", {"", {p}, {added.target_id}});
    move.push_back(since_us(t));
    // The state sample for this exact position (sent before the reply, so already here).
    c.waitFor(
        [&](const json& s) {
          return s["targets"].contains(id) && s["targets"][id]["lps"][0].get<double>() == p.x();
        },
        std::chrono::seconds(5));
    click.push_back(since_us(t));
  }

  // Motion: approve, wait for the robot to move, emergency-stop it, reset and resume; again.
  const auto& state = c.state();
  const Eigen::Matrix4d to_robot =
      ignav::protocol::matrixFromState(state["registration"]["image_to_robot"]);
  const Eigen::Vector3d reachable =
      (to_robot.inverse() * Eigen::Vector4d(8, 12, -175, 1)).head<3>();
  c.send("move_target", {"", {reachable}, {added.target_id}});
  if (!c.send("lock_plan").accepted) return 5;
  std::vector<double> approve, estop, halted;
  const int motions = std::max(10, rounds / 20);
  for (int i = 0; i < motions; ++i) {
    c.waitFor([](const json& s) { return s["approval"]["status"] == "pending"; },
              std::chrono::seconds(5));
    const json shown = c.state()["approval"];
    auto t = Clock::now();
    if (!c.approve(shown["plan_id"], shown["digest"]).accepted) return 6;
    c.waitFor([](const json& s) { return s["motion"]["state"] == "moving"; },
              std::chrono::seconds(5));
    approve.push_back(since_us(t));
    t = Clock::now();
    if (!c.emergencyStop().accepted) return 7;
    estop.push_back(since_us(t));
    c.waitFor([](const json& s) { return s["motion"]["state"] == "idle"; },
              std::chrono::seconds(5));
    halted.push_back(since_us(t));
    if (!c.send("reset_emergency").accepted || !c.send("resume").accepted) return 8;
  }
  auto print = [](const char* name, const std::vector<double>& v) {
    const auto s = stats(v);
    std::printf("%-44s median %8.1f us   p99 %8.1f us   (%zu rounds)\n", name, s.median_us,
                s.p99_us, v.size());
  };
  print("refused command -> reply", refused);
  print("query command -> reply", query);
  print("move_target -> reply (journal fsync)", move);
  print("move_target -> target state", click);
  print("approve -> motion state 'moving'", approve);
  print("emergency stop mid-move -> reply (halted)", estop);
  print("emergency stop mid-move -> motion 'idle'", halted);
  return 0;
}
