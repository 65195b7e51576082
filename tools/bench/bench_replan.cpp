// Commands answered while an intermittent CT is searched (issue 40; tools/bench/bench_replan.sh
// starts the server): the robot's first insertion stops part-way (pause_at), ignav-plan writes
// the world's intermittent CT of the needle there, then `scan_needle` runs ROUNDS times while a
// second client sends `ping` every 5 ms and times each round trip. Prints the job's duration and
// the pings' median, p95, p99 and worst in milliseconds, during the searches and idle before.
//   bench_replan DOMAIN DDS_CONFIG_XML SESSION_DIR IGNAV_PLAN_EXE [ROUNDS] [SLICE_MM]
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/LU>

#include "bench_support.hpp"
#include "ignav/protocol/client.hpp"

namespace {

using nlohmann::json;
using namespace std::chrono_literals;

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr,
                 "usage: bench_replan DOMAIN DDS_CONFIG_XML SESSION_DIR IGNAV_PLAN_EXE [ROUNDS]\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const std::string session = argv[3];
  const std::string plan_exe = argv[4];
  const int rounds = argc > 5 ? std::stoi(argv[5]) : 10;
  // Thin slices make a large scan, whose search takes long enough to measure commands during it.
  const std::string slice_mm = argc > 6 ? argv[6] : "0.25";
  ignav::protocol::Client c(domain, xml, "operator", nullptr,
                            ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s));
  if (!c.waitForServer(10s)) {
    std::fprintf(stderr, "no server on domain %u\n", domain);
    return 3;
  }
  if (!ignav::bench::loadAndRegister(c, "phantom:")) return 4;
  const Eigen::Matrix4d image_to_robot =
      ignav::protocol::matrixFromState(c.state()["registration"]["image_to_robot"]);
  const Eigen::Vector3d lps =
      (image_to_robot.inverse() * Eigen::Vector4d(8, 12, -175, 1)).head<3>();
  const auto added = c.send("add_target", {"", {lps}, {}});
  if (!added.accepted) return 5;
  const std::string id = std::to_string(added.target_id);
  c.waitFor([&](const json& s) { return s["targets"].contains(id); }, 10s);
  const double full_mm = c.state()["targets"][id]["joints"][2].get<double>();
  if (!c.send("pause_at", {std::to_string(full_mm / 2), {}, {added.target_id}}).accepted) return 6;
  if (!c.send("lock_plan").accepted) return 7;
  c.waitFor([](const json& s) { return s["approval"]["status"] == "pending"; }, 10s);
  const json shown = c.state()["approval"];
  if (!c.approve(shown["plan_id"], shown["digest"]).accepted) return 8;
  c.waitFor([&](const json& s) { return s["targets"][id]["paused"] == true; }, 60s);

  // The world's intermittent CT of the needle where it stopped (the agar of configs/tissues.yaml
  // bends it; the server is not told).
  const std::string scan = session + ".intermittent";
  const std::string make = plan_exe + " confirmation-phantom " + session +
                           " --robot configs/robots/torabi2014.yaml --out " + scan +
                           " --needle-at " + id + " --hidden-tissue agar --noise-hu 8 --slice-mm " +
                           slice_mm + " > /dev/null";
  if (std::system(make.c_str()) != 0) {
    std::fprintf(stderr, "%s failed\n", make.c_str());
    return 9;
  }

  const auto run = ignav::bench::timeJobsWhilePinging(c, domain, xml, rounds, [&] {
    return c.send("scan_needle", {scan, {}, {}, image_to_robot});
  });
  if (!ignav::bench::printJobsWhilePinging(run, "scan_needle", "intermittent CT search and re-aim",
                                           "the CT is searched")) {
    return 10;
  }
  std::system(("rm -rf " + scan + " " + scan + "_truth.json").c_str());
  return 0;
}
