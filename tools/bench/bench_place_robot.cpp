// Commands answered while the robot is placed (issue 41; tools/bench/bench_place_robot.sh starts
// the server): on the built-in phantom (registered from its beads, its anatomy loaded),
// `place_robot prostate from superior` runs ROUNDS times on the job thread (each followed by the
// placement check of the registered robot), while a second client sends `ping` every 5 ms.
// Prints the placement's duration and the pings' median, p95, p99 and worst in milliseconds, idle
// and meanwhile.
//   bench_place_robot DOMAIN DDS_CONFIG_XML [ROUNDS]
#include <cstdio>
#include <string>

#include "bench_support.hpp"

int main(int argc, char** argv) {
  using namespace std::chrono_literals;
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_place_robot DOMAIN DDS_CONFIG_XML [ROUNDS]\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const int rounds = argc > 3 ? std::stoi(argv[3]) : 3;

  ignav::protocol::Client c(domain, xml, "operator", nullptr,
                            ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s));
  if (!ignav::bench::phantomWithAnatomy(c, domain)) return 3;
  const auto run = ignav::bench::timeJobsWhilePinging(c, domain, xml, rounds, [&] {
    return c.send("place_robot", {"prostate from superior", {}, {}});
  });
  return ignav::bench::printJobsWhilePinging(run, "place_robot", "robot placement",
                                             "the robot is placed")
             ? 0
             : 5;
}
