// The background-job seam (background_jobs.hpp): every kind's description is whole, and what
// comes from it (staleness, recovery, a run that throws) holds for every kind alike.
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
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

// load_volume's job: the built-in phantom is written into the session folder as a DICOM series
// (a file per slice, which a person can open) and read back like any scan, with progress; a second
// run reads that series again (recovery, replay). A path that is not there is the load's failure,
// naming it.
TEST(BackgroundJobs, ACtLoadWritesThePhantomIntoTheSessionAndReadsItBack) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("ignav_ct_load_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto robot = test::paperRobot();
  std::size_t calls = 0, last_done = 0, last_total = 0;
  const JobContext context{dir, [&](std::size_t done, std::size_t total) {
                             ++calls;
                             last_done = done;
                             last_total = total;
                           }};
  const Input in = loadCt(12, kPhantomSource, *robot, context);
  ASSERT_EQ(in.kind, InputKind::kVolumeLoaded) << in.error;
  EXPECT_EQ(in.job, 12u);
  EXPECT_EQ(in.loaded.source, kPhantomSource);
  ASSERT_TRUE(in.loaded.volume);
  const auto grid = test::phantomCtGrid(*robot)->geometry;
  EXPECT_EQ(in.loaded.volume->geometry.dims, grid.dims);
  std::size_t slices = 0;
  for (const auto& f : fs::directory_iterator(dir / "phantom_ct"))
    slices += f.is_regular_file() ? 1 : 0;
  EXPECT_EQ(slices, static_cast<std::size_t>(grid.dims[2]));
  EXPECT_GT(calls, 0u);
  EXPECT_EQ(last_total, slices);
  EXPECT_EQ(last_done, last_total);

  const Input again = loadCt(13, kPhantomSource, *robot, {dir, {}});
  ASSERT_EQ(again.kind, InputKind::kVolumeLoaded) << again.error;
  EXPECT_EQ(again.loaded.volume->geometry.dims, grid.dims);

  const Input missing = loadCt(14, (dir / "no_such_scan").string(), *robot, context);
  EXPECT_EQ(missing.kind, InputKind::kVolumeLoadFailed);
  EXPECT_EQ(missing.job, 14u);
  EXPECT_NE(missing.error.find("no_such_scan"), std::string::npos) << missing.error;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ignav::workflow
