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
Input runTimed(const BackgroundJob& job, const workflow::JobContext& context) {
  const auto& spec = workflow::jobKindSpec(job.kind);
  const auto t = std::chrono::steady_clock::now();
  Input in;
  try {
    in = job.run(context);
  } catch (const std::exception& ex) {
    in = workflow::failedOutcome(job, std::string("the ") + spec.name + " failed: " + ex.what());
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  spdlog::info("{} #{} on {} took {:.0f} ms: {}", spec.name, job.id, job.source, ms,
               in.kind == spec.failed ? in.error : in.summary);
  return in;
}

}  // namespace

JobRunner::JobRunner(std::function<void()> wake, std::filesystem::path session_dir)
    : wake_up_(std::move(wake)),
      session_dir_(std::move(session_dir)),
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

std::pair<std::size_t, std::size_t> JobRunner::progress(workflow::JobKind kind) const {
  if (running_kind_ != static_cast<int>(kind)) return {0, 0};
  return {done_units_, total_units_};
}

void JobRunner::report(std::size_t done, std::size_t total) {
  done_units_ = done;
  total_units_ = total;
  // Wake the event thread about every 5 % so that the progress reaches clients.
  if (wake_up_ && (total == 0 || done % std::max<std::size_t>(1, total / 20) == 0)) wake_up_();
}

void JobRunner::loop() {
  const workflow::JobContext context{
      session_dir_, [this](std::size_t done, std::size_t total) { report(done, total); }};
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
    done_units_ = total_units_ = 0;
    running_kind_ = static_cast<int>(job.kind);
    Input in = runTimed(job, context);
    running_kind_ = -1;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.push_back(std::move(in));
    }
    if (wake_up_) wake_up_();
  }
}

}  // namespace ignav::server
