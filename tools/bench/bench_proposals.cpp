// Targets that fill a structure (issue 41; tools/bench/bench_proposals.sh starts the server): on
// the built-in phantom (registered from its beads, its anatomy loaded), `propose_targets prostate
// SPACING` runs ROUNDS times (each: a lattice through the prostate, every point evaluated as a
// target, on the job thread), each followed by `accept_proposals` of them all (evaluated again as
// they join the plan, on the event thread) and `clear_targets`, while a second client sends
// `ping` every 5 ms. Prints the proposal's duration, accept_proposals' round trip and the pings'
// median, p95, p99 and worst in milliseconds, idle and meanwhile. With COMMAND plan_seeds (issue
// 42) the proposal is a seed plan, ARGS its words after the structure (e.g. strength=0.6); the
// dose computation an accepted plan starts is waited for between rounds, untimed. With COMMAND
// compute_dose, one seed plan is made and accepted first, then each round computes its dose
// again (the planned dose of its seeds on the CT's voxels, the files into the session folder).
//   bench_proposals DOMAIN DDS_CONFIG_XML [ROUNDS] [ARGS] [COMMAND]
#include <cstdio>
#include <string>

#include "bench_support.hpp"

namespace {

using ignav::bench::Clock;
using ignav::bench::sinceMs;
using nlohmann::json;
using namespace std::chrono_literals;

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: bench_proposals DOMAIN DDS_CONFIG_XML [ROUNDS] [ARGS] [COMMAND]\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const int rounds = argc > 3 ? std::stoi(argv[3]) : 5;
  const std::string request = std::string("prostate ") + (argc > 4 ? argv[4] : "8");
  const std::string command = argc > 5 ? argv[5] : "propose_targets";

  ignav::protocol::Client c(domain, xml, "operator", nullptr,
                            ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s));
  if (!ignav::bench::phantomWithAnatomy(c, domain)) return 3;

  if (command == "compute_dose") {
    // The plan whose dose is computed again, accepted, and its first dose done.
    const auto planned = c.send("plan_seeds", {request, {}, {}});
    if (!planned.accepted || c.waitForJobOutcome(planned.job, 300s).status != "done") return 4;
    const auto accepted = c.send("accept_proposals");
    if (!accepted.accepted || c.waitForJobOutcome(accepted.job, 300s).status != "done") return 4;
    const auto run = ignav::bench::timeJobsWhilePinging(c, domain, xml, rounds, [&] {
      return c.send("compute_dose", {"prostate", {}, {}});
    });
    return ignav::bench::printJobsWhilePinging(run, command, "dose computation",
                                               "the dose is computed")
               ? 0
               : 5;
  }
  std::vector<double> accept_ms;
  const auto run = ignav::bench::timeJobsWhilePinging(
      c, domain, xml, rounds,
      [&] {
        return c.send(command, {request, {}, {}});
      },
      [&] {
        // The round before: its proposals into the plan (timed), then out again; an accepted
        // seed plan's dose computation ends first. (Its state follows its outcome on another
        // topic: the wait is a moment.)
        c.waitFor(
            [](const json& s) {
              return s.contains("structures") && s["structures"]["proposal_status"] == "proposed";
            },
            5s);
        const auto t = Clock::now();
        const auto accepted = c.send("accept_proposals");
        if (!accepted.accepted) return;
        accept_ms.push_back(sinceMs(t));
        if (accepted.job != 0) (void)c.waitForJobOutcome(accepted.job, 300s);
        c.send("clear_targets");
      });
  if (!ignav::bench::printJobsWhilePinging(run, command, "target proposal",
                                           "targets are proposed and accepted")) {
    return 5;
  }
  ignav::bench::print("accept_proposals (all of them) -> reply", accept_ms);
  return 0;
}
