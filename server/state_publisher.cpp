#include "state_publisher.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Geometry>

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
      verification_(p),
      structures_(p),
      job_outcome_(p),
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
  if (e.confirmation_changed || e.robot_changed) publishVerification(s);
  if (e.structures_changed) publishStructures(s, r);
  if (e.motion_changed || !e.controller.empty()) publishMotion(s, r.controller, r.lifecycle);
  if (e.workflow_changed) publishWorkflow(s);
  if (e.job_outcome) publishJobOutcome(*e.job_outcome);
}

void StatePublisher::publishJobOutcome(const workflow::JobOutcome& o) {
  job_outcome_.write({o.job, o.kind, o.input, o.status, o.message, o.revision});
}

void StatePublisher::publishStructures(const Session& s, const Readings& r) {
  const auto& st = s.structures;
  protocol::StructuresState m;
  m.status = st.status;
  m.source = st.source;
  m.message = st.message;
  m.site = s.site ? s.site->name : "";
  if (st.loaded.set) {
    const auto& set = st.loaded.set->structures;
    for (std::size_t n = 0; n < set.size(); ++n) {
      const auto& structure = set[n];
      // The box of the voxels' centres, in LPS.
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
      for (const auto& corner : structure.mask.corners()) {
        lo = lo.cwiseMin(corner);
        hi = hi.cwiseMax(corner);
      }
      const auto& role = st.roles.at(n);
      m.structures.push_back({structure.name,
                              structure.colour_rgb,
                              anatomy::toString(role.role),
                              role.margin_mm,
                              structure.mask.count(),
                              structure.mask.volume_cm3(),
                              {lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z()}});
    }
  }
  m.proposal_status = s.proposals.status;
  m.proposal_message = s.proposals.message;
  for (const auto& p : s.proposals.targets)
    m.proposed.push_back({p.id, {p.lps_mm.x(), p.lps_mm.y(), p.lps_mm.z()}});
  if (s.proposals.proposing) {
    m.proposal_progress_done = r.proposal_progress.first;
    m.proposal_progress_total = r.proposal_progress.second;
  }
  const auto& placed = s.robot_placement;
  m.placement_status = placed.status;
  m.placement_message = placed.message;
  m.placement_structure = placed.structure;
  if (placed.placing) {
    m.placement_progress_done = r.placement_progress.first;
    m.placement_progress_total = r.placement_progress.second;
  }
  auto array = [](const Eigen::Vector3d& v) { return std::array<double, 3>{v.x(), v.y(), v.z()}; };
  for (const auto& p : placed.poses) {
    m.placements.push_back({p.coverage.fraction(), array(p.pose.origin_lps_mm),
                            array(p.pose.insertion()), array(p.skin.entry_lps_mm), p.tilt_deg,
                            p.shift_mm, p.skin.skin_distance_mm, p.skin.seen});
  }
  m.mounted_status = placed.checking                  ? "measuring"
                     : placed.mounted                 ? "measured"
                     : placed.mounted_message.empty() ? "none"
                                                      : "failed";
  m.mounted_message = placed.mounted_message;
  if (placed.mounted) {
    m.mounted_coverage = placed.mounted->coverage.fraction();
    m.mounted_entry_mm = placed.mounted->deviation.entry_mm;
    m.mounted_axis_deg = placed.mounted->deviation.axis_deg;
  }
  m.dose_status = s.dose.status;
  m.dose_message = s.dose.message;
  if (const auto& computed = s.dose.computed) {
    for (const auto& d : computed->doses) {
      const auto& e = d.evaluation;
      protocol::DoseMetricsInfo target;
      target.structure = computed->structure;
      target.which = d.what;
      target.d90_percent = e.target.d90_percent;
      target.v100 = e.target.v100;
      target.v150 = e.target.v150;
      m.dose.push_back(target);
      for (const auto& o : e.organs) {
        protocol::DoseMetricsInfo organ;
        organ.structure = o.name;
        organ.which = d.what;
        organ.d10_percent = o.metrics.d10_percent;
        organ.dmax_percent = o.metrics.dmax_percent;
        organ.d2cc_gy = o.metrics.d2cc_Gy;
        m.dose.push_back(organ);
      }
    }
  }
  structures_.write(m);
}

