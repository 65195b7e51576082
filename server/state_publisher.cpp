#include "state_publisher.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "ignav/workflow/reducer.hpp"

namespace ignav::server {
namespace {

using namespace ignav::protocol;
using workflow::Session;

constexpr const char* kVersion = "0.1.0";

}  // namespace

StatePublisher::StatePublisher(const Participant& p, std::string controller_name,
                               std::filesystem::path session_dir)
    : workflow_(p, &ignav_msg_WorkflowState_desc, topic::kWorkflow, Qos::kState),
      robot_(p, &ignav_msg_RobotState_desc, topic::kRobot, Qos::kState),
      volume_(p, &ignav_msg_VolumeState_desc, topic::kVolume, Qos::kState),
      registration_(p, &ignav_msg_RegistrationState_desc, topic::kRegistration, Qos::kState),
      target_(p, &ignav_msg_TargetState_desc, topic::kTarget, Qos::kState),
      health_(p, &ignav_msg_Health_desc, topic::kHealth, Qos::kState),
      approval_(p, &ignav_msg_ApprovalState_desc, topic::kApprovalState, Qos::kState),
      motion_(p, &ignav_msg_MotionState_desc, topic::kMotion, Qos::kState),
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
  if (e.motion_changed || !e.controller.empty()) publishMotion(s, r.controller);
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
  const std::string none = "none", pending = "pending", empty;
  ignav_msg_ApprovalState a{};
  std::vector<ignav_msg_PlannedMove> moves;
  std::vector<std::string> kinds;
  std::vector<char*> approvers;
  for (const auto& id : s.policy.approvers)
    approvers.push_back(cstr(id));
  viewSequence(a.approvers, approvers);
  a.status = cstr(none);
  a.digest = a.summary = cstr(empty);
  if (const auto& p = s.pending) {
    a.status = cstr(pending);
    a.plan_id = p->plan_id;
    a.digest = cstr(p->digest);
    a.target_id = p->target_id;
    a.summary = cstr(p->summary);
    for (int m = 0; m < 3; ++m)
      a.from_steps[m] = p->from.motor[static_cast<std::size_t>(m)];
    kinds.reserve(p->moves.size());
    for (const auto& move : p->moves) {
      kinds.emplace_back(planning::toString(move.kind));
      ignav_msg_PlannedMove pm{};
      pm.kind = cstr(kinds.back());
      for (int m = 0; m < 3; ++m)
        pm.steps[m] = move.steps.motor[static_cast<std::size_t>(m)];
      pm.duration_s = move.duration_s;
      moves.push_back(pm);
    }
    a.duration_s = p->duration_s;
    a.tre_mm = p->tre_mm;
    a.expires_at_unix_s = p->expires_s;
    a.expires_in_s = p->expires_s - wallS();
  }
  viewSequence(a.moves, moves);
  approval_.write(a);
}

void StatePublisher::publishMotion(const Session& s, const actuation::ControllerStatus& r) {
  const std::string state = actuation::toString(r.state);
  const std::string fault = !s.fault.empty() ? s.fault : r.fault;
  std::string kind;
  ignav_msg_MotionState m{};
  m.controller = cstr(controller_name_);
  m.state = cstr(state);
  m.fault = cstr(fault);
  for (std::size_t a = 0; a < 3; ++a) {
    m.steps[a] = r.position.motor[a];
    m.verified_steps[a] = s.position.motor[a];
    m.goal_steps[a] = s.position.motor[a];
  }
  if (const auto& mo = s.motion) {
    const auto& move = mo->request().moves[std::min(mo->segment, mo->request().moves.size() - 1)];
    m.plan_id = mo->request().plan_id;
    m.target_id = mo->request().target_id;
    m.move_index = static_cast<std::uint32_t>(mo->segment + 1);
    m.move_count = static_cast<std::uint32_t>(mo->request().moves.size());
    kind = planning::toString(move.kind);
    for (std::size_t a = 0; a < 3; ++a)
      m.goal_steps[a] = mo->segment_from.motor[a] + move.steps.motor[a];
  }
  m.move_kind = cstr(kind);
  const auto& robot = *s.robot;
  const auto joints = robot.transmission.toJoints(r.position);
  m.theta_c_rad = joints.theta_c_rad;
  m.z_c_mm = joints.z_c_mm;
  m.z_s_mm = joints.z_s_mm;
  const Eigen::Vector3d tip = robot.kinematics.forward(joints).tip_mm;
  m.tip_robot = toMsg(tip);
  if (s.registration) {
    m.tip_lps = toMsg(s.registration->toImage(tip));
    m.tip_lps_valid = true;
  }
  m.uptime_s = uptimeS();
  motion_.write(m);
}

void StatePublisher::publishWorkflow(const Session& s) {
  const auto allowed = workflow::allowedCommands(s.phase);
  std::vector<char*> names;
  for (auto k : allowed)
    names.push_back(const_cast<char*>(workflow::toString(k)));
  const std::string phase = workflow::toString(s.phase);
  ignav_msg_WorkflowState w{};
  w.session_id = cstr(s.session_id);
  w.phase = cstr(phase);
  viewSequence(w.allowed_commands, names);
  w.revision = s.revision;
  w.last_event = cstr(s.last_event);
  w.safety_notice = cstr(safety_notice_);
  workflow_.write(w);
}

