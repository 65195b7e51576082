// `approval`, `approve`, `motion`, `emergency-stop`: what would move the robot, releasing it, where
// it is, and halting it. Approvals and emergency stops travel on topics of their own, not as
// commands (docs/PROTOCOL.md).
#include <iostream>
#include <memory>

#include "printers.hpp"
#include "subcommands.hpp"

namespace ignav::ctl {
namespace {

// `topic` ("approval", "motion") as a person reads it, or its JSON view.
int showTopic(Server& s, const char* topic, void (*print)(const protocol::StateMirror&)) {
  if (!s.present) return s.notYetKnown();
  if (s.as_json) {
    std::cout << s.client.state().value(topic, nlohmann::json()).dump(2) << "\n";
  } else {
    print(s.client.mirror());
  }
  return 0;
}

struct ApproveOptions {
  bool yes = false;
  std::uint64_t plan = 0;  // 0: what ApprovalState shows
  std::string digest;
};

// Without --plan: prints the pending request, asks (unless --yes), and approves exactly what it
// printed.
int approve(Server& s, ApproveOptions o) {
  if (o.plan == 0) {
    if (!s.present) return s.notYetKnown();
    const auto& shown = s.client.mirror().approval;
    if (!shown || shown->status != "pending") {
      std::cerr << "ignavctl: no motion is waiting for approval\n";
      return kExitRejected;
    }
    printApproval(s.client.mirror());
    o.plan = shown->plan_id;
    o.digest = shown->digest;
    if (!o.yes) {
      std::cout << "approve plan " << o.plan << " as shown? [y/N] " << std::flush;
      std::string answer;
      std::getline(std::cin, answer);
      if (answer != "y" && answer != "yes") {
        std::cout << "not approved\n";
        return kExitRejected;
      }
    }
  }
  const auto r = s.client.approve(o.plan, o.digest);
  printReply(r, s.as_json);
  return r.accepted ? 0 : kExitRejected;
}

int emergencyStop(Server& s) {
  const auto r = s.client.emergencyStop();
  printReply(r, s.as_json);
  return r.accepted ? 0 : kExitRejected;
}

}  // namespace

void addMotionCommands(CLI::App& app, Action& chosen) {
  onServer(app.add_subcommand("approval", "the motion waiting for approval"), chosen,
           [](Server& s) { return showTopic(s, "approval", printApproval); });
  onServer(app.add_subcommand("motion", "where the robot is and what it is doing"), chosen,
           [](Server& s) { return showTopic(s, "motion", printMotion); });

  auto o = std::make_shared<ApproveOptions>();
  auto* sub = app.add_subcommand(
      "approve", "approve the motion ApprovalState shows (asks first unless --yes)");
  sub->add_flag("--yes", o->yes, "do not ask");
  sub->add_option("--plan", o->plan, "approve exactly this plan id ...");
  sub->add_option("--digest", o->digest, "... and digest");
  onServer(sub, chosen, [o](Server& s) { return approve(s, *o); });

  onServer(app.add_subcommand("emergency-stop", "halt the robot now, from any phase"), chosen,
           emergencyStop);
}

}  // namespace ignav::ctl
