#include "state_publisher.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "ignav/workflow/reducer.hpp"

namespace ignav::server {
namespace {

namespace protocol = ignav::protocol;
using protocol::toPoint3;
using protocol::toPoints3;
using workflow::Session;

template <typename Motor>
protocol::MotorSteps stepsOf(const Motor& m) {
  return m.motor;
}

constexpr const char* kVersion = "0.1.0";

}  // namespace

StatePublisher::StatePublisher(const protocol::Participant& p, std::string controller_name,
                               std::filesystem::path session_dir)
    : workflow_(p),
      robot_(p),
      volume_(p),
      registration_(p),
      target_(p),
      health_(p),
      approval_(p),
      motion_(p),
      controller_name_(std::move(controller_name)),
      session_dir_(session_dir.string()),
      started_(Clock::now()) {}

double StatePublisher::uptimeS() const {
  return std::chrono::duration<double>(Clock::now() - started_).count();
}

void StatePublisher::publishEffects(const Session& s, const workflow::Effects& e,
                                    const Readings& r) {
  if (e.robot_changed) publishRobot(s);
  if (e.volume_changed) publishVolume(s, r.load_progress);
  if (e.registration_changed) publishRegistration(s);
  for (auto id : e.targets_removed)
    disposeTarget(id);
  for (auto id : e.targets_changed)
    publishTarget(s, id);
  if (e.approval_changed) publishApproval(s);
  if (e.motion_changed || !e.controller.empty()) publishMotion(s, r.controller, r.lifecycle);
  if (e.workflow_changed) publishWorkflow(s);
}

void StatePublisher::publishEverything(const Session& s, const Readings& r) {
  publishRobot(s);
  publishVolume(s, r.load_progress);
  publishRegistration(s);
  for (const auto& t : s.targets)
    publishTarget(s, t.id);
  publishApproval(s);
  publishWorkflow(s);
}

void StatePublisher::publishApproval(const Session& s) {
  protocol::ApprovalState a;
  a.status = "none";
  a.approvers = s.policy.approvers;
  if (const auto& p = s.pending) {
    a.status = "pending";
    a.plan_id = p->plan_id;
    a.digest = p->digest;
    a.target_id = p->target_id;
    a.summary = p->summary;
    a.from_steps = stepsOf(p->from);
    for (const auto& move : p->moves)
      a.moves.push_back({planning::toString(move.kind), stepsOf(move.steps), move.duration_s});
    a.duration_s = p->duration_s;
    a.tre_mm = p->tre_mm;
    a.expires_at_unix_s = p->expires_s;
    a.expires_in_s = p->expires_s - wallS();
  }
  approval_.write(a);
}

void StatePublisher::publishMotion(const Session& s, const actuation::ControllerStatus& r,
                                   const char* lifecycle) {
  protocol::MotionState m;
  m.controller = controller_name_;
  m.lifecycle = lifecycle;
  m.state = actuation::toString(r.state);
  m.fault = !s.fault.empty() ? s.fault : r.fault;
  m.steps = stepsOf(r.position);
  m.verified_steps = m.goal_steps = stepsOf(s.position);
  if (const auto& mo = s.motion) {
    const auto& move = mo->request().moves[std::min(mo->segment, mo->request().moves.size() - 1)];
    m.plan_id = mo->request().plan_id;
    m.target_id = mo->request().target_id;
    m.move_index = static_cast<std::uint32_t>(mo->segment + 1);
    m.move_count = static_cast<std::uint32_t>(mo->request().moves.size());
    m.move_kind = planning::toString(move.kind);
    for (std::size_t a = 0; a < 3; ++a)
      m.goal_steps[a] = mo->segment_from.motor[a] + move.steps.motor[a];
  }
  const auto& robot = *s.robot;
  const auto joints = robot.transmission.toJoints(r.position);
  m.joints = {joints.theta_c_rad, joints.z_c_mm, joints.z_s_mm};
  const Eigen::Vector3d tip = robot.kinematics.forward(joints).tip_mm;
  m.tip_robot = toPoint3(tip);
  if (s.registration) m.tip_lps = toPoint3(s.registration->toImage(tip));
  m.uptime_s = uptimeS();
  motion_.write(m);
}

void StatePublisher::publishWorkflow(const Session& s) {
  protocol::WorkflowState w;
  w.session_id = s.session_id;
  w.phase = workflow::toString(s.phase);
  for (auto k : workflow::allowedCommands(s.phase))
    w.allowed_commands.emplace_back(workflow::toString(k));
  w.revision = s.revision;
  w.last_event = s.last_event;
  w.safety_notice = safety_notice_;
  workflow_.write(w);
}

void StatePublisher::publishRobot(const Session& s) {
  const auto& robot = *s.robot;
  const auto ws = robot.kinematics.workspace();
  protocol::RobotState r;
  r.name = robot.config.name;
  r.config_path = s.robot_path;
  r.r_min_mm = ws.r_min_mm;
  r.r_max_mm = ws.r_max_mm;
  r.cannula_travel_mm = robot.config.instrument.cannula_travel_mm;
  r.stylet_travel_mm = robot.config.instrument.stylet_travel_mm;
  r.feasible_volume_cm3 = ws.volume_exact_cm3;
  r.feature_points_robot = toPoints3(robot.feature_points_mm);
  if (s.tissue) {
    r.tissue = s.tissue->name + " (λ1 " + fmt::format("{:g}", s.tissue->tissue.lambda1) + ", λ2 " +
               fmt::format("{:g}", s.tissue->tissue.lambda2) + ")";
  }
  robot_.write(r);
}

void StatePublisher::publishVolume(const Session& s, std::pair<std::size_t, std::size_t> progress) {
  const auto& st = s.volume_status;
  protocol::VolumeState v;
  v.status = st.status;
  v.source = st.source;
  v.message = st.message;
  if (const auto& vol = s.ct.volume) {
    const auto& g = vol->geometry;
    for (std::size_t a = 0; a < 3; ++a) {
      v.dims[a] = static_cast<std::uint32_t>(g.dims[a]);
      v.spacing_mm[a] = g.spacing_mm[a];
    }
    v.ijk_to_lps = protocol::toRowMajor(g.ijkToLps());
    if (hu_range_for_ != vol.get()) {
      hu_range_ = vol->valueRange();
      hu_range_for_ = vol.get();
    }
    v.hu_min = hu_range_.first;
    v.hu_max = hu_range_.second;
  }
  if (st.status == "loading") v.progress = {progress.first, progress.second};
  volume_.write(v);
}

void StatePublisher::publishRegistration(const Session& s) {
  const auto& st = s.registration_status;
  protocol::RegistrationState r;
  r.status = st.status;
  r.message = st.message;
  r.auto_detected = st.auto_detected;
  if (const auto& reg = s.registration) {
    r.kind = registration::toString(reg->kind);
    r.image_points = toPoints3(reg->image_mm);
    r.robot_points = toPoints3(reg->robot_mm);
    r.residuals_mm = reg->residuals_mm;
    r.image_to_robot = protocol::toRowMajor(reg->imageToRobot());
    r.scale = reg->scale;
    r.fre_mm = reg->fre_mm;
  }
  registration_.write(r);
}

void StatePublisher::publishTarget(const Session& s, std::uint32_t id) {
  for (std::size_t i = 0; i < s.targets.size(); ++i) {
    const auto& t = s.targets[i];
    if (t.id != id) continue;
    protocol::TargetState m;
    m.id = t.id;
    m.lps = toPoint3(t.lps_mm);
    m.robot = toPoint3(t.robot_mm);
    m.registered = t.registered;
    m.reachable = t.registered && t.solution.reachable();
    if (t.registered) m.reach = kinematics::toString(t.solution.reach);
    m.message = t.message;
    const auto& j = t.solution.joints;
    m.joints = {j.theta_c_rad, j.z_c_mm, j.z_s_mm};
    m.steps = stepsOf(t.steps);
    m.tre_mm = t.tre_mm;
    m.tre_warning = t.tre_warning;
    m.order = static_cast<std::uint32_t>(i + 1);
    if (std::isfinite(t.predicted_deviation_mm))
      m.predicted_deviation_mm = t.predicted_deviation_mm;
    m.status = t.status();
    m.outside_volume = t.outside_volume;
    m.path_warning = t.path_warning;
    if (m.reachable) m.path_lps = toPoints3(workflow::needlePathLps(s, j));
    target_.write(m);
    return;
  }
}

void StatePublisher::disposeTarget(std::uint32_t id) {
  protocol::TargetState m;
  m.id = id;
  target_.dispose(m);
}

void StatePublisher::publishHealth(const Session& s, const HealthFacts& facts) {
  protocol::Health h;
  h.version = kVersion;
  h.session_id = s.session_id;
  h.session_dir = session_dir_;
  h.uptime_s = uptimeS();
  h.commands_accepted = s.accepted;
  h.commands_rejected = s.rejected;
  h.journal = facts.journal_failure.empty() ? "ok" : facts.journal_failure;
  h.igtl_clients = static_cast<std::uint32_t>(facts.igtl_clients);
  h.server_time_unix_s = wallS();
  health_.write(h);
}

}  // namespace ignav::server
