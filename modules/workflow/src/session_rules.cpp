// The rules the transition rows' actions share: how a target is evaluated against the CT and the
// registration, how a registration is adopted, what a marker detection's outcome means, how the
// approval policy is taken in. Pure (DESIGN.md); internal to modules/workflow.
#include "session_rules.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "ignav/workflow/reducer.hpp"

namespace ignav::workflow::detail {

// modules/registration names its reasons; each is one of the reply codes (a test checks them).
Rejection registrationRefusal(const Error& error) {
  if (const auto code = replyCodeNamed(error.reason)) return Rejection{*code, error.message};
  return Rejection{ReplyCode::kInternal,
                   "registration refused (" + error.reason + "): " + error.message};
}

Target* findTarget(Session& s, std::uint32_t id) {
  for (auto& t : s.targets) {
    if (t.id == id) return &t;
  }
  return nullptr;
}

// A point to target must lie in tissue the loaded CT shows (issue 26: a CT whose field of view
// cuts the workspace left reachable targets in tissue nobody had seen). Without a CT here (the
// registration came from 3D Slicer, which holds the images) there is nothing to check against.
std::optional<Rejection> checkInsideCt(const Session& s, const Eigen::Vector3d& lps_mm) {
  if (!s.ct.volume) return std::nullopt;
  const double outside_mm = s.ct.volume->geometry.outsideBy_mm(lps_mm);
  if (outside_mm <= 0.0) return std::nullopt;
  return Rejection{ReplyCode::kOutsideVolume,
                   fmt::format("({:.1f}, {:.1f}, {:.1f}) mm LPS lies {:.1f} mm outside the loaded "
                               "CT ({}): only imaged tissue can be targeted",
                               lps_mm.x(), lps_mm.y(), lps_mm.z(), outside_mm, s.ct.source)};
}

namespace {

// How much of the planned path runs outside the loaded CT (t.path_outside_ct_mm), with a warning
// for a person (t.path_warning). The path's pieces are straight or gently curved, so
// half-millimetre samples measure the part outside well enough for a warning.
void checkPath(const Session& s, Target& t) {
  if (!s.ct.volume || !t.solution.reachable()) return;
  const auto path = needlePathLps(s, t.commandedJoints());
  const auto& geometry = s.ct.volume->geometry;
  constexpr double kSample_mm = 0.5;
  double outside_mm = 0.0, total_mm = 0.0, worst_mm = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector3d step = path[i] - path[i - 1];
    const double length = step.norm();
    const int pieces = std::max(1, static_cast<int>(std::ceil(length / kSample_mm)));
    for (int k = 0; k < pieces; ++k) {
      const double beyond = geometry.outsideBy_mm(path[i - 1] + step * ((k + 0.5) / pieces));
      if (beyond > 0.0) outside_mm += length / pieces;
      worst_mm = std::max(worst_mm, beyond);
    }
    total_mm += length;
  }
  t.path_outside_ct_mm = outside_mm;
  if (outside_mm <= 0.0) return;
  t.path_warning = fmt::format(
      "the planned path runs {:.1f} mm of its {:.1f} mm outside the loaded CT (up to {:.1f} mm "
      "from it): that tissue was not imaged",
      outside_mm, total_mm, worst_mm);
}

// With a tissue profile to aim with (use_tissue): the joints whose deflected tip lands on the
// target, or why there are none (the target is then not plannable). Reached targets keep what
// they were reached with (Target::reached_joints).
void aim(const Session& s, Target& t) {
  if (!s.aim_tissue) return;
  compensation::DeflectionModel model;
  model.needle = s.aim_tissue->needle;
  model.tissue = s.aim_tissue->tissue;
  auto c = compensation::compensate(s.robot->kinematics, model, t.robot_mm);
  if (!c) {
    t.compensation_refusal =
        fmt::format("aiming for tissue '{}': {}", s.aim_tissue->name, c.error().message);
    return;
  }
  t.compensated = CompensatedAim{s.aim_tissue->name, c->compensated, c->compensated_landing_mm,
                                 c->nominal_landing_mm, c->residual_mm};
}

}  // namespace

