#include "ignav/workflow/reducer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <type_traits>

#include <fmt/format.h>

#include "journal_records.hpp"
#include "motion.hpp"

namespace ignav::workflow {
namespace {

// Enough for any client's retries in flight; the session is copied per step, so not more.
constexpr std::size_t kRepliesKeptPerClient = 32;
constexpr std::size_t kClientsRemembered = 256;
constexpr double kMaxCoordinate_mm = 1e6;

using detail::Rejection;

// modules/registration names its reasons; each is one of the reply codes (a test checks them).
Rejection registrationRefusal(const Error& error) {
  if (const auto code = replyCodeNamed(error.reason)) return Rejection{*code, error.message};
  return Rejection{ReplyCode::kInternal,
                   "registration refused (" + error.reason + "): " + error.message};
}

const Transition* findTransition(Phase phase, InputKind kind) {
  for (const auto& t : transitionTable()) {
    if (t.from == phase && t.input == kind) return &t;
  }
  return nullptr;
}

bool declared(Phase from, InputKind kind, Phase to) {
  for (const auto& t : transitionTable()) {
    if (t.from == from && t.input == kind && t.to == to) return true;
  }
  return false;
}

// The index of the first byte that does not belong to well-formed UTF-8 (no overlong forms, no
// surrogates, nothing past U+10FFFF), or npos. The journal is JSON, which holds text only: a
// client id of raw bytes once threw out of the reducer and took the server down (found by
// fuzz_command, docs/RELIABILITY.md).
std::size_t invalidUtf8At(const std::string& text) {
  const auto* b = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned c = b[i];
    std::size_t len = 0;
    unsigned lo = 0x80, hi = 0xBF;  // the second byte's range
    if (c < 0x80) {
      ++i;
      continue;
    } else if (c >= 0xC2 && c <= 0xDF) {
      len = 2;
    } else if (c >= 0xE0 && c <= 0xEF) {
      len = 3;
      if (c == 0xE0) lo = 0xA0;
      if (c == 0xED) hi = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      len = 4;
      if (c == 0xF0) lo = 0x90;
      if (c == 0xF4) hi = 0x8F;
    } else {
      return i;
    }
    if (i + len > n || b[i + 1] < lo || b[i + 1] > hi) return i;
    for (std::size_t k = 2; k < len; ++k)
      if (b[i + k] < 0x80 || b[i + k] > 0xBF) return i;
    i += len;
  }
  return std::string::npos;
}

std::optional<Rejection> checkText(const char* field, const std::string& text) {
  const std::size_t at = invalidUtf8At(text);
  if (at == std::string::npos) return std::nullopt;
  return Rejection{ReplyCode::kBadText,
                   fmt::format("{} is not UTF-8 text (byte {} is 0x{:02X})", field, at,
                               static_cast<unsigned char>(text[at]))};
}

std::optional<Rejection> checkClient(const Input& in) {
  if (in.client_id.empty() || in.client_id.size() > kMaxIdLength) {
    return Rejection{ReplyCode::kBadClientId,
                     fmt::format("client_id must have 1 to {} characters", kMaxIdLength)};
  }
  return checkText("client_id", in.client_id);
}

std::optional<Rejection> checkShape(const Input& in) {
  if (in.path.size() > kMaxPathLength) {
    return Rejection{ReplyCode::kTooLong, fmt::format("path has {} characters; at most {}",
                                                      in.path.size(), kMaxPathLength)};
  }
  if (auto bad = checkText("path", in.path)) return bad;
  if (in.points.size() > kMaxTargets || in.ids.size() > kMaxTargets) {
    return Rejection{ReplyCode::kOversized,
                     fmt::format("{} points and {} ids given; at most {} of each", in.points.size(),
                                 in.ids.size(), kMaxTargets)};
  }
  for (std::size_t i = 0; i < in.points.size(); ++i) {
    if (!in.points[i].allFinite()) {
      return Rejection{ReplyCode::kNonFinite,
                       fmt::format("points[{}] has a non-finite coordinate", i)};
    }
    // A kilometre is no place in a patient; far larger finite values once overran a message
    // buffer downstream (docs/RELIABILITY.md).
    if (in.points[i].cwiseAbs().maxCoeff() > kMaxCoordinate_mm) {
      return Rejection{ReplyCode::kOutOfRange,
                       fmt::format("points[{}] has a coordinate of {:.4g} mm; at most ±{:.0f} mm",
                                   i, in.points[i].cwiseAbs().maxCoeff(), kMaxCoordinate_mm)};
    }
  }
  if (in.digest.size() > kMaxIdLength) {
    return Rejection{ReplyCode::kTooLong, fmt::format("digest has {} characters; at most {}",
                                                      in.digest.size(), kMaxIdLength)};
  }
  // The rest from the input table: what this kind carries, and nothing else.
  const InputSpec& spec = specOf(in.kind);
  const Arguments& a = spec.args;
  if (!a.path_is && !in.path.empty()) {
    return Rejection{ReplyCode::kBadArguments, fmt::format("{} takes no path", spec.name)};
  }
  if (a.path_is && in.path.empty()) {
    return Rejection{ReplyCode::kBadArguments,
                     fmt::format("{} needs a path: {}", spec.name, a.path_is)};
  }
  if (a.path_choices) {
    const std::string choices = std::string("|") + a.path_choices + "|";
    if (in.path.find('|') != std::string::npos ||
        choices.find("|" + in.path + "|") == std::string::npos) {
      return Rejection{ReplyCode::kBadArguments,
                       fmt::format("{}'s path is one of {}; got \"{}\"", spec.name, a.path_choices,
                                   in.path.substr(0, 64))};
    }
  }
  const bool points_ok = a.points == kAnyCount || in.points.size() == a.points;
  const bool ids_ok = a.ids == kAnyCount || in.ids.size() == a.ids;
  if (!points_ok || !ids_ok) {
    auto count = [](std::size_t n) {
      return n == kAnyCount ? std::string("any number of") : std::to_string(n);
    };
    return Rejection{ReplyCode::kBadArguments,
                     fmt::format("{} takes {} point(s) and {} id(s); got {} and {}", spec.name,
                                 count(a.points), count(a.ids), in.points.size(), in.ids.size())};
  }
  if (a.matrix_is && !in.matrix) {
    return Rejection{ReplyCode::kBadArguments, fmt::format("{} needs a 4x4 matrix", spec.name)};
  }
  if (!a.matrix_is && in.matrix) {
    return Rejection{ReplyCode::kBadArguments, fmt::format("{} takes no matrix", spec.name)};
  }
  return std::nullopt;
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

// How much of the planned path runs outside the loaded CT (t.path_outside_ct_mm), with a warning
// for a person (t.path_warning). The path's pieces are straight or gently curved, so
// half-millimetre samples measure the part outside well enough for a warning.
void checkPath(const Session& s, Target& t) {
  if (!s.ct.volume || !t.solution.reachable()) return;
  const auto path = needlePathLps(s, t.solution.joints);
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

void evaluate(const Session& s, Target& t) {
  Target fresh;
  fresh.id = t.id;
  fresh.lps_mm = t.lps_mm;
  fresh.reached = t.reached;  // where the needle has been stays true whatever the registration
  fresh.reached_s = t.reached_s;
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
  if (t.solution.reachable()) t.steps = robot.transmission.toSteps(t.solution.joints).steps;
  t.message += outside_note;
  if (!outside) checkPath(s, t);
  if (!t.path_warning.empty()) t.message += "; warning: " + t.path_warning;
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
    return;
  }
  t.tre_mm = registration::expectedTre_mm(registration::describeFiducials(reg.image_mm), t.lps_mm,
                                          settings.fle_mm, reg.kind);
  t.tre_warning = t.tre_mm > settings.max_tre_mm;
}

void evaluateAll(Session& s, Effects& e) {
  for (auto& t : s.targets) {
    evaluate(s, t);
    e.targets_changed.push_back(t.id);
  }
}

std::optional<Rejection> adoptRegistration(Session& s, const std::vector<Eigen::Vector3d>& image,
                                           bool auto_detected, Effects& e) {
  const auto& robot = *s.robot;
  const std::vector<Eigen::Vector3d> model(robot.feature_points_mm.begin(),
                                           robot.feature_points_mm.end());
  auto reg = registration::registerPoints(image, model, robot.config.registration.kind,
                                          robot.config.registration.limits);
  if (!reg) return registrationRefusal(reg.error());
  s.registration = std::move(reg).value();
  s.registration_status = {
      "registered",
      fmt::format("FRE {:.3f} mm, scale {:.4f}{}", s.registration->fre_mm, s.registration->scale,
                  auto_detected ? ", markers detected on the CT" : ""),
      auto_detected};
  e.registration_changed = true;
  evaluateAll(s, e);
  return std::nullopt;
}

bool isDetectionResult(InputKind kind) {
  return kind == InputKind::kFiducialsDetected || kind == InputKind::kFiducialDetectionFailed;
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

// Registered on detected markers: out of registration into planning, or, while interrupted, back
// to planning when resumed.
Phase afterDetectionRegistered(Session& s) {
  if (s.phase == Phase::kRegistration) return Phase::kPlanning;
  if (isInterruption(s.phase) && s.resume_phase == Phase::kRegistration) {
    s.resume_phase = Phase::kPlanning;
  }
  return s.phase;
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

// Puts the request for the next motion into `s.pending`; with nothing left to do, `to` becomes
// done instead.
std::optional<Rejection> issueRequest(Session& s, const Input& in, Effects& e, Phase& to) {
  auto next = detail::nextRequest(s, in.time_s);
  if (!next) return Rejection{ReplyCode::kPlanFailed, next.error().message};
  e.approval_changed = true;
  if (!next->has_value()) {
    to = Phase::kDone;
    return std::nullopt;
  }
  s.pending = std::move(**next);
  ++s.next_plan_id;
  return std::nullopt;
}

// The phases whose robot can be used: a controller fault there becomes the fault phase.
bool robotInUse(Phase p) {
  return p == Phase::kPlanLocked || p == Phase::kMoving || p == Phase::kAtTarget ||
         p == Phase::kDone;
}

// Where resume leads after an interruption now: a move in flight is never resumed as such, it is
// planned again from where the robot stands and approved again.
Phase resumeTo(Phase p) {
  return p == Phase::kMoving ? Phase::kPlanLocked : p;
}

// The record of the motion under way gets its end.
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

// Applies an allowed input. Returns a rejection without having touched `s` in any way that
// matters (callers discard `s` on rejection anyway). `to` starts as the table's phase; inputs
// with several declared outcomes pick one. `note` becomes the reply's message.
std::optional<Rejection> apply(Session& s, const Input& in, Effects& e, std::uint32_t& new_id,
                               Phase& to, std::string& note) {
  // Whatever else happens, a pending approval request dies with any change (DESIGN.md safety
  // invariant 1); only an approve consumes it, and new ones are issued below.
  if (!isQuestion(in.kind) && in.kind != InputKind::kApprove && s.pending) {
    s.pending.reset();
    e.approval_changed = true;
  }
  switch (in.kind) {
    case InputKind::kConfigLoaded:
      if (in.policy) adoptPolicy(s, *in.policy);
      if (in.tissue) s.tissue = in.tissue;
      e.robot_changed = e.approval_changed = true;
      return std::nullopt;
    case InputKind::kLoadVolume:
      if (s.volume_status.status == "loading") {
        return Rejection{ReplyCode::kBusy, "a volume is loading (" + s.volume_status.source + ")"};
      }
      s.ct = {};
      s.ct_revision = s.revision + 1;  // this step's
      s.volume_status = {"loading", in.path, "loading " + in.path};
      s.registration.reset();
      s.registration_status = {};
      s.detecting = 0;  // a detection on the CT before is ignored when it ends
      e.load_volume = in.path;
      e.volume_changed = e.registration_changed = true;
      evaluateAll(s, e);
      return std::nullopt;
    case InputKind::kVolumeLoaded:
      s.ct = in.loaded;
      s.volume_status = {"loaded", in.loaded.source, in.loaded.description};
      e.volume_changed = true;
      evaluateAll(s, e);  // which targets this CT shows
      // The load was asked for in imaging: an interruption since then resumes with the CT.
      if (isInterruption(s.phase) && s.resume_phase == Phase::kImaging) {
        s.resume_phase = Phase::kRegistration;
      }
      return std::nullopt;
    case InputKind::kVolumeLoadFailed:
      s.volume_status = {"failed", s.volume_status.source, in.error};
      e.volume_changed = true;
      if (isInterruption(s.phase) && s.resume_phase == Phase::kRegistration) {
        s.resume_phase = Phase::kImaging;
      }
      return std::nullopt;
    case InputKind::kSetFiducials:
      if (auto bad = adoptRegistration(s, in.points, false, e)) return bad;
      note = s.registration_status.message + dropDetection(s);
      return std::nullopt;
    case InputKind::kAutoFiducials: {
      if (!s.ct.volume) return Rejection{ReplyCode::kNoVolume, "no CT is loaded"};
      if (in.journal_format == 1) {
        // A format-1 journal's record (before issue 22): the detection ran within the step and
        // registered at once. Replayed so: detected again on the reloaded CT, here.
        s.detecting = s.revision + 1;
        const Input found = detectFiducials(*pendingDetection(s));
        s.detecting = 0;
        if (found.kind != InputKind::kFiducialsDetected)
          return Rejection{ReplyCode::kNoMatch, found.error};
        if (auto bad = adoptRegistration(s, found.points, true, e)) return bad;
        note = s.registration_status.message;
        to = s.phase == Phase::kRegistration ? Phase::kPlanning : s.phase;
        return std::nullopt;
      }
      if (s.detecting != 0) {
        return Rejection{ReplyCode::kBusy,
                         fmt::format("the markers are already being detected on the CT "
                                     "({}; detection #{}): wait for RegistrationState "
                                     "to show the outcome",
                                     s.ct.source, s.detecting)};
      }
      // The detection runs on the server's detector thread; its outcome comes back as
      // fiducials_detected or fiducial_detection_failed, naming this step's revision.
      s.detecting = s.revision + 1;
      s.registration_status.status = "detecting";
      s.registration_status.message = fmt::format(
          "detecting the robot's markers on the CT ({}){}", s.ct.source,
          s.registration ? "; the registration from before stays in use until then" : "");
      e.detect_fiducials = pendingDetection(s);
      e.registration_changed = true;
      note = fmt::format(
          "marker detection #{} started on the CT ({}): RegistrationState shows detecting, then "
          "the outcome (registered, or rejected with the reason)",
          s.detecting, s.ct.source);
      return std::nullopt;
    }
    case InputKind::kFiducialsDetected:
      s.detecting = 0;
      if (auto bad = adoptRegistration(s, in.points, true, e)) {
        detectionFailed(s, "the markers found do not register: " + bad->message, e);
        to = s.phase;
        return std::nullopt;
      }
      to = afterDetectionRegistered(s);
      return std::nullopt;
    case InputKind::kFiducialDetectionFailed:
      s.detecting = 0;
      detectionFailed(s, in.error, e);
      to = s.phase;
      return std::nullopt;
    case InputKind::kSetRegistration: {
      auto reg =
          registration::registrationFromMatrix(*in.matrix, s.robot->config.registration.limits);
      if (!reg) return registrationRefusal(reg.error());
      s.registration = std::move(reg).value();
      s.registration_status = {
          "registered",
          fmt::format("set by '{}' as a matrix: scale {:.4f}, no fiducials (TRE unknown)",
                      in.client_id, s.registration->scale),
          false};
      e.registration_changed = true;
      evaluateAll(s, e);
      note = s.registration_status.message + dropDetection(s);
      return std::nullopt;
    }
    case InputKind::kAddTarget: {
      if (s.targets.size() >= s.policy.limits.max_targets) {
        return Rejection{ReplyCode::kTooManyTargets,
                         fmt::format("the plan already has {} targets, the most one insertion "
                                     "takes (planning.max_targets)",
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
      new_id = t.id;
      note = t.message;
      e.targets_changed.push_back(t.id);
      s.targets.push_back(std::move(t));
      return std::nullopt;
    }
    case InputKind::kMoveTarget: {
      Target* t = findTarget(s, in.ids[0]);
      if (!t) return Rejection{ReplyCode::kUnknownTarget, fmt::format("no target {}", in.ids[0])};
      if (auto outside = checkInsideCt(s, in.points[0])) {
        outside->message = fmt::format("target {} cannot move there: {}", t->id, outside->message);
        return outside;
      }
      t->lps_mm = in.points[0];
      t->reached = false;  // a new place
      evaluate(s, *t);
      note = t->message;
      e.targets_changed.push_back(t->id);
      return std::nullopt;
    }
    case InputKind::kRemoveTarget: {
      auto it = std::find_if(s.targets.begin(), s.targets.end(),
                             [&](const Target& t) { return t.id == in.ids[0]; });
      if (it == s.targets.end()) {
        return Rejection{ReplyCode::kUnknownTarget, fmt::format("no target {}", in.ids[0])};
      }
      s.targets.erase(it);
      e.targets_removed.push_back(in.ids[0]);
      for (const auto& t : s.targets)
        e.targets_changed.push_back(t.id);  // orders moved up
      return std::nullopt;
    }
    case InputKind::kClearTargets:
      for (const auto& t : s.targets)
        e.targets_removed.push_back(t.id);
      s.targets.clear();
      s.order_fixed = false;
      return std::nullopt;
    case InputKind::kReorderTargets: {
      std::set<std::uint32_t> given(in.ids.begin(), in.ids.end());
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
        e.targets_changed.push_back(t.id);
      return std::nullopt;
    }
    case InputKind::kLockPlan: {
      if (s.targets.empty()) return Rejection{ReplyCode::kEmptyPlan, "the plan has no targets"};
      if (s.detecting != 0) {
        return Rejection{ReplyCode::kBusy,
                         fmt::format("the markers are being detected on the CT "
                                     "(detection #{}) and the registration may change: "
                                     "lock once RegistrationState shows the outcome",
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
      std::string bad;
      for (const auto& t : s.targets) {
        if (!t.registered || !t.solution.reachable()) {
          bad += (bad.empty() ? "" : "; ") + t.message;
        }
      }
      if (!bad.empty()) {
        return Rejection{ReplyCode::kUnreachableTargets, "remove or move these first: " + bad};
      }
      std::string order;
      if (auto rejected = detail::orderPlan(s, order)) return rejected;
      for (const auto& t : s.targets)
        e.targets_changed.push_back(t.id);
      if (auto rejected = issueRequest(s, in, e, to)) return rejected;
      if (!s.pending) {
        return Rejection{ReplyCode::kNothingToDo,
                         "every target was reached and the stylet is home"};
      }
      note = order + "; waiting for approval of " + s.pending->summary;
      return std::nullopt;
    }
    case InputKind::kRequestApproval:
      if (auto rejected = issueRequest(s, in, e, to)) return rejected;
      if (!s.pending) return Rejection{ReplyCode::kNothingToDo, "nothing is left to move"};
      note = s.pending->summary;
      return std::nullopt;
    case InputKind::kApprove: {
      auto approved = detail::ApprovalCheck::approve(s, in);
      if (auto* rejected = std::get_if<Rejection>(&approved)) return *rejected;
      ActiveMotion m{std::get<ApprovedMotion>(std::move(approved)), 0, s.pending->from, false};
      s.pending.reset();
      e.approval_changed = e.motion_changed = true;
      e.controller.push_back(ControllerCommand::move(m.approved, 0));
      note = fmt::format("plan {} approved: {} move(s), about {:.1f} s", m.request().plan_id,
                         m.request().moves.size(), m.request().duration_s);
      s.motions.push_back({m.request().plan_id, m.request().target_id,
                           in.identity.empty() ? in.client_id : in.identity, in.time_s, -1.0, ""});
      s.motion = std::move(m);
      return std::nullopt;
    }
    case InputKind::kSegmentDone: {
      if (!s.motion) return Rejection{ReplyCode::kInternal, "no motion is under way"};
      ActiveMotion& m = *s.motion;
      const auto& move = m.request().moves[m.segment];
      const std::string fault = readingFault(in);
      if (!fault.empty()) {
        interruptMotion(s, e, in.time_s, "fault: " + fault);
        s.fault = fmt::format("controller fault during {} of plan {}: {}",
                              planning::toString(move.kind), m.request().plan_id, fault);
        s.resume_phase = Phase::kPlanLocked;
        e.controller.push_back(ControllerCommand::abort());
        to = Phase::kFault;
        return std::nullopt;
      }
      if (in.controller->state == actuation::ControllerState::kMoving) {
        return Rejection{ReplyCode::kInternal, "segment_done while the controller still moves"};
      }
      actuation::Steps expected = m.segment_from;
      for (std::size_t a = 0; a < 3; ++a)
        expected.motor[a] += move.steps.motor[a];
      e.motion_changed = true;
      if (in.controller->position != expected) {
        interruptMotion(s, e, in.time_s, "fault: arrival check failed");
        s.fault = fmt::format("arrival check failed after {} of plan {}: {}",
                              planning::toString(move.kind), m.request().plan_id,
                              detail::describeMismatch(in.controller->position, expected));
        s.resume_phase = Phase::kPlanLocked;
        to = Phase::kFault;
        return std::nullopt;
      }
      s.position = expected;
      if (++m.segment < m.request().moves.size()) {
        m.segment_from = expected;
        e.controller.push_back(ControllerCommand::move(m.approved, m.segment));
        to = Phase::kMoving;
        return std::nullopt;
      }
      const std::uint32_t target = m.request().target_id;
      s.motion.reset();
      endMotionRecord(s, in.time_s, "arrived");
      if (target == 0) {
        to = Phase::kDone;
        return std::nullopt;
      }
      if (Target* t = findTarget(s, target)) {
        t->reached = true;
        t->reached_s = in.time_s;
        e.targets_changed.push_back(target);
      }
      to = Phase::kAtTarget;
      return issueRequest(s, in, e, to);
    }
    case InputKind::kControllerFault:
      s.fault = readingFault(in);
      e.controller.push_back(ControllerCommand::abort());
      interruptMotion(s, e, in.time_s, "fault: " + s.fault);
      if (robotInUse(s.phase)) {
        s.resume_phase = resumeTo(s.phase);
        to = Phase::kFault;
      } else {
        to = s.phase;  // recorded; approvals and resets check the controller themselves
      }
      return std::nullopt;
    case InputKind::kServerRestarted: {
      to = s.phase;
      const bool robot_moving =
          in.controller && in.controller->state == actuation::ControllerState::kMoving;
      // Whatever moves when the server starts moves without a live approval: halt it.
      if (robot_moving) e.controller.push_back(ControllerCommand::abort());
      if (s.phase == Phase::kMoving) {
        interruptMotion(s, e, in.time_s, "server restarted");
        s.fault = fmt::format("the server restarted during plan {}: check the position and reset",
                              s.motion ? s.motion->request().plan_id : 0);
        s.resume_phase = Phase::kPlanLocked;
        if (!robot_moving) e.controller.push_back(ControllerCommand::abort());
        to = Phase::kFault;
        return std::nullopt;
      }
      if (!robotInUse(s.phase)) return std::nullopt;  // resume and reset check the robot
      std::string doubt = readingFault(in);
      if (doubt.empty() && robot_moving) doubt = "the robot was moving when the server started";
      if (doubt.empty() && in.controller->position != s.position) {
        doubt =
            "after the restart " + detail::describeMismatch(in.controller->position, s.position);
      }
      if (!doubt.empty()) {
        s.fault = doubt;
        s.resume_phase = s.phase;
        to = Phase::kFault;
        return std::nullopt;
      }
      if (s.phase == Phase::kPlanLocked || s.phase == Phase::kAtTarget) {
        if (auto rejected = issueRequest(s, in, e, to)) return rejected;
        to = s.phase;
      }
      return std::nullopt;
    }
    case InputKind::kStop:
      s.resume_phase = resumeTo(s.phase);
      if (s.motion) {
        e.controller.push_back(ControllerCommand::stop());
        interruptMotion(s, e, in.time_s, "stopped");
      }
      return std::nullopt;
    case InputKind::kEmergencyStop:
      e.controller.push_back(ControllerCommand::abort());  // whatever moves, halt it
      interruptMotion(s, e, in.time_s, "emergency stop");
      // Taken while interrupted (stopped, manual, fault), the first interruption's phase stays.
      if (!isInterruption(s.phase)) s.resume_phase = resumeTo(s.phase);
      return std::nullopt;
    case InputKind::kManual:
      if (!isInterruption(s.phase)) s.resume_phase = resumeTo(s.phase);  // manual after a stop
      e.controller.push_back(ControllerCommand::stop());
      interruptMotion(s, e, in.time_s, "manual control");
      note = "manual control: the robot may be moved by hand; resume takes it back";
      return std::nullopt;
    case InputKind::kCheckReady: {
      if (auto busy = detail::checkAtRest(in)) return busy;
      if (in.controller->state == actuation::ControllerState::kFault) {
        return Rejection{ReplyCode::kControllerFault,
                         "the controller reports a fault: " + in.controller->fault};
      }
      if (in.path == "targeting" && !s.registration) {
        return Rejection{ReplyCode::kNotRegistered,
                         "no registration yet: register the image to the robot first"};
      }
      note = in.path == "robot" ? "the robot is ready" : "ready for targets";
      return std::nullopt;
    }
    case InputKind::kResume: {
      if (s.phase == Phase::kManual) {
        // Back from manual control: where the hands left the motors becomes the position.
        if (auto busy = detail::checkAtRest(in)) return busy;
        if (in.controller->state == actuation::ControllerState::kFault) {
          return Rejection{ReplyCode::kControllerFault,
                           "the controller reports a fault: " + in.controller->fault};
        }
        if (s.position != in.controller->position) e.motion_changed = true;
        s.position = in.controller->position;
        if (s.motion) {
          s.motion.reset();
          e.motion_changed = true;
        }
      }
      to = s.resume_phase;
      if (to != Phase::kPlanLocked && to != Phase::kAtTarget) return std::nullopt;
      if (auto busy = detail::checkAtRest(in)) return busy;
      if (in.controller->state == actuation::ControllerState::kFault) {
        return Rejection{ReplyCode::kControllerFault,
                         "the controller reports a fault: " + in.controller->fault +
                             "; emergency stop, then "
                             "reset"};
      }
      if (auto off = detail::checkPosition(s, in.controller->position)) return off;
      s.position = in.controller->position;
      if (s.motion) {
        s.motion.reset();
        e.motion_changed = true;
      }
      if (auto rejected = issueRequest(s, in, e, to)) return rejected;
      note = s.pending ? "waiting for approval of " + s.pending->summary : "nothing left to do";
      return std::nullopt;
    }
    case InputKind::kResetEmergency: {
      if (auto busy = detail::checkAtRest(in)) return busy;
      if (auto off = detail::checkPosition(s, in.controller->position)) return off;
      s.position = in.controller->position;
      if (s.motion) {
        s.motion.reset();
        e.motion_changed = true;
      }
      if (in.controller->state == actuation::ControllerState::kFault) {
        e.controller.push_back(ControllerCommand::clearFault());
      }
      s.fault.clear();
      note = fmt::format("position checked: motors at {} / {} / {} steps", s.position.motor[0],
                         s.position.motor[1], s.position.motor[2]);
      return std::nullopt;
    }
    case InputKind::kHome:
      if (auto busy = detail::checkAtRest(in)) return busy;
      e.controller.push_back(ControllerCommand::home());
      s.position = {};
      if (s.motion) {
        s.motion.reset();
        e.motion_changed = true;
      }
      note = "the present position is home now (zero steps on every motor)";
      return std::nullopt;
    case InputKind::kUnlockPlan:
      return std::nullopt;
    case InputKind::kQuery:
      e.robot_changed = e.volume_changed = e.registration_changed = true;
      e.approval_changed = e.motion_changed = true;
      for (const auto& t : s.targets)
        e.targets_changed.push_back(t.id);
      return std::nullopt;
    case InputKind::kPing:
      // The time the server stamped on the input as it took it; the reply carries the revision.
      note = fmt::format("server_time_unix_s={:.6f} revision={}", in.time_s, s.revision);
      return std::nullopt;
  }
  return Rejection{ReplyCode::kInternal, "unhandled input"};
}

void remember(Session& s, const Reply& reply) {
  auto& kept = s.replies[reply.client_id];
  kept[reply.request_id] = reply;
  while (kept.size() > kRepliesKeptPerClient)
    kept.erase(kept.begin());
  // Bounded in clients too: a sender spraying client ids would otherwise grow this without end.
  // Another client's replies go (the first in order: deterministic, as replay needs); its retries
  // would be executed again, a cost only a crowd of more than kClientsRemembered pays.
  while (s.replies.size() > kClientsRemembered) {
    auto victim = s.replies.begin();
    if (victim->first == reply.client_id) ++victim;
    s.replies.erase(victim);
  }
}

}  // namespace

std::vector<Eigen::Vector3d> needlePathLps(const Session& s, const kinematics::Joints& j) {
  if (!s.registration || !s.robot) return {};
  const auto& kin = s.robot->kinematics;
  const auto& reg = *s.registration;
  std::vector<Eigen::Vector3d> out;
  kinematics::Joints k{j.theta_c_rad, 0.0, 0.0};
  out.push_back(reg.toImage(kin.forward(k).tip_mm));
  k.z_c_mm = j.z_c_mm;
  constexpr int kArcSamples = 24;
  for (int i = 0; i <= kArcSamples; ++i) {
    k.z_s_mm = j.z_s_mm * i / kArcSamples;
    out.push_back(reg.toImage(kin.forward(k).tip_mm));
  }
  return out;
}

std::string Target::status() const {
  if (outside_volume && !reached) return "outside_volume";
  if (!registered) return "unregistered";
  if (reached) return "reached";
  return solution.reachable() ? "planned" : "unreachable";
}

Session newSession(std::string session_id, std::shared_ptr<const config::Robot> robot,
                   std::string robot_path) {
  Session s;
  s.session_id = std::move(session_id);
  s.robot = std::move(robot);
  s.robot_path = std::move(robot_path);
  return s;
}

Step reduce(const Session& session, const Input& in) {
  Step step{session, {}};
  Session& s = step.session;
  Effects& e = step.effects;
  const bool command = isCommand(in.kind);
  Reply reply{in.client_id, in.request_id, false, "", "", 0, s.revision};

  auto reject = [&](const Rejection& r) {
    Step rejected{session, {}};
    reply.error_code = toString(r.code);
    reply.message = r.message;
    reply.revision = session.revision;
    ++rejected.session.rejected;
    if (command && !in.client_id.empty() && in.client_id.size() <= kMaxIdLength &&
        invalidUtf8At(in.client_id) == std::string::npos) {
      remember(rejected.session, reply);
    }
    rejected.effects.replies.push_back(reply);
    return rejected;
  };

  if (command) {
    if (auto bad = checkClient(in)) return reject(*bad);
    const auto client = session.replies.find(in.client_id);
    if (client != session.replies.end()) {
      const auto seen = client->second.find(in.request_id);
      if (seen != client->second.end()) {  // a retry: answer again, do not execute twice
        Step again{session, {}};
        again.effects.replies.push_back(seen->second);
        return again;
      }
    }
  }
  // A detection's outcome counts only if it is the one awaited: not one on a CT replaced since,
  // nor one a registration given by hand made moot. Wherever it arrives, it changes nothing then.
  if (isDetectionResult(in.kind) && (session.detecting == 0 || in.job != session.detecting)) {
    return reject({ReplyCode::kStaleDetection, staleDetection(session, in)});
  }
  const Transition* t = findTransition(session.phase, in.kind);
  if (!t) {
    std::string allowed;
    for (auto k : allowedCommands(session.phase)) {
      allowed += (allowed.empty() ? "" : ", ") + std::string(toString(k));
    }
    return reject(
        {ReplyCode::kWrongPhase, fmt::format("{} is not allowed in {} (allowed: {})",
                                             toString(in.kind), toString(session.phase), allowed)});
  }
  if (command) {
    if (auto bad = checkShape(in)) return reject(*bad);
  }
  std::uint32_t new_id = 0;
  Phase to = t->to;
  std::string note;
  if (auto bad = apply(s, in, e, new_id, to, note)) return reject(*bad);
  if (!declared(session.phase, in.kind, to)) {
    return reject({ReplyCode::kInternal,
                   fmt::format("{} would lead from {} to {}, which the table does not "
                               "declare",
                               toString(in.kind), toString(session.phase), toString(to))});
  }

  const Phase before = s.phase;
  s.phase = to;
  // Questions change nothing, so there is nothing to journal (and no fsync on their path).
  const bool question = isQuestion(in.kind);
  if (!question) ++s.revision;
  s.last_event = toString(in.kind);
  if (command) ++s.accepted;
  e.workflow_changed = true;
  if (before != s.phase && in.kind == InputKind::kLoadVolume) e.volume_changed = true;
  if (!question) e.journal.push_back(detail::journalLine(in, s));
  if (command) {
    reply.accepted = true;
    reply.target_id = new_id;
    reply.revision = s.revision;
    reply.message = note.empty() ? std::string("ok") : note;
    remember(s, reply);
    e.replies.push_back(reply);
  }
  return step;
}

}  // namespace ignav::workflow
