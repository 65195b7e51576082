// The rows' actions of the closed loop (issue 23, actions.hpp): a confirmation CT measured
// against the reached targets, a person's corrections to the match, the tissue fitted from the
// errors, and the profile the plan aims with. The match and the errors are derived again from the
// seeds and the corrections after every change (rematch), so replay is exact.
#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "actions.hpp"
#include "ignav/verification/seed_matching.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {
namespace {

std::vector<const Target*> reachedTargets(const Session& s) {
  std::vector<const Target*> out;
  for (const auto& t : s.targets)
    if (t.reached) out.push_back(&t);
  return out;
}

const FoundSeed* seedById(const Confirmation& c, std::uint32_t id) {
  for (const auto& seed : c.seeds)
    if (seed.id == id) return &seed;
  return nullptr;
}

std::string seedIds(const Confirmation& c) {
  if (c.seeds.empty()) return "none";
  return fmt::format("{}-{}", c.seeds.front().id, c.seeds.back().id);
}

// What the model predicted for a reached target: the landing of the joints it was reached with,
// in the tissue it was aimed for (landing on the target, to the compensation's residual), or
// else in the session's prediction tissue.
void predict(const Session& s, const Target& t, MeasuredTarget& m) {
  std::optional<Eigen::Vector3d> landing;
  if (t.compensated) {
    landing = t.compensated->landing_robot_mm;
  } else if (s.tissue) {
    compensation::DeflectionModel model;
    model.needle = s.tissue->needle;
    model.tissue = s.tissue->tissue;
    if (auto l = compensation::predictLanding(s.robot->kinematics, model, t.reached_joints)) {
      landing = l->tip_mm;
    }
  }
  if (!landing) return;
  m.predicted_robot_mm = *landing;
  m.predicted_error_mm = (*landing - t.robot_mm).norm();
}

std::string summaryText(const Confirmation& c) {
  if (!c.summary) return "no target measured";
  const auto& e = c.summary->error;
  std::string text = fmt::format(
      "{} target(s): error {:.2f} ± {:.2f} mm (mean ± SD), max {:.2f}, min {:.2f}, RMS {:.2f} mm",
      e.count, e.mean, e.sd_sample, e.max, e.min, e.rms);
  auto ids = [](const std::vector<std::uint32_t>& v, const char* prefix) {
    std::string out;
    for (auto id : v)
      out += (out.empty() ? "" : ", ") + std::string(prefix) + std::to_string(id);
    return out;
  };
  if (!c.missing_targets.empty()) text += "; no seed for " + ids(c.missing_targets, "T");
  if (!c.extra_seeds.empty()) text += "; seeds of no target: " + ids(c.extra_seeds, "#");
  return text;
}

// The measured rows (targets to rows_source) from one confirmation into another.
void moveRows(Confirmation& from, Confirmation& to) {
  to.targets = std::move(from.targets);
  to.missing_targets = std::move(from.missing_targets);
  to.extra_seeds = std::move(from.extra_seeds);
  to.summary = std::move(from.summary);
  to.text = std::move(from.text);
  to.rows_source = std::move(from.rows_source);
}

// The match and the errors from the seeds (less those rejected) and the pairs a person fixed:
// fixed pairs first, the rest by the optimal assignment. An assignment that needs a person
// (ambiguous, or more seeds than targets) leaves the status unmatched, with the reason.
void rematch(Session& s) {
  Confirmation& c = s.confirmation;
  // A match that needs a person keeps the rows of the last scan that matched, not none.
  Confirmation kept;
  moveRows(c, kept);
  auto keepRows = [&](const std::string& why) {
    c.status = "unmatched";
    c.message = why;
    if (kept.targets.empty() && kept.missing_targets.empty()) return;
    moveRows(kept, c);
    c.message += fmt::format("; the errors measured on {} stay until then", c.rows_source);
  };
  c.targets.clear();
  c.missing_targets.clear();
  c.extra_seeds.clear();
  c.summary.reset();
  c.text.clear();
  c.rows_source.clear();
  if (!c.registration) return;
  const Eigen::Matrix4d image_to_robot = c.registration->registration.imageToRobot();
  const Eigen::Matrix4d robot_to_image = image_to_robot.inverse();
  std::map<std::uint32_t, std::pair<const FoundSeed*, std::string>> pairs;  // by target id
  std::set<std::uint32_t> used;
  std::vector<verification::TargetPoint> open;
  for (const Target* t : reachedTargets(s)) {
    const auto review = c.reviews.find(t->id);
    const FoundSeed* seed =
        review == c.reviews.end() ? nullptr : seedById(c, review->second.seed_id);
    if (seed && !seed->rejected) {
      pairs[t->id] = {seed, review->second.how};
      used.insert(seed->id);
    } else {
      open.push_back({t->id, (robot_to_image * t->robot_mm.homogeneous()).head<3>()});
    }
  }
  std::vector<const FoundSeed*> free;
  std::vector<Eigen::Vector3d> free_lps;
  for (const auto& seed : c.seeds) {
    if (seed.rejected || used.count(seed.id)) continue;
    free.push_back(&seed);
    free_lps.push_back(seed.lps_mm);
  }
  c.status = "measured";
  if (!open.empty() && !free.empty()) {
    auto match = verification::matchSeeds(open, free_lps);
    if (!match) {
      keepRows(fmt::format(
          "the seeds of {} need a person: {}: {} (reject_seed what is no seed of this plan, or "
          "place_seed / accept_seed the targets)",
          c.source, match.error().reason, match.error().message));
      return;
    }
    for (std::size_t i = 0; i < open.size(); ++i) {
      const auto& m = match->targets[i];
      if (m.seed) {
        const FoundSeed* seed = free[*m.seed];
        pairs[open[i].id] = {seed, seed->kind == "tip" ? "tip" : "detected"};
      }
    }
    for (std::size_t k : match->extra_seeds)
      c.extra_seeds.push_back(free[k]->id);
  } else {
    for (const auto* seed : free)
      c.extra_seeds.push_back(seed->id);
  }
  std::vector<verification::TargetError> errors;
  for (const Target* t : reachedTargets(s)) {
    const auto pair = pairs.find(t->id);
    if (pair == pairs.end()) {
      c.missing_targets.push_back(t->id);
      continue;
    }
    auto error =
        verification::targetError({t->id, t->robot_mm}, pair->second.first->lps_mm, image_to_robot);
    if (!error) {  // a finite similarity and finite points: cannot happen
      keepRows("target " + std::to_string(t->id) + ": " + error.error().message);
      return;
    }
    MeasuredTarget m{*error, pair->second.first->id, pair->second.second, t->reached_joints};
    predict(s, *t, m);
    c.targets.push_back(m);
    errors.push_back(*error);
  }
  if (!errors.empty()) c.summary = verification::summarizeErrors(errors);
  c.rows_source = c.source;
  c.text = summaryText(c);
  c.message = c.text;
}

// A scan refused: the measurement before stays (state unchanged) and the message says why.
void refuseScan(Confirmation& c, const std::string& source, const std::string& why) {
  c.measuring = 0;
  c.measuring_source.clear();
  c.measuring_matrix.reset();
  c.message = fmt::format("the confirmation CT {} was refused: {}{}", source, why,
                          c.source.empty() ? "" : "; the measurement of " + c.source + " stays");
}

// Seeds and fits need a measured scan of reached targets.
Refusal needsMeasurement(const Session& s) {
  if (!s.confirmation.registration) {
    return Rejection{ReplyCode::kNoConfirmation,
                     "no confirmation CT has been measured: load_confirmation first"};
  }
  return std::nullopt;
}

bool isProfileName(const std::string& name) {
  return !name.empty() && name.size() <= 64 && std::all_of(name.begin(), name.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-';
  });
}

