#include "motion.hpp"

#include "ignav/workflow/reducer.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace ignav::workflow::detail {

kinematics::Joints currentJoints(const config::Robot& robot, const actuation::Steps& position) {
  kinematics::Joints j = robot.transmission.toJoints(position);
  const auto& g = robot.kinematics.instrument();
  // Within one step of a limit, outside it: the coupled transmission reaches zs = 0 as
  // -0.17 µm, say. Such a pose is on the limit, not a pose no plan may start from
  // (docs/RELIABILITY.md, K1); a stalled motor leaves the robot much further out.
  auto snap = [](double& v, double hi, double one_step) {
    if (v < 0.0 && v > -one_step) v = 0.0;
    if (v > hi && v < hi + one_step) v = hi;
  };
  snap(j.z_c_mm, g.cannula_travel_mm, 1.0 / robot.transmission.cannulaStepsPerMm());
  snap(j.z_s_mm, g.stylet_travel_mm, 1.0 / robot.transmission.styletStepsPerMm());
  return j;
}
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

std::string stepsText(const actuation::Steps& s) {
  return fmt::format("{} {} {}", s.motor[0], s.motor[1], s.motor[2]);
}

// What the controller's profile makes of one move: the slowest motor's trapezoid.
double controllerDuration_s(const actuation::Steps& increments, const ApprovalPolicy& policy) {
  double longest = 0.0;
  for (auto d : increments.motor) {
    longest = std::max(longest,
                       actuation::trapezoidDuration_s(static_cast<double>(d), policy.speed_steps_s,
                                                      policy.acceleration_steps_s2));
  }
  return longest;
}

std::vector<planning::PlannedTarget> unreached(const Session& s) {
  std::vector<planning::PlannedTarget> out;
  for (const auto& t : s.targets) {
    if (!t.reached) out.push_back({t.id, t.commandedJoints()});
  }
  return out;
}

// Where the next motion to `t` ends: part-way when it is to stop first (pause_at) and has not.
std::optional<double> pendingPause(const Target& t) {
  if (!t.pause_z_s_mm || t.paused || *t.pause_z_s_mm >= t.commandedJoints().z_s_mm) {
    return std::nullopt;
  }
  return t.pause_z_s_mm;
}

std::string pointText(const Eigen::Vector3d& p) {
  return fmt::format("({:.3f}, {:.3f}, {:.3f})", p.x(), p.y(), p.z());
}

std::string clearanceText(const Target& t) {
  if (t.clearances.empty()) return "";
  std::string out = "; clearance of the whole needle:";
  for (const auto& c : t.clearances) {
    out += fmt::format(" {} {}{:.2f} mm at the {} (margin {:g} mm, uncertainty {:.2f} mm){};",
                       c.structure, c.beyond_reach ? "over " : "", c.distance_mm, c.part,
                       c.margin_mm, c.uncertainty_mm, c.tooClose() ? " TOO CLOSE" : "");
  }
  out.pop_back();
  if (!t.clearance_override.empty()) {
    out += fmt::format("; CLEARANCE OVERRIDDEN by the operator: \"{}\"", t.clearance_override);
  }
  return out;
}

// What the operator approves for a target: the joints, and what they depart from.
std::string aimText(const Target& t) {
  const auto& j = t.commandedJoints();
  // A registration given as a matrix has no fiducials to estimate the TRE from.
  const std::string tre = std::isnan(t.tre_mm) ? std::string("TRE unknown (registered by matrix)")
                                               : fmt::format("expected TRE {:.2f} mm", t.tre_mm);
  std::string where = fmt::format("T{} ({}, {})", t.id, jointsText(j), tre);
  if (t.reaimed) {  // nominal, previously aimed and re-aimed, each with its predicted landing
    const auto& r = *t.reaimed;
    where += fmt::format(
        ", re-aimed from {} (nominal {}; previously aimed {}, predicted to land {} mm robot, "
        "{:.2f} mm from the target; re-aimed lands {} mm robot, {:.4f} mm from it)",
        r.how == "path" ? "this needle's path on the intermittent CT"
                        : "the tissue refitted with a needle's path",
        jointsText(t.solution.joints), jointsText(r.before), pointText(r.before_landing_robot_mm),
        (r.before_landing_robot_mm - t.robot_mm).norm(), pointText(r.landing_robot_mm),
        (r.landing_robot_mm - t.robot_mm).norm());
  } else if (t.compensated) {  // the operator approves the aim, and sees what it departs from
    const auto& c = *t.compensated;
    where += fmt::format(
        ", compensated for tissue '{}' (nominal {} would land {:.2f} mm off; predicted landing "
        "{} mm robot, {:.4f} mm from the target)",
        c.profile, jointsText(t.solution.joints), (c.nominal_landing_robot_mm - t.robot_mm).norm(),
        pointText(c.landing_robot_mm), c.residual_mm);
  }
  return where;
}

