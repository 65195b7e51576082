// The rows' actions for motion (actions.hpp): the approval that releases it, the controller's
// feedback that walks it to its target, the interruptions, the restart, the robot taken back.
#include <fmt/format.h>

#include <variant>

#include "actions.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {
namespace {

using actuation::ControllerState;

Refusal controllerFaultRefusal(const Input& in, const std::string& then = "") {
  if (in.controller->state != ControllerState::kFault) return std::nullopt;
  return Rejection{ReplyCode::kControllerFault,
                   "the controller reports a fault: " + in.controller->fault + then};
}

// The motion, if any, stays only as a record: the robot's position is taken as verified.
void forgetMotion(Session& s, Effects& e) {
  if (!s.motion) return;
  s.motion.reset();
  e.motion_changed = true;
}

// segment_done: a motion must be under way for any of its rows.
Refusal checkMotion(const Session& s) {
  if (!s.motion) return Rejection{ReplyCode::kInternal, "no motion is under way"};
  return std::nullopt;
}

// segment_done's rows that take the move's end as the position: the controller at rest exactly
// there. The arrival check is the guard of the row before them (arrivalMismatch); it is made
// again here so that no order of rows can verify a position the controller does not report.
Refusal checkArrived(const Session& s, const Input& in) {
  if (auto none = checkMotion(s)) return none;
  if (!in.controller || in.controller->state == ControllerState::kMoving) {
    return Rejection{ReplyCode::kInternal, "segment_done while the controller still moves"};
  }
  if (in.controller->position != moveEnd(*s.motion)) {
    return Rejection{ReplyCode::kInternal, "segment_done away from the move's end"};
  }
  return std::nullopt;
}

// The last move ended where it should: the position is verified and the motion is over.
void endMotion(Session& s, const Input& in, Effects& e) {
  e.motion_changed = true;
  s.position = moveEnd(*s.motion);
  s.motion.reset();
  endMotionRecord(s, in.time_s, "arrived");
}

// Whatever moves when the server starts moves without a live approval: halt it.
void haltIfMoving(const Input& in, Effects& e) {
  if (in.controller && in.controller->state == ControllerState::kMoving) {
    e.controller.push_back(ControllerCommand::abort());
  }
}

}  // namespace

Refusal startApprovedMotion(Session& s, const Input& in, ActionOutput& out) {
  auto approved = ApprovalCheck::approve(s, in);
  if (auto* refused = std::get_if<Rejection>(&approved)) return *refused;
  ActiveMotion m{std::get<ApprovedMotion>(std::move(approved)), 0, s.pending->from, false};
  Effects& e = out.effects;
  s.pending.reset();
  e.approval_changed = e.motion_changed = true;
  e.controller.push_back(ControllerCommand::move(m.approved, 0));
  out.note = fmt::format("plan {} approved: {} move(s), about {:.1f} s", m.request().plan_id,
                         m.request().moves.size(), m.request().duration_s);
  s.motions.push_back({m.request().plan_id, m.request().target_id,
                       in.identity.empty() ? in.client_id : in.identity, in.time_s, -1.0, ""});
  s.motion = std::move(m);
  return std::nullopt;
}

Refusal faultDuringMove(Session& s, const Input& in, ActionOutput& out) {
  if (auto none = checkMotion(s)) return none;
  const ActiveMotion& m = *s.motion;
  const std::string fault = readingFault(in);
  s.fault = fmt::format("controller fault during {} of plan {}: {}",
                        planning::toString(m.request().moves[m.segment].kind), m.request().plan_id,
                        fault);
  interruptMotion(s, out.effects, in.time_s, "fault: " + fault);
  s.resume_phase = Phase::kPlanLocked;
  out.effects.controller.push_back(ControllerCommand::abort());
  return std::nullopt;
}

Refusal failArrivalCheck(Session& s, const Input& in, ActionOutput& out) {
  if (auto none = checkMotion(s)) return none;
  const ActiveMotion& m = *s.motion;
  s.fault = fmt::format("arrival check failed after {} of plan {}: {}",
                        planning::toString(m.request().moves[m.segment].kind), m.request().plan_id,
                        describeMismatch(in.controller->position, moveEnd(m)));
  interruptMotion(s, out.effects, in.time_s, "fault: arrival check failed");
  s.resume_phase = Phase::kPlanLocked;
  return std::nullopt;
}

