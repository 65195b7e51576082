// What the network tests and benches observe from a host of their own (tests/network/, docs/
// DEPLOYMENT.md), as ordinary DDS participants of one robot:
//
//   watch     a viewer that records every sample on the reply topic (so "exactly one reply per
//             command" is counted outside the client that sent them) and mirrors the state
//             topics; once --stop-file appears (holding the journal's last revision) it waits
//             until its mirror shows that revision and writes {replies, state, waited_ms}.
//   viewers   N viewers, each its own participant with a reader of the target topic, blocked on
//             a waitset; every sample's arrival time (CLOCK_MONOTONIC, one clock for every
//             namespace of a kernel) goes to --out as JSON lines, until --stop-file appears.
//   commander moves one target --rounds times (each to its own x) and times the reply; also
//             times `query`. Writes {moves: [{x, sent_ns, reply_ns}], queries_ms: [...]}.
//
// Each prints "net_probe <mode> ready" when it is matched with the server.
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include "ignav/protocol/client.hpp"
#include "ignav/protocol/wire/dds.hpp"

namespace {

using ignav::protocol::Client;
using ignav::protocol::Participant;
using ignav::protocol::Qos;
using ignav::protocol::Reader;
using nlohmann::json;
using namespace std::chrono_literals;

// CLOCK_MONOTONIC in ns: the same clock in every network namespace of one kernel, so arrival
// times from the viewer host and send times from the planning host compare directly.
std::int64_t monotonicNs() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

bool exists(const std::string& path) {
  return !path.empty() && ::access(path.c_str(), F_OK) == 0;
}

struct Options {
  std::uint32_t domain = 0;
  std::string dds_config = "loopback";
  ignav::protocol::DdsSite site;
  std::string identity_dir, robot, client_id = "net-probe", out, stop_file;
  int count = 30, rounds = 100, interval_ms = 100;
};

struct Connection {
  std::string xml;
  std::optional<ignav::protocol::SecurityIdentity> identity;
  std::string robot;
  const ignav::protocol::SecurityIdentity* secure() const {
    return identity ? &*identity : nullptr;
  }
};

Connection connect(const Options& o) {
  Connection c;
  c.xml = ignav::protocol::loadToolDdsConfig(o.dds_config, o.site);
  if (!o.identity_dir.empty()) c.identity = ignav::protocol::identityFromFolder(o.identity_dir);
  c.robot = ignav::protocol::chooseRobot(o.domain, c.xml, c.secure(), o.robot, 30s);
  return c;
}

void writeFile(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
  if (!f) throw std::runtime_error(path + ": cannot write");
}

// Each step of joining, with the seconds since start, on stderr: a watch that is slow to start on a
// lossy link says which handshake it is waiting for.
void progress(const char* step, std::chrono::steady_clock::time_point start) {
  const std::chrono::duration<double> s = std::chrono::steady_clock::now() - start;
  std::cerr << "net_probe: " << step << " after " << s.count() << " s" << std::endl;
}

int watch(const Options& o) {
  const auto joining = std::chrono::steady_clock::now();
  const Connection c = connect(o);
  progress("robot chosen", joining);
  Client client(o.domain, c.xml, o.client_id, c.secure(), c.robot);
  if (!client.waitForServer(60s)) throw std::runtime_error("no server answered");
  progress("the server's topics matched", joining);
  // The reply topic on a participant of its own (every client's replies, not only this one's),
  // made anew as a client's is when its handshake lost a message (Client::waitForServer).
  std::unique_ptr<Participant> participant;
  std::unique_ptr<Reader<ignav_msg_Reply>> replies;
  const auto matched_by = std::chrono::steady_clock::now() + 60s;
  ignav::protocol::RemakeSchedule schedule(3s, 30s);
  auto make = [&] {
    replies.reset();
    participant.reset();  // first: its peers forget its handshake
    participant =
        std::make_unique<Participant>(o.domain, c.xml, c.secure(), c.robot, "net_probe watch");
    replies = std::make_unique<Reader<ignav_msg_Reply>>(
        *participant, &ignav_msg_Reply_desc, ignav::protocol::topic::kReply, Qos::kRequest);
  };
  make();
  while (replies->matched() == 0) {
    if (std::chrono::steady_clock::now() >= matched_by) {
      throw std::runtime_error("the reply topic never matched");
    }
    if (c.secure() && schedule.due()) {
      make();
      schedule.remade();
    }
    std::this_thread::sleep_for(10ms);
  }
  progress("the reply topic matched", joining);
  std::cout << "net_probe watch ready robot=" << c.robot << std::endl;

  json seen = json::array();
  auto takeReplies = [&] {
    replies->take([&](const ignav_msg_Reply& r) {
      seen.push_back({{"client_id", r.client_id ? r.client_id : ""},
                      {"request_id", r.request_id},
                      {"accepted", r.accepted},
                      {"error_code", r.error_code ? r.error_code : ""},
                      {"revision", r.revision}});
    });
  };
  // Replies are kept 64 per client (keep-last): taking every 10 ms loses none.
  while (!exists(o.stop_file)) {
    takeReplies();
    client.poll();
    std::this_thread::sleep_for(10ms);
  }
  std::uint64_t final_revision = 0;
  std::ifstream(o.stop_file) >> final_revision;
  const auto start = std::chrono::steady_clock::now();
  const auto give_up = start + 60s;
  auto revision = [&] { return client.mirror().workflow ? client.mirror().workflow->revision : 0; };
  while (revision() < final_revision && std::chrono::steady_clock::now() < give_up) {
    takeReplies();
    client.poll();
    std::this_thread::sleep_for(10ms);
  }
  // Anything still on its way (a duplicate would come now if at all).
  for (int i = 0; i < 50; ++i) {
    takeReplies();
    std::this_thread::sleep_for(10ms);
  }
  client.poll();
  const double waited_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  writeFile(o.out,
            json{{"replies", seen}, {"state", client.state()}, {"waited_ms", waited_ms}}.dump(1));
  return 0;
}

int viewers(const Options& o) {
  const Connection c = connect(o);
  struct Viewer {
    std::unique_ptr<Participant> participant;
    std::unique_ptr<Reader<ignav_msg_TargetState>> reader;
    std::unique_ptr<ignav::protocol::WaitSet> waitset;
    std::vector<std::pair<double, std::int64_t>> arrivals;  // (lps x, t_ns)
    // Made anew when not matched within its attempt (10 s, doubling up to 40 s).
    ignav::protocol::RemakeSchedule schedule{10s, 40s};
  };
  std::vector<Viewer> all(static_cast<std::size_t>(o.count));
  int made_anew = 0;
  // A viewer as a client makes one (protocol::Client::waitForServer): a secured participant
  // whose handshake lost a message never matches, so one not matched within its attempt is made
  // anew, the attempt doubling (30 handshakes at once over a lossy link take a while).
  auto make = [&](std::size_t i) {
    auto& v = all[i];
    v.waitset.reset();
    v.reader.reset();
    v.participant.reset();
    v.participant = std::make_unique<Participant>(o.domain, c.xml, c.secure(), c.robot,
                                                  "net_probe viewer-" + std::to_string(i));
    v.reader = std::make_unique<Reader<ignav_msg_TargetState>>(
        *v.participant, &ignav_msg_TargetState_desc, ignav::protocol::topic::kTarget, Qos::kState);
    v.waitset = std::make_unique<ignav::protocol::WaitSet>(*v.participant);
    v.waitset->attach(v.reader->handle());
  };
  for (std::size_t i = 0; i < all.size(); ++i)
    make(i);
  const auto by = std::chrono::steady_clock::now() + 180s;
  auto remakeStuck = [&] {
    if (!c.secure()) return;
    for (std::size_t i = 0; i < all.size(); ++i) {
      auto& v = all[i];
      if (v.reader->matched() > 0 || !v.schedule.due()) continue;
      make(i);
      v.schedule.remade();
      ++made_anew;
    }
  };
  auto allMatched = [&] {
    for (const auto& v : all)
      if (v.reader->matched() == 0) return false;
    return true;
  };
  auto matchedCount = [&] {
    int n = 0;
    for (const auto& v : all)
      n += v.reader->matched() > 0 ? 1 : 0;
    return n;
  };
  for (int tick = 1; !allMatched() && std::chrono::steady_clock::now() < by; ++tick) {
    std::this_thread::sleep_for(20ms);
    remakeStuck();
    if (tick % 250 == 0) {
      std::cerr << "net_probe viewers: " << matchedCount() << " matched, " << made_anew
                << " made anew\n";
    }
  }
  if (!allMatched())
    throw std::runtime_error(std::to_string(matchedCount()) + " of " + std::to_string(o.count) +
                             " viewers matched the server in 180 s (" + std::to_string(made_anew) +
                             " made anew)");
  std::cout << "net_probe viewers ready count=" << o.count << " made_anew=" << made_anew
            << std::endl;

  std::atomic<bool> running{true};
  std::vector<std::thread> threads;
  for (auto& v : all) {
    threads.emplace_back([&v, &running] {
      while (running) {
        v.waitset->wait(200ms);
        const std::int64_t t = monotonicNs();
        v.reader->take(
            [&](const ignav_msg_TargetState& s) { v.arrivals.emplace_back(s.lps.x, t); });
      }
    });
  }
  while (!exists(o.stop_file))
    std::this_thread::sleep_for(50ms);
  running = false;
  for (auto& t : threads)
    t.join();
  std::ofstream out(o.out);
  for (std::size_t i = 0; i < all.size(); ++i)
    for (const auto& [x, t] : all[i].arrivals)
      out << json{{"viewer", i}, {"x", x}, {"t_ns", t}}.dump() << "\n";
  return out ? 0 : 1;
}

int commander(const Options& o) {
  const Connection c = connect(o);
  Client client(o.domain, c.xml, o.client_id, c.secure(), c.robot);
  if (!client.waitForServer(30s)) throw std::runtime_error("no server answered");
  client.waitFor([](const json& s) { return s.contains("workflow"); }, 30s);
  if (!client.state().contains("registration") ||
      client.state()["registration"]["status"] != "registered") {
    if (!client.send("load_volume", {"phantom:", {}, {}}, 60s).accepted)
      throw std::runtime_error("load_volume refused");
    client.waitFor([](const json& s) { return s["volume"]["status"] == "loaded"; }, 120s);
    if (!client.send("auto_fiducials", {}, 60s).accepted)
      throw std::runtime_error("auto_fiducials refused");
    client.waitFor([](const json& s) { return s["registration"]["status"] == "registered"; }, 120s);
  }
  const Eigen::Matrix4d to_robot =
      ignav::protocol::matrixFromState(client.state()["registration"]["image_to_robot"]);
  const Eigen::Vector3d base = (to_robot.inverse() * Eigen::Vector4d(8, 12, -175, 1)).head<3>();
  const auto added = client.send("add_target", {"", {base}, {}}, 60s);
  if (!added.accepted) throw std::runtime_error("add_target refused: " + added.message);
  std::cout << "net_probe commander ready target=" << added.target_id << std::endl;

  json moves = json::array(), queries = json::array();
  for (int i = 0; i < o.rounds; ++i) {
    // Each move to an x of its own (sub-micrometre steps): a viewer's sample names its move.
    const Eigen::Vector3d p = base + Eigen::Vector3d(0.0001 * (i + 1), 0, 0);
    const std::int64_t sent = monotonicNs();
    const auto r = client.send("move_target", {"", {p}, {added.target_id}}, 60s);
    const std::int64_t replied = monotonicNs();
    if (!r.accepted) throw std::runtime_error("move_target refused: " + r.message);
    moves.push_back({{"x", p.x()}, {"sent_ns", sent}, {"reply_ns", replied}});
    const std::int64_t q = monotonicNs();
    client.send("query", {}, 60s);
    queries.push_back(static_cast<double>(monotonicNs() - q) / 1e6);
    std::this_thread::sleep_for(std::chrono::milliseconds(o.interval_ms));
    client.poll();
  }
  client.send("remove_target", {"", {}, {added.target_id}}, 60s);
  writeFile(o.out, json{{"moves", moves}, {"queries_ms", queries}}.dump());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("net_probe: observe an ignav server from a host of its own (tests/network)");
  Options o;
  app.add_option("--domain", o.domain)->required();
  app.add_option("--dds-config", o.dds_config);
  app.add_option("--dds-interface", o.site.interface);
  app.add_option("--dds-peer", o.site.peers);
  app.add_option("--identity", o.identity_dir);
  app.add_option("--robot", o.robot);
  app.add_option("--client-id", o.client_id);
  app.add_option("--out", o.out)->required();
  auto* w = app.add_subcommand("watch", "record replies, mirror the state");
  w->add_option("--stop-file", o.stop_file)->required();
  auto* v = app.add_subcommand("viewers", "N viewers timing target samples");
  v->add_option("--count", o.count);
  v->add_option("--stop-file", o.stop_file)->required();
  auto* m = app.add_subcommand("commander", "time move_target and query");
  m->add_option("--rounds", o.rounds);
  m->add_option("--interval-ms", o.interval_ms);
  app.require_subcommand(1);
  CLI11_PARSE(app, argc, argv);
  try {
    if (*w) return watch(o);
    if (*v) return viewers(o);
    return commander(o);
  } catch (const std::exception& e) {
    std::cerr << "net_probe: " << e.what() << "\n";
    return 1;
  }
}
