// Re-planning during an insertion (issue 40, the paper's future work), actions.hpp: an insertion
// set to stop part-way (pause_at), an intermittent CT of the needle there searched in the
// background (scan_needle -> needle_scanned | needle_scan_failed), and the re-aim it proposes
// adopted (reaim): the rest of the insertion, and the targets after it, then go to new joints that
// the approval request shows beside the nominal and the previous ones.
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "actions.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
// A stop closer than this to the target's depth leaves no rest worth re-aiming.
constexpr double kMinRest_mm = 1.0;

Rejection notPaused(const Session& s) {
  return Rejection{ReplyCode::kNotPaused,
                   fmt::format("no insertion is stopped part-way ({}): set pause_at on a target "
                               "before lock_plan, and approve its motion",
                               s.targets.empty() ? "no targets"
                                                 : "the next target's needle is "
                                                   "not paused")};
}

}  // namespace

Refusal pauseAt(Session& s, const Input& in, ActionOutput& out) {
  Target* t = findTarget(s, in.ids[0]);
  if (!t) {
    return Rejection{ReplyCode::kUnknownTarget, fmt::format("no target {}", in.ids[0])};
  }
  if (t->reached || t->paused) {
    return Rejection{ReplyCode::kBadDepth,
                     fmt::format("target {} was {} already", t->id,
                                 t->reached ? "reached" : "stopped part-way")};
  }
  if (in.path == "none") {
    t->pause_z_s_mm.reset();
    out.effects.targets_changed.push_back(t->id);
    out.note = fmt::format("target {} is inserted all the way at once", t->id);
    return std::nullopt;
  }
  if (!t->plannable()) {
    return Rejection{
        ReplyCode::kUnreachableTargets,
        fmt::format("target {} cannot be planned ({}): no depth to stop at", t->id, t->message)};
  }
  // The whole text must be the number: "12.5", not "12.5mm" or "1e999".
  errno = 0;
  char* end = nullptr;
  const double depth_mm = std::strtod(in.path.c_str(), &end);
  const double full_mm = t->commandedJoints().z_s_mm;
  if (in.path.empty() || end != in.path.c_str() + in.path.size() || errno != 0 ||
      !std::isfinite(depth_mm) || !(depth_mm > 0.0) || !(depth_mm <= full_mm - kMinRest_mm)) {
    return Rejection{ReplyCode::kBadDepth,
                     fmt::format("pause_at {}: '{}' is no stylet depth to stop at: give mm more "
                                 "than 0 and at least {:.0f} mm short of the target's {:.3f} mm "
                                 "(or none)",
                                 t->id, in.path.substr(0, 32), kMinRest_mm, full_mm)};
  }
  t->pause_z_s_mm = depth_mm;
  out.effects.targets_changed.push_back(t->id);
  out.note = fmt::format(
      "target {}'s insertion stops with the stylet {:.3f} of {:.3f} mm out, for an intermittent "
      "CT (scan_needle) and a re-aim (reaim); the rest is approved of its own",
      t->id, depth_mm, full_mm);
  return std::nullopt;
}

Refusal startNeedleScan(Session& s, const Input& in, ActionOutput& out) {
  if (s.scanning_needle != 0) {
    return Rejection{ReplyCode::kBusy,
                     fmt::format("an intermittent CT is being searched ({}): wait for its outcome",
                                 s.scanning_source)};
  }
  const Target* t = pausedInsertion(s);
  if (!t) return notPaused(s);
  if (!s.registration) {
    return Rejection{ReplyCode::kNotRegistered,
                     "the session has no registration to compare the intermittent CT with"};
  }
  if (auto bad = checkGivenMatrix(s, in.matrix, "the intermittent CT's matrix")) return bad;
  s.scanning_needle = s.revision + 1;  // this step's
  s.scanning_source = in.path;
  s.scanning_matrix = in.matrix;
  out.effects.start_jobs.push_back(JobKind::kNeedleScan);
  out.effects.targets_changed.push_back(t->id);
  out.note = fmt::format(
      "searching the intermittent CT {} (#{}) for T{}'s needle: the job's outcome says what it "
      "found and the re-aim it proposes (TargetState.replan)",
      in.path, s.scanning_needle, t->id);
  return std::nullopt;
}

