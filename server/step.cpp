// One input through the reducer, and its effects in the order DESIGN.md's safety invariants
// require, which workflow::executeStep (effect_order.hpp) keeps: halts first, then the journal
// (fdatasync), the new session, the other controller commands, the state topics, the replies,
// and last the files for people (reports thread), a volume load, the background jobs (job thread)
// and the OpenIGTLink bridge. Before that, the inputs held until a fresh controller reading.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <csignal>

#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/effect_order.hpp"
#include "ignav/workflow/reducer.hpp"
#include "server_core.hpp"

namespace ignav::server {

using workflow::Input;
using workflow::InputKind;
using workflow::Session;

// What the server does with one step's effects (called by workflow::executeStep, in its order).
class Server::Sink final : public workflow::EffectSink {
 public:
  Sink(Server& server, const Input& in, const workflow::Step& step)
      : s_(server), in_(in), effects_(step.effects), revision_(step.session.revision) {}

  // Handed to the component's halt thread, which sends them at once (queued moves are dropped).
  void halt(const workflow::ControllerCommand& c) override { s_.runController(c); }

  bool journal(const std::vector<std::string>& records) override {
    s_.crashPoint("before_journal", revision_);
    if (!s_.journal_failure_.empty()) return false;
    for (const auto& line : records) {
      if (auto ok = s_.journal_->append(line); !ok) {
        // Nothing is published or acknowledged that the journal does not hold. The robot is
        // halted (its arrivals could not be recorded) and every later change is refused until
        // a restart recovers from the journal as it stands.
        s_.journal_failure_ = ok.error().message;
        spdlog::critical("{}: halting the robot and refusing every change until restarted",
                         s_.journal_failure_);
        s_.runController(workflow::ControllerCommand::stop());
        s_.publishHealth();
        return false;
      }
    }
    s_.crashPoint("after_journal", revision_);
    return true;
  }

  void unjournaled(const workflow::Effects& e) override { s_.refuseUnjournaled(in_, e); }

  void commit(Session&& session) override {
    s_.replaceSession(std::move(session));
    const auto& e = effects_;
    if (!e.journal.empty() || !e.replies.empty()) {
      spdlog::info("{} from '{}'{} #{}: {} -> {}", workflow::toString(in_.kind), in_.client_id,
                   in_.identity.empty() ? "" : " (" + in_.identity + ")", in_.request_id,
                   e.replies.empty() || e.replies.front().accepted
                       ? "accepted"
                       : "rejected (" + e.replies.front().error_code + ")",
                   workflow::toString(s_.session_.phase));
    }
  }

  // A move is sent only if the robot is still at rest where its approval says it starts.
  void command(const workflow::ControllerCommand& c) override { s_.runController(c); }

  void publish(const workflow::Effects& e) override {
    s_.state_.publishEffects(s_.session_, e, s_.readings());
  }

  void reply(const workflow::Reply& r) override { s_.sendReply(r); }

  // The files for people (Slicer exports, report slices, the report) on the reports thread:
  // handed a snapshot of the session, never waited for. Then the background jobs the step asked
  // for (handed to the job thread, never waited for), then the bridge.
  void finish(const workflow::Effects& e) override {
    const Session& now = s_.session_;
    auto& reports = s_.reports_;
    if (!workflow::isQuestion(in_.kind) &&
        (e.registration_changed || e.structures_changed || !e.targets_changed.empty() ||
         !e.targets_removed.empty())) {
      reports.exports(s_.snapshot());
    }
    if (e.plan_slices) reports.slices(s_.snapshot(), true, 0);
    if (e.reached_target_slices) reports.slices(s_.snapshot(), false, *e.reached_target_slices);
    if (e.confirmation_changed || e.tissue_fitted) reports.verification(s_.snapshot());
    if (!e.journal.empty()) reports.report(s_.snapshot());
    for (const auto kind : e.start_jobs) {
      if (auto job = workflow::jobKindSpec(kind).pending(now)) s_.jobs_.start(std::move(*job));
    }
    if (s_.igtl_) s_.igtl_->onState(now);
  }

