// The rows' actions before motion: configuration, the CT, the registration, the targets and the
// plan (actions.hpp). Each does one row's work on the session copy; the row says where it leads.
#include <algorithm>
#include <set>

#include <fmt/format.h>

#include "actions.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {

Refusal adoptConfig(Session& s, const Input& in, ActionOutput& out) {
  if (in.policy) adoptPolicy(s, *in.policy);
  if (in.tissue) s.tissue = in.tissue;
  s.site = in.site;
  s.robot_id = in.robot_id;
  s.session_uuid = in.session_uuid;
  out.effects.robot_changed = out.effects.approval_changed = true;
  return std::nullopt;
}

Refusal startVolumeLoad(Session& s, const Input& in, ActionOutput& out) {
  if (s.volume_status.status == "loading") {
    return Rejection{ReplyCode::kBusy, "a volume is loading (" + s.volume_status.source + ")"};
  }
  Effects& e = out.effects;
  s.ct = {};
  s.ct_revision = s.revision + 1;  // this step's
  s.volume_status = {"loading", in.path, "loading " + in.path};
  s.registration.reset();
  s.registration_status = {};
  s.detecting = 0;    // a detection on the CT before is ignored when it ends
  s.structures = {};  // drawn on the CT before (a load under way is ignored when it ends)
  s.proposals = {};   // in them
  s.dose = {};        // on it
  s.robot_placement = {};
  e.structures_changed = true;
  e.start_jobs.push_back(JobKind::kVolumeLoad);  // its outcome names this step's revision
  e.volume_changed = e.registration_changed = true;
  evaluateAll(s, e);
  out.note = fmt::format(
      "CT load #{} started ({}): VolumeState shows loading with the files read, then loaded or "
      "failed",
      s.ct_revision, in.path);
  return std::nullopt;
}

Refusal keepLoadedCt(Session& s, const Input& in, ActionOutput& out) {
  s.ct = in.loaded;
  s.volume_status = {"loaded", in.loaded.source, in.loaded.description};
  out.effects.volume_changed = true;
  evaluateAll(s, out.effects);  // which targets this CT shows
  // The load was asked for in imaging: an interruption since then resumes with the CT.
  if (isInterruption(s.phase) && s.resume_phase == Phase::kImaging) {
    s.resume_phase = Phase::kRegistration;
  }
  return std::nullopt;
}

Refusal noteLoadFailure(Session& s, const Input& in, ActionOutput& out) {
  s.volume_status = {"failed", s.volume_status.source, in.error};
  out.effects.volume_changed = true;
  if (isInterruption(s.phase) && s.resume_phase == Phase::kRegistration) {
    s.resume_phase = Phase::kImaging;
  }
  return std::nullopt;
}

Refusal registerClickedFiducials(Session& s, const Input& in, ActionOutput& out) {
  if (auto bad = adoptRegistration(s, in.points, false, out.effects)) return bad;
  out.note = s.registration_status.message + dropDetection(s);
  return std::nullopt;
}

Refusal startMarkerDetection(Session& s, const Input&, ActionOutput& out) {
  if (!s.ct.volume) return Rejection{ReplyCode::kNoVolume, "no CT is loaded"};
  if (s.detecting != 0) {
    return Rejection{ReplyCode::kBusy,
                     fmt::format("the markers are already being detected on the CT ({}; "
                                 "detection #{}): wait for RegistrationState to show the outcome",
                                 s.ct.source, s.detecting)};
  }
  // The detection runs on the server's job thread; its outcome comes back as
  // fiducials_detected or fiducial_detection_failed, naming this step's revision.
  s.detecting = s.revision + 1;
  s.registration_status.status = "detecting";
  s.registration_status.message =
      fmt::format("detecting the robot's markers on the CT ({}){}", s.ct.source,
                  s.registration ? "; the registration from before stays in use until then" : "");
  out.effects.start_jobs.push_back(JobKind::kMarkerDetection);
  out.effects.registration_changed = true;
  out.note = fmt::format(
      "marker detection #{} started on the CT ({}): RegistrationState shows detecting, then the "
      "outcome (registered, or rejected with the reason)",
      s.detecting, s.ct.source);
  return std::nullopt;
}

