// The order of a step's effects (effect_order.hpp), as DESIGN.md's safety invariants 3 and 4 need
// it: halts before the journal, nothing but the halts when the journal fails, moves only after the
// journal and the new session, then the state, the replies and the rest.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "ignav/workflow/effect_order.hpp"

namespace ignav::workflow {
namespace {

struct Recorder final : EffectSink {
  void halt(const ControllerCommand& c) override {
    calls.push_back(std::string("halt ") + toString(c.action()));
  }
  bool journal(const std::vector<std::string>& records) override {
    calls.push_back("journal " + std::to_string(records.size()));
    return journal_ok;
  }
  void unjournaled(const Effects&) override { calls.push_back("unjournaled"); }
  void commit(Session&& session) override {
    calls.push_back("commit " + std::to_string(session.revision));
  }
  void command(const ControllerCommand& c) override {
    calls.push_back(std::string("command ") + toString(c.action()));
  }
  void publish(const Effects&) override { calls.push_back("publish"); }
  void reply(const Reply& r) override { calls.push_back("reply " + std::to_string(r.request_id)); }
  void finish(const Effects&) override { calls.push_back("finish"); }

  bool journal_ok = true;
  std::vector<std::string> calls;
};

Step aStep() {
  Step s;
  s.session.revision = 7;
  s.effects.journal = {"{\"revision\": 6}", "{\"revision\": 7}"};
  // A move exists only from an approval (motion_test covers those); clear_fault stands for any
  // command that is not a halt.
  s.effects.controller = {ControllerCommand::clearFault(), ControllerCommand::stop(),
                          ControllerCommand::home(), ControllerCommand::abort()};
  Reply a, b;
  a.request_id = 1;
  b.request_id = 2;
  s.effects.replies = {a, b};
  return s;
}

TEST(EffectOrder, HaltsThenJournalThenSessionThenMovesThenStateRepliesAndTheRest) {
  Step step = aStep();
  Recorder r;
  EXPECT_TRUE(executeStep(step, r));
  const std::vector<std::string> expected = {
      "halt stop",    "halt abort", "journal 2", "commit 7", "command clear_fault",
      "command home", "publish",    "reply 1",   "reply 2",  "finish"};
  EXPECT_EQ(r.calls, expected);
  EXPECT_EQ(step.effects.replies.size(), 2u);  // the effects stay with the caller
}

TEST(EffectOrder, AJournalThatFailsLeavesOnlyTheHalts) {
  Step step = aStep();
  Recorder r;
  r.journal_ok = false;
  EXPECT_FALSE(executeStep(step, r));
  const std::vector<std::string> expected = {"halt stop", "halt abort", "journal 2", "unjournaled"};
  EXPECT_EQ(r.calls, expected);
}

TEST(EffectOrder, AStepWithoutRecordsDoesNotTouchTheJournal) {
  Step step;
  step.session.revision = 3;
  Reply a;
  a.request_id = 9;
  step.effects.replies = {a};
  Recorder r;
  r.journal_ok = false;  // never asked
  EXPECT_TRUE(executeStep(step, r));
  const std::vector<std::string> expected = {"commit 3", "publish", "reply 9", "finish"};
  EXPECT_EQ(r.calls, expected);
}

}  // namespace
}  // namespace ignav::workflow
