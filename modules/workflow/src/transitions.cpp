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
    case Phase::kStopped:
      return "stopped";
    case Phase::kEmergency:
      return "emergency";
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
    case InputKind::kConfigLoaded:
      return "config_loaded";
    case InputKind::kVolumeLoaded:
      return "volume_loaded";
    case InputKind::kVolumeLoadFailed:
      return "volume_load_failed";
  }
  return "unknown";
}

bool isCommand(InputKind kind) {
  return kind != InputKind::kConfigLoaded && kind != InputKind::kVolumeLoaded &&
         kind != InputKind::kVolumeLoadFailed;
}

namespace {

using P = Phase;
using I = InputKind;

// Stop, emergency stop and query are allowed everywhere; they are added below per phase.
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
      // A load finishing while stopped is kept; the workflow stays stopped.
      {P::kStopped, I::kVolumeLoaded, P::kStopped, "CT loaded"},
      {P::kStopped, I::kVolumeLoadFailed, P::kStopped, "load failed"},
      {P::kStopped, I::kResume, P::kStopped, "back to the interrupted phase"},
      {P::kEmergency, I::kVolumeLoaded, P::kEmergency, "CT loaded"},
      {P::kEmergency, I::kVolumeLoadFailed, P::kEmergency, "load failed"},
      {P::kEmergency, I::kResetEmergency, P::kStopped, "operator reset"},
  };
  for (Phase p : kAllPhases) {
    if (p != P::kStopped && p != P::kEmergency) t.push_back({p, I::kStop, P::kStopped, "stop"});
    if (p != P::kEmergency) t.push_back({p, I::kEmergencyStop, P::kEmergency, "EMERGENCY"});
    t.push_back({p, I::kQuery, p, "query"});
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
    if (t.input == InputKind::kQuery) continue;  // a self-loop on every phase
    std::string line = std::string("  ") + toString(t.from) + " --> " +
                       (t.input == InputKind::kResume ? "resume_target" : toString(t.to)) + ": " +
                       toString(t.input) + " (" + t.why + ")\n";
    if (seen.insert(line).second) out += line;
  }
  out += "  resume_target: the phase stop interrupted\n";
  out += "  note right of stopped: query is accepted in every phase\n";
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
