// The job thread: the workflow's background jobs (workflow/background_jobs.hpp: CT loads, marker
// detections, confirmation CT measurements, and whatever kinds are declared next) run here, off
// the event thread, one at a time. The event thread hands over a job (it holds an immutable
// snapshot) and never waits; the outcome comes back as an input through finished(), with the event
// thread woken.
//
// One queued job per kind: a newer job replaces one of its kind still queued (the session awaits
// one of each at most: an older job's outcome would be refused as stale anyway). When several
// kinds are queued, the earlier JobKind runs first. At destruction the job under way is finished
// (it cannot be interrupted); queued ones are dropped: a restarted server runs what its journal
// awaits again (workflow::pendingJobs).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "ignav/workflow/background_jobs.hpp"

namespace ignav::server {

class JobRunner {
 public:
  // `wake` is called (from the job thread) whenever an outcome is waiting, and as a job's progress
  // passes every 5 %: the server triggers its waitset's guard. Jobs leave their files for people
  // in `session_dir` (JobContext).
  JobRunner(std::function<void()> wake, std::filesystem::path session_dir);
  ~JobRunner();
  JobRunner(const JobRunner&) = delete;
  JobRunner& operator=(const JobRunner&) = delete;

  // Queue a job (replacing one of its kind still queued); return at once.
  void start(workflow::BackgroundJob job);
  // The outcomes that came since last time, as inputs, in the order the jobs ended.
  std::vector<workflow::Input> finished();
  // The running job's progress (done, total) when it is of `kind`; {0, 0} otherwise.
  std::pair<std::size_t, std::size_t> progress(workflow::JobKind kind) const;

 private:
  void loop();
  void report(std::size_t done, std::size_t total);

  std::function<void()> wake_up_;
  const std::filesystem::path session_dir_;
  std::atomic<int> running_kind_{-1};  // a JobKind, -1: none
  std::atomic<std::size_t> done_units_{0}, total_units_{0};
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<std::optional<workflow::BackgroundJob>> queued_;  // by JobKind
  std::deque<workflow::Input> done_;
  bool stopping_ = false;
  std::thread thread_;  // last: it starts once everything above is built
};

}  // namespace ignav::server