// The final retraction from `position`: the stylet home, cannula where it is.
struct Retraction {
  kinematics::Joints from, to;
  actuation::Steps steps;  // zero when the stylet is home already
};
Retraction retraction(const config::Robot& robot, const actuation::Steps& position) {
  Retraction r;
  r.from = currentJoints(robot, position);
  r.to = r.from;
  r.to.z_s_mm = 0.0;
  r.steps = robot.transmission.move(r.from, r.to).steps;
  return r;
}

}  // namespace

std::string jointsText(const kinematics::Joints& j) {
  return fmt::format("θc {:.2f}°, zc {:.3f} mm, zs {:.3f} mm", j.theta_c_rad * kRadToDeg, j.z_c_mm,
                     j.z_s_mm);
}

std::string canonicalText(const MotionScope& scope, const MotionRequest& r) {
  std::string text = scope.session_uuid.empty()
                         ? fmt::format("ignav motion request v1\nsession {}\n", scope.session_id)
                         : fmt::format("ignav motion request v2\nrobot {}\nsession {} {}\n",
                                       scope.robot_id, scope.session_id, scope.session_uuid);
  text += fmt::format("plan {}\ntarget {}\nfrom {}\n", r.plan_id, r.target_id, stepsText(r.from));
  // Only a motion that stops part-way says so: the texts of every other stay as they were.
  if (r.pause_z_s_mm) text += fmt::format("pause stylet {:.6f} mm\n", *r.pause_z_s_mm);
  for (const auto& m : r.moves) {
    text += fmt::format("move {} {}\n", planning::toString(m.kind), stepsText(m.steps));
  }
  return text;
}

}  // namespace ignav::workflow::detail

namespace ignav::workflow {

std::string requestDigest(const MotionScope& scope, const MotionRequest& request) {
  return sha256Hex(detail::canonicalText(scope, request));
}

MotionScope scopeOf(const Session& session) {
  return {session.robot_id, session.session_id, session.session_uuid};
}

std::string sha256Hex(const std::string& text) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_Digest(text.data(), text.size(), digest, &length, EVP_sha256(), nullptr);
  std::string hex;
  for (unsigned int i = 0; i < length; ++i)
    hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

}  // namespace ignav::workflow