// The profiles use_tissue may name: the configured one and those fitted in this session.
std::vector<const config::TissueProfile*> knownProfiles(const Session& s) {
  std::vector<const config::TissueProfile*> out;
  if (s.tissue) out.push_back(&*s.tissue);
  for (const auto& f : s.fitted_tissues)
    out.push_back(&f.profile);
  return out;
}

}  // namespace

Refusal startConfirmation(Session& s, const Input& in, ActionOutput& out) {
  Confirmation& c = s.confirmation;
  if (c.measuring != 0) {
    return Rejection{ReplyCode::kBusy, fmt::format("a confirmation CT is being measured ({}): "
                                                   "wait for VerificationState to show it",
                                                   c.measuring_source)};
  }
  if (reachedTargets(s).empty()) {
    return Rejection{ReplyCode::kNothingReached,
                     "no target has been reached: there are no seeds to measure yet"};
  }
  if (!s.registration) {
    return Rejection{ReplyCode::kNotRegistered,
                     "the session has no registration to compare the confirmation CT with"};
  }
  if (auto bad = checkGivenMatrix(s, in.matrix, "the confirmation CT's matrix")) return bad;
  c.measuring = s.revision + 1;  // this step's
  c.measuring_source = in.path;
  c.measuring_matrix = in.matrix;
  out.effects.start_jobs.push_back(JobKind::kConfirmationMeasurement);
  out.effects.confirmation_changed = true;
  out.note = fmt::format(
      "measuring the confirmation CT {} (#{}): VerificationState shows measuring, then the "
      "seeds and the errors, or why the scan was refused",
      in.path, c.measuring);
  return std::nullopt;
}

