#include "fiducial_detector.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <exception>
#include <utility>

#include "ignav/workflow/reducer.hpp"

namespace ignav::server {

using workflow::Input;
using workflow::InputKind;

FiducialDetector::FiducialDetector(protocol::WaitSet& waitset)
    : waitset_(waitset), thread_([this] { loop(); }) {}

FiducialDetector::~FiducialDetector() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    if (queued_) {
      spdlog::info("marker detection #{} dropped at shutdown (a restart runs it again)",
                   queued_->job);
    }
    queued_.reset();
  }
  wake_.notify_one();
  thread_.join();
}

void FiducialDetector::start(workflow::FiducialDetectionJob job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queued_) {
      spdlog::info("marker detection #{} replaced by #{} before it ran", queued_->job, job.job);
    }
    queued_ = std::move(job);
  }
  wake_.notify_one();
}

std::vector<Input> FiducialDetector::finished() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Input> out(std::make_move_iterator(done_.begin()),
                         std::make_move_iterator(done_.end()));
  done_.clear();
  return out;
}

void FiducialDetector::loop() {
  for (;;) {
    workflow::FiducialDetectionJob job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || queued_.has_value(); });
      if (stopping_) return;
      job = std::move(*queued_);
      queued_.reset();
    }
    const auto t = std::chrono::steady_clock::now();
    Input in;
    try {
      in = workflow::detectFiducials(job);
    } catch (const std::exception& ex) {  // e.g. out of memory on a huge CT: said, not fatal
      in = Input{};
      in.kind = InputKind::kFiducialDetectionFailed;
      in.job = job.job;
      in.path = job.ct_source;
      in.error = std::string("the detection failed: ") + ex.what();
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
    spdlog::info("marker detection #{} on {} took {:.0f} ms: {}", job.job, job.ct_source, ms,
                 in.kind == InputKind::kFiducialsDetected ? in.summary : in.error);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.push_back(std::move(in));
    }
    waitset_.trigger();
  }
}

}  // namespace ignav::server