namespace ignav::workflow::detail {

Expected<std::optional<MotionRequest>> nextRequest(const Session& s, double time_s) {
  const auto& robot = *s.robot;
  const kinematics::Joints start = currentJoints(robot, s.position);
  MotionRequest r;
  r.plan_id = s.next_plan_id;
  r.from = s.position;
  const auto todo = unreached(s);
  std::string where;
  if (!todo.empty()) {
    const Target& t = *std::find_if(s.targets.begin(), s.targets.end(),
                                    [&](const Target& x) { return x.id == todo.front().id; });
    planning::PlannedTarget goal = todo.front();
    r.pause_z_s_mm = pendingPause(t);
    if (r.pause_z_s_mm) goal.joints.z_s_mm = *r.pause_z_s_mm;
    r.target_id = t.id;
    if (t.paused && !r.pause_z_s_mm) {
      // The insertion goes on from where it stopped: where the cannula stays (to the step), only
      // the stylet moves; a re-aim that turns or moves the cannula draws the stylet in first.
      kinematics::Joints in_place = start;
      in_place.z_s_mm = goal.joints.z_s_mm;
      const auto direct = robot.transmission.move(start, goal.joints).steps;
      if (direct == robot.transmission.move(start, in_place).steps) {
        const auto kind = goal.joints.z_s_mm >= start.z_s_mm ? planning::MoveKind::kDeployStylet
                                                             : planning::MoveKind::kRetractStylet;
        r.moves.push_back({kind, start, goal.joints, direct, 0.0});
      }
    }
    if (r.moves.empty()) {
      auto plan = planning::planInsertion(robot.kinematics, robot.transmission, {goal}, start,
                                          s.policy.limits);
      if (!plan) return plan.error();
      r.moves = plan->motions.front().moves;
    }
    r.tre_mm = t.tre_mm;
    where = aimText(t);
    if (r.pause_z_s_mm) {
      where = fmt::format(
          "part-way to {}: the stylet stops {:.3f} mm out (pause_at) for an intermittent CT "
          "(scan_needle); the rest is approved of its own",
          where, *r.pause_z_s_mm);
    } else if (t.paused) {
      where = "the rest of the insertion to " + where;
    }
    where += clearanceText(t);
  } else {
    const Retraction back = retraction(robot, s.position);
    if (back.steps == actuation::Steps{}) return std::optional<MotionRequest>{};
    r.moves.push_back({planning::MoveKind::kRetractStylet, back.from, back.to, back.steps, 0.0});
    where = "retract the stylet after the last target";
  }
  std::string moves;
  for (auto& m : r.moves) {
    m.duration_s = controllerDuration_s(m.steps, s.policy);
    r.duration_s += m.duration_s;
    moves += fmt::format("{}{} [{}]", moves.empty() ? "" : ", ", planning::toString(m.kind),
                         stepsText(m.steps));
  }
  r.issued_s = time_s;
  r.expires_s = time_s + s.policy.expiry_s;
  r.digest = requestDigest(scopeOf(s), r);
  r.summary = fmt::format("plan {}: {}; steps per motor {}; about {:.1f} s", r.plan_id, where,
                          moves, r.duration_s);
  return std::optional<MotionRequest>{std::move(r)};
}

bool nothingLeftToMove(const Session& s, const actuation::Steps& position,
                       std::uint32_t just_reached) {
  const bool all_reached = std::all_of(s.targets.begin(), s.targets.end(), [&](const Target& t) {
    return t.reached || t.id == just_reached;
  });
  return all_reached && retraction(*s.robot, position).steps == actuation::Steps{};
}

std::optional<Rejection> issueRequest(Session& s, const Input& in, Effects& e) {
  auto next = nextRequest(s, in.time_s);
  if (!next) return Rejection{ReplyCode::kPlanFailed, next.error().message};
  e.approval_changed = true;
  if (!next->has_value()) return std::nullopt;
  s.pending = std::move(**next);
  ++s.next_plan_id;
  return std::nullopt;
}

void endMotionRecord(Session& s, double time_s, const std::string& outcome) {
  if (s.motions.empty() || s.motions.back().ended_s >= 0.0) return;
  s.motions.back().ended_s = time_s;
  s.motions.back().outcome = outcome;
}

void interruptMotion(Session& s, Effects& e, double time_s, const std::string& why) {
  if (!s.motion) return;
  if (!s.motion->interrupted) endMotionRecord(s, time_s, why);
  s.motion->interrupted = true;
  e.motion_changed = true;
}

std::string readingFault(const Input& in) {
  if (!in.controller) return in.error.empty() ? "no controller reading" : in.error;
  if (!in.controller->fault.empty()) return in.controller->fault;
  return in.controller->state == actuation::ControllerState::kDisconnected
             ? "the controller does not answer"
             : std::string();
}

actuation::Steps moveEnd(const ActiveMotion& m) {
  return m.segment_from + m.request().moves[m.segment].steps;
}

std::string restartDoubt(const Session& s, const Input& in) {
  if (std::string fault = readingFault(in); !fault.empty()) return fault;
  if (in.controller->state == actuation::ControllerState::kMoving) {
    return "the robot was moving when the server started";
  }
  if (in.controller->position != s.position) {
    return "after the restart " + describeMismatch(in.controller->position, s.position);
  }
  return "";
}

std::optional<Rejection> orderPlan(Session& s, std::string& summary) {
  const auto& robot = *s.robot;
  const kinematics::Joints start = currentJoints(robot, s.position);
  const auto todo = unreached(s);
  planning::Ordering ordering;
  if (s.order_fixed) {
    std::vector<std::size_t> as_given(todo.size());
    for (std::size_t i = 0; i < todo.size(); ++i)
      as_given[i] = i;
    ordering = planning::evaluateOrder(todo, as_given, start, s.policy.limits);
  } else {
    ordering = planning::orderTargets(todo, start, s.policy.limits);
  }
  const double limit = s.policy.limits.max_total_rotation_rad;
  if (ordering.total_rotation_rad > limit + 1e-12) {
    return Rejection{ReplyCode::kRotationLimit,
                     fmt::format("this order turns the cannula {:.1f}° in all, more than {:.1f}°{}",
                                 ordering.total_rotation_rad * kRadToDeg, limit * kRadToDeg,
                                 s.order_fixed ? "; reorder the targets or let the server order "
                                                 "them (clear and add them again)"
                                               : "")};
  }
  std::vector<Target> ordered;
  for (const auto& t : s.targets) {
    if (t.reached) ordered.push_back(t);
  }
  std::string ids;
  for (std::size_t i : ordering.order) {
    const auto id = todo[i].id;
    ordered.push_back(*std::find_if(s.targets.begin(), s.targets.end(),
                                    [&](const Target& t) { return t.id == id; }));
    ids += (ids.empty() ? "T" : ", T") + std::to_string(id);
  }
  s.targets = std::move(ordered);
  summary = todo.empty() ? std::string("every target reached")
                         : fmt::format(
                               "order {} ({}): cannula rotation {:.1f}° of {:.0f}°, about "
                               "{:.0f} s of motion",
                               ids, s.order_fixed ? "as given" : "chosen by the server",
                               ordering.total_rotation_rad * kRadToDeg, limit * kRadToDeg,
                               ordering.duration_s);
  return std::nullopt;
}

std::optional<Rejection> checkAtRest(const Input& in) {
  if (!in.controller || in.controller->state == actuation::ControllerState::kDisconnected) {
    return Rejection{
        ReplyCode::kControllerUnavailable,
        "the controller does not answer" + (in.controller && !in.controller->fault.empty()
                                                ? ": " + in.controller->fault
                                                : std::string())};
  }
  if (in.controller->state == actuation::ControllerState::kMoving) {
    return Rejection{ReplyCode::kControllerBusy,
                     "the robot is still moving; wait until it is at rest"};
  }
  return std::nullopt;
}

std::string describeMismatch(const actuation::Steps& reading, const actuation::Steps& expected) {
  for (std::size_t m = 0; m < 3; ++m) {
    if (reading.motor[m] != expected.motor[m]) {
      return fmt::format("motor {} reads {} steps, expected {} ({:+})", m + 1, reading.motor[m],
                         expected.motor[m], reading.motor[m] - expected.motor[m]);
    }
  }
  return "every motor where expected";
}

std::optional<Rejection> checkPosition(const Session& s, const actuation::Steps& reading) {
  if (!s.motion || !s.motion->interrupted) {
    if (reading == s.position) return std::nullopt;
    return Rejection{ReplyCode::kPositionMismatch,
                     "position check failed: " + describeMismatch(reading, s.position) +
                         "; bring the robot home and send home, then reset"};
  }
  const auto& m = *s.motion;
  const auto& from = m.segment_from.motor;
  const auto& inc = m.request().moves[m.segment].steps.motor;
  for (std::size_t a = 0; a < 3; ++a) {
    const auto lo = std::min(from[a], from[a] + inc[a]);
    const auto hi = std::max(from[a], from[a] + inc[a]);
    if (reading.motor[a] < lo || reading.motor[a] > hi) {
      return Rejection{
          ReplyCode::kPositionMismatch,
          fmt::format("position check failed: motor {} reads {} steps, off the interrupted {} "
                      "from {} to {}; bring the robot home and send home, then reset",
                      a + 1, reading.motor[a],
                      planning::toString(m.request().moves[m.segment].kind), from[a],
                      from[a] + inc[a])};
    }
  }
  return std::nullopt;
}

namespace {

std::optional<Rejection> checkApproval(const Session& s, const Input& in) {
  if (!s.pending)
    return Rejection{ReplyCode::kNoPendingApproval, "no motion is waiting for approval"};
  const auto& p = *s.pending;
  const auto& approvers = s.policy.approvers;
  const auto listed = [&](const std::string& who) {
    return !who.empty() && std::find(approvers.begin(), approvers.end(), who) != approvers.end();
  };
  if (!listed(in.client_id) && !listed(in.identity)) {
    std::string list;
    for (const auto& a : approvers)
      list += (list.empty() ? "" : ", ") + a;
    return Rejection{ReplyCode::kNotApprover,
                     fmt::format("client '{}'{} may not approve motion (approvers: {})",
                                 in.client_id, in.identity.empty() ? "" : " (" + in.identity + ")",
                                 list.empty() ? "none configured" : list)};
  }
  if (in.plan_id != p.plan_id) {
    return Rejection{
        ReplyCode::kStalePlan,
        fmt::format("plan {} is not the pending request; plan {} is", in.plan_id, p.plan_id)};
  }
  if (in.digest != p.digest) {
    return Rejection{ReplyCode::kWrongDigest,
                     fmt::format("the digest does not match plan {}: approve exactly what the "
                                 "request shows",
                                 p.plan_id)};
  }
  if (in.time_s > p.expires_s) {
    return Rejection{ReplyCode::kExpired,
                     fmt::format("plan {} expired {:.1f} s ago; request_approval for a "
                                 "fresh one",
                                 p.plan_id, in.time_s - p.expires_s)};
  }
  if (auto busy = checkAtRest(in)) return busy;
  if (in.controller->state == actuation::ControllerState::kFault) {
    return Rejection{ReplyCode::kControllerFault,
                     "the controller reports a fault: " + in.controller->fault};
  }
  if (in.controller->position != p.from) {
    return Rejection{ReplyCode::kControllerChanged,
                     fmt::format("the robot is not where plan {} starts: {}", p.plan_id,
                                 describeMismatch(in.controller->position, p.from))};
  }
  return std::nullopt;
}

}  // namespace

std::variant<ApprovedMotion, Rejection> ApprovalCheck::approve(const Session& s, const Input& in) {
  if (auto rejected = checkApproval(s, in)) return *rejected;
  return ApprovedMotion(scopeOf(s), *s.pending);
}

}  // namespace ignav::workflow::detail