void StatePublisher::publishEverything(const Session& s, const Readings& r) {
  publishVerification(s);
  publishStructures(s, r);
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
    m.goal_steps = stepsOf(mo->segment_from + move.steps);
  }
  const auto& robot = *s.robot;
  const auto joints = robot.transmission.toJoints(r.position);
  m.joints = {joints.theta_c_rad, joints.z_c_mm, joints.z_s_mm};
  const Eigen::Vector3d tip = robot.kinematics.forward(joints).tip_mm;
  m.tip_robot = toPoint3(tip);
  if (s.registration) m.tip_lps = toPoint3(s.registration->toImage(tip));
  m.needle_lps = toPoints3(workflow::needlePathLps(s, joints));
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
  for (const auto& t : s.targets)
    w.target_ids.push_back(t.id);
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
    m.reachable = t.plannable();
    if (t.registered) m.reach = kinematics::toString(t.solution.reach);
    m.message = t.message;
    const auto& j = t.commandedJoints();
    m.joints = {j.theta_c_rad, j.z_c_mm, j.z_s_mm};
    if (t.compensated) {
      const auto& c = *t.compensated;
      const auto& n = t.solution.joints;
      m.compensated = true;
      m.aim_tissue = c.profile;
      m.nominal_joints = {n.theta_c_rad, n.z_c_mm, n.z_s_mm};
      m.nominal_landing_robot = toPoint3(c.nominal_landing_robot_mm);
      m.predicted_landing_robot = toPoint3(c.landing_robot_mm);
    }
    if (t.pause_z_s_mm) m.pause_z_s_mm = *t.pause_z_s_mm;
    if (t.paused) {
      m.paused = true;
      m.paused_joints = {t.paused->theta_c_rad, t.paused->z_c_mm, t.paused->z_s_mm};
    }
    if (t.reaimed) {
      const auto& r = *t.reaimed;
      const auto& n = t.solution.joints;
      m.reaimed = true;
      m.nominal_joints = {n.theta_c_rad, n.z_c_mm, n.z_s_mm};
      m.previous_joints = {r.before.theta_c_rad, r.before.z_c_mm, r.before.z_s_mm};
      m.previous_landing_robot = toPoint3(r.before_landing_robot_mm);
      m.reaimed_landing_robot = toPoint3(r.landing_robot_mm);
    }
    m.replan = t.replan;
    for (const auto& c : t.clearances) {
      m.clearances.push_back({c.structure, c.distance_mm, c.margin_mm, c.uncertainty_mm, c.part,
                              toPoint3(c.needle_lps_mm), toPoint3(c.structure_lps_mm),
                              c.beyond_reach, c.tooClose()});
    }
    m.clearance_refusal = t.clearance_refusal;
    m.clearance_override = t.clearance_override;
    m.steps = stepsOf(t.steps);
    m.tre_mm = t.tre_mm;
    m.tre_warning = t.tre_warning;
    m.order = static_cast<std::uint32_t>(i + 1);
    if (std::isfinite(t.predicted_deviation_mm))
      m.predicted_deviation_mm = t.predicted_deviation_mm;
    m.status = t.status();
    m.outside_volume = t.outside_volume;
    m.path_warning = t.path_warning;
    // The needle's path wherever the robot reaches, refused or not: a path too close to a
    // structure is what a viewer must show.
    if (t.registered && t.solution.reachable())
      m.path_lps = toPoints3(workflow::needlePathLps(s, j));
    target_.write(m);
    return;
  }
}

namespace {

protocol::ErrorStats statsOf(const verification::Stats& s) {
  return {static_cast<std::uint32_t>(s.count), s.mean, s.sd_sample, s.min, s.max, s.rms};
}

}  // namespace

