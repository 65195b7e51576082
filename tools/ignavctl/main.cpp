// ignavctl: a human and scripted client of ignav-server over DDS.
//   ignavctl status | load PATH|phantom | fiducials auto | fiducials set P1 P2 P3
//   ignavctl targets add X,Y,Z | rm ID | ls | clear | lock | unlock
//   ignavctl slice --view axial --lps X,Y,Z --out s.png | watch | run script.yaml
//   ignavctl approval | approve [--yes] [--plan N --digest HEX] | motion | emergency-stop
//   ignavctl verify [load PATH | place ID X,Y,Z | accept ID | reject SEED | fit NAME | aim NAME]
//   ignavctl replay SESSION [--speed 1|10|max] [--until SEQ]
//   ignavctl robots (the servers on the domain); --robot ID picks one where several share it
//   ignavctl doctor (participants, robots, round trips, clock offsets, what looks wrong)
//   and every other command by its name: ignavctl ping | add-target X,Y,Z | check-ready robot ...
#include <fmt/format.h>
#include <yaml-cpp/yaml.h>
#include <CLI/CLI.hpp>

#include <unistd.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <thread>

#include "ignav/commands/command_table.hpp"
#include "ignav/protocol/client.hpp"
#include "verification_view.hpp"

namespace {

using ignav::protocol::ApprovalState;
using ignav::protocol::Client;
using ignav::protocol::CommandArgs;
using ignav::protocol::Health;
using ignav::protocol::MotionState;
using ignav::protocol::Point3;
using ignav::protocol::RegistrationState;
using ignav::protocol::RobotState;
using ignav::protocol::StateMirror;
using ignav::protocol::TargetState;
using ignav::protocol::toEigen;
using ignav::protocol::VolumeState;
using ignav::protocol::WorkflowState;
using nlohmann::json;
using namespace std::chrono_literals;

constexpr int kExitRejected = 1;
constexpr int kExitUsage = 2;
constexpr int kExitNoServer = 3;

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

Eigen::Vector3d triple(const std::string& text) {
  Eigen::Vector3d p;
  char extra = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &p.x(), &p.y(), &p.z(), &extra) != 3 ||
      !p.allFinite()) {
    throw UsageError("'" + text + "' is not X,Y,Z");
  }
  return p;
}

// "m00,m01,...,m33": a row-major 4x4.
Eigen::Matrix4d matrix16(const std::string& text) {
  Eigen::Matrix4d m;
  std::stringstream in(text);
  std::string item;
  int k = 0;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (k >= 16 || end == item.c_str() || *end != '\0' || !std::isfinite(v)) {
      throw UsageError("'" + text + "' is not 16 comma-separated numbers");
    }
    m(k / 4, k % 4) = v;
    ++k;
  }
  if (k != 16) throw UsageError("'" + text + "' is not 16 comma-separated numbers");
  return m;
}

// `round_trip_ms` (< 0: not measured) is from writing the command to taking its reply.
void printReply(const ignav::protocol::Reply& r, bool as_json, double round_trip_ms = -1.0) {
  if (as_json) {
    json out = r;  // its JSON view, from the Reply's one list of fields
    if (round_trip_ms >= 0) out["round_trip_ms"] = round_trip_ms;
    std::cout << out.dump() << "\n";
  } else if (r.accepted) {
    std::cout << "accepted" << (r.target_id ? " (target " + std::to_string(r.target_id) + ")" : "")
              << ": " << r.message << "\n";
  } else {
    std::cout << "REJECTED [" << r.error_code << "]: " << r.message << "\n";
  }
}

// A derived subcommand's words as its command's arguments, in usageOf()'s order: the path,
// then the ids, the points, the matrix.
CommandArgs commandArgs(const ignav::commands::InputSpec& spec,
                        const std::vector<std::string>& words) {
  const auto& a = spec.args;
  const std::string usage = std::string(spec.name) + " " + ignav::commands::usageOf(spec);
  CommandArgs out;
  std::size_t next = 0;
  auto take = [&]() -> const std::string& {
    if (next >= words.size()) throw UsageError("usage: " + usage);
    return words[next++];
  };
  if (a.path_is) out.path = take();
  auto count = [&](std::size_t n, std::size_t others) {
    // "Any number" takes what the fields after it leave.
    return n == ignav::commands::kAnyCount ? words.size() - std::min(words.size(), next + others)
                                           : n;
  };
  const std::size_t matrix_words = a.matrix_is && !a.matrix_optional ? 1 : 0;
  const std::size_t after_ids =
      (a.points == ignav::commands::kAnyCount ? 0 : a.points) + matrix_words;
  for (std::size_t i = 0, n = count(a.ids, after_ids); i < n; ++i) {
    const std::string& word = take();
    try {
      std::size_t used = 0;
      const unsigned long id = std::stoul(word, &used);
      if (used != word.size() || id > UINT32_MAX) throw std::out_of_range(word);
      out.ids.push_back(static_cast<std::uint32_t>(id));
    } catch (const std::logic_error&) {
      throw UsageError("'" + word + "' is not a target id; usage: " + usage);
    }
  }
  for (std::size_t i = 0, n = count(a.points, matrix_words); i < n; ++i)
    out.points.push_back(triple(take()));
  if (a.matrix_is && (!a.matrix_optional || next < words.size())) out.matrix = matrix16(take());
  if (next != words.size()) throw UsageError("too many arguments; usage: " + usage);
  return out;
}