Refusal startNextMove(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = checkArrived(s, in)) return refused;
  ActiveMotion& m = *s.motion;
  if (m.segment + 1 >= m.request().moves.size()) {  // moreMovesFollow() said otherwise
    return Rejection{ReplyCode::kInternal, "no move of the motion follows"};
  }
  out.effects.motion_changed = true;
  s.position = moveEnd(m);
  m.segment_from = s.position;
  ++m.segment;
  out.effects.controller.push_back(ControllerCommand::move(m.approved, m.segment));
  return std::nullopt;
}

Refusal endRetraction(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = checkArrived(s, in)) return refused;
  endMotion(s, in, out.effects);
  return std::nullopt;
}

// At a target: it is reached, and the request for what comes next (the next target, or the final
// retraction; none when the stylet is home after the last target) awaits approval.
Refusal arriveAtTarget(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = checkArrived(s, in)) return refused;
  const std::uint32_t target = s.motion->request().target_id;
  const std::optional<double> pause = s.motion->request().pause_z_s_mm;
  endMotion(s, in, out.effects);
  Target* paused = pause ? findTarget(s, target) : nullptr;
  if (paused) {  // stopped part-way: the rest waits for an approval of its own
    kinematics::Joints at = paused->commandedJoints();
    at.z_s_mm = *pause;
    paused->paused = at;
    out.effects.targets_changed.push_back(target);
  } else if (Target* t = findTarget(s, target)) {
    t->reached = true;
    t->reached_s = in.time_s;
    t->reached_joints = t->commandedJoints();
    out.effects.targets_changed.push_back(target);
    out.effects.reached_target_slices = target;
  }
  return issueRequest(s, in, out.effects);
}

Refusal faultStopsTheRobot(Session& s, const Input& in, ActionOutput& out) {
  s.fault = readingFault(in);
  out.effects.controller.push_back(ControllerCommand::abort());
  interruptMotion(s, out.effects, in.time_s, "fault: " + s.fault);
  s.resume_phase = resumeTo(s.phase);
  return std::nullopt;
}

// The robot is not in use: the fault is recorded; approvals and resets check the controller
// themselves.
Refusal noteControllerFault(Session& s, const Input& in, ActionOutput& out) {
  s.fault = readingFault(in);
  out.effects.controller.push_back(ControllerCommand::abort());
  interruptMotion(s, out.effects, in.time_s, "fault: " + s.fault);
  return std::nullopt;
}

// A move was in flight when the server went down: it goes on without a live approval, or stalled
// somewhere; halted either way, and the position is checked at reset.
Refusal restartedMidMotion(Session& s, const Input& in, ActionOutput& out) {
  out.effects.controller.push_back(ControllerCommand::abort());
  interruptMotion(s, out.effects, in.time_s, "server restarted");
  s.fault = fmt::format("the server restarted during plan {}: check the position and reset",
                        s.motion ? s.motion->request().plan_id : 0);
  s.resume_phase = Phase::kPlanLocked;
  return std::nullopt;
}

Refusal restartedInDoubt(Session& s, const Input& in, ActionOutput& out) {
  haltIfMoving(in, out.effects);
  s.fault = restartDoubt(s, in);
  s.resume_phase = s.phase;
  return std::nullopt;
}

// The robot is where it was left: a request waiting for approval before the crash is issued
// afresh (approvals never survive a restart, safety invariant 2).
Refusal restartedRobotInPlace(Session& s, const Input& in, ActionOutput& out) {
  haltIfMoving(in, out.effects);
  if (s.phase != Phase::kPlanLocked && s.phase != Phase::kAtTarget) return std::nullopt;
  return issueRequest(s, in, out.effects);
}

// The robot is not in use: resume and reset check it when it is taken up again.
Refusal restartedIdle(Session&, const Input& in, ActionOutput& out) {
  haltIfMoving(in, out.effects);
  return std::nullopt;
}

Refusal stop(Session& s, const Input& in, ActionOutput& out) {
  s.resume_phase = resumeTo(s.phase);
  if (s.motion) {
    out.effects.controller.push_back(ControllerCommand::stop());
    interruptMotion(s, out.effects, in.time_s, "stopped");
  }
  return std::nullopt;
}

// A stop while the robot is already interrupted (stopped, manual, emergency, fault): a stop
// button must always stop, so the controller is told to halt again (a hand jog in manual, a
// motor still coasting); the phase, and where resume would return, stay.
Refusal haltInPlace(Session&, const Input&, ActionOutput& out) {
  out.effects.controller.push_back(ControllerCommand::stop());
  out.note = "halted; the robot stays interrupted";
  return std::nullopt;
}

