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

const char* toString(InputKind kind) {
  switch (kind) {
    case InputKind::kLoadVolume:
      return "load_volume";
    case InputKind::kSetFiducials:
      return "set_fiducials";
    case InputKind::kAutoFiducials:
      return "auto_fiducials";
    case InputKind::kAddTarget:
      return "add_target";
    case InputKind::kMoveTarget:
      return "move_target";
    case InputKind::kRemoveTarget:
      return "remove_target";
    case InputKind::kClearTargets:
      return "clear_targets";
    case InputKind::kReorderTargets:
      return "reorder_targets";
    case InputKind::kLockPlan:
      return "lock_plan";
    case InputKind::kUnlockPlan:
      return "unlock_plan";
    case InputKind::kStop:
      return "stop";
    case InputKind::kResume:
      return "resume";
    case InputKind::kEmergencyStop:
      return "emergency_stop";
    case InputKind::kResetEmergency:
      return "reset_emergency";
    case InputKind::kQuery:
      return "query";
    case InputKind::kApprove:
      return "approve";
    case InputKind::kRequestApproval:
      return "request_approval";
    case InputKind::kHome:
      return "home";
    case InputKind::kSetRegistration:
      return "set_registration";
    case InputKind::kManual:
      return "manual";
    case InputKind::kCheckReady:
      return "check_ready";
    case InputKind::kConfigLoaded:
      return "config_loaded";
    case InputKind::kVolumeLoaded:
      return "volume_loaded";
    case InputKind::kVolumeLoadFailed:
      return "volume_load_failed";
    case InputKind::kSegmentDone:
      return "segment_done";
    case InputKind::kControllerFault:
      return "controller_fault";
    case InputKind::kServerRestarted:
      return "server_restarted";
  }
  return "unknown";
}

bool isCommand(InputKind kind) {
  switch (kind) {
    case InputKind::kConfigLoaded:
    case InputKind::kVolumeLoaded:
    case InputKind::kVolumeLoadFailed:
    case InputKind::kSegmentDone:
    case InputKind::kControllerFault:
    case InputKind::kServerRestarted:
      return false;
    default:
      return true;
  }
}

bool needsControllerReading(InputKind kind) {
  switch (kind) {
    case InputKind::kApprove:
    case InputKind::kResume:
    case InputKind::kResetEmergency:
    case InputKind::kHome:
    case InputKind::kManual:
    case InputKind::kCheckReady:
    case InputKind::kSegmentDone:
    case InputKind::kControllerFault:
    case InputKind::kServerRestarted:
      return true;
    default:
      return false;
  }
}

namespace {

using P = Phase;
using I = InputKind;

// Stop, emergency stop and query are allowed (almost) everywhere; they are added below per phase.
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
      {P::kRegistration, I::kAutoFiducials, P::kPlanning, "markers found, registered"},
      {P::kImaging, I::kSetRegistration, P::kPlanning, "registered elsewhere (no CT here)"},
      {P::kRegistration, I::kSetRegistration, P::kPlanning, "registered elsewhere"},
      {P::kPlanning, I::kSetRegistration, P::kPlanning, "re-register"},
      {P::kPlanning, I::kLoadVolume, P::kImaging, "another CT"},
      {P::kPlanning, I::kSetFiducials, P::kPlanning, "re-register"},
      {P::kPlanning, I::kAutoFiducials, P::kPlanning, "re-register"},
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
    t.push_back({p, I::kQuery, p, "query"});
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
  std::string out = "stateDiagram-v2\n  [*] --> startup\n";
  std::set<std::string> seen;
  for (const auto& t : transitionTable()) {
    // Self-loops on (almost) every phase, noted once.
    if (t.input == InputKind::kQuery || t.input == InputKind::kCheckReady) continue;
    // The server's own inputs that leave a phase as it is: noted once, not drawn per phase.
    const bool server_self_loop =
        (t.input == InputKind::kControllerFault || t.input == InputKind::kServerRestarted) &&
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
  out +=
      "  note right of stopped: query is accepted in every phase; check_ready in every phase "
      "but moving, emergency, fault and manual\n";
  out +=
      "  note right of fault: controller_fault and server_restarted leave the other phases "
      "as they are\n";
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

}  // namespace ignav::workflow