// A format-1 journal's record (before issue 22): the detection ran within the step and registered
// at once. Replayed so: detected again on the reloaded CT, here. A detection that finds no match
// refuses the step (the record then does not replay), so the row's phase needs no guard of it.
Refusal detectAndRegisterAtOnce(Session& s, const Input&, ActionOutput& out) {
  if (!s.ct.volume) return Rejection{ReplyCode::kNoVolume, "no CT is loaded"};
  s.detecting = s.revision + 1;
  const Input found = detectFiducials(*pendingDetection(s));
  s.detecting = 0;
  if (found.kind != InputKind::kFiducialsDetected) {
    return Rejection{ReplyCode::kNoMatch, found.error};
  }
  if (auto bad = adoptRegistration(s, found.points, true, out.effects)) return bad;
  out.note = s.registration_status.message;
  return std::nullopt;
}

// The row leads out of registration into planning; while interrupted, resume then returns to
// planning instead of registration.
Refusal registerDetectedMarkers(Session& s, const Input& in, ActionOutput& out) {
  s.detecting = 0;
  if (auto bad = adoptRegistration(s, in.points, true, out.effects)) return bad;
  if (isInterruption(s.phase) && s.resume_phase == Phase::kRegistration) {
    s.resume_phase = Phase::kPlanning;
  }
  return std::nullopt;
}

Refusal refuseDetectedMarkers(Session& s, const Input& in, ActionOutput& out) {
  s.detecting = 0;
  const auto reg = registerOnRobot(*s.robot, in.points);
  if (reg) {  // markersRegister() said otherwise: the table's guards and this action disagree
    return Rejection{ReplyCode::kInternal, "the detected markers register after all"};
  }
  out.note = "the markers found do not register: " + registrationRefusal(reg.error()).message;
  out.outcome_failed = true;
  detectionFailed(s, out.note, out.effects);
  return std::nullopt;
}

Refusal noteDetectionFailure(Session& s, const Input& in, ActionOutput& out) {
  s.detecting = 0;
  detectionFailed(s, in.error, out.effects);
  return std::nullopt;
}

Refusal registerByMatrix(Session& s, const Input& in, ActionOutput& out) {
  auto reg = registration::registrationFromMatrix(*in.matrix, s.robot->config.registration.limits);
  if (!reg) return registrationRefusal(reg.error());
  s.registration = std::move(reg).value();
  s.registration_status = {
      "registered",
      fmt::format("set by '{}' as a matrix: scale {:.4f}, no fiducials (TRE unknown)", in.client_id,
                  s.registration->scale),
      false};
  out.effects.registration_changed = true;
  evaluateAll(s, out.effects);
  checkMountedRobot(s, out.effects);
  out.note = s.registration_status.message + dropDetection(s);
  return std::nullopt;
}

Refusal addTarget(Session& s, const Input& in, ActionOutput& out) {
  if (s.targets.size() >= s.policy.limits.max_targets) {
    return Rejection{ReplyCode::kTooManyTargets,
                     fmt::format("the plan already has {} targets, the most one insertion takes "
                                 "(planning.max_targets)",
                                 s.policy.limits.max_targets)};
  }
  if (auto outside = checkInsideCt(s, in.points[0])) {
    outside->message = "target " + outside->message;
    return outside;
  }
  Target t;
  t.id = s.next_target_id++;
  t.lps_mm = in.points[0];
  evaluate(s, t);
  out.new_target_id = t.id;
  out.note = t.message;
  out.effects.targets_changed.push_back(t.id);
  s.targets.push_back(std::move(t));
  return std::nullopt;
}

Refusal moveTarget(Session& s, const Input& in, ActionOutput& out) {
  Target* t = findTarget(s, in.ids[0]);
  if (!t) return Rejection{ReplyCode::kUnknownTarget, fmt::format("no target {}", in.ids[0])};
  if (auto outside = checkInsideCt(s, in.points[0])) {
    outside->message = fmt::format("target {} cannot move there: {}", t->id, outside->message);
    return outside;
  }
  t->lps_mm = in.points[0];
  t->reached = false;             // a new place
  t->clearance_override.clear();  // given for the path before
  evaluate(s, *t);
  out.note = t->message;
  out.effects.targets_changed.push_back(t->id);
  return std::nullopt;
}

