// What re-planning mid-insertion buys through the server (issue 40; replan_study.sh starts one):
// N random reachable targets (both joints 5-38 mm, seed 1, as `ignav-plan world-study` draws
// them), each insertion stopped with half its stylet out (pause_at); at each stop the world
// (`ignav-plan confirmation-phantom --world` or `--hidden-tissue`) writes the intermittent CT of
// the needle there, with its truth: where the insertion would land if finished as aimed. The
// server searches the scan, refits and re-aims (scan_needle with the session's registration),
// `reaim` takes it, the insertion is finished. A confirmation CT of every seed then measures
// where each landed. Prints, over the targets, the world's as-aimed landings and the measured
// re-aimed ones: mean and worst, and how many scans were refused.
//   replan_study DOMAIN DDS_CONFIG_XML SESSION_DIR IGNAV_PLAN_EXE N WORLD_ARGS...
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "bench_support.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/protocol/client.hpp"

namespace {

using nlohmann::json;
using namespace std::chrono_literals;

json run(const std::string& command) {
  std::string out;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return json();
  char buf[4096];
  while (std::size_t n = fread(buf, 1, sizeof buf, p))
    out.append(buf, n);
  if (pclose(p) != 0) {
    std::fprintf(stderr, "%s failed:\n%s\n", command.c_str(), out.c_str());
    return json();
  }
  const auto brace = out.find('{');
  return brace == std::string::npos ? json() : json::parse(out.substr(brace), nullptr, false);
}

void waitPending(ignav::protocol::Client& c) {
  c.waitFor([](const json& s) { return s["approval"]["status"] == "pending"; }, 30s);
}

// Approves what is shown; waits until the robot rests after it.
bool approveAndRest(ignav::protocol::Client& c) {
  waitPending(c);
  const json shown = c.state()["approval"];
  const auto r = c.approve(shown["plan_id"], shown["digest"]);
  if (!r.accepted) return false;
  c.waitFor(
      [&](const json& s) {
        return (s["workflow"]["phase"] == "at_target" || s["workflow"]["phase"] == "done") &&
               s["workflow"]["revision"].get<std::uint64_t>() > r.revision &&
               s["motion"]["state"] == "idle";
      },
      120s);
  return true;
}

struct Stats {
  double mean = 0.0, worst = 0.0;
};
Stats stats(const std::vector<double>& v) {
  Stats s;
  for (double x : v) {
    s.mean += x / static_cast<double>(v.size());
    s.worst = std::max(s.worst, x);
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 7) {
    std::fprintf(stderr,
                 "usage: replan_study DOMAIN DDS_CONFIG_XML SESSION_DIR IGNAV_PLAN_EXE N "
                 "WORLD_ARGS...\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const std::string session = argv[3];
  const std::string plan = argv[4];
  const int n = std::stoi(argv[5]);
  std::string world;
  for (int i = 6; i < argc; ++i)
    world += std::string(" ") + argv[i];
  const std::string robot_path = "configs/robots/torabi2014.yaml";
  auto robot = ignav::config::loadRobot(robot_path);
  if (!robot) {
    std::fprintf(stderr, "%s\n", robot.error().message.c_str());
    return 2;
  }
  ignav::protocol::Client c(domain, xml, "operator", nullptr,
                            ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s));
  if (!c.waitForServer(10s) || !ignav::bench::loadAndRegister(c, "phantom:")) return 3;
  const Eigen::Matrix4d image_to_robot =
      ignav::protocol::matrixFromState(c.state()["registration"]["image_to_robot"]);

  // The targets, as world-study draws them.
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> theta(0.0, 2.0 * M_PI), depth(5.0, 38.0);
  std::vector<std::uint32_t> ids;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d robot_mm =
        robot->kinematics.forward({theta(rng), depth(rng), depth(rng)}).tip_mm;
    const Eigen::Vector3d lps = (image_to_robot.inverse() * robot_mm.homogeneous()).head<3>();
    const auto added = c.send("add_target", {"", {lps}, {}});
    if (!added.accepted) {
      std::fprintf(stderr, "add_target: %s\n", added.message.c_str());
      return 4;
    }
    ids.push_back(added.target_id);
  }
  c.waitFor([&](const json& s) { return s["targets"].size() == ids.size(); }, 10s);
  for (auto id : ids) {
    const double full_mm = c.state()["targets"][std::to_string(id)]["joints"][2].get<double>();
    if (!c.send("pause_at", {std::to_string(full_mm / 2), {}, {id}}).accepted) return 5;
  }
  const auto locked = c.send("lock_plan");
  if (!locked.accepted) {
    std::fprintf(stderr, "lock_plan: %s\n", locked.message.c_str());
    return 6;
  }

  std::map<std::uint32_t, double> as_aimed_mm;  // the world's answer for the aim before
  int refused = 0, scans = 0;
  std::string last_refusal;
  while (c.state()["workflow"]["phase"] != "done") {
    waitPending(c);
    const json shown = c.state()["approval"];
    const bool part_way =
        shown["summary"].get<std::string>().find("part-way to T") != std::string::npos;
    const auto id = shown["target_id"].get<std::uint32_t>();
    if (!approveAndRest(c)) return 7;
    if (!part_way) continue;
    const std::string scan = session + ".scan" + std::to_string(++scans);
    const json truth =
        run(plan + " confirmation-phantom " + session + " --robot " + robot_path + " --out " +
            scan + " --needle-at " + std::to_string(id) + " --noise-hu 8 --json" + world);
    if (truth.is_null()) return 8;
    for (const auto& t : truth["targets"])
      if (t["id"].get<std::uint32_t>() == id) as_aimed_mm[id] = t["finished_off_plan_mm"];
    const auto sent = c.send("scan_needle", {scan, {}, {}, image_to_robot});
    if (!sent.accepted) return 9;
    const auto outcome = c.waitForJobOutcome(sent.job, 300s);
    std::string refusal = outcome.status == "done" ? "" : outcome.message;
    if (refusal.empty()) {
      const auto taken = c.send("reaim");
      if (!taken.accepted) refusal = taken.error_code + ": " + taken.message;
    }
    std::fprintf(stderr, "T%u: %s\n", id,
                 refusal.empty() ? outcome.message.c_str() : refusal.c_str());
    if (!refusal.empty()) {
      ++refused;
      last_refusal = refusal;
      // scan_needle ended the request from the stop (any change does): the rest as aimed.
      if (!c.send("request_approval").accepted) return 12;
    }
    std::system(("rm -rf " + scan + " " + scan + "_truth.json").c_str());
  }

  const std::string scan = session + ".confirmation";
  if (run(plan + " confirmation-phantom " + session + " --robot " + robot_path + " --out " + scan +
          " --noise-hu 8 --json" + world)
          .is_null())
    return 10;
  const auto load = c.send("load_confirmation", {scan, {}, {}});
  if (!load.accepted) return 11;
  c.waitFor(
      [&](const json& s) {
        return s["workflow"]["revision"].get<std::uint64_t>() > load.revision &&
               s["verification"]["status"] != "measuring" && s["verification"]["status"] != "none";
      },
      120s);
  std::vector<double> before, after;
  for (const auto& row : c.state()["verification"]["targets"]) {
    const auto id = row["target_id"].get<std::uint32_t>();
    if (!as_aimed_mm.count(id)) continue;
    before.push_back(as_aimed_mm[id]);
    after.push_back(row["error_mm"].get<double>());
  }
  std::system(("rm -rf " + scan + " " + scan + "_truth.json").c_str());
  const Stats b = stats(before), a = stats(after);
  std::printf("world:%s\n", world.c_str());
  std::printf("%zu targets measured (of %d; %d scans refused%s%s)\n", after.size(), n, refused,
              last_refusal.empty() ? "" : "; the last: ", last_refusal.c_str());
  std::printf("as aimed (the world's answer)      mean %.2f mm, worst %.2f mm\n", b.mean, b.worst);
  std::printf("re-aimed mid-insertion (measured)  mean %.2f mm, worst %.2f mm\n", a.mean, a.worst);
  std::printf("verification: %s\n",
              c.state()["verification"]["message"].get<std::string>().c_str());
  return 0;
}
