// The guards of the transition rows (actions.hpp): pure predicates on the session and the input
// that pick which row of a (phase, input) pair fires, before any action runs. Where an action
// computes what decides the outcome (a registration, an arrival check, the next request), the
// guard computes the same thing with the same helper: twice, but never out of step.
#include "actions.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {

bool isFormatOneRecord(const Session&, const Input& in) {
  return in.journal_format == 1;
}

bool markersRegister(const Session& s, const Input& in) {
  return s.robot && registerOnRobot(*s.robot, in.points).ok();
}

bool readingReportsFault(const Session&, const Input& in) {
  return !readingFault(in).empty();
}

bool arrivalMismatch(const Session& s, const Input& in) {
  if (!s.motion || !in.controller || in.controller->state == actuation::ControllerState::kMoving) {
    return false;  // no arrival to check (the action refuses the segment_done)
  }
  return in.controller->position != moveEnd(*s.motion);
}

bool moreMovesFollow(const Session& s, const Input&) {
  return s.motion && s.motion->segment + 1 < s.motion->request().moves.size();
}

bool retractionEnded(const Session& s, const Input&) {
  return s.motion && s.motion->request().target_id == 0;
}

// The last move to a target ended: with every other target reached and the stylet home there
// (a target at zs = 0), no retraction is left to approve.
bool nothingLeftAfterArrival(const Session& s, const Input&) {
  // A motion that stops part-way reaches nothing.
  return s.motion && s.robot && !s.motion->request().pause_z_s_mm &&
         nothingLeftToMove(s, moveEnd(*s.motion), s.motion->request().target_id);
}

bool positionInDoubt(const Session& s, const Input& in) {
  return !restartDoubt(s, in).empty();
}

Phase resumeDestination(const Session& s, const Input& in) {
  const Phase back = s.resume_phase;
  if (back != Phase::kPlanLocked && back != Phase::kAtTarget) return back;
  // resume adopts the controller's position and requests the next motion from there (without a
  // reading it refuses, whatever the row).
  const actuation::Steps& at = in.controller ? in.controller->position : s.position;
  return s.robot && nothingLeftToMove(s, at) ? Phase::kDone : back;
}

}  // namespace ignav::workflow::detail
