// `robots` and `doctor`: the servers on the domain, and whether a deployment works (who is
// there, round trips, clock offsets, what looks wrong). They talk to no one robot.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <thread>

#include "subcommands.hpp"

namespace ignav::ctl {
namespace {

using nlohmann::json;
using protocol::Client;
using protocol::Health;

// `ignavctl robots`: one line per server (two with one robot id are both shown, marked).
void printRobots(const std::vector<Health>& robots, bool as_json) {
  if (as_json) {
    std::cout << json(robots).dump(2) << "\n";
    return;
  }
  std::map<std::string, int> per_id;
  for (const auto& h : robots)
    ++per_id[h.robot_id];
  std::printf("%-20s %-20s %-34s %-10s %10s  %s\n", "robot", "host", "session", "version",
              "uptime(s)", "journal");
  for (const auto& h : robots) {
    std::printf("%-20s %-20s %-34s %-10s %10.0f  %s%s\n", h.robot_id.c_str(), h.host.c_str(),
                h.session_id.c_str(), h.version.c_str(), h.uptime_s, h.journal.c_str(),
                per_id[h.robot_id] > 1 ? "  DUPLICATE robot id: the later server stops" : "");
  }
  if (robots.empty()) std::printf("(none found)\n");
}

// `ignavctl doctor`: who is on the domain, each robot's round trip and clock offset, and what looks
// wrong. Exit 0 when every check passes, 1 when one fails, 3 when nothing answers.
int runDoctor(const Domain& d, std::chrono::milliseconds listen) {
  using Clock = std::chrono::steady_clock;
  const std::uint32_t domain = d.options.domain;
  const auto* identity = d.identity();
  const bool as_json = d.options.as_json;
  const auto participants = protocol::discoverParticipants(domain, d.xml, identity, listen);
  const auto robots = protocol::discoverRobots(domain, d.xml, identity, listen);
  json report{{"domain", domain},
              {"security", identity ? "on" : "off"},
              {"participants", json::array()},
              {"robots", json::array()},
              {"checks", json::array()}};
  for (const auto& p : participants)
    report["participants"].push_back({{"guid", p.guid}, {"name", p.name}, {"subject", p.subject}});
  bool failed = false;
  auto checkLine = [&](const std::string& level, const std::string& text) {
    report["checks"].push_back({{"level", level}, {"text", text}});
    if (level == "FAIL") failed = true;
  };
  std::map<std::string, int> per_id;
  for (const auto& h : robots)
    ++per_id[h.robot_id];
  for (const auto& [id, n] : per_id) {
    if (n > 1)
      checkLine("FAIL", "robot id '" + id + "' is served by " + std::to_string(n) +
                            " servers: the later ones stop; give each robot its own");
  }
  for (const auto& [id, n] : per_id) {
    Client c(domain, d.xml, d.options.client_id, identity, id);
    json r{{"robot_id", id}};
    if (!c.waitForServer(std::chrono::seconds(5))) {
      checkLine("FAIL", "robot '" + id + "': its Health is seen but its commands are not matched");
      report["robots"].push_back(r);
      continue;
    }
    // A first ping until one is answered: with DDS Security the server may match this client's
    // reply reader a moment after this client sees the server, and a reply written before is
    // lost. Then ten measured ones; one unanswered is a finding, not the end of the check.
    auto ping = [&](std::chrono::milliseconds timeout) -> std::optional<double> {
      const auto t0 = Clock::now();
      try {
        c.send("ping", {}, timeout);
      } catch (const protocol::Timeout&) {
        return std::nullopt;
      }
      return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    };
    bool answered = false;
    for (int attempt = 0; attempt < 3 && !answered; ++attempt)
      answered = ping(std::chrono::seconds(2)).has_value();
    std::vector<double> rtt_ms;
    for (int i = 0; i < 10 && answered; ++i) {
      if (auto ms = ping(std::chrono::seconds(2))) rtt_ms.push_back(*ms);
    }
    if (rtt_ms.empty()) {
      checkLine("FAIL", "robot '" + id + "': matched, but no ping was answered");
      report["robots"].push_back(r);
      continue;
    }
    if (rtt_ms.size() < 10) {
      checkLine("WARN", "robot '" + id + "': " + std::to_string(10 - rtt_ms.size()) +
                            " of 10 pings unanswered (packet loss?)");
    }
    std::sort(rtt_ms.begin(), rtt_ms.end());
    const double median = rtt_ms[rtt_ms.size() / 2];
    // The server's clock: the next Health sample (once a second) against ours when it arrives,
    // plus half the quickest round trip for its way here (slower ones waited for a busy CPU,
    // not for the network). Good to the poll period plus that half, and whatever delay the
    // Health sample met on its way beyond it.
    c.poll();
    const double before = c.mirror().health ? c.mirror().health->server_time_unix_s : 0.0;
    std::optional<double> offset_ms;
    const auto end = Clock::now() + std::chrono::milliseconds(2500);
    while (Clock::now() < end && !offset_ms) {
      c.poll();
      if (c.mirror().health && c.mirror().health->server_time_unix_s != before) {
        const double now_s =
            std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
                .count();
        offset_ms = (c.mirror().health->server_time_unix_s - now_s) * 1000.0 + rtt_ms.front() / 2;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    const auto& h = *c.mirror().health;
    r.update(
        {{"host", h.host},
         {"session", h.session_id},
         {"version", h.version},
         {"uptime_s", h.uptime_s},
         {"journal", h.journal},
         {"round_trip_ms", {{"min", rtt_ms.front()}, {"median", median}, {"max", rtt_ms.back()}}}});
    if (offset_ms) r["clock_offset_ms"] = *offset_ms;
    report["robots"].push_back(r);
    if (h.journal != "ok") checkLine("FAIL", "robot '" + id + "': journal: " + h.journal);
    if (offset_ms && std::abs(*offset_ms) > 1000.0) {
      checkLine("WARN",
                fmt::format("robot '{}': its clock is {:+.0f} ms from this host's (approval "
                            "countdowns use the server's; check NTP)",
                            id, *offset_ms));
    }
  }
  if (robots.empty() && !participants.empty()) {
    bool secure_there = false;
    for (const auto& p : participants)
      secure_there = secure_there || !p.subject.empty();
    checkLine("FAIL", std::string("participants are on the domain but no ignav server answers: ") +
                          (secure_there && !identity
                               ? "they carry certificates (DDS Security on) and this client has "
                                 "no --identity"
                               : "a DDS Security mismatch (another CA, or an identity scoped to "
                                 "another robot), or no server runs"));
  }
  if (robots.empty() && participants.empty()) {
    checkLine("FAIL", "nothing on DDS domain " + std::to_string(domain) +
                          " (wrong domain, interface or peers? no multicast on this network?)");
  }
  if (as_json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << "DDS domain " << domain << ", security " << (identity ? "on" : "OFF") << "\n"
              << "participants (" << participants.size() << ", this one not counted):\n";
    for (const auto& p : participants) {
      std::printf("  %s  %-40s %s\n", p.guid.substr(0, 12).c_str(),
                  p.name.empty() ? "(unnamed: not ignav?)" : p.name.c_str(), p.subject.c_str());
    }
    std::cout << "robots (" << report["robots"].size() << "):\n";
    for (const auto& r : report["robots"]) {
      if (!r.contains("round_trip_ms")) {
        std::printf("  %s: not answering\n", r["robot_id"].get<std::string>().c_str());
        continue;
      }
      std::printf(
          "  %s on %s: session %s, version %s, up %.0f s, journal %s\n"
          "    round trip (ping x10): median %.2f ms, max %.2f ms; clock offset %s\n",
          r["robot_id"].get<std::string>().c_str(), r["host"].get<std::string>().c_str(),
          r["session"].get<std::string>().c_str(), r["version"].get<std::string>().c_str(),
          r["uptime_s"].get<double>(), r["journal"].get<std::string>().c_str(),
          r["round_trip_ms"]["median"].get<double>(), r["round_trip_ms"]["max"].get<double>(),
          r.contains("clock_offset_ms")
              ? fmt::format("{:+.1f} ms", r["clock_offset_ms"].get<double>()).c_str()
              : "unknown (no Health sample in 2.5 s)");
    }
    std::cout << "checks:\n";
    if (report["checks"].empty()) std::cout << "  ok   everything answers, each robot id once\n";
    for (const auto& c : report["checks"]) {
      std::printf("  %-4s %s\n", c["level"].get<std::string>().c_str(),
                  c["text"].get<std::string>().c_str());
    }
  }
  if (robots.empty() && participants.empty()) return kExitNoServer;
  return failed ? kExitRejected : 0;
}

}  // namespace

void addDomainCommands(CLI::App& app, Action& chosen) {
  auto* robots = app.add_subcommand(
      "robots", "the ignav servers on this DDS domain: robot id, host, session, version, uptime");
  robots->callback([&chosen] {
    chosen.on_domain = [](const Domain& d) {
      const auto found = protocol::discoverRobots(d.options.domain, d.xml, d.identity(), d.wait);
      printRobots(found, d.options.as_json);
      return found.empty() ? kExitNoServer : 0;
    };
  });

  auto doctor_s = std::make_shared<double>(2.0);
  auto* doctor = app.add_subcommand(
      "doctor",
      "check a deployment: the participants and robots on this domain, round trips, clock "
      "offsets, and what looks wrong");
  doctor->add_option("--seconds", *doctor_s, "how long to listen for participants (default 2)");
  doctor->callback([&chosen, doctor_s] {
    chosen.on_domain = [doctor_s](const Domain& d) {
      return runDoctor(d, std::chrono::milliseconds(static_cast<long>(*doctor_s * 1000)));
    };
  });
}

}  // namespace ignav::ctl