namespace ignav::workflow {

const char* toString(ControllerAction action) {
  switch (action) {
    case ControllerAction::kMove:
      return "move";
    case ControllerAction::kStop:
      return "stop";
    case ControllerAction::kAbort:
      return "abort";
    case ControllerAction::kHome:
      return "home";
    case ControllerAction::kClearFault:
      return "clear_fault";
  }
  return "unknown";
}

bool ApprovedMotion::intact() const {
  return requestDigest(scope_, request_) == request_.digest;
}

ControllerCommand ControllerCommand::move(const ApprovedMotion& approved, std::size_t segment) {
  ControllerCommand c(ControllerAction::kMove);
  c.increments_ = approved.request().moves.at(segment).steps;
  c.approved_ = approved;
  c.segment_ = segment;
  return c;
}

actuation::Steps ControllerCommand::segmentStart() const {
  if (!approved_) return {};
  const auto& request = approved_->request();
  actuation::Steps start = request.from;
  for (std::size_t k = 0; k < segment_ && k < request.moves.size(); ++k)
    start = start + request.moves[k].steps;
  return start;
}

bool ControllerCommand::releasable() const {
  if (action_ != ControllerAction::kMove) return true;
  if (!approved_ || !approved_->intact()) return false;
  const auto& moves = approved_->request().moves;
  return segment_ < moves.size() && moves[segment_].steps == increments_;
}

}  // namespace ignav::workflow
