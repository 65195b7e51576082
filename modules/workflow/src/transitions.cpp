#include <algorithm>
#include <array>
#include <iterator>
#include <set>
#include <utility>

#include "actions.hpp"
#include "ignav/workflow/background_jobs.hpp"
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
using namespace detail;  // the guards and actions (actions.hpp)

constexpr Guard always = nullptr;

// resume's guards, one per destination in kResumePhases: resumesTo<kResumePhases[i]>.
template <std::size_t... i>
constexpr std::array<Guard, sizeof...(i)> resumeGuards(std::index_sequence<i...>) {
  return {&resumesTo<kResumePhases[i]>...};
}
constexpr auto kResumeGuards = resumeGuards(std::make_index_sequence<std::size(kResumePhases)>());

// The actions of the inputs allowed in every phase (kEveryPhase in the command table).
struct EveryPhaseAction {
  InputKind input;
  Action action;
};
constexpr EveryPhaseAction kEveryPhaseActions[] = {
    {I::kQuery, republishEverything},
    {I::kPing, answerPing},
};

Action everyPhaseAction(InputKind kind) {
  for (const auto& a : kEveryPhaseActions) {
    if (a.input == kind) return a.action;
  }
  return nullptr;  // a test finds it: every row has an action
}

// Stop, emergency stop and the kEveryPhase inputs (query, ping) are allowed (almost) everywhere;
// they are added below per phase. The rows of one (phase, input) pair are tried in this order: a
// guarded row comes before the pair's row without a guard.
std::vector<Transition> buildTable() {
  std::vector<Transition> t = {
      // from, input, guard, to, action, why
      {P::kStartup, I::kConfigLoaded, always, P::kImaging, adoptConfig, "robot config valid"},
      {P::kImaging, I::kLoadVolume, always, P::kImaging, startVolumeLoad, "load a CT"},
      {P::kImaging, I::kVolumeLoaded, always, P::kRegistration, keepLoadedCt, "CT loaded"},
      {P::kImaging, I::kVolumeLoadFailed, always, P::kImaging, noteLoadFailure, "load failed"},
      {P::kRegistration, I::kLoadVolume, always, P::kImaging, startVolumeLoad, "another CT"},
      {P::kRegistration, I::kSetFiducials, always, P::kPlanning, registerClickedFiducials,
       "3 points registered"},
      // auto_fiducials starts a marker detection on the server's job thread; its outcome
      // comes back as fiducials_detected or fiducial_detection_failed. (A format-1 journal's
      // auto_fiducials detected and registered within its step: replay only.)
      {P::kRegistration, I::kAutoFiducials, isFormatOneRecord, P::kPlanning,
       detectAndRegisterAtOnce, "format-1 journal: registered at once"},
      {P::kRegistration, I::kAutoFiducials, always, P::kRegistration, startMarkerDetection,
       "detect the markers"},
      {P::kRegistration, I::kFiducialsDetected, markersRegister, P::kPlanning,
       registerDetectedMarkers, "markers found, registered"},
      {P::kRegistration, I::kFiducialsDetected, always, P::kRegistration, refuseDetectedMarkers,
       "markers do not register"},
      {P::kRegistration, I::kFiducialDetectionFailed, always, P::kRegistration,
       noteDetectionFailure, "no markers matched"},
      {P::kImaging, I::kSetRegistration, always, P::kPlanning, registerByMatrix,
       "registered elsewhere (no CT here)"},
      {P::kRegistration, I::kSetRegistration, always, P::kPlanning, registerByMatrix,
       "registered elsewhere"},
      {P::kPlanning, I::kSetRegistration, always, P::kPlanning, registerByMatrix, "re-register"},
      {P::kPlanning, I::kLoadVolume, always, P::kImaging, startVolumeLoad, "another CT"},
      {P::kPlanning, I::kSetFiducials, always, P::kPlanning, registerClickedFiducials,
       "re-register"},
      {P::kPlanning, I::kAutoFiducials, isFormatOneRecord, P::kPlanning, detectAndRegisterAtOnce,
       "format-1 journal: re-registered at once"},
      {P::kPlanning, I::kAutoFiducials, always, P::kPlanning, startMarkerDetection,
       "re-detect the markers"},
      {P::kPlanning, I::kFiducialsDetected, markersRegister, P::kPlanning, registerDetectedMarkers,
       "re-registered"},
      {P::kPlanning, I::kFiducialsDetected, always, P::kPlanning, refuseDetectedMarkers,
       "markers do not register: the old stays"},
      {P::kPlanning, I::kFiducialDetectionFailed, always, P::kPlanning, noteDetectionFailure,
       "no match: the old stays"},
      {P::kPlanning, I::kAddTarget, always, P::kPlanning, addTarget, "click"},
      {P::kPlanning, I::kMoveTarget, always, P::kPlanning, moveTarget, "drag"},
      {P::kPlanning, I::kRemoveTarget, always, P::kPlanning, removeTarget, "remove"},
      {P::kPlanning, I::kClearTargets, always, P::kPlanning, clearTargets, "clear"},
      {P::kPlanning, I::kReorderTargets, always, P::kPlanning, reorderTargets, "reorder"},
      {P::kPlanning, I::kLockPlan, always, P::kPlanLocked, lockPlan, "all targets reachable"},
      {P::kPlanLocked, I::kUnlockPlan, always, P::kPlanning, unlockPlan, "edit again"},
      {P::kPlanLocked, I::kApprove, always, P::kMoving, startApprovedMotion,
       "approved: plan id, digest, approver, fresh"},
      {P::kPlanLocked, I::kRequestApproval, always, P::kPlanLocked, requestApproval,
       "fresh request"},
      // A move ended (or the controller stopped answering): faults first, then where it ended.
      {P::kMoving, I::kSegmentDone, readingReportsFault, P::kFault, faultDuringMove,
       "the controller reports a fault"},
      {P::kMoving, I::kSegmentDone, arrivalMismatch, P::kFault, failArrivalCheck,
       "arrival check failed"},
      {P::kMoving, I::kSegmentDone, moreMovesFollow, P::kMoving, startNextMove, "next move"},
      {P::kMoving, I::kSegmentDone, retractionEnded, P::kDone, endRetraction,
       "stylet home after the last target"},
      {P::kMoving, I::kSegmentDone, nothingLeftAfterArrival, P::kDone, arriveAtTarget,
       "at the last target, the stylet home"},
      {P::kMoving, I::kSegmentDone, always, P::kAtTarget, arriveAtTarget,
       "arrived, steps verified"},
      {P::kAtTarget, I::kApprove, always, P::kMoving, startApprovedMotion, "next motion approved"},
      {P::kAtTarget, I::kRequestApproval, always, P::kAtTarget, requestApproval, "fresh request"},
      {P::kAtTarget, I::kUnlockPlan, always, P::kPlanning, unlockPlan,
       "edit the remaining targets"},
      {P::kDone, I::kUnlockPlan, always, P::kPlanning, unlockPlan, "plan more targets"},
      // A load finishing while stopped is kept; the workflow stays stopped.
      {P::kStopped, I::kVolumeLoaded, always, P::kStopped, keepLoadedCt, "CT loaded"},
      {P::kStopped, I::kVolumeLoadFailed, always, P::kStopped, noteLoadFailure, "load failed"},
      {P::kEmergency, I::kVolumeLoaded, always, P::kEmergency, keepLoadedCt, "CT loaded"},
      {P::kEmergency, I::kVolumeLoadFailed, always, P::kEmergency, noteLoadFailure, "load failed"},
      {P::kEmergency, I::kResetEmergency, always, P::kStopped, resetAfterPositionCheck,
       "operator reset, position checked"},
      {P::kEmergency, I::kHome, always, P::kEmergency, adoptHome, "robot homed by hand"},
      {P::kStopped, I::kHome, always, P::kStopped, adoptHome, "robot homed by hand"},
      {P::kFault, I::kResetEmergency, always, P::kStopped, resetAfterPositionCheck,
       "operator reset, position checked"},
      {P::kFault, I::kHome, always, P::kFault, adoptHome, "robot homed by hand"},
      {P::kFault, I::kVolumeLoaded, always, P::kFault, keepLoadedCt, "CT loaded"},
      {P::kFault, I::kVolumeLoadFailed, always, P::kFault, noteLoadFailure, "load failed"},
      {P::kManual, I::kHome, always, P::kManual, adoptHome, "robot homed by hand"},
      {P::kManual, I::kVolumeLoaded, always, P::kManual, keepLoadedCt, "CT loaded"},
      {P::kManual, I::kVolumeLoadFailed, always, P::kManual, noteLoadFailure, "load failed"},
  };
  // A marker detection started in registration or planning may end while interrupted: its outcome
  // is kept (resume then returns to planning if it registered); the phase stays.
  for (Phase p : {P::kStopped, P::kEmergency, P::kFault, P::kManual}) {
    t.push_back({p, I::kFiducialsDetected, markersRegister, p, registerDetectedMarkers,
                 "markers found, registered"});
    t.push_back(
        {p, I::kFiducialsDetected, always, p, refuseDetectedMarkers, "markers do not register"});
    t.push_back(
        {p, I::kFiducialDetectionFailed, always, p, noteDetectionFailure, "no markers matched"});
  }
  // The closed loop (issue 23): a confirmation CT is measured, its seeds corrected and a tissue
  // fitted wherever the robot rests with targets planned; the measurement may end anywhere. The
  // aim changes only with the plan open.
  for (Phase p : {P::kPlanning, P::kPlanLocked, P::kAtTarget, P::kDone, P::kStopped, P::kManual}) {
    t.push_back({p, I::kLoadConfirmation, always, p, startConfirmation, "measure the seeds"});
    t.push_back({p, I::kPlaceSeed, always, p, placeSeed, "a seed clicked"});
    t.push_back({p, I::kAcceptSeed, always, p, acceptSeed, "a match accepted"});
    t.push_back({p, I::kRejectSeed, always, p, rejectSeed, "no seed"});
    t.push_back({p, I::kFitTissue, always, p, fitTissue, "tissue fitted"});
    t.push_back({p, I::kDiscardTissue, always, p, discardTissue, "a fit forgotten"});
    t.push_back({p, I::kComputeDose, always, p, startDoseComputation, "the seeds' dose"});
  }
  for (Phase p : kAllPhases) {
    if (p == P::kStartup) continue;
    t.push_back({p, I::kConfirmationMeasured, always, p, adoptConfirmation, "seeds measured"});
    t.push_back({p, I::kConfirmationFailed, always, p, noteConfirmationFailure, "scan refused"});
  }
  t.push_back({P::kPlanning, I::kUseTissue, always, P::kPlanning, useTissue, "aim for a tissue"});
  // Re-planning during an insertion (issue 40): a stop part-way is planned with the plan; the
  // needle stopped there is scanned and re-aimed before the rest is approved. The scan's outcome
  // may end anywhere (it re-aims only an insertion still paused where it was scanned).
  t.push_back({P::kPlanning, I::kPauseAt, always, P::kPlanning, pauseAt, "stop part-way"});
  t.push_back({P::kAtTarget, I::kScanNeedle, always, P::kAtTarget, startNeedleScan,
               "search the paused needle"});
  t.push_back({P::kAtTarget, I::kReaim, always, P::kAtTarget, adoptReaim, "re-aimed"});
  for (Phase p : kAllPhases) {
    if (p == P::kStartup) continue;
    t.push_back({p, I::kNeedleScanned, always, p, adoptNeedleScan, "re-aim proposed"});
    t.push_back({p, I::kNeedleScanFailed, always, p, noteNeedleScanFailure, "scan refused"});
  }
  // The patient's structures (issue 41): loaded on the CT and given roles before the plan is
  // locked; a load may end anywhere.
  for (Phase p : {P::kRegistration, P::kPlanning}) {
    t.push_back({p, I::kLoadStructures, always, p, startStructureLoad, "load the structures"});
    t.push_back({p, I::kStructureRole, always, p, setStructureRole, "a structure's role"});
  }
  t.push_back({P::kPlanning, I::kOverrideClearance, always, P::kPlanning, overrideClearance,
               "plan a target too close, for a reason"});
  t.push_back({P::kPlanning, I::kProposeTargets, always, P::kPlanning, startTargetProposal,
               "fill a structure with targets"});
  t.push_back({P::kPlanning, I::kPlanSeeds, always, P::kPlanning, startSeedPlan,
               "plan seeds that dose a structure"});
  t.push_back({P::kPlanning, I::kAcceptProposals, always, P::kPlanning, acceptProposals,
               "proposed targets into the plan"});
  // Where to mount the robot: on the planning CT before it is registered, or after.
  for (Phase p : {P::kRegistration, P::kPlanning})
    t.push_back({p, I::kPlaceRobot, always, p, startRobotPlacement, "where to mount the robot"});
  for (Phase p : kAllPhases) {
    if (p == P::kStartup) continue;
    t.push_back({p, I::kStructuresLoaded, always, p, adoptStructures, "structures loaded"});
    t.push_back(
        {p, I::kStructuresLoadFailed, always, p, noteStructureLoadFailure, "structures refused"});
    t.push_back({p, I::kTargetsProposed, always, p, adoptProposals, "targets proposed"});
    t.push_back(
        {p, I::kTargetProposalFailed, always, p, noteProposalFailure, "no targets proposed"});
    t.push_back({p, I::kRobotPlaced, always, p, adoptRobotPlacement, "robot placed"});
    t.push_back(
        {p, I::kRobotPlacementFailed, always, p, noteRobotPlacementFailure, "no placement"});
    t.push_back(
        {p, I::kPlacementChecked, always, p, adoptPlacementCheck, "mounted robot measured"});
    t.push_back({p, I::kPlacementCheckFailed, always, p, notePlacementCheckFailure,
                 "mounted robot not measured"});
    t.push_back({p, I::kDoseComputed, always, p, adoptDose, "dose computed"});
    t.push_back({p, I::kDoseFailed, always, p, noteDoseFailure, "no dose"});
  }
  // resume returns to the phase the first interruption left (a move in flight: plan_locked, to be
  // approved again), or to done when nothing is left to move. Interruptions taken while
  // interrupted (manual after stop, emergency in manual) keep that phase (issue 27).
  for (std::size_t i = 0; i < std::size(kResumePhases); ++i) {
    const Phase back = kResumePhases[i];
    t.push_back(
        {P::kStopped, I::kResume, kResumeGuards[i], back, resume, "back to the interrupted phase"});
    t.push_back({P::kManual, I::kResume, kResumeGuards[i], back, resume,
                 "back to the interrupted phase, position taken over"});
  }
  for (Phase p : kAllPhases) {
    // A stop button always stops (issue 25). Where the robot is already interrupted it halts the
    // controller again and the phase stays: a fault is left only by a reset with a position check
    // (or an emergency stop), manual control by resume, an emergency by its reset.
    if (p != P::kStopped && p != P::kEmergency && p != P::kFault && p != P::kManual) {
      t.push_back({p, I::kStop, always, P::kStopped, stop, "stop"});
    } else {
      t.push_back({p, I::kStop, always, p, haltInPlace, "stop: halt again"});
    }
    // An emergency stop is always taken, an emergency's too: the controller is aborted again.
    t.push_back({p, I::kEmergencyStop, always, P::kEmergency, emergencyStop, "EMERGENCY"});
    for (const auto& spec : inputTable()) {
      if (spec.traits & kEveryPhase) {
        t.push_back({p, spec.kind, always, p, everyPhaseAction(spec.kind), spec.name});
      }
    }
    // Manual control and readiness questions: not while the robot is in trouble or moving.
    const bool troubled = p == P::kEmergency || p == P::kFault || p == P::kManual;
    if (!troubled && p != P::kStartup && p != P::kMoving) {
      t.push_back({p, I::kManual, always, P::kManual, handOverTheRobot, "hand the robot over"});
    }
    if (!troubled && p != P::kMoving) {
      t.push_back({p, I::kCheckReady, always, p, checkReadiness, "readiness check"});
    }
    if (p == P::kStartup) continue;
    // Only where the robot is in use does a controller fault become the fault phase.
    if (robotInUse(p)) {
      t.push_back(
          {p, I::kControllerFault, always, P::kFault, faultStopsTheRobot, "controller fault"});
    } else {
      t.push_back({p, I::kControllerFault, always, p, noteControllerFault, "controller fault"});
    }
    // After a crash: approvals are gone; a move in flight or a position that moved is a fault.
    if (p == P::kMoving) {
      t.push_back({p, I::kServerRestarted, always, P::kFault, restartedMidMotion,
                   "recovered, position in doubt"});
    } else if (robotInUse(p)) {
      t.push_back({p, I::kServerRestarted, positionInDoubt, P::kFault, restartedInDoubt,
                   "recovered, position in doubt"});
      t.push_back({p, I::kServerRestarted, always, p, restartedRobotInPlace, "recovered"});
    } else {
      t.push_back({p, I::kServerRestarted, always, p, restartedIdle, "recovered"});
    }
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

namespace {

// "every phase", "every phase but moving and fault", or "planning, plan_locked and done".
std::string phasesInWords(const std::vector<Phase>& phases) {
  auto list = [](const std::vector<Phase>& ps) {
    std::string out;
    for (std::size_t i = 0; i < ps.size(); ++i) {
      out += (i == 0 ? "" : i + 1 == ps.size() ? " and " : ", ") + std::string(toString(ps[i]));
    }
    return out;
  };
  std::vector<Phase> missing;
  for (Phase p : kAllPhases) {
    if (std::find(phases.begin(), phases.end(), p) == phases.end()) missing.push_back(p);
  }
  if (missing.empty()) return "every phase";
  if (missing.size() < phases.size()) return "every phase but " + list(missing);
  return list(phases);
}

}  // namespace

// Derived from the table alone, so that a new input is drawn or noted without a list to keep:
// a row that changes the phase is drawn; an input that leaves at most kDrawnSelfLoops phases as
// they are has those loops drawn, one that leaves more is noted once with its phases (inputs
// with the same phases share a note). resume's destinations are drawn once, as the phase the
// interruption left.
std::string mermaidDiagram() {
  constexpr std::size_t kDrawnSelfLoops = 2;
  std::vector<std::vector<Phase>> stays(inputTable().size());
  for (const auto& t : transitionTable()) {
    auto& phases = stays[static_cast<std::size_t>(t.input)];
    if (t.from == t.to && std::find(phases.begin(), phases.end(), t.from) == phases.end()) {
      phases.push_back(t.from);
    }
  }
  std::string out = "stateDiagram-v2\n  [*] --> startup\n";
  std::set<std::string> seen;
  for (const auto& t : transitionTable()) {
    const auto& phases = stays[static_cast<std::size_t>(t.input)];
    if (t.from == t.to && phases.size() > kDrawnSelfLoops) continue;
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
  // One note per set of phases, in the table's order of inputs.
  std::vector<std::pair<std::vector<Phase>, std::string>> notes;
  for (const auto& spec : inputTable()) {
    auto phases = stays[static_cast<std::size_t>(spec.kind)];
    if (phases.size() <= kDrawnSelfLoops) continue;
    std::sort(phases.begin(), phases.end());
    auto same =
        std::find_if(notes.begin(), notes.end(), [&](const auto& n) { return n.first == phases; });
    if (same == notes.end()) {
      notes.push_back({phases, spec.name});
    } else {
      same->second += std::string(" / ") + spec.name;
    }
  }
  for (const auto& [phases, inputs] : notes) {
    const bool several = inputs.find('/') != std::string::npos;
    out += std::string("  note right of ") + toString(phases.front()) + ": " + inputs +
           (several ? " leave" : " leaves") + " the phase as it is in " + phasesInWords(phases) +
           "\n";
  }
  return out;
}

std::string workflowMarkdown() {
  std::string out =
      "# Workflow\n\n"
      "Generated from the transition table in modules/workflow/src/transitions.cpp by\n"
      "`build/tools/workflow-diagram/ignav-workflow-diagram > docs/WORKFLOW.md`; a test fails "
      "when\nthis file is not current. Every (phase, input) pair not drawn is rejected with "
      "\"<input> is\nnot allowed in <phase>\" and changes nothing. Where one input has several "
      "edges from a\nphase, they are its outcomes, tried in the order listed: the first whose "
      "condition (the text in\nparentheses; a guard in the table) holds is taken.\n\n```mermaid\n" +
      mermaidDiagram() + "```\n\n| phase | commands a client may send |\n|---|---|\n";
  for (Phase p : kAllPhases) {
    std::string allowed;
    for (auto k : allowedCommands(p)) {
      allowed += (allowed.empty() ? "" : ", ") + std::string("`") + toString(k) + "`";
    }
    out += std::string("| ") + toString(p) + " | " + allowed + " |\n";
  }
  out +=
      "\n## Background jobs\n\nFrom modules/workflow/src/background_jobs.cpp. Each runs on the "
      "server's job thread and\ncomes back as one of its outcome inputs; an outcome the session "
      "no longer awaits is refused\n(`stale_detection`) and changes nothing; after a crash the "
      "awaited ones run again.\n\n| job | outcomes |\n|---|---|\n";
  for (const auto& job : jobKinds()) {
    out += std::string("| ") + job.name + " | `" + toString(job.succeeded) + "`, `" +
           toString(job.failed) + "` |\n";
  }
  return out;
}

namespace {

// "every phase", "every phase but a and b" or "a, b and c": where the table allows `kind`.
std::string allowedIn(InputKind kind) {
  std::vector<Phase> in;
  for (Phase p : kAllPhases) {
    const bool allowed =
        std::any_of(transitionTable().begin(), transitionTable().end(),
                    [&](const Transition& t) { return t.from == p && t.input == kind; });
    if (allowed) in.push_back(p);
  }
  return phasesInWords(in);
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
  if (a.matrix_is) {
    add(std::string("`matrix`") + (a.matrix_optional ? " (optional: all zeros for none)" : "") +
        ": " + a.matrix_is);
  }
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