std::string fmt3(const Point3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%7.2f, %7.2f, %7.2f)", p.x, p.y, p.z);
  return buf;
}

template <typename T, std::size_t N>
std::string list(const std::array<T, N>& values) {
  return json(values).dump();
}

// The printers read the mirrored values (StateMirror, protocol/types.hpp), not JSON by key: a
// field renamed in the IDL is then a compile error here, not an empty column.
void printTargets(const StateMirror& state) {
  std::printf("%-4s %-5s %-26s %-26s %-12s %8s %8s %8s %6s\n", "id", "order", "LPS (mm)",
              "robot (mm)", "status", "θc(deg)", "zc(mm)", "zs(mm)", "TRE");
  std::vector<const TargetState*> rows;
  for (const auto& [id, t] : state.targets)
    rows.push_back(&t);
  std::sort(rows.begin(), rows.end(),
            [](const TargetState* a, const TargetState* b) { return a->order < b->order; });
  for (const TargetState* t : rows) {
    std::printf("%-4u %-5u %-26s %-26s %-12s %8.2f %8.3f %8.3f %6.2f\n", t->id, t->order,
                fmt3(t->lps).c_str(), fmt3(t->robot).c_str(), t->status.c_str(),
                t->joints[0] * 180.0 / M_PI, t->joints[1], t->joints[2], t->tre_mm);
    if (t->status != "planned" || !t->path_warning.empty())
      std::printf("     %s\n", t->message.c_str());
  }
}

void printApproval(const StateMirror& s) {
  if (!s.approval || s.approval->status != "pending") {
    std::cout << "no motion is waiting for approval\n";
    return;
  }
  const ApprovalState& a = *s.approval;
  std::cout << a.summary << "\n"
            << "  plan " << a.plan_id << ", digest " << a.digest << "\n"
            << "  from steps " << list(a.from_steps) << ", expires in "
            << static_cast<int>(a.expires_in_s) << " s; approvers " << json(a.approvers).dump()
            << "\n";
  for (const auto& m : a.moves)
    std::printf("  %-18s %s  %.2f s\n", m.kind.c_str(), list(m.steps).c_str(), m.duration_s);
}

void printMotion(const StateMirror& s) {
  if (!s.motion) {
    std::cout << "no motion state yet\n";
    return;
  }
  const MotionState& m = *s.motion;
  std::cout << "controller " << m.controller << ": " << m.state << " (link " << m.lifecycle << ")\n"
            << "  steps " << list(m.steps) << " (verified " << list(m.verified_steps) << ")\n"
            << "  joints θc " << m.joints[0] * 180.0 / M_PI << "°, zc " << m.joints[1] << " mm, zs "
            << m.joints[2] << " mm\n"
            << "  tip robot " << fmt3(m.tip_robot)
            << (m.tip_lps ? ", LPS " + fmt3(*m.tip_lps) : std::string()) << "\n";
  if (m.plan_id != 0) {
    std::cout << "  plan " << m.plan_id << " to target " << m.target_id << ": move " << m.move_index
              << " of " << m.move_count << " (" << m.move_kind << ") towards " << list(m.goal_steps)
              << "\n";
  }
  if (!m.fault.empty()) std::cout << "  fault: " << m.fault << "\n";
}

void printStatus(const StateMirror& s) {
  const auto or_dash = [](const auto& part, auto field) {
    return part ? json((*part).*field).dump() : std::string("-");
  };
  std::cout << "session      " << or_dash(s.health, &Health::session_dir) << "\n"
            << "phase        " << or_dash(s.workflow, &WorkflowState::phase) << " (revision "
            << or_dash(s.workflow, &WorkflowState::revision) << ")\n"
            << "allowed      " << or_dash(s.workflow, &WorkflowState::allowed_commands) << "\n"
            << "robot        " << or_dash(s.robot, &RobotState::name) << "\n"
            << "volume       " << or_dash(s.volume, &VolumeState::status) << " "
            << or_dash(s.volume, &VolumeState::message) << "\n"
            << "registration " << or_dash(s.registration, &RegistrationState::status) << " "
            << or_dash(s.registration, &RegistrationState::message) << "\n"
            << "targets      " << s.targets.size() << "\n";
  if (s.workflow && !s.workflow->safety_notice.empty())
    std::cout << "SAFETY       " << s.workflow->safety_notice << "\n";
}

