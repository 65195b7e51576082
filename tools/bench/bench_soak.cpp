// bench_load's soak (bench_load.cpp's header comment): one operator repeats a whole insertion —
// clear, add K targets, lock, approve every motion through the simulated controller to the last
// retraction, unlock — and the server's RSS and fds are printed per cycle.
#include <cstdio>
#include <string>

#include "bench_load.hpp"

namespace ignav::bench {
namespace {

bool waitApprovalAndApprove(Client& c, std::string& why) {
  c.waitFor(
      [](const json& s) {
        return s.contains("approval") && s["approval"]["status"] == "pending" &&
               s["workflow"]["phase"] != "moving";
      },
      60s);
  const json a = c.state()["approval"];
  const auto r = c.approve(a["plan_id"].get<std::uint64_t>(), a["digest"].get<std::string>());
  if (!r.accepted) why = "approve: " + r.error_code + " " + r.message;
  return r.accepted;
}

}  // namespace

int runSoak(std::uint32_t domain, const std::string& xml, int cycles, int targets_per_cycle,
            int server_pid) {
  Client c(domain, xml, "operator", nullptr,
           ignav::protocol::chooseRobot(domain, xml, nullptr, "", 20s));
  if (!c.waitForServer(20s) || !registered(c)) {
    std::fprintf(stderr, "bench_load: the server did not load and register the phantom\n");
    return 1;
  }
  std::mt19937 rng(42);
  const auto start = Clock::now();
  int reached_total = 0, refused_rotation = 0;
  std::printf("%6s %9s %9s %6s %9s\n", "cycle", "reached", "RSS MiB", "fds", "cycle s");
  for (int cycle = 1; cycle <= cycles; ++cycle) {
    const auto t0 = Clock::now();
    std::string why;
    // Clustered, as the targets of one biopsy are. From where the last insertion left the
    // cannula, some clusters need more than the 360° of rotation a plan may use: the server
    // refuses those (rightly); they are counted and another cluster is drawn.
    for (int attempt = 0; why.empty(); ++attempt) {
      if (!c.send("clear_targets").accepted) why = "clear_targets refused";
      const double sector_rad = std::uniform_real_distribution<double>(-M_PI, M_PI)(rng);
      for (int k = 0; k < targets_per_cycle && why.empty(); ++k) {
        const auto r =
            c.send("add_target", {"", {lpsOf(c.state(), reachablePoint(rng, sector_rad))}, {}});
        if (!r.accepted) why = "add_target: " + r.message;
      }
      if (!why.empty()) break;
      const auto r = c.send("lock_plan");
      if (r.accepted) break;
      if (r.error_code != "rotation_limit" || attempt == 20) why = "lock_plan: " + r.message;
      ++refused_rotation;
    }
    int reached = 0;
    // One approval per target, then one for the final retraction.
    for (int m = 0; m <= targets_per_cycle && why.empty(); ++m) {
      if (!waitApprovalAndApprove(c, why)) break;
      c.waitFor(
          [](const json& s) {
            const auto& p = s["workflow"]["phase"];
            return p == "at_target" || p == "done" || p == "fault" || p == "emergency";
          },
          60s);
      const auto phase = c.state()["workflow"]["phase"].get<std::string>();
      if (phase == "at_target") {
        ++reached;
      } else if (phase != "done") {
        why = "motion ended in " + phase;
      }
    }
    if (why.empty()) {
      if (reached != targets_per_cycle) why = "reached " + std::to_string(reached);
      const auto r = c.send("unlock_plan");
      if (!r.accepted) why = "unlock_plan: " + r.message;
    }
    reached_total += reached;
    const auto s = server_pid > 0 ? sampleProcess(server_pid, start) : ProcessSample{};
    std::printf("%6d %9d %9.1f %6d %9.2f\n", cycle, reached_total, s.rss_mib, s.fds,
                std::chrono::duration<double>(Clock::now() - t0).count());
    std::fflush(stdout);
    if (!why.empty()) {
      std::printf("FAIL in cycle %d: %s\n", cycle, why.c_str());
      return 1;
    }
  }
  std::printf(
      "soak: %d cycles, %d targets reached in %.1f s; %d target sets refused as needing more than "
      "360 deg of cannula rotation\nPASS\n",
      cycles, reached_total, std::chrono::duration<double>(Clock::now() - start).count(),
      refused_rotation);
  return 0;
}

}  // namespace ignav::bench