void StatePublisher::publishRobot(const Session& s) {
  const auto& robot = *s.robot;
  const auto ws = robot.kinematics.workspace();
  auto features = toMsgs(robot.feature_points_mm);
  ignav_msg_RobotState r{};
  r.name = cstr(robot.config.name);
  r.config_path = cstr(s.robot_path);
  r.r_min_mm = ws.r_min_mm;
  r.r_max_mm = ws.r_max_mm;
  r.cannula_travel_mm = robot.config.instrument.cannula_travel_mm;
  r.stylet_travel_mm = robot.config.instrument.stylet_travel_mm;
  r.feasible_volume_cm3 = ws.volume_exact_cm3;
  const std::string tissue =
      s.tissue ? s.tissue->name + " (λ1 " + fmt::format("{:g}", s.tissue->tissue.lambda1) +
                     ", λ2 " + fmt::format("{:g}", s.tissue->tissue.lambda2) + ")"
               : std::string();
  r.tissue = cstr(tissue);
  viewSequence(r.feature_points_robot, features);
  robot_.write(r);
}

void StatePublisher::publishVolume(const Session& s, std::pair<std::size_t, std::size_t> progress) {
  const auto& st = s.volume_status;
  ignav_msg_VolumeState v{};
  v.status = cstr(st.status);
  v.source = cstr(st.source);
  v.message = cstr(st.message);
  if (const auto& vol = s.ct.volume) {
    const auto& g = vol->geometry;
    for (int a = 0; a < 3; ++a) {
      v.dims[a] = static_cast<std::uint32_t>(g.dims[a]);
      v.spacing_mm[a] = g.spacing_mm[a];
    }
    toRowMajor(g.ijkToLps(), v.ijk_to_lps);
    if (hu_range_for_ != vol.get()) {
      hu_range_ = vol->valueRange();
      hu_range_for_ = vol.get();
    }
    v.hu_min = hu_range_.first;
    v.hu_max = hu_range_.second;
  }
  if (st.status == "loading") {
    v.progress_done = progress.first;
    v.progress_total = progress.second;
  }
  volume_.write(v);
}

void StatePublisher::publishRegistration(const Session& s) {
  const auto& st = s.registration_status;
  ignav_msg_RegistrationState r{};
  r.status = cstr(st.status);
  r.message = cstr(st.message);
  r.auto_detected = st.auto_detected;
  std::vector<ignav_msg_Point3> image, robot;
  std::vector<double> residuals;
  std::string kind;
  if (const auto& reg = s.registration) {
    kind = registration::toString(reg->kind);
    image = toMsgs(reg->image_mm);
    robot = toMsgs(reg->robot_mm);
    residuals = reg->residuals_mm;
    toRowMajor(reg->imageToRobot(), r.image_to_robot);
    r.scale = reg->scale;
    r.fre_mm = reg->fre_mm;
  }
  r.kind = cstr(kind);
  viewSequence(r.image_points, image);
  viewSequence(r.robot_points, robot);
  viewSequence(r.residuals_mm, residuals);
  registration_.write(r);
}

void StatePublisher::publishTarget(const Session& s, std::uint32_t id) {
  for (std::size_t i = 0; i < s.targets.size(); ++i) {
    const auto& t = s.targets[i];
    if (t.id != id) continue;
    // Named, not temporaries: the sample points into them until it is written (ASan found a
    // `cond ? reach : std::string()` that died first).
    const std::string reach = t.registered ? kinematics::toString(t.solution.reach) : "";
    const std::string status = t.status();
    ignav_msg_TargetState m{};
    m.id = t.id;
    m.lps = toMsg(t.lps_mm);
    m.robot = toMsg(t.robot_mm);
    m.registered = t.registered;
    m.reachable = t.registered && t.solution.reachable();
    m.reach = cstr(reach);
    m.message = cstr(t.message);
    m.theta_c_rad = t.solution.joints.theta_c_rad;
    m.z_c_mm = t.solution.joints.z_c_mm;
    m.z_s_mm = t.solution.joints.z_s_mm;
    for (int a = 0; a < 3; ++a)
      m.steps[a] = t.steps.motor[static_cast<std::size_t>(a)];
    m.tre_mm = t.tre_mm;
    m.tre_warning = t.tre_warning;
    m.order = static_cast<std::uint32_t>(i + 1);
    m.deviation_predicted = std::isfinite(t.predicted_deviation_mm);
    m.predicted_deviation_mm = m.deviation_predicted ? t.predicted_deviation_mm : 0.0;
    m.status = cstr(status);
    m.outside_volume = t.outside_volume;
    m.path_warning = cstr(t.path_warning);
    std::vector<ignav_msg_Point3> path;
    if (m.reachable) path = toMsgs(workflow::needlePathLps(s, t.solution.joints));
    viewSequence(m.path_lps, path);
    target_.write(m);
    return;
  }
}

void StatePublisher::disposeTarget(std::uint32_t id) {
  ignav_msg_TargetState m{};
  m.id = id;
  const std::string empty;
  m.reach = m.message = m.status = cstr(empty);
  target_.dispose(m);
}

void StatePublisher::publishHealth(const Session& s, const HealthFacts& facts) {
  const std::string version = kVersion;
  ignav_msg_Health h{};
  h.version = cstr(version);
  h.session_id = cstr(s.session_id);
  h.session_dir = cstr(session_dir_);
  h.uptime_s = uptimeS();
  h.commands_accepted = s.accepted;
  h.commands_rejected = s.rejected;
  const std::string journal = facts.journal_failure.empty() ? "ok" : facts.journal_failure;
  h.journal = cstr(journal);
  h.igtl_clients = static_cast<std::uint32_t>(facts.igtl_clients);
  h.server_time_unix_s = wallS();
  health_.write(h);
}

}  // namespace ignav::server
