// The motion half of the reducer: approval requests, their checks, and the controller feedback
// that walks an approved motion to its target. Internal to modules/workflow; pure.
#pragma once

#include <optional>
#include <string>
#include <variant>

#include "ignav/workflow/reply_codes.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::workflow::detail {

using workflow::Rejection;

// The request for the next motion from the verified position: to the first target in plan order
// not reached yet, else the final retraction of the stylet. nullopt: nothing left to do.
// The joints at these motor positions, for planning from: what quantisation alone puts outside
// a joint range is put back on its limit.
kinematics::Joints currentJoints(const config::Robot& robot, const actuation::Steps& position);
Expected<std::optional<MotionRequest>> nextRequest(const Session& s, double time_s);

// Would nextRequest() find nothing left to move with the robot at `position` and `just_reached`
// counted as reached (0: none)? Every target reached and the stylet home. The guards that send a
// step to done ask it before the action that issues the request (guards.cpp).
bool nothingLeftToMove(const Session& s, const actuation::Steps& position,
                       std::uint32_t just_reached = 0);

// nextRequest() into `s.pending` (a plan id used), the approval state to publish. With nothing
// left to move, nothing is pending afterwards.
std::optional<Rejection> issueRequest(Session& s, const Input& in, Effects& e);

// The phases whose robot can be used: a controller fault there becomes the fault phase.
constexpr bool robotInUse(Phase p) {
  return p == Phase::kPlanLocked || p == Phase::kMoving || p == Phase::kAtTarget ||
         p == Phase::kDone;
}

// Where resume leads after an interruption now: a move in flight is never resumed as such, it is
// planned again from where the robot stands and approved again.
constexpr Phase resumeTo(Phase p) {
  return p == Phase::kMoving ? Phase::kPlanLocked : p;
}

// Where the move under way ends: its start plus its increments.
actuation::Steps moveEnd(const ActiveMotion& m);

// After a restart with the robot in use: why its position is in doubt ("" when it is not): the
// controller's fault or silence, the robot moving, or a position other than the last verified.
std::string restartDoubt(const Session& s, const Input& in);

// The record of the motion under way gets its end.
void endMotionRecord(Session& s, double time_s, const std::string& outcome);
// A motion under way stops being one (stop, emergency, fault, manual control, restart): its
// record ends with `why` (once), and it stays for the position check of reset and resume.
void interruptMotion(Session& s, Effects& e, double time_s, const std::string& why);

// What is wrong with the controller by `in`'s reading ("" when nothing is): its fault, no
// answer, or no reading at all.
std::string readingFault(const Input& in);

// Orders the unreached targets (unless the user fixed the order) and checks the rotation limit;
// on success `s.targets` is in plan order and `summary` says what was chosen.
std::optional<Rejection> orderPlan(Session& s, std::string& summary);

// The one maker of ApprovedMotion: the pending request, released by `in` (an approve), or why it
// cannot be.
struct ApprovalCheck {
  static std::variant<ApprovedMotion, Rejection> approve(const Session& s, const Input& in);
};

// The controller reading an input carried, checked for a robot at rest and usable.
std::optional<Rejection> checkAtRest(const Input& in);

// The position check for leaving stop, emergency or fault: the controller's reading must lie
// on the interrupted move (between where it started and where it was going, per motor) or, with
// no move interrupted, equal the last verified position.
std::optional<Rejection> checkPosition(const Session& s, const actuation::Steps& reading);

// "motor 2 reads 1200 steps, expected 1180 (+20)" for the first motor that differs.
std::string describeMismatch(const actuation::Steps& reading, const actuation::Steps& expected);

// "θc 30.00°, zc 10.000 mm, zs 26.000 mm": joints as the approval requests and re-aims show them.
std::string jointsText(const kinematics::Joints& joints);

// The text the digest covers: robot, session, plan id, target, start position and every
// increment. A session journaled before issue 38 has no robot id or random id: its text is v1.
std::string canonicalText(const MotionScope& scope, const MotionRequest& request);

}  // namespace ignav::workflow::detail
