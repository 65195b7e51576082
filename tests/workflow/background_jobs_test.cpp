// The background-job seam (background_jobs.hpp): every kind's description is whole, and what
// comes from it (staleness, recovery, a run that throws) holds for every kind alike.
#include <gtest/gtest.h>

#include <set>

#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "workflow/bench.hpp"

namespace ignav::workflow {
namespace {

TEST(BackgroundJobs, EveryKindsOutcomesAreTheServersOwnInputsAndHaveTransitions) {
  std::set<InputKind> outcomes;
  for (const auto& spec : jobKinds()) {
    SCOPED_TRACE(spec.name);
    EXPECT_EQ(&jobKindSpec(spec.kind), &spec);
    for (const InputKind outcome : {spec.succeeded, spec.failed}) {
      EXPECT_FALSE(isCommand(outcome)) << toString(outcome) << ": a client could forge it";
      EXPECT_EQ(jobOfOutcome(outcome), &spec);
      EXPECT_TRUE(outcomes.insert(outcome).second) << toString(outcome) << " ends two kinds";
      bool has_row = false;
      for (const auto& t : transitionTable())
        has_row = has_row || t.input == outcome;
      EXPECT_TRUE(has_row) << toString(outcome) << " would be refused in every phase";
    }
  }
  EXPECT_EQ(jobOfOutcome(InputKind::kAddTarget), nullptr);
}

TEST(BackgroundJobs, AnOutcomeOfAJobNotAwaitedIsRefusedAndChangesNothingForEveryKind) {
  rig::Bench b;
  ASSERT_TRUE(pendingJobs(b.s).empty());  // nothing to start again after a crash
  for (const auto& spec : jobKinds()) {
    SCOPED_TRACE(spec.name);
    ASSERT_EQ(spec.awaited(b.s), 0u);
    for (const InputKind outcome : {spec.succeeded, spec.failed}) {
      Input in = b.internal(outcome);
      in.job = 7;
      in.path = "/scans/elsewhere";
      const Session before = b.s;
      const Step step = reduce(before, in);
      ASSERT_EQ(step.effects.replies.size(), 1u);
      EXPECT_EQ(step.effects.replies[0].error_code, "stale_detection");
      EXPECT_EQ(step.effects.replies[0].message, spec.stale(before, in));
      EXPECT_EQ(step.session.revision, before.revision);
      EXPECT_TRUE(step.effects.journal.empty());
      EXPECT_TRUE(step.effects.start_jobs.empty());
    }
  }
}

TEST(BackgroundJobs, ARunThatCannotFinishBecomesItsKindsFailureNamingTheJob) {
  for (const auto& spec : jobKinds()) {
    SCOPED_TRACE(spec.name);
    BackgroundJob job{spec.kind, 42, "/scans/ct", nullptr};
    const Input failed = failedOutcome(job, "out of memory");
    EXPECT_EQ(failed.kind, spec.failed);
    EXPECT_EQ(failed.job, 42u);
    EXPECT_EQ(failed.path, "/scans/ct");
    EXPECT_EQ(failed.error, "out of memory");
  }
}

}  // namespace
}  // namespace ignav::workflow
