#include "image_analysis.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <exception>
#include <utility>

#include "ignav/workflow/reducer.hpp"

namespace ignav::server {

using workflow::Input;
using workflow::InputKind;

namespace {

// The analysis itself, timed and logged; an exception (out of memory on a huge CT, say) is said,
// not fatal.
template <typename Job, typename Run>
Input runTimed(const Job& job, const char* what, const std::string& source, InputKind failed,
               Run run) {
  const auto t = std::chrono::steady_clock::now();
  Input in;
  try {
    in = run(job);
  } catch (const std::exception& ex) {
    in = Input{};
    in.kind = failed;
    in.job = job.job;
    in.path = source;
    in.error = std::string("the analysis failed: ") + ex.what();
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  spdlog::info("{} #{} on {} took {:.0f} ms: {}", what, job.job, source, ms,
               in.kind == failed ? in.error : in.summary);
  return in;
}

}  // namespace

ImageAnalysis::ImageAnalysis(protocol::WaitSet& waitset)
    : waitset_(waitset), thread_([this] { loop(); }) {}

ImageAnalysis::~ImageAnalysis() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    if (queued_detection_) {
      spdlog::info("marker detection #{} dropped at shutdown (a restart runs it again)",
                   queued_detection_->job);
    }
    if (queued_confirmation_) {
      spdlog::info("confirmation CT measurement #{} dropped at shutdown (a restart runs it again)",
                   queued_confirmation_->job);
    }
    queued_detection_.reset();
    queued_confirmation_.reset();
  }
  wake_.notify_one();
  thread_.join();
}

void ImageAnalysis::start(workflow::FiducialDetectionJob job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queued_detection_) {
      spdlog::info("marker detection #{} replaced by #{} before it ran", queued_detection_->job,
                   job.job);
    }
    queued_detection_ = std::move(job);
  }
  wake_.notify_one();
}

void ImageAnalysis::start(workflow::ConfirmationJob job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queued_confirmation_) {
      spdlog::info("confirmation CT measurement #{} replaced by #{} before it ran",
                   queued_confirmation_->job, job.job);
    }
    queued_confirmation_ = std::move(job);
  }
  wake_.notify_one();
}

std::vector<Input> ImageAnalysis::finished() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Input> out(std::make_move_iterator(done_.begin()),
                         std::make_move_iterator(done_.end()));
  done_.clear();
  return out;
}

void ImageAnalysis::loop() {
  for (;;) {
    std::optional<workflow::FiducialDetectionJob> detection;
    std::optional<workflow::ConfirmationJob> confirmation;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] {
        return stopping_ || queued_detection_.has_value() || queued_confirmation_.has_value();
      });
      if (stopping_) return;
      if (queued_detection_) {
        detection = std::move(queued_detection_);
        queued_detection_.reset();
      } else {
        confirmation = std::move(queued_confirmation_);
        queued_confirmation_.reset();
      }
    }
    Input in = detection
                   ? runTimed(*detection, "marker detection", detection->ct_source,
                              InputKind::kFiducialDetectionFailed, workflow::detectFiducials)
                   : runTimed(*confirmation, "confirmation CT measurement", confirmation->source,
                              InputKind::kConfirmationFailed, workflow::measureConfirmation);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.push_back(std::move(in));
    }
    waitset_.trigger();
  }
}

}  // namespace ignav::server
