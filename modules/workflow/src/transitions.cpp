#include <algorithm>
#include <set>

#include "ignav/workflow/reducer.hpp"

namespace ignav::workflow {

const char* toString(Phase phase) {
  switch (phase) {
    case Phase::kStartup:
      return "startup";
    case Phase::kImaging:
      return "imaging";
    case Phase::kRegistration:
      return "registration";
    case Phase::kPlanning:
      return "planning";
    case Phase::kPlanLocked:
      return "plan_locked";
    case Phase::kMoving:
      return "moving";
    case Phase::kAtTarget:
      return "at_target";
    case Phase::kDone:
      return "done";
    case Phase::kStopped:
      return "stopped";
    case Phase::kEmergency:
      return "emergency";
    case Phase::kFault:
      return "fault";
    case Phase::kManual:
      return "manual";
  }
  return "unknown";
}

namespace {

using P = Phase;
using I = InputKind;

// Stop, emergency stop and the kEveryPhase inputs (query, ping) are allowed (almost) everywhere;
// they are added below per phase.
// A (phase, input) pair may lead to several phases; the reducer picks one of the declared ones.
std::vector<Transition> buildTable() {
  std::vector<Transition> t = {
      // from              input                 to                why
      {P::kStartup, I::kConfigLoaded, P::kImaging, "robot config valid"},
      {P::kImaging, I::kLoadVolume, P::kImaging, "load a CT"},
      {P::kImaging, I::kVolumeLoaded, P::kRegistration, "CT loaded"},
      {P::kImaging, I::kVolumeLoadFailed, P::kImaging, "load failed"},
      {P::kRegistration, I::kLoadVolume, P::kImaging, "another CT"},
      {P::kRegistration, I::kSetFiducials, P::kPlanning, "3 points registered"},
      // auto_fiducials starts a marker detection on the server's detector thread; its outcome
      // comes back as fiducials_detected or fiducial_detection_failed. (A format-1 journal's
      // auto_fiducials detected and registered within its step: the second row, replay only.)
      {P::kRegistration, I::kAutoFiducials, P::kRegistration, "detect the markers"},
      {P::kRegistration, I::kAutoFiducials, P::kPlanning, "format-1 journal: registered at once"},
      {P::kRegistration, I::kFiducialsDetected, P::kPlanning, "markers found, registered"},
      {P::kRegistration, I::kFiducialsDetected, P::kRegistration, "markers do not register"},
      {P::kRegistration, I::kFiducialDetectionFailed, P::kRegistration, "no markers matched"},
      {P::kImaging, I::kSetRegistration, P::kPlanning, "registered elsewhere (no CT here)"},
      {P::kRegistration, I::kSetRegistration, P::kPlanning, "registered elsewhere"},
      {P::kPlanning, I::kSetRegistration, P::kPlanning, "re-register"},
      {P::kPlanning, I::kLoadVolume, P::kImaging, "another CT"},
      {P::kPlanning, I::kSetFiducials, P::kPlanning, "re-register"},
      {P::kPlanning, I::kAutoFiducials, P::kPlanning, "re-detect the markers"},
      {P::kPlanning, I::kFiducialsDetected, P::kPlanning, "re-registered, or the old stays"},
      {P::kPlanning, I::kFiducialDetectionFailed, P::kPlanning, "no match: the old stays"},
      {P::kPlanning, I::kAddTarget, P::kPlanning, "click"},
      {P::kPlanning, I::kMoveTarget, P::kPlanning, "drag"},
      {P::kPlanning, I::kRemoveTarget, P::kPlanning, "remove"},
      {P::kPlanning, I::kClearTargets, P::kPlanning, "clear"},
      {P::kPlanning, I::kReorderTargets, P::kPlanning, "reorder"},
      {P::kPlanning, I::kLockPlan, P::kPlanLocked, "all targets reachable"},
      {P::kPlanLocked, I::kUnlockPlan, P::kPlanning, "edit again"},
      {P::kPlanLocked, I::kApprove, P::kMoving, "approved: plan id, digest, approver, fresh"},
      {P::kPlanLocked, I::kRequestApproval, P::kPlanLocked, "fresh request"},
      {P::kMoving, I::kSegmentDone, P::kMoving, "next move"},
      {P::kMoving, I::kSegmentDone, P::kAtTarget, "arrived, steps verified"},
      {P::kMoving, I::kSegmentDone, P::kDone, "stylet home after the last target"},
      {P::kMoving, I::kSegmentDone, P::kFault, "arrival check failed"},
      {P::kAtTarget, I::kApprove, P::kMoving, "next motion approved"},
      {P::kAtTarget, I::kRequestApproval, P::kAtTarget, "fresh request"},
      {P::kAtTarget, I::kUnlockPlan, P::kPlanning, "edit the remaining targets"},
      {P::kDone, I::kUnlockPlan, P::kPlanning, "plan more targets"},
      // A load finishing while stopped is kept; the workflow stays stopped.
      {P::kStopped, I::kVolumeLoaded, P::kStopped, "CT loaded"},
      {P::kStopped, I::kVolumeLoadFailed, P::kStopped, "load failed"},
      {P::kEmergency, I::kVolumeLoaded, P::kEmergency, "CT loaded"},
      {P::kEmergency, I::kVolumeLoadFailed, P::kEmergency, "load failed"},
      {P::kEmergency, I::kResetEmergency, P::kStopped, "operator reset, position checked"},
      {P::kEmergency, I::kHome, P::kEmergency, "robot homed by hand"},
      {P::kStopped, I::kHome, P::kStopped, "robot homed by hand"},
      {P::kFault, I::kResetEmergency, P::kStopped, "operator reset, position checked"},
      {P::kFault, I::kHome, P::kFault, "robot homed by hand"},
      {P::kFault, I::kVolumeLoaded, P::kFault, "CT loaded"},
      {P::kFault, I::kVolumeLoadFailed, P::kFault, "load failed"},
      {P::kManual, I::kHome, P::kManual, "robot homed by hand"},
      {P::kManual, I::kVolumeLoaded, P::kManual, "CT loaded"},
      {P::kManual, I::kVolumeLoadFailed, P::kManual, "load failed"},
  };
  // A marker detection started in registration or planning may end while interrupted: its outcome
  // is kept (resume then returns to planning if it registered); the phase stays.
  for (Phase p : {P::kStopped, P::kEmergency, P::kFault, P::kManual}) {
    t.push_back({p, I::kFiducialsDetected, p, "markers found, registered"});
    t.push_back({p, I::kFiducialDetectionFailed, p, "no markers matched"});
  }
  // resume returns to the phase the first interruption left (a move in flight: plan_locked, to be
  // approved again), or to done when nothing is left to move. Interruptions taken while
  // interrupted (manual after stop, emergency in manual) keep that phase (issue 27).
  for (Phase back : kResumePhases) {
    t.push_back({P::kStopped, I::kResume, back, "back to the interrupted phase"});
    t.push_back(
        {P::kManual, I::kResume, back, "back to the interrupted phase, position taken over"});
  }
  for (Phase p : kAllPhases) {
    // A fault is left only by a reset with a position check (or an emergency stop).
    // Manual control is left by resume (the robot is already halted and in someone's hands).
    if (p != P::kStopped && p != P::kEmergency && p != P::kFault && p != P::kManual) {
      t.push_back({p, I::kStop, P::kStopped, "stop"});
    }
    if (p != P::kEmergency) t.push_back({p, I::kEmergencyStop, P::kEmergency, "EMERGENCY"});
    for (const auto& spec : inputTable()) {
      if (spec.traits & kEveryPhase) t.push_back({p, spec.kind, p, spec.name});
    }
    // Manual control and readiness questions: not while the robot is in trouble or moving.
    const bool troubled = p == P::kEmergency || p == P::kFault || p == P::kManual;
    if (!troubled && p != P::kStartup && p != P::kMoving) {
      t.push_back({p, I::kManual, P::kManual, "hand the robot over"});
    }
    if (!troubled && p != P::kMoving) t.push_back({p, I::kCheckReady, p, "readiness check"});
    if (p == P::kStartup) continue;
    // Only where the robot is in use does a controller fault become the fault phase.
    const bool keeps = p != P::kPlanLocked && p != P::kMoving && p != P::kAtTarget && p != P::kDone;
    t.push_back({p, I::kControllerFault, keeps ? p : P::kFault, "controller fault"});
    // After a crash: approvals are gone; a move in flight or a position that moved is a fault.
    if (p != P::kMoving) t.push_back({p, I::kServerRestarted, p, "recovered"});
    if (!keeps) t.push_back({p, I::kServerRestarted, P::kFault, "recovered, position in doubt"});
  }
  return t;
}

}  // namespace

const std::vector<Transition>& transitionTable() {
  static const std::vector<Transition> table = buildTable();
  return table;
}

std::vector<InputKind> allowedCommands(Phase phase) {
  std::vector<InputKind> out;
  for (const auto& t : transitionTable()) {
    if (t.from == phase && isCommand(t.input) &&
        std::find(out.begin(), out.end(), t.input) == out.end()) {
      out.push_back(t.input);
    }
  }
  return out;
}

std::string mermaidDiagram() {
  std::string everywhere;
  for (const auto& spec : inputTable()) {
    if (spec.traits & kEveryPhase)
      everywhere += (everywhere.empty() ? "" : ", ") + std::string(spec.name);
  }
  std::string out = "stateDiagram-v2\n  [*] --> startup\n";
  std::set<std::string> seen;
  for (const auto& t : transitionTable()) {
    // Self-loops on (almost) every phase, noted once.
    if ((specOf(t.input).traits & kEveryPhase) || t.input == InputKind::kCheckReady) continue;
    // The server's own inputs that leave a phase as it is: noted once, not drawn per phase.
    const bool detection_result =
        t.input == InputKind::kFiducialsDetected || t.input == InputKind::kFiducialDetectionFailed;
    const bool server_self_loop =
        (t.input == InputKind::kControllerFault || t.input == InputKind::kServerRestarted ||
         (detection_result && isInterruption(t.from))) &&
        t.from == t.to;
    if (server_self_loop) continue;
    // resume's destinations are drawn once, as the phase the interruption left.
    const bool resume_back = t.input == InputKind::kResume;
    std::string line = std::string("  ") + toString(t.from) + " --> " +
                       (resume_back ? "resume_target" : toString(t.to)) + ": " + toString(t.input) +
                       " (" + t.why + ")\n";
    if (seen.insert(line).second) out += line;
  }
  std::string destinations;
  for (Phase p : kResumePhases)
    destinations += (destinations.empty() ? "" : ", ") + std::string(toString(p));
  out += "  resume_target: the phase the interruption left (" + destinations + ")\n";
  out += "  note right of stopped: accepted in every phase: " + everywhere +
         "; check_ready in every phase but moving, emergency, fault and manual\n";
  out +=
      "  note right of fault: controller_fault and server_restarted leave the other phases "
      "as they are; a marker detection's outcome (fiducials_detected, "
      "fiducial_detection_failed) is kept in stopped, emergency, fault and manual\n";
  return out;
}

std::string workflowMarkdown() {
  std::string out =
      "# Workflow\n\n"
      "Generated from the transition table in modules/workflow/src/transitions.cpp by\n"
      "`build/tools/workflow-diagram/ignav-workflow-diagram > docs/WORKFLOW.md`; a test fails "
      "when\nthis file is not current. Every (phase, input) pair not drawn is rejected with "
      "\"<input> is\nnot allowed in <phase>\" and changes nothing.\n\n```mermaid\n" +
      mermaidDiagram() + "```\n\n| phase | commands a client may send |\n|---|---|\n";
  for (Phase p : kAllPhases) {
    std::string allowed;
    for (auto k : allowedCommands(p)) {
      allowed += (allowed.empty() ? "" : ", ") + std::string("`") + toString(k) + "`";
    }
    out += std::string("| ") + toString(p) + " | " + allowed + " |\n";
  }
  return out;
}

namespace {

// "every phase", "every phase but a, b" or "a, b, c": where the table allows `kind`.
std::string allowedIn(InputKind kind) {
  std::vector<std::string> in, out;
  for (Phase p : kAllPhases) {
    const bool allowed =
        std::any_of(transitionTable().begin(), transitionTable().end(),
                    [&](const Transition& t) { return t.from == p && t.input == kind; });
    (allowed ? in : out).push_back(toString(p));
  }
  auto join = [](const std::vector<std::string>& words) {
    std::string text;
    for (const auto& w : words)
      text += (text.empty() ? "" : ", ") + w;
    return text;
  };
  if (out.empty()) return "every phase";
  if (out.size() < in.size()) return "every phase but " + join(out);
  return join(in);
}

std::string argumentsText(const InputSpec& spec) {
  const Arguments& a = spec.args;
  std::string text;
  auto add = [&](const std::string& part) { text += (text.empty() ? "" : "; ") + part; };
  if (a.path_is) add(std::string("`path`: ") + a.path_is);
  auto counted = [](std::size_t n, const char* field) {
    if (n == kAnyCount) return std::string("`") + field + "`";
    return "`" + std::string(field) + "` (" + std::to_string(n) + ")";
  };
  if (a.ids) add(counted(a.ids, "ids") + ": " + a.ids_are);
  if (a.points) add(counted(a.points, "points") + ": " + a.points_are);
  if (a.matrix_is) add(std::string("`matrix`: ") + a.matrix_is);
  return text.empty() ? "—" : text;
}

}  // namespace

std::string commandsMarkdown() {
  std::string out =
      "| kind | command | least role | arguments | what it does | allowed in |\n"
      "|---|---|---|---|---|---|\n";
  for (const auto& spec : inputTable()) {
    if (!(spec.traits & kFromClients)) continue;
    const std::string kind =
        spec.wire_kind == kNoWireKind ? "(own topic)" : std::to_string(spec.wire_kind);
    out += "| " + kind + " | `" + spec.name + "` | " + toString(spec.role) + " | " +
           argumentsText(spec) + " | " + spec.help + " | " + allowedIn(spec.kind) + " |\n";
  }
  return out;
}

}  // namespace ignav::workflow
