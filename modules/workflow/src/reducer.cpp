#include "ignav/workflow/reducer.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "actions.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "journal_records.hpp"
#include "session_rules.hpp"

namespace ignav::workflow {
namespace {

// Enough for any client's retries in flight; the session is copied per step, so not more.
constexpr std::size_t kRepliesKeptPerClient = 32;
constexpr std::size_t kClientsRemembered = 256;
constexpr double kMaxCoordinate_mm = 1e6;

using detail::Rejection;

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
  if (a.matrix_is && !a.matrix_optional && !in.matrix) {
    return Rejection{ReplyCode::kBadArguments, fmt::format("{} needs a 4x4 matrix", spec.name)};
  }
  if (!a.matrix_is && in.matrix) {
    return Rejection{ReplyCode::kBadArguments, fmt::format("{} takes no matrix", spec.name)};
  }
  return std::nullopt;
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
  if (registered && solution.reachable() && compensation_refusal.empty() && tooClose()) {
    return "too_close";
  }
  return plannable() ? "planned" : "unreachable";
}

Session newSession(std::string session_id, std::shared_ptr<const config::Robot> robot,
                   std::string robot_path) {
  Session s;
  s.session_id = std::move(session_id);
  s.robot = std::move(robot);
  s.robot_path = std::move(robot_path);
  return s;
}

const Transition* firingTransition(const Session& session, const Input& in) {
  for (const auto& t : transitionTable()) {
    if (t.from == session.phase && t.input == in.kind && (!t.guard || t.guard(session, in))) {
      return &t;
    }
  }
  return nullptr;
}

Step reduce(const Session& session, const Input& in) {
  Step step{session, {}};
  Session& s = step.session;
  Effects& e = step.effects;
  const bool command = isCommand(in.kind);
  Reply reply{in.client_id, in.request_id, false, "", "", 0, s.revision};
  reply.server_time_s = in.time_s;

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
  // A background job's outcome counts only if it is the one awaited: not one on a CT replaced
  // since, nor one a registration given by hand made moot. Wherever it arrives, it changes nothing
  // then.
  if (const JobKindSpec* job = jobOfOutcome(in.kind)) {
    const std::uint64_t awaited = job->awaited(session);
    if (awaited == 0 || in.job != awaited) {
      const std::string why = job->stale(session, in);
      Step stale = reject({ReplyCode::kStaleDetection, why});
      stale.effects.job_outcome =
          JobOutcome{in.job, job->name, toString(in.kind), "stale", why, session.revision};
      return stale;
    }
  }
  const auto& table = transitionTable();
  const bool allowed = std::any_of(table.begin(), table.end(), [&](const Transition& t) {
    return t.from == session.phase && t.input == in.kind;
  });
  if (!allowed) {
    std::string names;
    for (auto k : allowedCommands(session.phase)) {
      names += (names.empty() ? "" : ", ") + std::string(toString(k));
    }
    return reject(
        {ReplyCode::kWrongPhase, fmt::format("{} is not allowed in {} (allowed: {})",
                                             toString(in.kind), toString(session.phase), names)});
  }
  if (command) {
    if (auto bad = checkShape(in)) return reject(*bad);
  }
  const Transition* row = firingTransition(session, in);
  if (!row) {  // a test walks the table to make sure this never happens
    return reject({ReplyCode::kInternal,
                   fmt::format("{} in {}: no row's guard holds, which the table does not foresee",
                               toString(in.kind), toString(session.phase))});
  }
  // Whatever else happens, a pending approval request dies with any change (DESIGN.md safety
  // invariant 1): one rule before every row's action. Only an approve consumes it; the actions
  // that issue new ones do so after this.
  if (!isQuestion(in.kind) && in.kind != InputKind::kApprove && s.pending) {
    s.pending.reset();
    e.approval_changed = true;
  }
  detail::ActionOutput out{e, 0, {}};
  if (auto bad = row->action(s, in, out)) return reject(*bad);

  const Phase before = s.phase;
  s.phase = row->to;
  // Questions change nothing, so there is nothing to journal (and no fsync on their path).
  const bool question = isQuestion(in.kind);
  if (!question) ++s.revision;
  s.last_event = toString(in.kind);
  if (command) ++s.accepted;
  e.workflow_changed = true;
  if (before != s.phase && in.kind == InputKind::kLoadVolume) e.volume_changed = true;
  if (!question) e.journal.push_back(detail::journalLine(in, s));
  if (const JobKindSpec* job = jobOfOutcome(in.kind)) {
    const bool failed = in.kind == job->failed || out.outcome_failed;
    e.job_outcome = JobOutcome{in.job,
                               job->name,
                               toString(in.kind),
                               failed ? "failed" : "done",
                               !out.note.empty() ? out.note
                               : failed          ? in.error
                                                 : in.summary,
                               s.revision};
  }
  if (command) {
    reply.accepted = true;
    reply.target_id = out.new_target_id;
    reply.revision = s.revision;
    reply.message = out.note.empty() ? std::string("ok") : out.note;
    if (!e.start_jobs.empty()) reply.job = s.revision;
    remember(s, reply);
    e.replies.push_back(reply);
  }
  return step;
}

}  // namespace ignav::workflow
