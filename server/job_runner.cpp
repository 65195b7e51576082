#include "job_runner.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <utility>

namespace ignav::server {

using workflow::BackgroundJob;
using workflow::Input;

namespace {

// The job itself, timed and logged; an exception (out of memory on a huge CT, say) is said, not
// fatal.
Input runTimed(const BackgroundJob& job) {
  const auto& spec = workflow::jobKindSpec(job.kind);
  const auto t = std::chrono::steady_clock::now();
  Input in;
  try {
    in = job.run();
  } catch (const std::exception& ex) {
    in = workflow::failedOutcome(job, std::string("the analysis failed: ") + ex.what());
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  spdlog::info("{} #{} on {} took {:.0f} ms: {}", spec.name, job.id, job.source, ms,
               in.kind == spec.failed ? in.error : in.summary);
  return in;
}

}  // namespace

JobRunner::JobRunner(std::function<void()> wake)
    : wake_up_(std::move(wake)),
      queued_(workflow::jobKinds().size()),
      thread_([this] { loop(); }) {}

JobRunner::~JobRunner() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    for (auto& job : queued_) {
      if (!job) continue;
      spdlog::info("{} #{} dropped at shutdown (a restart runs it again)",
                   workflow::jobKindSpec(job->kind).name, job->id);
      job.reset();
    }
  }
  wake_.notify_one();
  thread_.join();
}

void JobRunner::start(BackgroundJob job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto& slot = queued_.at(static_cast<std::size_t>(job.kind));
    if (slot) {
      spdlog::info("{} #{} replaced by #{} before it ran", workflow::jobKindSpec(job.kind).name,
                   slot->id, job.id);
    }
    slot = std::move(job);
  }
  wake_.notify_one();
}

std::vector<Input> JobRunner::finished() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Input> out(std::make_move_iterator(done_.begin()),
                         std::make_move_iterator(done_.end()));
  done_.clear();
  return out;
}

void JobRunner::loop() {
  for (;;) {
    BackgroundJob job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      auto first_queued = [this] {
        return std::find_if(queued_.begin(), queued_.end(),
                            [](const auto& slot) { return slot.has_value(); });
      };
      wake_.wait(lock, [&] { return stopping_ || first_queued() != queued_.end(); });
      if (stopping_) return;
      auto slot = first_queued();
      job = std::move(**slot);
      slot->reset();
    }
    Input in = runTimed(job);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.push_back(std::move(in));
    }
    if (wake_up_) wake_up_();
  }
}

}  // namespace ignav::server
