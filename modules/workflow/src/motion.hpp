// The motion half of the reducer: approval requests, their checks, and the controller feedback
// that walks an approved motion to its target. Internal to modules/workflow; pure.
#pragma once

#include <optional>
#include <string>
#include <variant>

#include "ignav/workflow/reply_codes.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::workflow::detail {

struct Rejection {
  ReplyCode code;
  std::string message;
};

// The request for the next motion from the verified position: to the first target in plan order
// not reached yet, else the final retraction of the stylet. nullopt: nothing left to do.
// The joints at these motor positions, for planning from: what quantisation alone puts outside
// a joint range is put back on its limit.
kinematics::Joints currentJoints(const config::Robot& robot, const actuation::Steps& position);
Expected<std::optional<MotionRequest>> nextRequest(const Session& s, double time_s);

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

// The text the digest covers: session, plan id, target, start position and every increment.
std::string canonicalText(const std::string& session_id, const MotionRequest& request);

}  // namespace ignav::workflow::detail
