// The order in which a step's effects are carried out, in one place: the server and the tests
// that play its part (tests/workflow/motion_test.cpp) both run a step through executeStep(), so
// the order the safety invariants need (DESIGN.md 3 and 4) is written once:
//
//   1. halts (stop, abort): before anything else, even the journal (invariant 3);
//   2. the journal records, durably (invariant 4); if they cannot be written, nothing else of
//      the step happens (unjournaled());
//   3. the new session replaces the old (commit);
//   4. the other controller commands (moves, home, clear fault): only once the journal holds
//      the input that released them;
//   5. the changed state is published;
//   6. the replies;
//   7. the rest (files for people, a volume load, a marker detection, bridges): finish().
//
// Pure: no threads, no I/O here; the sink does the work.
#pragma once

#include <string>
#include <vector>

#include "ignav/workflow/session.hpp"

namespace ignav::workflow {

struct EffectSink {
  virtual ~EffectSink() = default;
  // 1. A stop or an abort, before the journal.
  virtual void halt(const ControllerCommand& command) = 0;
  // 2. Appends the records durably (called only when there are some); false when they could not
  // all be written.
  virtual bool journal(const std::vector<std::string>& records) = 0;
  // 2'. The records could not be written: only the halts happened. Says so to whom it concerns.
  virtual void unjournaled(const Effects& /*effects*/) {}
  // 3. The step is durable: its session becomes the current one (the sink may move it).
  virtual void commit(Session&& session) = 0;
  // 4. Any controller command that is not a halt, in the reducer's order, after commit.
  virtual void command(const ControllerCommand& command) = 0;
  // 5. 6. 7.
  virtual void publish(const Effects& /*effects*/) {}
  virtual void reply(const Reply& /*reply*/) {}
  virtual void finish(const Effects& /*effects*/) {}
};

// Runs `step` through `sink` in the order above; `step.session` is moved into commit(), the
// effects stay. False when the journal could not be written (nothing but the halts happened).
bool executeStep(Step& step, EffectSink& sink);

}  // namespace ignav::workflow