Refusal adoptConfirmation(Session& s, const Input& in, ActionOutput& out) {
  Confirmation& c = s.confirmation;
  out.effects.confirmation_changed = true;
  auto refuse = [&](const std::string& why) { refuseScan(c, in.path, why); };
  if (!s.registration) {
    refuse("the session's registration is gone (a CT loaded meanwhile)");
    return std::nullopt;
  }
  auto reg = registerScan(*s.robot, s.registration, in.points, c.measuring_matrix);
  if (!reg) {
    refuse(reg.error().reason + ": " + reg.error().message);
    return std::nullopt;
  }
  if (in.seeds.empty()) {
    refuse("no_seeds: no seeds found (" + in.summary + ")");
    return std::nullopt;
  }
  Confirmation fresh;
  fresh.source = in.path;
  fresh.ct = in.loaded.volume;
  fresh.markers_lps_mm = in.points;
  fresh.registration = std::move(reg).value();
  fresh.detection_summary = in.summary;
  fresh.seeds = in.seeds;
  // The rows measured so far go along: rematch replaces them, or keeps them (and says so) while
  // the new scan's match needs a person.
  moveRows(c, fresh);
  c = std::move(fresh);
  rematch(s);
  c.message = c.registration->message + "; " + c.message;
  recomputeDose(s, in, "the seeds a confirmation CT found", out);  // delivered beside planned
  return std::nullopt;
}

Refusal noteConfirmationFailure(Session& s, const Input& in, ActionOutput& out) {
  refuseScan(s.confirmation, in.path, in.error);
  out.effects.confirmation_changed = true;
  return std::nullopt;
}

Refusal placeSeed(Session& s, const Input& in, ActionOutput& out) {
  if (auto bad = needsMeasurement(s)) return bad;
  const Target* t = findTarget(s, in.ids[0]);
  if (!t || !t->reached) {
    return Rejection{
        ReplyCode::kUnknownTarget,
        fmt::format("no reached target {}: seeds belong to reached targets", in.ids[0])};
  }
  Confirmation& c = s.confirmation;
  const auto review = c.reviews.find(t->id);
  FoundSeed* placed = nullptr;
  if (review != c.reviews.end() && review->second.how == "placed") {
    for (auto& seed : c.seeds)
      if (seed.id == review->second.seed_id) placed = &seed;
  }
  if (!placed) {
    FoundSeed seed;
    seed.id = c.seeds.empty() ? 1 : c.seeds.back().id + 1;
    seed.placed = true;
    c.seeds.push_back(seed);
    placed = &c.seeds.back();
  }
  placed->lps_mm = in.points[0];
  c.reviews[t->id] = {placed->id, "placed"};
  rematch(s);
  out.effects.confirmation_changed = true;
  out.note =
      fmt::format("target {}'s seed placed by hand (seed #{}); {}", t->id, placed->id, c.message);
  return std::nullopt;
}

