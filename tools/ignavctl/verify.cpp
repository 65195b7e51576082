// `verify`: the confirmation CT's targeting errors (VerificationState), and the commands that
// measure and correct them, as command_words.cpp's aliases `verify load`, `verify place`, ...
#include <iostream>
#include <memory>

#include "command_words.hpp"
#include "printers.hpp"
#include "subcommands.hpp"
#include "verification_view.hpp"

namespace ignav::ctl {
namespace {

using namespace std::chrono_literals;

constexpr const char* kSameFrameUsage = " | load PATH same-frame | scan PATH same-frame";

struct VerifyOptions {
  std::vector<std::string> words;  // none: show the measurement
  double measure_wait_s = 300.0;
};

void showVerification(Server& s) {
  s.client.poll();
  if (s.as_json) {
    std::cout << s.client.state().value("verification", nlohmann::json()).dump(2) << "\n";
  } else {
    printVerification(s.client.mirror());
  }
}

// same-frame: the robot and the patient did not move since planning (a needle left in touches
// the markers on its axis): the session's registration goes with the scan.
Eigen::Matrix4d sessionRegistration(Server& s, const std::string& path) {
  s.client.waitUntil([](const protocol::StateMirror& m) { return m.registration.has_value(); }, 2s);
  const auto& reg = *s.client.mirror().registration;
  if (reg.status != "registered") {
    throw UsageError("verify load|scan " + path +
                     " same-frame: the session has no registration to give the scan");
  }
  return protocol::fromRowMajor(reg.image_to_robot);
}

// Accepted when the measurement starts; waits for the job's outcome (JobOutcome, named by the
// reply's job), then shows the VerificationState it left.
int measure(Server& s, const AliasCall& call, double wait_s) {
  const auto outcome = s.sendAndAwaitJob(call.row.name, call.args, wait_s);
  if (!outcome) return kExitRejected;
  s.client.waitUntil([](const protocol::StateMirror& m) { return m.verification.has_value(); },
                     std::chrono::seconds(5));
  showVerification(s);
  // Done but unmatched (the match needs a person) is not measured yet.
  const auto& v = *s.client.mirror().verification;
  return outcome->status == "done" && v.status == "measured" ? 0 : kExitRejected;
}

// Accepted when the search starts; waits for its outcome: the re-aim proposed (TargetState.replan
// of the paused target shows it too), or why the scan was refused.
int scanNeedle(Server& s, const AliasCall& call, double wait_s) {
  protocol::Reply r;
  const auto outcome = s.sendAndAwaitJob(call.row.name, call.args, wait_s, &r);
  if (!outcome) return kExitRejected;
  if (s.as_json) {
    std::cout << nlohmann::json{{"accepted", true},
                                {"message", r.message},
                                {"revision", r.revision},
                                {"outcome", *outcome}}
                     .dump()
              << "\n";
  } else {
    std::cout << (outcome->status == "done" ? "re-aim proposed (verify reaim takes it): "
                                            : "intermittent CT " + outcome->status + ": ")
              << outcome->message << "\n";
  }
  return outcome->status == "done" ? 0 : kExitRejected;
}

// The measurement as the state shows it.
int showMeasured(Server& s) {
  try {  // the topic's present arrives on its own after discovery
    s.client.waitUntil([](const protocol::StateMirror& m) { return m.verification.has_value(); },
                       2s);
  } catch (const protocol::Timeout&) {
  }
  showVerification(s);
  return 0;
}

// The words, read as `verify`'s aliases (UsageError) when the command line is parsed.
Work readVerify(const VerifyOptions& o) {
  if (o.words.empty()) return showMeasured;
  std::vector<std::string> words = o.words;
  const bool same_frame =
      words.size() == 3 && (words[0] == "load" || words[0] == "scan") && words[2] == "same-frame";
  if (same_frame) words.pop_back();
  const auto call = aliasCall("verify", words, aliasUsage("verify") + kSameFrameUsage);
  const auto kind = call.row.kind;
  if (kind != commands::InputKind::kLoadConfirmation && kind != commands::InputKind::kScanNeedle)
    return [call](Server& s) { return s.send(call.row.name, call.args); };
  return [call, same_frame, wait_s = o.measure_wait_s](Server& s) {
    AliasCall given = call;
    if (same_frame) given.args.matrix = sessionRegistration(s, call.args.path);
    if (given.row.kind == commands::InputKind::kScanNeedle) return scanNeedle(s, given, wait_s);
    return measure(s, given, wait_s);
  };
}

}  // namespace

void addVerify(CLI::App& app, Action& chosen) {
  auto o = std::make_shared<VerifyOptions>();
  auto* verify = app.add_subcommand(
      "verify",
      "the confirmation CT's targeting errors (VerificationState); load PATH (measure a "
      "confirmation CT and wait for it), place TARGET X,Y,Z | accept TARGET | reject SEED (the "
      "click fallback), fit NAME (tissue from the errors), aim NAME|none (compensate for it); "
      "scan PATH (the needle stopped part-way on an intermittent CT: wait for the re-aim it "
      "proposes), reaim (take it)");
  verify->add_option("args", o->words, aliasUsage("verify") + kSameFrameUsage);
  verify->add_option("--wait-s", o->measure_wait_s,
                     "load, scan: how long to wait for the outcome (default 300)");
  onServerReadNow(verify, chosen, [o] { return readVerify(*o); });
}

}  // namespace ignav::ctl