 private:
  Server& s_;
  const Input& in_;
  const workflow::Effects& effects_;
  const std::uint64_t revision_;  // the step's
};

void Server::stepNow(Input in) {
  in.time_s = wallS();
  if (workflow::needsControllerReading(in.kind) && !in.controller) {
    // The component's latest reading: taken after every command sent so far (step() held the
    // input until then), or the last word before the connection went. A move it releases is
    // checked again on a reading taken just before it is sent (ControllerComponent::execute).
    in.controller = latestReading().status;
    // An operator resetting or homing may have just reconnected the cable: try again now.
    if ((in.kind == InputKind::kResetEmergency || in.kind == InputKind::kHome) &&
        in.controller->state == actuation::ControllerState::kDisconnected && component_) {
      component_->reconnectNow();
    }
  }
  workflow::Step s = workflow::reduce(session_, in);
  Sink sink(*this, in, s);
  workflow::executeStep(s, sink);
}

void Server::replaceSession(Session&& session) {
  session_ = std::move(session);
  snapshot_.reset();
}

const Reports::Snapshot& Server::snapshot() {
  if (!snapshot_) snapshot_ = std::make_shared<const Session>(session_);
  return snapshot_;
}

void Server::sendReply(const workflow::Reply& r) {
  if (igtl_ && igtl_->reply(r, session_)) return;
  // The server's own inputs (a job's outcome, a controller event) have no one to answer: a refused
  // one is only logged (a stale outcome's clients hear of it on JobOutcome).
  if (!r.client_id.empty() || r.request_id != 0) replies_.write(toWire(r));
  if (!r.accepted) spdlog::warn("rejected: {}", r.message);
}

// An input whose journal record cannot be written: nothing of it happens (but the halts, which
// ran first) and its sender is told why.
void Server::refuseUnjournaled(const Input& in, const workflow::Effects& effects) {
  for (const auto& r : effects.replies) {
    sendReply({r.client_id, r.request_id, false,
               workflow::toString(workflow::ReplyCode::kJournalFailed),
               fmt::format("not done: the session journal cannot be written ({}){}; restart "
                           "the server once the disk is fixed",
                           journal_failure_,
                           in.kind == InputKind::kEmergencyStop ? "; the robot WAS halted" : ""),
               0, session_.revision});
  }
  // The server's own inputs (a finished move, say) come back every control period: say it once.
  if (effects.replies.empty() && unjournaled_kinds_.insert(in.kind).second) {
    spdlog::error("{} not recorded (journal failed): dropped", workflow::toString(in.kind));
  }
}

// Fault injection for the crash tests: IGNAV_CRASH_AT=before_journal:REV or after_journal:REV
// kills the server (SIGKILL, as a power loss) at that point of the step that makes revision REV.
void Server::crashPoint(const char* where, std::uint64_t revision) const {
  if (crash_at_.empty()) return;
  if (crash_at_ == std::string(where) + ":" + std::to_string(revision)) {
    spdlog::critical("IGNAV_CRASH_AT={}: killing the server", crash_at_);
    spdlog::default_logger()->flush();
    ::raise(SIGKILL);
  }
}

void Server::publishHealth() {
  state_.publishHealth(session_, {journal_failure_, igtl_ ? igtl_->clientCount() : 0,
                                  options_.robot_id, host_, started_unix_s_});
}

// Inputs that judge the robot by a controller reading wait (held, in order, with the client
// commands that come after them) for a reading taken after every command already sent to the
// controller: the latest one may predate a move or a halt, and a slow controller takes seconds
// per reading. The event loop goes on meanwhile. Emergency stops, queries and pings never wait; an
// emergency stop refuses what was held (it came after them and must not be undone by them).
void Server::step(Input in) {
  if (in.kind == InputKind::kEmergencyStop) {
    refuseHeld(workflow::toString(workflow::ReplyCode::kSuperseded),
               "not done: an emergency stop came while this waited for a reading of the "
               "controller");
    // Before the robot-id check lets this server touch the controller, its halt goes out the
    // moment the controller starts (at once after the others' if another server has the robot).
    if (!controllerPending()) return stepNow(std::move(in));
    held_since_ = Clock::now();
    held_.push_back({std::move(in), held_since_});
    return;
  }
  // Questions that need no reading (query, ping) never wait behind the held inputs.
  const bool at_once = workflow::isQuestion(in.kind) && !workflow::needsControllerReading(in.kind);
  const bool client = workflow::isCommand(in.kind) && !at_once;
  const auto arrived = Clock::now();
  if ((client && !held_.empty()) || waitsForReading(in, arrived)) {
    if (held_.empty()) held_since_ = arrived;
    held_.push_back({std::move(in), arrived});
    if (component_) component_->pollNow();
    return;
  }
  stepNow(std::move(in));
}

// An input judged by a reading waits for one taken after every command sent so far; one that
// releases motion (approve) waits for one begun after it arrived, so that motors moved
// by hand a moment before are seen (issue 38: an approval accepted on the old position made a
// move the executor then refused, and a fault).
bool Server::waitsForReading(const Input& in, Clock::time_point arrived) const {
  if (in.controller) return false;
  // The controller not yet started (the robot-id check): what reads or halts it waits.
  if (controllerPending()) {
    return workflow::needsControllerReading(in.kind) || in.kind == InputKind::kStop ||
           in.kind == InputKind::kEmergencyStop;
  }
  if (!workflow::needsControllerReading(in.kind)) return false;
  const auto r = component_->latest();
  if (r.status.state == actuation::ControllerState::kDisconnected) return false;
  if (r.after_command < last_submitted_) return true;
  return workflow::releasesMotion(in.kind) && r.taken < arrived;
}

// Steps the held inputs whose reading has come; one that waited too long is refused.
void Server::releaseHeld() {
  const auto limit = std::chrono::milliseconds(6 * options_.controller.timeout_ms + 1000);
  while (!held_.empty()) {
    if (waitsForReading(held_.front().input, held_.front().arrived)) {
      if (controllerPending() || Clock::now() - held_since_ < limit) return;
      const Input& late = held_.front().input;
      sendReply({late.client_id, late.request_id, false,
                 workflow::toString(workflow::ReplyCode::kControllerUnavailable),
                 fmt::format("not done: no reading of the controller came within {} ms after "
                             "its last command; try again",
                             limit.count()),
                 0, session_.revision});
      held_.pop_front();
      held_since_ = Clock::now();
      continue;
    }
    Input in = std::move(held_.front().input);
    held_.pop_front();
    held_since_ = Clock::now();
    stepNow(std::move(in));
  }
}

void Server::refuseHeld(const char* code, const std::string& why) {
  for (const auto& held : held_) {
    const Input& in = held.input;
    if (!workflow::isCommand(in.kind)) continue;
    sendReply({in.client_id, in.request_id, false, code, why, 0, session_.revision});
  }
  held_.clear();
}

}  // namespace ignav::server
