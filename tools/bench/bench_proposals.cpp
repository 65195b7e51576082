// Targets that fill a structure (issue 41; tools/bench/bench_proposals.sh starts the server): on
// the built-in phantom (registered from its beads, its anatomy loaded), `propose_targets prostate
// SPACING` runs ROUNDS times (each: a lattice through the prostate, every point evaluated as a
// target, on the job thread), each followed by `accept_proposals` of them all (evaluated again as
// they join the plan, on the event thread) and `clear_targets`, while a second client sends
// `ping` every 5 ms. Prints the proposal's duration, accept_proposals' round trip and the pings'
// median, p95, p99 and worst in milliseconds, idle and meanwhile. With COMMAND plan_seeds (issue
// 42) the proposal is a seed plan, ARGS its words after the structure (e.g. strength=0.6).
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

  std::vector<double> accept_ms;
  bool before = false;
  const auto run = ignav::bench::timeJobsWhilePinging(c, domain, xml, rounds, [&] {
    // The round before: its proposals into the plan (timed), then out again. (Its state follows
    // its outcome on another topic: the wait is a moment, counted in this round.)
    const auto proposed = [](const json& s) {
      return s.contains("structures") && s["structures"]["proposal_status"] == "proposed";
    };
    if (before) c.waitFor(proposed, 5s);
    before = true;
    if (proposed(c.state())) {
      const auto t = Clock::now();
      if (c.send("accept_proposals").accepted) accept_ms.push_back(sinceMs(t));
      c.send("clear_targets");
    }
    return c.send(command, {request, {}, {}});
  });
  if (!ignav::bench::printJobsWhilePinging(run, command, "target proposal",
                                           "targets are proposed and accepted")) {
    return 5;
  }
  ignav::bench::print("accept_proposals (all of them) -> reply", accept_ms);
  return 0;
}
