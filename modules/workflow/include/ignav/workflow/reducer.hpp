// The workflow as a table and a pure reducer: (session, input) -> (session', effects).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "ignav/workflow/reply_codes.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::workflow {

namespace detail {
struct ActionOutput;  // what an action leaves for the reply (actions.hpp)
}  // namespace detail

// Whether a row is the one that fires for this session and input (pure; never changes anything).
using Guard = bool (*)(const Session&, const Input&);
// A row's work: changes the session (a copy) and asks for effects; refuses with a Rejection for
// what is wrong with the arguments or the robot (unknown target, no CT, busy), which leaves the
// session as it was. It never picks the phase: the row's `to` is where the step goes.
using Action = std::optional<Rejection> (*)(Session&, const Input&, detail::ActionOutput&);

// One row per outcome of an allowed (phase, input) pair, as in IGSTK's state machines: every pair
// not listed is rejected with "<input> is not allowed in <phase>". The rows of a pair are tried in
// table order and the first whose guard holds fires (no guard: always); a test checks that some
// row fires for every session a pair meets. Before any row's action, a pending approval request
// dies with any input but a question or an approve (DESIGN.md safety invariant 1; reduce()).
struct Transition {
  Phase from;
  InputKind input;
  Guard guard;  // nullptr: always
  Phase to;
  Action action;
  const char* why;  // shown on the diagram's edge
};
const std::vector<Transition>& transitionTable();

// The inputs a client may send now (for WorkflowState.allowed_commands).
std::vector<InputKind> allowedCommands(Phase phase);

// The table as a Mermaid state diagram (docs/WORKFLOW.md holds the same text; CI checks it).
std::string mermaidDiagram();
// docs/WORKFLOW.md: the diagram and the table of (phase, allowed commands).
std::string workflowMarkdown();
// docs/PROTOCOL.md's table of commands, from the command table (ignav/commands/command_table.hpp)
// and the transitions: wire kind, name, least role, arguments, what it does, where it is allowed.
std::string commandsMarkdown();

// A fresh session for this robot (phase startup, no volume). The approval policy arrives with
// the config_loaded input.
Session newSession(std::string session_id, std::shared_ptr<const config::Robot> robot,
                   std::string robot_path);

// The planned needle path in LPS for joints of a registered session: the tip at home (z_c = 0,
// z_s = 0), the cannula's translation to z_c, then the stylet's arc as it deploys (25 samples).
// Empty without a registration.
std::vector<Eigen::Vector3d> needlePathLps(const Session& session,
                                           const kinematics::Joints& joints);

// The digest an approve must echo: SHA-256 (lower-case hex) over a canonical text of the robot id,
// the session (folder name and random id), plan id, target, starting motor position and every
// step increment the controller would receive, so a client approves exactly what it was shown,
// for this robot in this session only.
std::string requestDigest(const MotionScope& scope, const MotionRequest& request);
MotionScope scopeOf(const Session& session);
std::string sha256Hex(const std::string& text);

// The row that fires for `input` in `session`'s phase: the first of the pair's rows whose guard
// holds; nullptr when none does or the pair is not declared. (reduce() checks the input's shape
// before it asks; the guards assume a well-formed input.)
const Transition* firingTransition(const Session& session, const Input& input);

// Deterministic: the same inputs in the same order give the same sessions and effects.
Step reduce(const Session& session, const Input& input);

// The marker detection `session` awaits (Session::detecting), to run again after a crash; none
// when it awaits none.
std::optional<FiducialDetectionJob> pendingDetection(const Session& session);
// Runs a marker detection (registration::findFiducials: up to seconds on a large CT; the server
// runs it off its event thread) and returns the input that brings its outcome back to the
// reducer: fiducials_detected with the matched image points, or fiducial_detection_failed.
Input detectFiducials(const FiducialDetectionJob& job);
// The confirmation CT measurement `session` awaits (Confirmation::measuring), to run again after a
// crash; none when it awaits none. measureConfirmation() (closed_loop.hpp) runs it.
std::optional<ConfirmationJob> pendingConfirmation(const Session& session);
// The intermittent CT search `session` awaits (Session::scanning_needle), from the insertion
// paused now; scanNeedle() (closed_loop.hpp) runs it.
std::optional<NeedleScanJob> pendingNeedleScan(const Session& session);

// The session journal: one JSON object per line, per accepted input that changes the session:
//   {"v": 2, "revision": N, "t": Unix seconds, "input": "add_target", "phase": after,
//    "client_id", "request_id", "path", "points", "ids", "error", "source", "description",
//    "job", "summary"}
// Revisions run 1, 2, 3 ... with no gaps, so they double as the record's sequence number.
//
// Format 2 (issue 22): auto_fiducials only starts a marker detection; its outcome is a record of
// its own, fiducials_detected (with the matched image points, so replay registers from them
// without detecting again) or fiducial_detection_failed. Format 1 records are still read: a
// format-1 auto_fiducials detected and registered within its own step, and replays so (the
// detection runs again on the reloaded CT, inside that step). A journal may hold format-1 records
// followed by format-2 ones (a session recorded before the upgrade and continued after it).
constexpr int kJournalFormat = 2;
constexpr int kOldestJournalFormat = 1;

struct JournalEntry {
  Input input;  // for volume_loaded, the caller loads input.loaded.source again
  std::uint64_t revision = 0;
  std::string phase;
};
// Errors (kFormat) say what is wrong with the record.
Expected<JournalEntry> parseJournalRecord(const std::string& line);

// The session for a person (the server writes it as report.md): phase, CT, registration, a
// table of the targets with joints, motor steps, expected TRE and when each was reached, the
// robot and every approved motion; then `images` (paths relative to the report) as pictures.
std::string procedureReport(const Session& session, const std::vector<std::string>& images = {});

// Loads the CT a volume_loaded record names (I/O stays with the caller).
using CtLoader = std::function<Expected<LoadedCt>(const std::string& source)>;

// One journal line through reduce(), checking that it gives its recorded revision and phase.
// `where` names the line in errors ("journal.jsonl line 7"). The step's input is in `input`.
struct ReplayedStep {
  Step step;
  Input input;
};
Expected<ReplayedStep> replayRecord(const Session& session, const std::string& line,
                                    const CtLoader& load_ct, const std::string& where);

// Feeds journal lines through replayRecord() from `start`: crash recovery and the offline
// determinism check. Errors name `journal_name` and the line.
Expected<Session> replayJournal(Session start, const std::vector<std::string>& lines,
                                const CtLoader& load_ct, const std::string& journal_name);

}  // namespace ignav::workflow