void StatePublisher::publishVerification(const Session& s) {
  const workflow::Confirmation& c = s.confirmation;
  protocol::VerificationState v;
  v.status = c.measuring != 0 ? "measuring" : c.status;
  v.source = c.source;
  v.measuring_source = c.measuring_source;
  v.message = c.measuring != 0 ? "measuring the confirmation CT " + c.measuring_source : c.message;
  Eigen::Matrix4d image_to_robot = Eigen::Matrix4d::Identity();
  if (c.registration) {
    v.registration_reused = c.registration->reused;
    v.marker_shift_mm = c.registration->marker_shift_mm;
    v.fre_mm = c.registration->registration.fre_mm;
    image_to_robot = c.registration->registration.imageToRobot();
    v.image_to_robot = protocol::toRowMajor(image_to_robot);
  }
  v.detection_summary = c.detection_summary;
  for (const auto& seed : c.seeds) {
    protocol::SeedState m;
    m.id = seed.id;
    m.kind = seed.kind;
    m.lps = toPoint3(seed.lps_mm);
    for (const auto& p : seed.path_lps_mm)
      m.path_lps.push_back(toPoint3(p));
    m.robot = toPoint3((image_to_robot * seed.lps_mm.homogeneous()).head<3>());
    m.length_mm = seed.length_mm;
    m.width_mm = seed.width_mm;
    m.placed = seed.placed;
    m.rejected = seed.rejected;
    for (const auto& t : c.targets)  // rows kept from an earlier scan name its seeds, not these
      if (t.seed_id == seed.id && c.rowsAreThisScans()) m.target_id = t.error.target_id;
    v.seeds.push_back(m);
  }
  for (const auto& t : c.targets) {
    const auto& e = t.error;
    protocol::MeasuredTargetState m;
    m.target_id = e.target_id;
    m.seed_id = t.seed_id;
    m.matched = t.matched;
    m.planned_robot = toPoint3(e.planned_robot_mm);
    m.actual_robot = toPoint3(e.actual_robot_mm);
    m.planned_lps = toPoint3(e.planned_lps_mm);
    m.actual_lps = toPoint3(e.actual_lps_mm);
    m.error_robot = toPoint3(e.error_robot_mm);
    m.error_lps = toPoint3(e.error_lps_mm);
    m.error_mm = e.error_mm;
    m.lateral_mm = e.lateral_mm;
    m.radial_mm = e.radial_mm;
    m.tangential_mm = e.tangential_mm;
    m.depth_mm = e.depth_mm;
    if (std::isfinite(t.predicted_error_mm)) {
      m.predicted_robot = toPoint3(t.predicted_robot_mm);
      m.predicted_error_mm = t.predicted_error_mm;
    }
    v.targets.push_back(m);
  }
  v.missing_targets = c.missing_targets;
  v.extra_seeds = c.extra_seeds;
  if (c.summary) {
    v.error = statsOf(c.summary->error);
    v.lateral = statsOf(c.summary->lateral);
    v.depth = statsOf(c.summary->depth);
  }
  v.summary = c.rowsAreThisScans() || c.text.empty()
                  ? c.text
                  : fmt::format("measured on {}: {}", c.rows_source, c.text);
  for (const auto& f : s.fitted_tissues) {
    protocol::FittedTissueState m;
    m.name = f.profile.name;
    m.lambda1 = f.fit.tissue.lambda1;
    m.lambda2 = f.fit.tissue.lambda2;
    m.lambda1_se = f.fit.standard_errors.size() > 0 ? f.fit.standard_errors[0] : 0.0;
    m.lambda2_se = f.fit.standard_errors.size() > 1 ? f.fit.standard_errors[1] : 0.0;
    m.rms_mm = f.fit.rms_mm;
    m.rms_bicycle_mm = f.fit.rms_bicycle_mm;
    m.rms_no_deflection_mm = f.fit.rms_no_deflection_mm;
    m.targets = static_cast<std::uint32_t>(f.targets);
    m.limit = f.fit.limit;
    m.yaml = f.yaml;
    v.fitted_tissues.push_back(m);
  }
  v.aim_tissue = s.aim_tissue ? s.aim_tissue->name : "";
  verification_.write(v);
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
  h.robot_id = facts.robot_id;
  h.host = facts.host;
  h.started_unix_s = facts.started_unix_s;
  health_.write(h);
}

}  // namespace ignav::server