void evaluate(const Session& s, Target& t) {
  Target fresh;
  fresh.id = t.id;
  fresh.lps_mm = t.lps_mm;
  fresh.reached = t.reached;  // where the needle has been stays true whatever the registration
  fresh.reached_s = t.reached_s;
  fresh.reached_joints = t.reached_joints;
  if (t.reached) fresh.compensated = t.compensated;  // as it was reached
  fresh.pause_z_s_mm = t.pause_z_s_mm;               // a plan choice
  fresh.paused = t.paused;                           // where the needle has been
  fresh.replan = t.replan;
  fresh.clearance_override = t.clearance_override;  // a plan choice
  if (t.reached) fresh.reaimed = t.reaimed;         // as it was reached
  t = fresh;
  const auto outside = checkInsideCt(s, t.lps_mm);
  t.outside_volume = outside.has_value();
  const std::string outside_note = outside ? "; " + outside->message : std::string();
  if (!s.registration) {
    t.message = "not registered yet: register the CT to the robot first" + outside_note;
    return;
  }
  const auto& robot = *s.robot;
  const auto& reg = *s.registration;
  t.registered = true;
  t.robot_mm = reg.toRobot(t.lps_mm);
  auto solution = robot.kinematics.inverse(t.robot_mm);
  if (!solution) {  // only for non-finite targets, which validation refuses
    t.message = solution.error().message;
    return;
  }
  t.solution = *solution;
  t.message = fmt::format("target {}: {}", t.id, robot.kinematics.describe(t.solution, t.robot_mm));
  if (t.solution.reachable() && !t.reached) aim(s, t);
  if (t.solution.reachable()) t.steps = robot.transmission.toSteps(t.commandedJoints()).steps;
  t.message += outside_note;
  if (!outside) checkPath(s, t);
  if (!t.path_warning.empty()) t.message += "; warning: " + t.path_warning;
  if (!t.compensation_refusal.empty()) t.message += "; refused: " + t.compensation_refusal;
  if (t.compensated) {
    const auto& c = *t.compensated;
    t.message += fmt::format(
        "; aimed for tissue '{}': θc {:.2f}°, zc {:.3f} mm, zs {:.3f} mm (the nominal joints "
        "would land {:.2f} mm off)",
        c.profile, c.joints.theta_c_rad * 180.0 / M_PI, c.joints.z_c_mm, c.joints.z_s_mm,
        (c.nominal_landing_robot_mm - t.robot_mm).norm());
  }
  if (s.tissue && t.solution.reachable()) {
    // A model prediction only: the cannula's sideways drift after zc mm pushed into the tissue.
    const double zc = t.solution.joints.z_c_mm;
    if (zc <= 0.0) {
      t.predicted_deviation_mm = 0.0;
    } else if (auto path = deflection::simulate(s.tissue->needle, s.tissue->tissue, zc, zc)) {
      t.predicted_deviation_mm = path->back().y_mm;
    }
  }
  const auto& settings = robot.config.registration;
  if (reg.image_mm.empty()) {  // registered elsewhere: no fiducials to estimate it from
    t.tre_mm = std::numeric_limits<double>::quiet_NaN();
  } else {
    t.tre_mm = registration::expectedTre_mm(registration::describeFiducials(reg.image_mm), t.lps_mm,
                                            settings.fle_mm, reg.kind);
    t.tre_warning = t.tre_mm > settings.max_tre_mm;
  }
  checkClearance(s, t);  // with the drift predicted above
  if (!t.clearance_refusal.empty()) {
    t.message += t.clearance_override.empty()
                     ? "; refused: " + t.clearance_refusal
                     : "; overridden (" + t.clearance_override + "): " + t.clearance_refusal;
  }
}

void evaluateAll(Session& s, Effects& e) {
  for (auto& t : s.targets) {
    evaluate(s, t);
    e.targets_changed.push_back(t.id);
  }
}

Expected<registration::Registration> registerOnRobot(const config::Robot& robot,
                                                     const std::vector<Eigen::Vector3d>& image) {
  const std::vector<Eigen::Vector3d> model(robot.feature_points_mm.begin(),
                                           robot.feature_points_mm.end());
  return registration::registerPoints(image, model, robot.config.registration.kind,
                                      robot.config.registration.limits);
}

std::optional<Rejection> adoptRegistration(Session& s, const std::vector<Eigen::Vector3d>& image,
                                           bool auto_detected, Effects& e) {
  auto reg = registerOnRobot(*s.robot, image);
  if (!reg) return registrationRefusal(reg.error());
  s.registration = std::move(reg).value();
  s.registration_status = {
      "registered",
      fmt::format("FRE {:.3f} mm, scale {:.4f}{}", s.registration->fre_mm, s.registration->scale,
                  auto_detected ? ", markers detected on the CT" : ""),
      auto_detected};
  e.registration_changed = true;
  evaluateAll(s, e);
  checkMountedRobot(s, e);
  return std::nullopt;
}

// A marker detection's outcome that registered nothing: a registration from before stays in use.
void detectionFailed(Session& s, const std::string& why, Effects& e) {
  if (s.registration) {
    s.registration_status.status = "registered";
    s.registration_status.message =
        "marker detection failed: " + why + "; the registration from before stays in use";
  } else {
    s.registration_status = {"rejected", "marker detection failed: " + why, false};
  }
  e.registration_changed = true;
}