Eigen::Vector3d jsonPoint(const json& p) {
  return {p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
}

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
int runDoctor(std::uint32_t domain, const std::string& xml,
              const ignav::protocol::SecurityIdentity* identity, const std::string& client_id,
              std::chrono::milliseconds listen, bool as_json) {
  using Clock = std::chrono::steady_clock;
  const auto participants = ignav::protocol::discoverParticipants(domain, xml, identity, listen);
  const auto robots = ignav::protocol::discoverRobots(domain, xml, identity, listen);
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
    Client c(domain, xml, client_id, identity, id);
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
      } catch (const ignav::protocol::Timeout&) {
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

// Robot-frame points become LPS through the current registration (scripts plan in the robot
// frame so they do not depend on where the phantom lies).
Eigen::Vector3d robotToLps(const StateMirror& state, const Eigen::Vector3d& robot) {
  if (!state.registration || state.registration->status != "registered") {
    throw UsageError("robot_mm needs a registration");
  }
  const Eigen::Matrix4d m = ignav::protocol::fromRowMajor(state.registration->image_to_robot);
  const Eigen::Vector4d lps = m.inverse() * robot.homogeneous();
  return lps.head<3>();
}

// Dotted path into the state ("volume.status", "targets.3.status").
const json* at(const json& state, const std::string& path) {
  const json* node = &state;
  std::size_t start = 0;
  while (start <= path.size()) {
    const std::size_t dot = path.find('.', start);
    const std::string key =
        path.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (!node->is_object() || !node->contains(key)) return nullptr;
    node = &(*node)[key];
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  return node;
}

json yamlToJson(const YAML::Node& n) {
  if (n.IsSequence()) {
    json a = json::array();
    for (const auto& e : n)
      a.push_back(yamlToJson(e));
    return a;
  }
  if (n.IsMap()) {
    json o = json::object();
    for (const auto& kv : n)
      o[kv.first.Scalar()] = yamlToJson(kv.second);
    return o;
  }
  const std::string s = n.Scalar();
  if (s == "true" || s == "false") return s == "true";
  // YAML's spellings of the IEEE specials, so scripts can send them and see them refused.
  if (s == ".nan" || s == ".NaN" || s == ".NAN") return std::nan("");
  if (s == ".inf" || s == "+.inf" || s == ".Inf") return HUGE_VAL;
  if (s == "-.inf" || s == "-.Inf") return -HUGE_VAL;
  try {
    std::size_t used = 0;
    const double d = std::stod(s, &used);
    if (used == s.size()) return d;
  } catch (const std::exception&) {
  }
  return s;
}

bool matches(const json& actual, const json& expected) {
  if (expected.is_number() && actual.is_number()) {
    return std::abs(actual.get<double>() - expected.get<double>()) < 1e-9;
  }
  return actual == expected;
}

// `ignavctl run`: each step sends a command (and checks the reply), waits for a state, or
// fetches a slice. Any mismatch stops the script with exit code 1.
int runScript(Client& client, const std::string& path, const std::string& out_dir, bool as_json) {
  YAML::Node doc;
  try {
    doc = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw UsageError(path + ": " + e.what());
  }
  if (!doc["steps"] || !doc["steps"].IsSequence()) throw UsageError(path + ": steps: is missing");
  std::map<std::string, std::uint32_t> names;
  int index = 0;
  // Read your writes: the next step sees at least the state the last reply's revision names, and
  // the target the reply names (state topics and replies travel separately, and each state topic
  // on its own: on a lossy network the workflow's sample may come before the target's).
  auto catchUp = [&](const ignav::protocol::Reply& r) {
    if (!r.accepted) return;
    client.waitUntil(
        [&](const StateMirror& s) {
          return s.workflow && s.workflow->revision >= r.revision &&
                 (r.target_id == 0 || s.targets.count(r.target_id) > 0);
        },
        std::chrono::seconds(10));
  };
  for (const auto& step_node : doc["steps"]) {
    ++index;
    const json step = yamlToJson(step_node);
    const std::string where = path + ": step " + std::to_string(index);
    client.poll();
    if (step.contains("send")) {
      CommandArgs args;
      if (step.contains("path")) args.path = step["path"];
      for (const auto& p : step.value("points", json::array())) {
        args.points.push_back(jsonPoint(p));
      }
      for (const auto& p : step.value("robot_mm", json::array())) {
        args.points.push_back(robotToLps(client.mirror(), jsonPoint(p)));
      }
      for (const auto& id : step.value("ids", json::array())) {
        args.ids.push_back(id.is_string() ? names.at(id.get<std::string>())
                                          : id.get<std::uint32_t>());
      }
      const auto reply = client.send(step["send"], args);
      std::cout << where << " " << step["send"].get<std::string>() << ": ";
      printReply(reply, as_json);
      const std::string expect = step.value("expect", "accepted");
      if ((expect == "accepted") != reply.accepted) {
        std::cerr << where << ": expected " << expect << "\n";
        return kExitRejected;
      }
      if (step.contains("error_code") && step["error_code"] != reply.error_code) {
        std::cerr << where << ": expected error_code " << step["error_code"] << "\n";
        return kExitRejected;
      }
      if (step.contains("name")) names[step["name"]] = reply.target_id;
      catchUp(reply);
    } else if (step.contains("approve") || step.contains("emergency_stop")) {
      // approve: pending  approves what ApprovalState shows; {plan_id, digest} sends exactly
      // those (scripts use it to show that wrong ones are refused).
      ignav::protocol::Reply reply;
      if (step.contains("emergency_stop")) {
        reply = client.emergencyStop();
        std::cout << where << " emergency_stop: ";
      } else {
        const json a = step["approve"];
        const ApprovalState shown = client.mirror().approval.value_or(ApprovalState{});
        std::uint64_t plan = shown.plan_id;
        std::string digest = shown.digest;
        if (a.is_object()) {
          // Script numbers arrive as doubles (yamlToJson).
          if (a.contains("plan_id")) plan = static_cast<std::uint64_t>(a["plan_id"].get<double>());
          if (a.contains("digest")) {
            digest = a["digest"].is_string() ? a["digest"].get<std::string>() : a["digest"].dump();
          }
        } else if (a != "pending") {
          throw UsageError(where + ": approve: 'pending' or {plan_id, digest}");
        }
        reply = client.approve(plan, digest);
        std::cout << where << " approve plan " << plan << ": ";
      }
      printReply(reply, as_json);
      const std::string expect = step.value("expect", "accepted");
      if ((expect == "accepted") != reply.accepted) {
        std::cerr << where << ": expected " << expect << "\n";
        return kExitRejected;
      }
      if (step.contains("error_code") && step["error_code"] != reply.error_code) {
        std::cerr << where << ": expected error_code " << step["error_code"] << "\n";
        return kExitRejected;
      }
      catchUp(reply);
    } else if (step.contains("wait")) {
      const json want = step["wait"];
      const double seconds = step.value("timeout_s", 60.0);
      client.waitFor(
          [&](const json& s) {
            for (const auto& [key, value] : want.items()) {
              const json* actual = at(s, key);
              if (!actual || !matches(*actual, value)) return false;
            }
            return true;
          },
          std::chrono::milliseconds(static_cast<long>(seconds * 1000)));
      std::cout << where << " wait: " << want.dump() << " ok\n";
    } else if (step.contains("slice")) {
      const json s = step["slice"];
      ignav::protocol::SliceArgs a;
      a.view = s.value("view", "axial");
      if (s.contains("lps")) {
        a.centre_lps = jsonPoint(s["lps"]);
      } else if (s.contains("target")) {
        const auto id = names.at(s["target"].get<std::string>());
        const auto& targets = client.mirror().targets;
        const auto t = targets.find(id);
        if (t == targets.end()) throw UsageError(where + ": no target " + std::to_string(id));
        a.centre_lps = toEigen(t->second.lps);
      }
      a.size_px = s.value("size", 512u);
      a.pixel_mm = s.value("pixel_mm", 0.0);
      const auto result = client.slice(a);
      if (!result.ok) {
        std::cerr << where << ": slice failed: " << result.message << "\n";
        return kExitRejected;
      }
      const std::string file = out_dir + "/" + s.value("out", "slice.png");
      std::ofstream(file, std::ios::binary)
          .write(reinterpret_cast<const char*>(result.png.data()),
                 static_cast<std::streamsize>(result.png.size()));
      std::cout << where << " slice: " << file << " (" << result.width << "x" << result.height
                << ")\n";
    } else {
      throw UsageError(where + ": expected send, approve, emergency_stop, wait or slice");
    }
  }
  client.poll();
  return 0;
}

// ignav-server: $IGNAV_SERVER, else next to this program (installed) or in the build tree.
std::string serverExecutable() {
  if (const char* env = std::getenv("IGNAV_SERVER")) return env;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path();
  for (const auto& candidate : {self / "ignav-server", self / "../../server/ignav-server"}) {
    if (std::filesystem::exists(candidate, ec)) return candidate.lexically_normal().string();
  }
  return "ignav-server";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ignavctl: drive ignav-server over DDS"};
  app.require_subcommand(1);
  std::uint32_t domain = 0;
  std::string dds_config = "loopback";
  ignav::protocol::DdsSite dds_site;
  std::string client_id = "ignavctl-" + std::to_string(::getpid());
  bool as_json = false;
  double wait_s = 10.0;
  app.add_option("--domain", domain, "DDS domain id");
  app.add_option("--dds-config", dds_config,
                 "Cyclone XML, or a name: loopback, site-multicast, site-unicast ('' = Cyclone's "
                 "defaults)");
  app.add_option("--dds-interface", dds_site.interface,
                 "the network interface a site configuration uses");
  app.add_option("--dds-peer", dds_site.peers, "a unicast discovery peer, once per host");
  app.add_option("--client-id", client_id, "who this client is in replies and the journal");
  app.add_flag("--json", as_json, "machine-readable output");
  app.add_option("--wait-server", wait_s, "seconds to wait for the server");
  std::string robot_id;
  app.add_option("--robot", robot_id,
                 "the robot whose server to talk to (its robot_id); needed when several robots "
                 "share the domain")
      ->envname("IGNAV_ROBOT");
  std::string identity;
  app.add_option("--identity", identity,
                 "DDS Security identity folder (cert.pem, key.pem, permissions.p7s, ...); "
                 "without one, security is off")
      ->envname("IGNAV_IDENTITY");

  auto* robots = app.add_subcommand(
      "robots", "the ignav servers on this DDS domain: robot id, host, session, version, uptime");
  double doctor_s = 2.0;
  auto* doctor = app.add_subcommand(
      "doctor",
      "check a deployment: the participants and robots on this domain, round trips, clock "
      "offsets, and what looks wrong");
  doctor->add_option("--seconds", doctor_s, "how long to listen for participants (default 2)");
  auto* status = app.add_subcommand("status", "phase, volume, registration, targets");
  std::string load_path;
  auto* load = app.add_subcommand("load", "load a CT: a server-side path, or 'phantom'");
  load->add_option("path", load_path)->required();
  std::vector<std::string> fid_args;
  auto* fid = app.add_subcommand("fiducials", "'auto', or 'set X,Y,Z X,Y,Z X,Y,Z' (LPS)");
  fid->add_option("args", fid_args)->required();
  double detect_wait_s = 120.0;
  fid->add_option("--wait-s", detect_wait_s,
                  "auto: how long to wait for the detection's outcome (default 120)");
  std::vector<std::string> target_args;
  auto* targets = app.add_subcommand("targets", "add X,Y,Z | rm ID | ls | clear | lock | unlock");
  targets->add_option("args", target_args)->required();
  std::string view = "axial", lps_text, out = "slice.png";
  std::uint32_t size = 512;
  auto* slice = app.add_subcommand("slice", "a slice as PNG, with its pixel -> LPS mapping");
  slice->add_option("--view", view);
  slice->add_option("--lps", lps_text, "X,Y,Z centre");
  slice->add_option("--size", size);
  slice->add_option("--out", out);
  double watch_s = 0.0;
  auto* watch = app.add_subcommand("watch", "print state changes as they happen");
  watch->add_option("--seconds", watch_s, "stop after this long (0 = until Ctrl-C)");
  std::string script, script_out = ".";
  auto* run = app.add_subcommand("run", "run a script of commands and expected replies");
  run->add_option("script", script)->required();
  run->add_option("--out-dir", script_out, "where slices go");
  auto* approval = app.add_subcommand("approval", "the motion waiting for approval");
  auto* motion = app.add_subcommand("motion", "where the robot is and what it is doing");
  bool yes = false;
  std::uint64_t approve_plan = 0;
  std::string approve_digest;
  auto* approve = app.add_subcommand(
      "approve", "approve the motion ApprovalState shows (asks first unless --yes)");
  approve->add_flag("--yes", yes, "do not ask");
  approve->add_option("--plan", approve_plan, "approve exactly this plan id ...");
  approve->add_option("--digest", approve_digest, "... and digest");
  auto* emergency = app.add_subcommand("emergency-stop", "halt the robot now, from any phase");
  std::string matrix_text;
  auto* set_registration = app.add_subcommand(
      "set-registration", "register with a matrix computed elsewhere (image LPS -> robot)");
  set_registration->add_option("matrix", matrix_text, "16 comma-separated numbers, row-major 4x4")
      ->required();
  std::string ready_what;
  auto* ready = app.add_subcommand("ready", "is the robot (or the plan) ready? changes nothing");
  ready->add_option("what", ready_what, "robot | targeting")->required();
  // Every other command, from the table that declares them (commands/command_table.hpp):
  // "add-target X,Y,Z", "ping", ... with the arguments its row names.
  const ignav::commands::InputSpec* derived = nullptr;
  std::vector<std::string> derived_words;
  for (const auto& spec : ignav::commands::inputTable()) {
    if (spec.wire_kind == ignav::commands::kNoWireKind) continue;
    std::string name = spec.name;
    std::replace(name.begin(), name.end(), '_', '-');
    const auto given =
        app.get_subcommands([&name](CLI::App* sub) { return sub->get_name() == name; });
    if (!given.empty()) continue;  // given a friendlier form above
    auto* sub = app.add_subcommand(name, spec.help);
    sub->callback([&derived, &spec] { derived = &spec; });
    const std::string usage = ignav::commands::usageOf(spec);
    if (!usage.empty()) sub->add_option("args", derived_words, usage)->required();
  }
  std::vector<std::string> verify_args;
  double measure_wait_s = 300.0;
  auto* verify = app.add_subcommand(
      "verify",
      "the confirmation CT's targeting errors (VerificationState); load PATH (measure a "
      "confirmation CT and wait for it), place TARGET X,Y,Z | accept TARGET | reject SEED (the "
      "click fallback), fit NAME (tissue from the errors), aim NAME|none (compensate for it)");
  verify->add_option("args", verify_args);
  verify->add_option("--wait-s", measure_wait_s,
                     "load: how long to wait for the measurement (default 300)");
  std::string replay_dir, replay_speed = "1", server_config = "configs/server.yaml";
  std::uint64_t replay_until = 0;
  auto* replay = app.add_subcommand(
      "replay",
      "publish a recorded session's states over DDS as they happened (a read-only "
      "ignav-server)");
  replay->add_option("session", replay_dir, "the session folder")->required();
  replay->add_option("--speed", replay_speed, "1, 10, ... times real time, or max");
  replay->add_option("--until", replay_until, "stop at this revision (journal sequence number)");
  replay->add_option("--server-config", server_config, "server YAML (robot config)");
  std::string replay_identity;
  replay->add_option("--server-identity", replay_identity,
                     "the replaying server's DDS Security identity (a service identity)");
  CLI11_PARSE(app, argc, argv);

  if (*replay) {
    // The server's own code publishes the replay (one implementation of every state topic); it
    // takes this client's domain and DDS config.
    const std::string server = serverExecutable();
    std::vector<std::string> args{
        server,       "--config", server_config,          "--replay",     replay_dir, "--speed",
        replay_speed, "--domain", std::to_string(domain), "--dds-config", dds_config};
    if (!dds_site.interface.empty()) {
      args.push_back("--dds-interface");
      args.push_back(dds_site.interface);
    }
    for (const auto& peer : dds_site.peers) {
      args.push_back("--dds-peer");
      args.push_back(peer);
    }
    if (!robot_id.empty()) {  // else the server's: its config's robot id with -replay
      args.push_back("--robot-id");
      args.push_back(robot_id);
    }
    if (!replay_identity.empty()) {
      args.push_back("--identity");
      args.push_back(replay_identity);
    } else {
      args.push_back("--insecure");
    }
    if (replay_until != 0) {
      args.push_back("--until");
      args.push_back(std::to_string(replay_until));
    }
    std::vector<char*> argv_exec;
    for (auto& a : args)
      argv_exec.push_back(a.data());
    argv_exec.push_back(nullptr);
    ::execvp(server.c_str(), argv_exec.data());
    std::cerr << "ignavctl: cannot run " << server << ": " << std::strerror(errno)
              << " (set IGNAV_SERVER to its path)\n";
    return kExitUsage;
  }

  try {
    const std::string xml = ignav::protocol::loadToolDdsConfig(dds_config, dds_site);
    std::optional<ignav::protocol::SecurityIdentity> secure;
    if (!identity.empty()) {
      secure = ignav::protocol::identityFromFolder(identity);
    } else {
      std::cerr << "ignavctl: DDS Security is off (no --identity): for local development only\n";
    }
    const auto wait = std::chrono::milliseconds(static_cast<long>(wait_s * 1000));
    const auto* secure_id = secure ? &*secure : nullptr;
    if (*doctor) {
      return runDoctor(domain, xml, secure_id, client_id,
                       std::chrono::milliseconds(static_cast<long>(doctor_s * 1000)), as_json);
    }
    if (*robots) {
      const auto found = ignav::protocol::discoverRobots(domain, xml, secure_id, wait);
      printRobots(found, as_json);
      return found.empty() ? kExitNoServer : 0;
    }
    std::string robot;
    try {
      robot = ignav::protocol::chooseRobot(domain, xml, secure_id, robot_id, wait);
    } catch (const ignav::protocol::RobotNotChosen& e) {
      std::cerr << "ignavctl: " << e.what() << "\n";
      return robot_id.empty() ? kExitNoServer : kExitUsage;
    }
    Client client(domain, xml, client_id, secure_id, robot);
    if (!client.waitForServer(wait)) {
      std::cerr << "ignavctl: no ignav-server for robot '" << robot << "' on DDS domain " << domain
                << (secure ? " that authenticates this identity" : "")
                << (robot_id.empty() ? "" : " (ignavctl robots lists those there)") << "\n";
      return kExitNoServer;
    }
    // The state topics are transient-local: a late joiner gets the present, each topic on its
    // own. What is printed from it waits for all of it; what is still missing then is "not yet
    // known", never "none" (issue 38: "no motion is waiting" was said while one was).
    const bool present = client.waitForPresent(5s);
    if (!client.mirror().workflow) throw ignav::protocol::Timeout("no WorkflowState within 5 s");
    auto not_yet_known = [&]() {
      std::string missing;
      for (const auto& m : client.missingState())
        missing += (missing.empty() ? "" : ", ") + m;
      std::cerr << "ignavctl: not yet known: the server's " << missing
                << " state did not arrive within 5 s\n";
      return kExitNoServer;
    };
    auto send = [&](const std::string& command, const CommandArgs& args = {}) {
      const auto r = client.send(command, args);
      printReply(r, as_json);
      return r.accepted ? 0 : kExitRejected;
    };
    if (*status) {
      if (!present) return not_yet_known();
      if (as_json) {
        std::cout << client.state().dump(2) << "\n";
      } else {
        printStatus(client.mirror());
      }
      return 0;
    }
    if (*set_registration) {
      const auto r = client.setRegistration(matrix16(matrix_text));
      printReply(r, as_json);
      return r.accepted ? 0 : kExitRejected;
    }
    if (*ready) return send("check_ready", {ready_what, {}, {}});
    if (*load)
      return send("load_volume", {load_path == "phantom" ? "phantom:" : load_path, {}, {}});
    if (*fid) {
      if (fid_args[0] == "auto") {
        // Accepted when the detection starts (issue 22); its outcome shows in RegistrationState,
        // published before the reply: wait for the status to leave `detecting`.
        const auto r = client.send("auto_fiducials");
        if (!r.accepted || !as_json) printReply(r, as_json);
        if (!r.accepted) return kExitRejected;
        client.waitUntil(
            [&](const StateMirror& s) {
              return s.registration && s.workflow && s.workflow->revision >= r.revision &&
                     s.registration->status != "detecting";
            },
            std::chrono::seconds(static_cast<long>(detect_wait_s)));
        const RegistrationState& reg = *client.mirror().registration;
        const std::string& outcome = reg.status;
        const std::string& message = reg.message;
        // A failed detection leaves a registration from before in use; the message says so.
        const bool registered =
            outcome == "registered" && message.rfind("marker detection failed", 0) != 0;
        if (as_json) {
          std::cout << json{{"accepted", true},           {"message", r.message},
                            {"request_id", r.request_id}, {"revision", r.revision},
                            {"registered", registered},   {"registration", reg}}
                           .dump()
                    << "\n";
        } else {
          std::cout << "registration " << outcome << ": " << message << "\n";
        }
        return registered ? 0 : kExitRejected;
      }
      if (fid_args[0] == "set" && fid_args.size() == 4) {
        return send("set_fiducials",
                    {"", {triple(fid_args[1]), triple(fid_args[2]), triple(fid_args[3])}, {}});
      }
      throw UsageError("fiducials: 'auto' or 'set P1 P2 P3'");
    }
    if (*targets) {
      const std::string& verb = target_args[0];
      if (verb == "add" && target_args.size() == 2) {
        return send("add_target", {"", {triple(target_args[1])}, {}});
      }
      if (verb == "rm" && target_args.size() == 2) {
        return send("remove_target",
                    {"", {}, {static_cast<std::uint32_t>(std::stoul(target_args[1]))}});
      }
      if (verb == "clear") return send("clear_targets");
      if (verb == "lock") return send("lock_plan");
      if (verb == "unlock") return send("unlock_plan");
      if (verb == "ls") {
        if (!present) return not_yet_known();
        client.poll();
        if (as_json) {
          std::cout << client.state()["targets"].dump(2) << "\n";
        } else {
          printTargets(client.mirror());
        }
        return 0;
      }
      throw UsageError("targets: add X,Y,Z | rm ID | ls | clear | lock | unlock");
    }
    if (*slice) {
      ignav::protocol::SliceArgs a;
      a.view = view;
      if (!lps_text.empty()) a.centre_lps = triple(lps_text);
      a.size_px = size;
      const auto r = client.slice(a);
      if (!r.ok) {
        std::cerr << "ignavctl: slice: " << r.message << "\n";
        return kExitRejected;
      }
      std::ofstream(out, std::ios::binary)
          .write(reinterpret_cast<const char*>(r.png.data()),
                 static_cast<std::streamsize>(r.png.size()));
      json m = json::array();
      for (int i = 0; i < 4; ++i) {
        m.push_back({r.pixel_to_lps(i, 0), r.pixel_to_lps(i, 1), r.pixel_to_lps(i, 2),
                     r.pixel_to_lps(i, 3)});
      }
      std::cout << json{{"out", out}, {"width", r.width}, {"height", r.height}, {"pixel_to_lps", m}}
                       .dump(as_json ? -1 : 2)
                << "\n";
      return 0;
    }
    if (*watch) {
      const auto end = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(static_cast<long>(watch_s * 1000));
      while (watch_s <= 0 || std::chrono::steady_clock::now() < end) {
        for (const auto& topic : client.poll()) {
          const json& s = client.state();
          const json v = topic == "target" ? s["targets"] : s.value(topic, json());
          std::cout << topic << " " << v.dump() << "\n" << std::flush;
        }
        std::this_thread::sleep_for(20ms);
      }
      return 0;
    }
    if (*run) return runScript(client, script, script_out, as_json);
    if (*verify) {
      auto show = [&] {
        client.poll();
        if (as_json) {
          std::cout << client.state().value("verification", json()).dump(2) << "\n";
        } else {
          ignav::ctl::printVerification(client.mirror());
        }
      };
      if (verify_args.empty()) {
        try {  // the topic's present arrives on its own after discovery
          client.waitUntil([](const StateMirror& s) { return s.verification.has_value(); }, 2s);
        } catch (const ignav::protocol::Timeout&) {
        }
        show();
        return 0;
      }
      const std::string& verb = verify_args[0];
      const std::vector<std::string> rest(verify_args.begin() + 1, verify_args.end());
      auto id = [&](std::size_t i) {
        if (rest.size() <= i) throw UsageError("verify " + verb + ": an id is missing");
        return static_cast<std::uint32_t>(std::stoul(rest[i]));
      };
      const bool same_frame = rest.size() == 2 && rest[1] == "same-frame";
      if (verb == "load" && (rest.size() == 1 || same_frame)) {
        // same-frame: the robot and the patient did not move since planning (a needle left in
        // touches the markers on its axis): the session's registration goes with the scan.
        std::optional<Eigen::Matrix4d> given;
        if (same_frame) {
          client.waitUntil([](const StateMirror& s) { return s.registration.has_value(); }, 2s);
          const auto& reg = *client.mirror().registration;
          if (reg.status != "registered") {
            throw UsageError("verify load " + rest[0] +
                             " same-frame: the session has no registration to give the scan");
          }
          given = ignav::protocol::fromRowMajor(reg.image_to_robot);
        }
        // Accepted when the measurement starts; its outcome shows in VerificationState.
        const auto r = client.send("load_confirmation", {rest[0], {}, {}, given});
        if (!r.accepted) {
          printReply(r, as_json);
          return kExitRejected;
        }
        client.waitUntil(
            [&](const StateMirror& s) {
              return s.verification && s.workflow && s.workflow->revision > r.revision &&
                     s.verification->status != "measuring";
            },
            std::chrono::seconds(static_cast<long>(measure_wait_s)));
        show();
        const auto& v = *client.mirror().verification;
        return v.status == "measured" && v.source == rest[0] ? 0 : kExitRejected;
      }
      if (verb == "place" && rest.size() == 2)
        return send("place_seed", {"", {triple(rest[1])}, {id(0)}});
      if (verb == "accept" && rest.size() == 1) return send("accept_seed", {"", {}, {id(0)}});
      if (verb == "reject" && rest.size() == 1) return send("reject_seed", {"", {}, {id(0)}});
      if (verb == "fit" && rest.size() == 1) return send("fit_tissue", {rest[0], {}, {}});
      if (verb == "aim" && rest.size() == 1) return send("use_tissue", {rest[0], {}, {}});
      throw UsageError(
          "verify: load PATH [same-frame] | place TARGET X,Y,Z | accept TARGET | reject SEED | fit "
          "NAME | aim "
          "NAME|none");
    }
    if (*approval || *motion) {
      if (!present) return not_yet_known();
      const char* topic = *approval ? "approval" : "motion";
      if (as_json) {
        std::cout << client.state().value(topic, json()).dump(2) << "\n";
      } else if (*approval) {
        printApproval(client.mirror());
      } else {
        printMotion(client.mirror());
      }
      return 0;
    }
    if (*emergency) {
      const auto r = client.emergencyStop();
      printReply(r, as_json);
      return r.accepted ? 0 : kExitRejected;
    }
    if (*approve) {
      if (approve_plan == 0) {
        if (!present) return not_yet_known();
        const auto& shown = client.mirror().approval;
        if (!shown || shown->status != "pending") {
          std::cerr << "ignavctl: no motion is waiting for approval\n";
          return kExitRejected;
        }
        printApproval(client.mirror());
        approve_plan = shown->plan_id;
        approve_digest = shown->digest;
        if (!yes) {
          std::cout << "approve plan " << approve_plan << " as shown? [y/N] " << std::flush;
          std::string answer;
          std::getline(std::cin, answer);
          if (answer != "y" && answer != "yes") {
            std::cout << "not approved\n";
            return kExitRejected;
          }
        }
      }
      const auto r = client.approve(approve_plan, approve_digest);
      printReply(r, as_json);
      return r.accepted ? 0 : kExitRejected;
    }
    if (derived) {
      const auto started = std::chrono::steady_clock::now();
      const auto r = client.send(derived->name, commandArgs(*derived, derived_words));
      const auto round_trip = std::chrono::steady_clock::now() - started;
      printReply(r, as_json, std::chrono::duration<double, std::milli>(round_trip).count());
      return r.accepted ? 0 : kExitRejected;
    }
  } catch (const UsageError& e) {
    std::cerr << "ignavctl: " << e.what() << "\n";
    return kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "ignavctl: " << e.what() << "\n";
    return kExitRejected;
  }
  return 0;
}
