// The transition rows' guards and actions (the table: transitions.cpp). Guards are pure
// predicates that pick which row of a (phase, input) pair fires (guards.cpp); actions do the
// row's work (planning_actions.cpp: configuration, CT, registration, targets, plan; and
// motion_actions.cpp: approval, motion, interruptions, the robot). Internal to modules/workflow.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "motion.hpp"

namespace ignav::workflow::detail {

// What an action leaves besides the session: the step's effects, and for the reply, the id of a
// target it made and a message ("ok" when empty).
struct ActionOutput {
  Effects& effects;
  std::uint32_t new_target_id = 0;
  std::string note;
  // A background job's outcome was taken but its work came to nothing (markers found that do not
  // register): JobOutcome.status failed, with the note.
  bool outcome_failed = false;
};

using Refusal = std::optional<Rejection>;

// ---- Guards (guards.cpp) ----

// auto_fiducials: a format-1 journal record, which detected and registered within its own step.
bool isFormatOneRecord(const Session& s, const Input& in);
// fiducials_detected: the markers found register the robot (the same computation the action
// then adopts).
bool markersRegister(const Session& s, const Input& in);
// segment_done, in the order the rows try them: the controller reports a fault (or no reading);
// it came to rest somewhere else than the move's end; another move of the motion follows; the
// final retraction ended; the last target was reached and nothing is left (the stylet home).
bool readingReportsFault(const Session& s, const Input& in);
bool arrivalMismatch(const Session& s, const Input& in);
bool moreMovesFollow(const Session& s, const Input& in);
bool retractionEnded(const Session& s, const Input& in);
bool nothingLeftAfterArrival(const Session& s, const Input& in);
// server_restarted while the robot is in use: its position is in doubt (a fault, the robot
// moving, a position other than the last verified one).
bool positionInDoubt(const Session& s, const Input& in);
// Where resume leads: the phase the first interruption left, or done when that phase waits for
// an approval and nothing is left to move from where the robot stands.
Phase resumeDestination(const Session& s, const Input& in);
template <Phase kTo>
bool resumesTo(const Session& s, const Input& in) {
  return resumeDestination(s, in) == kTo;
}

// ---- Actions: configuration, CT, registration, targets, plan (planning_actions.cpp) ----

Refusal adoptConfig(Session& s, const Input& in, ActionOutput& out);
Refusal startVolumeLoad(Session& s, const Input& in, ActionOutput& out);
Refusal keepLoadedCt(Session& s, const Input& in, ActionOutput& out);
Refusal noteLoadFailure(Session& s, const Input& in, ActionOutput& out);
Refusal registerClickedFiducials(Session& s, const Input& in, ActionOutput& out);
Refusal startMarkerDetection(Session& s, const Input& in, ActionOutput& out);
Refusal detectAndRegisterAtOnce(Session& s, const Input& in, ActionOutput& out);  // format 1
Refusal registerDetectedMarkers(Session& s, const Input& in, ActionOutput& out);
Refusal refuseDetectedMarkers(Session& s, const Input& in, ActionOutput& out);
Refusal noteDetectionFailure(Session& s, const Input& in, ActionOutput& out);
Refusal registerByMatrix(Session& s, const Input& in, ActionOutput& out);
Refusal addTarget(Session& s, const Input& in, ActionOutput& out);
Refusal moveTarget(Session& s, const Input& in, ActionOutput& out);
Refusal removeTarget(Session& s, const Input& in, ActionOutput& out);
Refusal clearTargets(Session& s, const Input& in, ActionOutput& out);
Refusal reorderTargets(Session& s, const Input& in, ActionOutput& out);
Refusal lockPlan(Session& s, const Input& in, ActionOutput& out);
Refusal unlockPlan(Session& s, const Input& in, ActionOutput& out);
Refusal requestApproval(Session& s, const Input& in, ActionOutput& out);

// ---- Actions: approval, motion, interruptions, the robot (motion_actions.cpp) ----

Refusal startApprovedMotion(Session& s, const Input& in, ActionOutput& out);
Refusal faultDuringMove(Session& s, const Input& in, ActionOutput& out);
Refusal failArrivalCheck(Session& s, const Input& in, ActionOutput& out);
Refusal startNextMove(Session& s, const Input& in, ActionOutput& out);
Refusal endRetraction(Session& s, const Input& in, ActionOutput& out);
Refusal arriveAtTarget(Session& s, const Input& in, ActionOutput& out);
Refusal faultStopsTheRobot(Session& s, const Input& in, ActionOutput& out);
Refusal noteControllerFault(Session& s, const Input& in, ActionOutput& out);
Refusal restartedMidMotion(Session& s, const Input& in, ActionOutput& out);
Refusal restartedInDoubt(Session& s, const Input& in, ActionOutput& out);
Refusal restartedRobotInPlace(Session& s, const Input& in, ActionOutput& out);
Refusal restartedIdle(Session& s, const Input& in, ActionOutput& out);
Refusal stop(Session& s, const Input& in, ActionOutput& out);
Refusal haltInPlace(Session& s, const Input& in, ActionOutput& out);
Refusal emergencyStop(Session& s, const Input& in, ActionOutput& out);
Refusal handOverTheRobot(Session& s, const Input& in, ActionOutput& out);
Refusal checkReadiness(Session& s, const Input& in, ActionOutput& out);
Refusal resume(Session& s, const Input& in, ActionOutput& out);
Refusal resetAfterPositionCheck(Session& s, const Input& in, ActionOutput& out);
Refusal adoptHome(Session& s, const Input& in, ActionOutput& out);
Refusal republishEverything(Session& s, const Input& in, ActionOutput& out);
Refusal answerPing(Session& s, const Input& in, ActionOutput& out);

// ---- Actions: the closed loop (verification_actions.cpp) ----

Refusal startConfirmation(Session& s, const Input& in, ActionOutput& out);
Refusal adoptConfirmation(Session& s, const Input& in, ActionOutput& out);
Refusal noteConfirmationFailure(Session& s, const Input& in, ActionOutput& out);
Refusal placeSeed(Session& s, const Input& in, ActionOutput& out);
Refusal acceptSeed(Session& s, const Input& in, ActionOutput& out);
Refusal rejectSeed(Session& s, const Input& in, ActionOutput& out);
Refusal fitTissue(Session& s, const Input& in, ActionOutput& out);
Refusal useTissue(Session& s, const Input& in, ActionOutput& out);
Refusal discardTissue(Session& s, const Input& in, ActionOutput& out);

// ---- Actions: re-planning during an insertion (replan_actions.cpp) ----

Refusal pauseAt(Session& s, const Input& in, ActionOutput& out);
Refusal startNeedleScan(Session& s, const Input& in, ActionOutput& out);
Refusal adoptNeedleScan(Session& s, const Input& in, ActionOutput& out);
Refusal noteNeedleScanFailure(Session& s, const Input& in, ActionOutput& out);
Refusal adoptReaim(Session& s, const Input& in, ActionOutput& out);

// ---- Actions: the patient's structures (anatomy_actions.cpp) ----

Refusal startStructureLoad(Session& s, const Input& in, ActionOutput& out);
Refusal adoptStructures(Session& s, const Input& in, ActionOutput& out);
Refusal noteStructureLoadFailure(Session& s, const Input& in, ActionOutput& out);
Refusal setStructureRole(Session& s, const Input& in, ActionOutput& out);
Refusal overrideClearance(Session& s, const Input& in, ActionOutput& out);
Refusal startTargetProposal(Session& s, const Input& in, ActionOutput& out);
Refusal startSeedPlan(Session& s, const Input& in, ActionOutput& out);
Refusal adoptProposals(Session& s, const Input& in, ActionOutput& out);
Refusal noteProposalFailure(Session& s, const Input& in, ActionOutput& out);
Refusal acceptProposals(Session& s, const Input& in, ActionOutput& out);
// plan_seeds' and compute_dose's words: [STRUCTURE] [model=] [rx=] [strength=] (and for a plan
// [spacing=] [implanted=], a structure required), each checked, the model among the site's, the
// structure a target; defaults: the site's dosimetry (for a dose, the accepted seed plan's).
struct SeedWords {
  SeedPlanAsk ask;
  double spacing_mm = 0.0;
  std::string structure;  // as the set names it; "" when none was given
};
Refusal readSeedWords(const Session& s, const std::string& text, bool planning, SeedWords& out);

// ---- Actions: the seeds' dose (dose_actions.cpp) ----

Refusal startDoseComputation(Session& s, const Input& in, ActionOutput& out);
Refusal adoptDose(Session& s, const Input& in, ActionOutput& out);
Refusal noteDoseFailure(Session& s, const Input& in, ActionOutput& out);
// The dose of the session's seeds again (after a seed plan is accepted, a confirmation CT
// measured): when the session knows its seeds' model (DoseStatus::seeds), the seeds as they are
// now are kept for the job (failed at once when there are none).
void recomputeDose(Session& s, const Input& in, const std::string& why, ActionOutput& out);

// ---- Actions: where to mount the robot (placement_actions.cpp) ----

Refusal startRobotPlacement(Session& s, const Input& in, ActionOutput& out);
Refusal adoptRobotPlacement(Session& s, const Input& in, ActionOutput& out);
Refusal noteRobotPlacementFailure(Session& s, const Input& in, ActionOutput& out);
Refusal adoptPlacementCheck(Session& s, const Input& in, ActionOutput& out);
Refusal notePlacementCheckFailure(Session& s, const Input& in, ActionOutput& out);

}  // namespace ignav::workflow::detail