// A registration given by hand (or by matrix) while the markers were being detected: the
// detection's result will be ignored. The note for the reply.
std::string dropDetection(Session& s) {
  if (s.detecting == 0) return "";
  const auto job = s.detecting;
  s.detecting = 0;
  return fmt::format("; marker detection #{} under way is dropped (its result will be ignored)",
                     job);
}

// Why a detection's outcome is not the one the session awaits (Session::detecting).
std::string staleDetection(const Session& s, const Input& in) {
  std::string why;
  if (s.ct_revision > in.job) {
    why = fmt::format("the CT it ran on is no longer loaded ({} was asked for at revision {})",
                      s.volume_status.source, s.ct_revision);
  } else if (s.detecting != 0) {
    why = fmt::format("detection #{} is the one awaited", s.detecting);
  } else {
    why = "a registration was given meanwhile, or none was awaited";
  }
  return fmt::format("marker detection #{} on {} ignored, nothing registered: {}", in.job,
                     in.path.empty() ? "an unnamed CT" : in.path, why);
}

std::optional<Rejection> checkGivenMatrix(const Session& s,
                                          const std::optional<Eigen::Matrix4d>& matrix,
                                          const std::string& what) {
  if (!matrix) return std::nullopt;
  auto given = registration::registrationFromMatrix(*matrix, s.robot->config.registration.limits);
  if (given) return std::nullopt;
  Rejection why = registrationRefusal(given.error());
  why.message = what + ": " + why.message;
  return why;
}

Expected<verification::ConfirmationRegistration> registerScan(
    const config::Robot& robot, const std::optional<registration::Registration>& session,
    const std::vector<Eigen::Vector3d>& markers_lps_mm,
    const std::optional<Eigen::Matrix4d>& given) {
  const auto& limits = robot.config.registration.limits;
  if (given) return verification::registerConfirmationByMatrix(*given, limits);
  if (!session) {
    return makeError(ErrorCode::kInvalidArgument,
                     "the session has no registration to compare the scan with", "not_registered");
  }
  const std::vector<Eigen::Vector3d> model(robot.feature_points_mm.begin(),
                                           robot.feature_points_mm.end());
  return verification::registerConfirmation(*session, markers_lps_mm, model,
                                            robot.config.registration.kind, limits);
}

const Target* pausedInsertion(const Session& s) {
  for (const auto& t : s.targets) {
    if (!t.reached) return t.paused ? &t : nullptr;
  }
  return nullptr;
}

Target* pausedInsertion(Session& s) {
  return const_cast<Target*>(pausedInsertion(static_cast<const Session&>(s)));
}

std::vector<compensation::TargetingRecord> measuredRecords(const Session& s) {
  std::vector<compensation::TargetingRecord> records;
  const Confirmation& c = s.confirmation;
  if (!c.registration) return records;
  const Eigen::Matrix4d image_to_robot = c.registration->registration.imageToRobot();
  for (const auto& m : c.targets) {
    compensation::TargetingRecord record{"T" + std::to_string(m.error.target_id),
                                         m.error.planned_robot_mm,
                                         m.joints,
                                         m.error.actual_robot_mm,
                                         {}};
    // Where the scan still shows the needle, its centreline too (a tip moved or accepted by a
    // person keeps it: the path is the needle's, wherever the click put the tip).
    for (const auto& seed : c.seeds) {
      if (seed.id != m.seed_id) continue;
      for (const auto& p : seed.path_lps_mm)
        record.path_mm.push_back((image_to_robot * p.homogeneous()).head<3>());
    }
    records.push_back(std::move(record));
  }
  return records;
}

void adoptPolicy(Session& s, ApprovalPolicy policy) {
  s.policy = std::move(policy);
  if (s.robot) {
    // The planner's joint speeds are what the controller's step profile gives the joint whose
    // motors turn fastest, so the order's time estimate and the requests' agree.
    const Eigen::Matrix3d& c = s.robot->transmission.coupling();
    planning::AxisProfile* axes[3] = {&s.policy.limits.theta_c, &s.policy.limits.z_c,
                                      &s.policy.limits.z_s};
    for (int j = 0; j < 3; ++j) {
      const double steps_per_unit = c.col(j).cwiseAbs().maxCoeff();
      axes[j]->speed = s.policy.speed_steps_s / steps_per_unit;
      axes[j]->acceleration = s.policy.acceleration_steps_s2 / steps_per_unit;
    }
  }
}

}  // namespace ignav::workflow::detail