Refusal emergencyStop(Session& s, const Input& in, ActionOutput& out) {
  out.effects.controller.push_back(ControllerCommand::abort());  // whatever moves, halt it
  interruptMotion(s, out.effects, in.time_s, "emergency stop");
  // Taken while interrupted (stopped, manual, fault), the first interruption's phase stays.
  if (!isInterruption(s.phase)) s.resume_phase = resumeTo(s.phase);
  return std::nullopt;
}

Refusal handOverTheRobot(Session& s, const Input& in, ActionOutput& out) {
  if (!isInterruption(s.phase)) s.resume_phase = resumeTo(s.phase);  // manual after a stop
  out.effects.controller.push_back(ControllerCommand::stop());
  interruptMotion(s, out.effects, in.time_s, "manual control");
  out.note = "manual control: the robot may be moved by hand; resume takes it back";
  return std::nullopt;
}

Refusal checkReadiness(Session& s, const Input& in, ActionOutput& out) {
  if (auto busy = checkAtRest(in)) return busy;
  if (auto fault = controllerFaultRefusal(in)) return fault;
  if (in.path == "targeting" && !s.registration) {
    return Rejection{ReplyCode::kNotRegistered,
                     "no registration yet: register the image to the robot first"};
  }
  out.note = in.path == "robot" ? "the robot is ready" : "ready for targets";
  return std::nullopt;
}

// Back to the phase the first interruption left (the rows' guards, resumesTo<>, pick which); a
// phase that waits for an approval gets a fresh request from where the robot stands.
Refusal resume(Session& s, const Input& in, ActionOutput& out) {
  Effects& e = out.effects;
  if (s.phase == Phase::kManual) {
    // Back from manual control: where the hands left the motors becomes the position.
    if (auto busy = checkAtRest(in)) return busy;
    if (auto fault = controllerFaultRefusal(in)) return fault;
    if (s.position != in.controller->position) e.motion_changed = true;
    s.position = in.controller->position;
    forgetMotion(s, e);
  }
  if (s.resume_phase != Phase::kPlanLocked && s.resume_phase != Phase::kAtTarget) {
    return std::nullopt;
  }
  if (auto busy = checkAtRest(in)) return busy;
  if (auto fault = controllerFaultRefusal(in, "; emergency stop, then reset")) return fault;
  if (auto off = checkPosition(s, in.controller->position)) return off;
  s.position = in.controller->position;
  forgetMotion(s, e);
  if (auto refused = issueRequest(s, in, e)) return refused;
  out.note = s.pending ? "waiting for approval of " + s.pending->summary : "nothing left to do";
  return std::nullopt;
}

Refusal resetAfterPositionCheck(Session& s, const Input& in, ActionOutput& out) {
  if (auto busy = checkAtRest(in)) return busy;
  if (auto off = checkPosition(s, in.controller->position)) return off;
  s.position = in.controller->position;
  forgetMotion(s, out.effects);
  if (in.controller->state == ControllerState::kFault) {
    out.effects.controller.push_back(ControllerCommand::clearFault());
  }
  s.fault.clear();
  out.note = fmt::format("position checked: motors at {} / {} / {} steps", s.position.motor[0],
                         s.position.motor[1], s.position.motor[2]);
  return std::nullopt;
}

Refusal adoptHome(Session& s, const Input& in, ActionOutput& out) {
  if (auto busy = checkAtRest(in)) return busy;
  out.effects.controller.push_back(ControllerCommand::home());
  s.position = {};
  forgetMotion(s, out.effects);
  out.note = "the present position is home now (zero steps on every motor)";
  return std::nullopt;
}

Refusal republishEverything(Session& s, const Input&, ActionOutput& out) {
  Effects& e = out.effects;
  e.robot_changed = e.volume_changed = e.registration_changed = true;
  e.approval_changed = e.motion_changed = true;
  for (const auto& t : s.targets)
    e.targets_changed.push_back(t.id);
  return std::nullopt;
}

// The time the server stamped on the input as it took it; the reply carries the revision.
Refusal answerPing(Session& s, const Input& in, ActionOutput& out) {
  out.note = fmt::format("server_time_unix_s={:.6f} revision={}", in.time_s, s.revision);
  return std::nullopt;
}

}  // namespace ignav::workflow::detail