Refusal acceptSeed(Session& s, const Input& in, ActionOutput& out) {
  if (auto bad = needsMeasurement(s)) return bad;
  Confirmation& c = s.confirmation;
  const auto m = std::find_if(c.targets.begin(), c.targets.end(), [&](const MeasuredTarget& x) {
    return x.error.target_id == in.ids[0];
  });
  if (m == c.targets.end()) {
    return Rejection{ReplyCode::kUnknownTarget,
                     fmt::format("target {} has no matched seed to accept{}", in.ids[0],
                                 c.status == "unmatched" ? " (the match needs a person)" : "")};
  }
  c.reviews[in.ids[0]] = {m->seed_id, "accepted"};
  rematch(s);
  out.effects.confirmation_changed = true;
  return std::nullopt;
}

Refusal rejectSeed(Session& s, const Input& in, ActionOutput& out) {
  if (auto bad = needsMeasurement(s)) return bad;
  Confirmation& c = s.confirmation;
  const auto seed = std::find_if(c.seeds.begin(), c.seeds.end(),
                                 [&](const FoundSeed& x) { return x.id == in.ids[0]; });
  if (seed == c.seeds.end()) {
    return Rejection{
        ReplyCode::kUnknownSeed,
        fmt::format("no seed {} on the confirmation CT (seeds {})", in.ids[0], seedIds(c))};
  }
  seed->rejected = true;
  for (auto r = c.reviews.begin(); r != c.reviews.end();) {
    r = r->second.seed_id == in.ids[0] ? c.reviews.erase(r) : std::next(r);
  }
  rematch(s);
  out.effects.confirmation_changed = true;
  out.note = fmt::format("seed #{} rejected; {}", in.ids[0], c.message);
  return std::nullopt;
}

Refusal fitTissue(Session& s, const Input& in, ActionOutput& out) {
  if (!isProfileName(in.path)) {
    return Rejection{ReplyCode::kBadName,
                     "a tissue profile's name is 1-64 letters, digits, '_' or '-'"};
  }
  if (auto bad = needsMeasurement(s)) return bad;
  const Confirmation& c = s.confirmation;
  if (c.status != "measured" || c.targets.empty()) {
    return Rejection{ReplyCode::kNoConfirmation,
                     "no measured errors to fit (the match needs a person first)"};
  }
  if (!s.tissue) {
    return Rejection{ReplyCode::kFitFailed,
                     "no needle model: the server runs without a tissue profile (server.yaml "
                     "tissue:), whose needle the fit would use"};
  }
  compensation::DeflectionModel model;
  model.needle = s.tissue->needle;
  const std::vector<compensation::TargetingRecord> records = measuredRecords(s);
  auto fit = compensation::fitTissueFromTargeting(s.robot->kinematics, model, records);
  if (!fit) return Rejection{ReplyCode::kFitFailed, "the fit: " + fit.error().message};
  FittedTissue fitted;
  fitted.fit = *fit;
  fitted.targets = records.size();
  fitted.profile.name = in.path;
  fitted.profile.source = fmt::format("fitted to {} targets of session {} (confirmation CT {})",
                                      records.size(), s.session_id, c.source);
  fitted.profile.needle = model.needle;
  fitted.profile.tissue = fit->tissue;
  auto yaml = compensation::tissueProfileYaml(in.path, *fit, fitted.profile.source, false);
  if (!yaml) return Rejection{ReplyCode::kFitFailed, yaml.error().message};
  fitted.yaml = *yaml;
  auto same = std::find_if(s.fitted_tissues.begin(), s.fitted_tissues.end(),
                           [&](const FittedTissue& f) { return f.profile.name == in.path; });
  if (same != s.fitted_tissues.end()) {
    *same = fitted;
  } else {
    s.fitted_tissues.push_back(fitted);
  }
  out.effects.tissue_fitted = out.effects.confirmation_changed = true;
  out.note = fmt::format(
      "tissue '{}' fitted to {} targets: λ1 {:.3f} ± {:.3f}, λ2 {:.3f} ± {:.3f}; RMS {:.3f} mm "
      "(plain bicycle {:.3f}, no deflection {:.3f}){}",
      in.path, records.size(), fit->tissue.lambda1, fit->standard_errors.at(0), fit->tissue.lambda2,
      fit->standard_errors.at(1), fit->rms_mm, fit->rms_bicycle_mm, fit->rms_no_deflection_mm,
      fit->limit.empty() ? "" : "; " + fit->limit);
  return std::nullopt;
}

