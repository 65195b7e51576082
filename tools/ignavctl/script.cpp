// `run`: a script of steps (configs/demo/plan.yaml): commands with the replies they expect,
// approvals, waits for a state, slices. docs/PROTOCOL.md lists the steps.
#include <yaml-cpp/yaml.h>

#include <Eigen/Dense>

#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>

#include "printers.hpp"
#include "subcommands.hpp"

namespace ignav::ctl {
namespace {

using nlohmann::json;
using protocol::ApprovalState;
using protocol::Client;
using protocol::CommandArgs;
using protocol::StateMirror;

Eigen::Vector3d jsonPoint(const json& p) {
  return {p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
}

// Robot-frame points become LPS through the current registration (scripts plan in the robot
// frame so they do not depend on where the phantom lies).
Eigen::Vector3d robotToLps(const StateMirror& state, const Eigen::Vector3d& robot) {
  if (!state.registration || state.registration->status != "registered") {
    throw UsageError("robot_mm needs a registration");
  }
  const Eigen::Matrix4d m = protocol::fromRowMajor(state.registration->image_to_robot);
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
// A step's reply as the script expects it (`expect`: accepted | rejected, and `error_code`); says
// what was expected when not.
bool asExpected(const json& step, const protocol::Reply& reply, const std::string& where) {
  const std::string expect = step.value("expect", "accepted");
  if ((expect == "accepted") != reply.accepted) {
    std::cerr << where << ": expected " << expect << "\n";
    return false;
  }
  if (step.contains("error_code") && step["error_code"] != reply.error_code) {
    std::cerr << where << ": expected error_code " << step["error_code"] << "\n";
    return false;
  }
  return true;
}

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
  auto catchUp = [&](const protocol::Reply& r) {
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
      if (step.contains("path")) {
        // YAML gives `path: 12` (pause_at's depth) as a number: the command takes its text.
        const json& given = step["path"];
        args.path = given.is_string() ? given.get<std::string>() : given.dump();
      }
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
      if (!asExpected(step, reply, where)) return kExitRejected;
      if (step.contains("name")) names[step["name"]] = reply.target_id;
      catchUp(reply);
      // wait_job: until the background job the command started ends (its JobOutcome, not a
      // state field a job before it may have left as it is waited for).
      if (step.value("wait_job", false) && reply.accepted && reply.job != 0) {
        const auto seconds = step.value("timeout_s", 60.0);
        const auto outcome = client.waitForJobOutcome(
            reply.job, std::chrono::milliseconds(static_cast<long>(seconds * 1000)));
        std::cout << where << " job " << outcome.job << " (" << outcome.kind
                  << "): " << outcome.status << ": " << outcome.message << "\n";
        if (outcome.status != "done") return kExitRejected;
        client.waitUntil(
            [&](const StateMirror& m) {
              return m.workflow && m.workflow->revision >= outcome.revision;
            },
            std::chrono::seconds(10));
      }
    } else if (step.contains("approve") || step.contains("emergency_stop")) {
      // approve: pending  approves what ApprovalState shows; {plan_id, digest} sends exactly
      // those (scripts use it to show that wrong ones are refused).
      protocol::Reply reply;
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
      if (!asExpected(step, reply, where)) return kExitRejected;
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
      protocol::SliceArgs a;
      a.view = s.value("view", "axial");
      if (s.contains("lps")) {
        a.centre_lps = jsonPoint(s["lps"]);
      } else if (s.contains("target")) {
        const auto id = names.at(s["target"].get<std::string>());
        const auto& targets = client.mirror().targets;
        const auto t = targets.find(id);
        if (t == targets.end()) throw UsageError(where + ": no target " + std::to_string(id));
        a.centre_lps = protocol::toEigen(t->second.lps);
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

}  // namespace

void addScriptRunner(CLI::App& app, Action& chosen) {
  struct RunOptions {
    std::string script;
    std::string out_dir = ".";
  };
  auto o = std::make_shared<RunOptions>();
  auto* run = app.add_subcommand("run", "run a script of commands and expected replies");
  run->add_option("script", o->script)->required();
  run->add_option("--out-dir", o->out_dir, "where slices go");
  onServer(run, chosen,
           [o](Server& s) { return runScript(s.client, o->script, o->out_dir, s.as_json); });
}

}  // namespace ignav::ctl