Refusal removeTarget(Session& s, const Input& in, ActionOutput& out) {
  auto it = std::find_if(s.targets.begin(), s.targets.end(),
                         [&](const Target& t) { return t.id == in.ids[0]; });
  if (it == s.targets.end()) {
    return Rejection{ReplyCode::kUnknownTarget, fmt::format("no target {}", in.ids[0])};
  }
  s.targets.erase(it);
  out.effects.targets_removed.push_back(in.ids[0]);
  for (const auto& t : s.targets)
    out.effects.targets_changed.push_back(t.id);  // orders moved up
  return std::nullopt;
}

Refusal clearTargets(Session& s, const Input&, ActionOutput& out) {
  for (const auto& t : s.targets)
    out.effects.targets_removed.push_back(t.id);
  s.targets.clear();
  s.order_fixed = false;
  return std::nullopt;
}

Refusal reorderTargets(Session& s, const Input& in, ActionOutput& out) {
  const std::set<std::uint32_t> given(in.ids.begin(), in.ids.end());
  std::set<std::uint32_t> have;
  for (const auto& t : s.targets)
    have.insert(t.id);
  if (given != have || in.ids.size() != s.targets.size()) {
    return Rejection{ReplyCode::kBadOrder,
                     fmt::format("reorder_targets needs each of the {} target ids exactly once",
                                 s.targets.size())};
  }
  std::vector<Target> ordered;
  for (auto id : in.ids)
    ordered.push_back(*findTarget(s, id));
  s.targets = std::move(ordered);
  s.order_fixed = true;
  for (const auto& t : s.targets)
    out.effects.targets_changed.push_back(t.id);
  return std::nullopt;
}

namespace {

// Why the plan cannot be locked as it stands, if it cannot.
Refusal checkLockable(const Session& s) {
  if (s.targets.empty()) return Rejection{ReplyCode::kEmptyPlan, "the plan has no targets"};
  if (s.detecting != 0) {
    return Rejection{ReplyCode::kBusy,
                     fmt::format("the markers are being detected on the CT (detection #{}) and "
                                 "the registration may change: lock once RegistrationState shows "
                                 "the outcome",
                                 s.detecting)};
  }
  std::string outside;
  for (const auto& t : s.targets) {
    if (t.outside_volume && !t.reached) {
      outside += fmt::format("{}target {}: {}", outside.empty() ? "" : "; ", t.id,
                             checkInsideCt(s, t.lps_mm)->message);
    }
  }
  if (!outside.empty()) {
    return Rejection{ReplyCode::kOutsideVolume, "remove or move these first: " + outside};
  }
  std::string close;
  for (const auto& t : s.targets) {
    if (t.status() == "too_close") {
      close += fmt::format("{}target {}: {}", close.empty() ? "" : "; ", t.id, t.clearance_refusal);
    }
  }
  if (!close.empty()) {
    return Rejection{ReplyCode::kTooClose,
                     "move these, or override_clearance with a reason: " + close};
  }
  std::string bad;
  for (const auto& t : s.targets) {
    if (!t.plannable()) bad += (bad.empty() ? "" : "; ") + t.message;
  }
  if (!bad.empty()) {
    return Rejection{ReplyCode::kUnreachableTargets, "remove or move these first: " + bad};
  }
  return std::nullopt;
}

}  // namespace

Refusal lockPlan(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = checkLockable(s)) return refused;
  std::string order;
  if (auto refused = orderPlan(s, order)) return refused;
  for (const auto& t : s.targets)
    out.effects.targets_changed.push_back(t.id);
  if (auto refused = issueRequest(s, in, out.effects)) return refused;
  if (!s.pending) {
    return Rejection{ReplyCode::kNothingToDo, "every target was reached and the stylet is home"};
  }
  out.note = order + "; waiting for approval of " + s.pending->summary;
  out.effects.plan_slices = true;
  return std::nullopt;
}

// Editing again: the request pending dies with the step (safety invariant 1, reduce()), and that
// is all there is to do.
Refusal unlockPlan(Session&, const Input&, ActionOutput&) {
  return std::nullopt;
}

Refusal requestApproval(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = issueRequest(s, in, out.effects)) return refused;
  if (!s.pending) return Rejection{ReplyCode::kNothingToDo, "nothing is left to move"};
  out.note = s.pending->summary;
  return std::nullopt;
}

}  // namespace ignav::workflow::detail