Refusal useTissue(Session& s, const Input& in, ActionOutput& out) {
  if (in.path == "none") {
    s.aim_tissue.reset();
  } else {
    std::string names;
    const config::TissueProfile* chosen = nullptr;
    for (const auto* p : knownProfiles(s)) {
      names += (names.empty() ? "" : ", ") + p->name;
      if (p->name == in.path) chosen = p;  // a fitted one of the same name comes later: wins
    }
    if (!chosen) {
      return Rejection{ReplyCode::kUnknownTissue,
                       fmt::format("no tissue profile '{}' (known: {}; none: aim without "
                                   "compensation)",
                                   in.path.substr(0, 64), names.empty() ? "none" : names)};
    }
    s.aim_tissue = *chosen;
  }
  evaluateAll(s, out.effects);
  out.effects.robot_changed = true;  // RobotState names the aim
  std::size_t refused = 0;
  for (const auto& t : s.targets)
    if (!t.compensation_refusal.empty()) ++refused;
  out.note = s.aim_tissue ? fmt::format("aiming for tissue '{}'{}", s.aim_tissue->name,
                                        refused ? fmt::format(": {} target(s) out of reach so "
                                                              "aimed (TargetState says why)",
                                                              refused)
                                                : std::string())
                          : std::string("aiming at the targets as planned (no compensation)");
  return std::nullopt;
}

// A fit judged wrong is forgotten: not offered to use_tissue, not in tissues_fitted.yaml or the
// report. The aim is the plan's: it drops the profile only with the plan open (evaluated again as
// planned), and a locked plan that aims with it is refused rather than changed under an approval.
Refusal discardTissue(Session& s, const Input& in, ActionOutput& out) {
  auto fitted = std::find_if(s.fitted_tissues.begin(), s.fitted_tissues.end(),
                             [&](const FittedTissue& f) { return f.profile.name == in.path; });
  if (fitted == s.fitted_tissues.end()) {
    std::string names;
    for (const auto& f : s.fitted_tissues)
      names += (names.empty() ? "" : ", ") + f.profile.name;
    return Rejection{ReplyCode::kUnknownTissue,
                     fmt::format("no tissue '{}' was fitted in this session (fitted: {})",
                                 in.path.substr(0, 64), names.empty() ? "none" : names)};
  }
  // The aim is a copy of the profile chosen; a fitted one shadows a configured one of its name.
  const bool aimed = s.aim_tissue && s.aim_tissue->name == fitted->profile.name &&
                     s.aim_tissue->source == fitted->profile.source;
  if (aimed && s.phase != Phase::kPlanning) {
    return Rejection{ReplyCode::kWrongPhase,
                     fmt::format("the plan aims with tissue '{}' and is not open ({}): discard it "
                                 "in planning (unlock_plan first; its targets are then aimed as "
                                 "planned)",
                                 in.path, toString(s.phase))};
  }
  s.fitted_tissues.erase(fitted);
  out.effects.tissue_fitted = out.effects.confirmation_changed = true;
  if (aimed) {
    s.aim_tissue.reset();
    evaluateAll(s, out.effects);
    out.effects.robot_changed = true;  // RobotState names the aim
  }
  out.note = fmt::format("tissue '{}' discarded{}", in.path,
                         aimed ? "; the targets are aimed as planned (no compensation)" : "");
  return std::nullopt;
}

}  // namespace ignav::workflow::detail
