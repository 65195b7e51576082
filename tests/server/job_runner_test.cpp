// The job thread (server/job_runner.hpp) on its own, with jobs whose runs are gated by the test:
// one job at a time, a newer job replaces a queued one of its kind, earlier kinds go first, and a
// run that throws becomes its kind's failure. No timing: every wait is on a condition.
#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "job_runner.hpp"

namespace ignav::server {
namespace {

using workflow::BackgroundJob;
using workflow::Input;
using workflow::JobKind;

// Holds runs until released, and records the order they ran in.
class Gate {
 public:
  void open() {
    std::lock_guard<std::mutex> lock(m_);
    open_ = true;
    cv_.notify_all();
  }
  void passThrough(std::uint64_t id) {
    std::unique_lock<std::mutex> lock(m_);
    ran_.push_back(id);
    cv_.notify_all();
    cv_.wait(lock, [&] { return open_; });
  }
  void waitUntilRunning(std::size_t n) {
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait(lock, [&] { return ran_.size() >= n; });
  }
  std::vector<std::uint64_t> ran() {
    std::lock_guard<std::mutex> lock(m_);
    return ran_;
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool open_ = false;
  std::vector<std::uint64_t> ran_;
};

BackgroundJob job(JobKind kind, std::uint64_t id, Gate& gate) {
  return BackgroundJob{kind, id, "/scans/" + std::to_string(id),
                       [kind, id, &gate](const workflow::JobContext&) {
                         gate.passThrough(id);
                         Input in;
                         in.kind = workflow::jobKindSpec(kind).succeeded;
                         in.job = id;
                         return in;
                       }};
}

// Collects outcomes as the event thread would, woken by the runner.
class Outcomes {
 public:
  explicit Outcomes(JobRunner*& runner) : runner_(runner) {}
  void wake() {
    std::lock_guard<std::mutex> lock(m_);
    ++wakes_;
    cv_.notify_all();
  }
  std::vector<Input> waitFor(std::size_t n) {
    std::vector<Input> got;
    std::unique_lock<std::mutex> lock(m_);
    for (;;) {
      for (auto& in : runner_->finished())
        got.push_back(std::move(in));
      if (got.size() >= n) return got;
      const auto seen = wakes_;
      cv_.wait(lock, [&] { return wakes_ != seen; });
    }
  }

 private:
  JobRunner*& runner_;
  std::mutex m_;
  std::condition_variable cv_;
  std::size_t wakes_ = 0;
};

// A runner whose outcomes are collected as the event thread would.
struct Rig {
  JobRunner* runner_ptr = nullptr;
  Outcomes outcomes{runner_ptr};
  JobRunner runner{[this] { outcomes.wake(); }, "/sessions/s1"};
  Rig() { runner_ptr = &runner; }
};

TEST(JobRunner, ANewerJobReplacesAQueuedOneOfItsKindAndEarlierKindsGoFirst) {
  Gate gate;
  Rig rig;
  auto& runner = rig.runner;
  auto& outcomes = rig.outcomes;

  runner.start(job(JobKind::kConfirmationMeasurement, 1, gate));
  gate.waitUntilRunning(1);  // #1 runs; the rest queue behind it
  runner.start(job(JobKind::kConfirmationMeasurement, 2, gate));
  runner.start(job(JobKind::kConfirmationMeasurement, 3, gate));  // replaces #2
  runner.start(job(JobKind::kMarkerDetection, 4, gate));          // an earlier kind: first
  gate.open();
  const auto got = outcomes.waitFor(3);
  EXPECT_EQ(gate.ran(), (std::vector<std::uint64_t>{1, 4, 3}));
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].job, 1u);
  EXPECT_EQ(got[1].job, 4u);
  EXPECT_EQ(got[1].kind, workflow::InputKind::kFiducialsDetected);
  EXPECT_EQ(got[2].job, 3u);
  EXPECT_EQ(got[2].kind, workflow::InputKind::kConfirmationMeasured);
}

TEST(JobRunner, ARunThatThrowsBecomesItsKindsFailureAndTheThreadGoesOn) {
  Gate gate;
  gate.open();
  Rig rig;
  auto& runner = rig.runner;
  auto& outcomes = rig.outcomes;
  runner.start(BackgroundJob{
      JobKind::kMarkerDetection, 7, "/scans/huge",
      [](const workflow::JobContext&) -> Input { throw std::runtime_error("std::bad_alloc"); }});
  auto got = outcomes.waitFor(1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].kind, workflow::InputKind::kFiducialDetectionFailed);
  EXPECT_EQ(got[0].job, 7u);
  EXPECT_EQ(got[0].path, "/scans/huge");
  EXPECT_EQ(got[0].error, "the marker detection failed: std::bad_alloc");
  runner.start(job(JobKind::kMarkerDetection, 8, gate));
  got = outcomes.waitFor(1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].job, 8u);
}

// A run says how far it is through its context; the event thread reads it for that kind only, and
// the run finds the session folder there.
TEST(JobRunner, ARunsProgressIsReadForItsKindWhileItRuns) {
  Gate gate;
  Rig rig;
  auto& runner = rig.runner;
  auto& outcomes = rig.outcomes;
  std::string folder_seen;
  runner.start(
      BackgroundJob{JobKind::kVolumeLoad, 5, "/scans/ct", [&](const workflow::JobContext& context) {
                      folder_seen = context.session_dir.string();
                      context.progress(30, 120);
                      gate.passThrough(5);
                      Input in;
                      in.kind = workflow::InputKind::kVolumeLoadFailed;
                      in.job = 5;
                      return in;
                    }});
  gate.waitUntilRunning(1);
  using Progress = std::pair<std::size_t, std::size_t>;
  EXPECT_EQ(runner.progress(JobKind::kVolumeLoad), (Progress{30, 120}));
  EXPECT_EQ(runner.progress(JobKind::kMarkerDetection), (Progress{0, 0}));
  gate.open();
  const auto got = outcomes.waitFor(1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].job, 5u);
  EXPECT_EQ(folder_seen, "/sessions/s1");
  EXPECT_EQ(runner.progress(JobKind::kVolumeLoad), (Progress{0, 0}));
}

}  // namespace
}  // namespace ignav::server