Refusal adoptNeedleScan(Session& s, const Input& in, ActionOutput& out) {
  s.scanning_needle = 0;
  s.scanning_source.clear();
  s.scanning_matrix.reset();
  Target* t = pausedInsertion(s);
  // The insertion went on (or was planned again) while the scan was searched: nothing to re-aim.
  if (!in.reaim || !t || t->id != in.reaim->target_id ||
      !(t->paused->z_s_mm == in.reaim->paused.z_s_mm &&
        t->paused->z_c_mm == in.reaim->paused.z_c_mm &&
        t->paused->theta_c_rad == in.reaim->paused.theta_c_rad)) {
    out.outcome_failed = true;
    out.note = fmt::format(
        "the intermittent CT {} shows an insertion that is no longer paused "
        "there: nothing re-aimed",
        in.path);
    return std::nullopt;
  }
  s.reaim = in.reaim;
  t->replan = "proposed: " + in.reaim->message + " (reaim adopts it)";
  for (const auto& a : in.reaim->aims)
    out.effects.targets_changed.push_back(a.target_id);
  out.effects.targets_changed.push_back(t->id);
  out.note = in.reaim->message;
  return std::nullopt;
}

Refusal noteNeedleScanFailure(Session& s, const Input& in, ActionOutput& out) {
  s.scanning_needle = 0;
  s.scanning_source.clear();
  s.scanning_matrix.reset();
  if (Target* t = pausedInsertion(s)) {
    t->replan = "the intermittent CT " + in.path + " was refused: " + in.error;
    out.effects.targets_changed.push_back(t->id);
  }
  return std::nullopt;
}

Refusal adoptReaim(Session& s, const Input& in, ActionOutput& out) {
  Target* paused = pausedInsertion(s);
  if (!paused) return notPaused(s);
  if (!s.reaim || s.reaim->adopted || s.reaim->target_id != paused->id) {
    return Rejection{ReplyCode::kNoReaim,
                     fmt::format("no re-aim is proposed for T{} (scan_needle first{})", paused->id,
                                 s.reaim && s.reaim->adopted ? "; the last one was adopted" : "")};
  }
  const auto& robot = *s.robot;
  for (const auto& a : s.reaim->aims) {
    Target* t = findTarget(s, a.target_id);
    if (!t || t->reached) continue;  // gone or reached since: its aim is history
    if (auto ok = robot.kinematics.checkJoints(a.joints); !ok) {
      return Rejection{ReplyCode::kNoReaim,
                       fmt::format("T{}'s re-aimed joints: {}", a.target_id, ok.error().message)};
    }
    t->reaimed = a;
    t->steps = robot.transmission.toSteps(a.joints).steps;
    out.effects.targets_changed.push_back(t->id);
  }
  // The rotation limit holds for the joints now aimed at, in the plan's order.
  std::vector<planning::PlannedTarget> remaining;
  std::vector<std::size_t> order;
  for (const auto& t : s.targets) {
    if (t.reached) continue;
    order.push_back(remaining.size());
    remaining.push_back({t.id, t.commandedJoints()});
  }
  const auto ordering =
      planning::evaluateOrder(remaining, order, currentJoints(robot, s.position), s.policy.limits);
  if (ordering.total_rotation_rad > s.policy.limits.max_total_rotation_rad + 1e-12) {
    return Rejection{ReplyCode::kNoReaim,
                     fmt::format("re-aimed, the cannula would turn {:.1f}° in all, more than "
                                 "{:.1f}°: the aim stays",
                                 ordering.total_rotation_rad * kRadToDeg,
                                 s.policy.limits.max_total_rotation_rad * kRadToDeg)};
  }
  s.reaim->adopted = true;
  const ReaimedAim& here = *paused->reaimed;
  paused->replan = fmt::format("re-aimed from {}: {} (was {})", s.reaim->source,
                               jointsText(here.joints), jointsText(here.before));
  out.note = fmt::format("{} target(s) re-aimed; {}", s.reaim->aims.size(), paused->replan);
  return issueRequest(s, in, out.effects);
}

}  // namespace ignav::workflow::detail
