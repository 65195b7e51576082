// The subcommands that send the table's commands (commands/command_table.hpp): the spellings
// people type (`load phantom`, `targets add X,Y,Z`: command_words.cpp's aliases) and every other
// command by its name (`add-target X,Y,Z`, `ping`). All read their words by the command's row.
#include <algorithm>
#include <iostream>
#include <memory>

#include "command_words.hpp"
#include "printers.hpp"
#include "subcommands.hpp"

namespace ignav::ctl {
namespace {

using nlohmann::json;
using Words = std::shared_ptr<std::vector<std::string>>;

// A subcommand that is an alias, or a group of them (`targets add ...`): its words, all required.
Words wordsOf(CLI::App* sub, const std::string& usage) {
  auto words = std::make_shared<std::vector<std::string>>();
  sub->add_option("args", *words, usage)->required();
  return words;
}

int sendCall(Server& s, const AliasCall& call) {
  return s.send(call.row.name, call.args);
}

// `sub` takes the words of `group`'s aliases: read when it is parsed, sent by `send` once the
// server is there.
void onAlias(CLI::App* sub, Action& chosen, const std::string& group, const std::string& usage,
             std::function<int(Server&, const AliasCall&)> send = sendCall) {
  onServerReadNow(sub, chosen, [group, usage, send, words = wordsOf(sub, usage)]() -> Work {
    return [call = aliasCall(group, *words, usage), send](Server& s) { return send(s, call); };
  });
}

// A load that runs as a background job (`phantom` names the built-in phantom): accepted when it
// starts, its outcome awaited.
std::optional<protocol::JobOutcome> sendLoad(Server& s, const AliasCall& call, double wait_s,
                                             protocol::Reply& r) {
  protocol::CommandArgs args = call.args;
  if (args.path == "phantom") args.path = "phantom:";
  return s.sendAndAwaitJob(call.row.name, args, wait_s, &r);
}

json loadJson(const protocol::Reply& r, const protocol::JobOutcome& outcome) {
  return {{"accepted", true},
          {"message", r.message},
          {"request_id", r.request_id},
          {"revision", r.revision},
          {"outcome", outcome}};
}

// Waits for the CT load's outcome, then shows what was loaded (or why not).
int loadCt(Server& s, const AliasCall& call, double wait_s) {
  protocol::Reply r;
  const auto outcome = sendLoad(s, call, wait_s, r);
  if (!outcome) return kExitRejected;
  if (s.as_json) {
    std::cout << loadJson(r, *outcome).dump() << "\n";
  } else {
    std::cout << "CT " << (outcome->status == "done" ? "loaded" : outcome->status) << ": "
              << outcome->message << "\n";
  }
  return outcome->status == "done" ? 0 : kExitRejected;
}

// Accepted when the detection starts (issue 22); waits for the job's outcome, then shows the
// RegistrationState it left.
int detectFiducials(Server& s, const AliasCall& call, double wait_s) {
  protocol::Reply r;
  const auto outcome = s.sendAndAwaitJob(call.row.name, call.args, wait_s, &r);
  if (!outcome) return kExitRejected;
  s.client.waitUntil([](const protocol::StateMirror& m) { return m.registration.has_value(); },
                     std::chrono::seconds(5));
  const protocol::RegistrationState& reg = *s.client.mirror().registration;
  // A failed detection leaves a registration from before in use: the outcome says it failed.
  const bool registered = outcome->status == "done";
  if (s.as_json) {
    std::cout << json{{"accepted", true},           {"message", r.message},
                      {"request_id", r.request_id}, {"revision", r.revision},
                      {"registered", registered},   {"outcome", *outcome},
                      {"registration", reg}}
                     .dump()
              << "\n";
  } else {
    std::cout << "registration " << reg.status << ": " << reg.message << "\n";
  }
  return registered ? 0 : kExitRejected;
}

// Waits for the outcome of a structure load, a target proposal or a robot placement, then lists
// the structures, the targets proposed and the poses (or says why not).
int structuresJob(Server& s, const AliasCall& call, double wait_s) {
  protocol::Reply r;
  const auto outcome = sendLoad(s, call, wait_s, r);
  if (!outcome) return kExitRejected;
  // The state after the outcome's step (another topic: it may come a moment later).
  s.client.waitUntil(
      [](const protocol::StateMirror& m) {
        return m.structures && m.structures->status != "loading" &&
               m.structures->proposal_status != "proposing" &&
               m.structures->placement_status != "placing" &&
               m.structures->dose_status != "computing";
      },
      std::chrono::seconds(5));
  if (s.as_json) {
    json out = loadJson(r, *outcome);
    out["structures"] = *s.client.mirror().structures;
    std::cout << out.dump() << "\n";
  } else if (outcome->status == "done") {
    printStructures(s.client.mirror());
  } else {
    std::cout << "structures " << outcome->status << ": " << outcome->message << "\n";
  }
  return outcome->status == "done" ? 0 : kExitRejected;
}

// Not a command: the structures as the state shows them.
int listStructures(Server& s) {
  if (!s.present) return s.notYetKnown();
  s.client.poll();
  if (s.as_json) {
    std::cout << s.client.state()["structures"].dump(2) << "\n";
  } else {
    printStructures(s.client.mirror());
  }
  return 0;
}

// Not a command: the targets as the state shows them.
int listTargets(Server& s) {
  if (!s.present) return s.notYetKnown();
  s.client.poll();
  if (s.as_json) {
    std::cout << s.client.state()["targets"].dump(2) << "\n";
  } else {
    printTargets(s.client.mirror());
  }
  return 0;
}

}  // namespace

void addAliasCommands(CLI::App& app, Action& chosen) {
  auto* load = app.add_subcommand(
      "load", "load a CT: a server-side path, or 'phantom'; waits for the load to end");
  auto load_wait_s = std::make_shared<double>(300.0);
  load->add_option("--wait-s", *load_wait_s, "how long to wait for the load (default 300)");
  onAlias(
      load, chosen, "load", aliasUsage("load"),
      [load_wait_s](Server& s, const AliasCall& call) { return loadCt(s, call, *load_wait_s); });

  auto* fiducials = app.add_subcommand("fiducials", aliasUsage("fiducials") + " (LPS)");
  auto detect_wait_s = std::make_shared<double>(120.0);
  fiducials->add_option("--wait-s", *detect_wait_s,
                        "auto: how long to wait for the detection's outcome (default 120)");
  onAlias(fiducials, chosen, "fiducials", aliasUsage("fiducials"),
          [detect_wait_s](Server& s, const AliasCall& call) {
            if (call.row.kind == commands::InputKind::kAutoFiducials)
              return detectFiducials(s, call, *detect_wait_s);
            return sendCall(s, call);
          });

  const std::string targets_usage = aliasUsage("targets") + " | ls";
  auto* targets = app.add_subcommand("targets", targets_usage);
  auto propose_wait_s = std::make_shared<double>(300.0);
  targets->add_option("--wait-s", *propose_wait_s,
                      "propose, seeds, dose: how long to wait for the outcome (default 300)");
  onServerReadNow(
      targets, chosen,
      [words = wordsOf(targets, targets_usage), targets_usage, propose_wait_s]() -> Work {
        if (*words == std::vector<std::string>{"ls"}) return listTargets;
        return [call = aliasCall("targets", *words, targets_usage), propose_wait_s](Server& s) {
          if (call.row.kind == commands::InputKind::kProposeTargets ||
              call.row.kind == commands::InputKind::kPlanSeeds ||
              call.row.kind == commands::InputKind::kComputeDose)
            return structuresJob(s, call, *propose_wait_s);
          return sendCall(s, call);
        };
      });

  const std::string structures_usage = aliasUsage("structures") + " | ls";
  auto* structures = app.add_subcommand("structures", structures_usage);
  auto structures_wait_s = std::make_shared<double>(300.0);
  structures->add_option("--wait-s", *structures_wait_s,
                         "load, place: how long to wait for the outcome (default 300)");
  onServerReadNow(structures, chosen,
                  [words = wordsOf(structures, structures_usage), structures_usage,
                   structures_wait_s]() -> Work {
                    if (*words == std::vector<std::string>{"ls"}) return listStructures;
                    return [call = aliasCall("structures", *words, structures_usage),
                            structures_wait_s](Server& s) {
                      if (call.row.kind == commands::InputKind::kLoadStructures ||
                          call.row.kind == commands::InputKind::kPlaceRobot)
                        return structuresJob(s, call, *structures_wait_s);
                      return sendCall(s, call);
                    };
                  });

  onAlias(app.add_subcommand("set-registration",
                             "register with a matrix computed elsewhere (image LPS -> robot)"),
          chosen, "set-registration", aliasUsage("set-registration"));
  onAlias(app.add_subcommand("ready", "is the robot (or the plan) ready? changes nothing"), chosen,
          "ready", aliasUsage("ready"));
}

void addCommandsByName(CLI::App& app, Action& chosen) {
  for (const auto& spec : commands::inputTable()) {
    if (spec.wire_kind == commands::kNoWireKind) continue;
    std::string name = spec.name;
    std::replace(name.begin(), name.end(), '_', '-');
    const auto given =
        app.get_subcommands([&name](CLI::App* sub) { return sub->get_name() == name; });
    if (!given.empty()) continue;  // spelled so above (emergency-stop, set-registration)
    auto* sub = app.add_subcommand(name, spec.help);
    auto words = std::make_shared<std::vector<std::string>>();
    const std::string usage = commands::usageOf(spec);
    if (!usage.empty()) sub->add_option("args", *words, usage)->required();
    onServerReadNow(sub, chosen, [&spec, name, words]() -> Work {
      return [&spec, args = commandArgs(spec, *words, name)](Server& s) {
        const auto started = std::chrono::steady_clock::now();
        const auto r = s.client.send(spec.name, args);
        const auto round_trip = std::chrono::steady_clock::now() - started;
        printReply(r, s.as_json, std::chrono::duration<double, std::milli>(round_trip).count());
        return r.accepted ? 0 : kExitRejected;
      };
    });
  }
}

}  // namespace ignav::ctl
