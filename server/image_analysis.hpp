// The image analyses that take seconds on a large CT, on a thread of their own, the analysis
// thread: auto_fiducials' marker detections (registration::findFiducials) and load_confirmation's
// measurements (a confirmation CT loaded, its markers and seeds found: issue 23). The event
// thread hands over a job (immutable: the CT as a shared_ptr<const Volume>, or the scan's path
// and the robot) and never waits; the outcome comes back as an input (fiducials_detected /
// fiducial_detection_failed, confirmation_measured / confirmation_failed) through finished(),
// with the waitset woken.
//
// One analysis at a time, marker detections first. A newer job of a kind replaces one of that
// kind still queued (the session awaits one of each at most: an older job's result would be
// ignored anyway). At destruction the analysis under way is finished (it cannot be interrupted);
// queued ones are dropped: a restarted server runs what its journal awaits again.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "ignav/protocol/wire/dds.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

class ImageAnalysis {
 public:
  explicit ImageAnalysis(protocol::WaitSet& waitset);
  ~ImageAnalysis();
  ImageAnalysis(const ImageAnalysis&) = delete;
  ImageAnalysis& operator=(const ImageAnalysis&) = delete;

  // Queue an analysis (replacing one of its kind still queued); return at once.
  void start(workflow::FiducialDetectionJob job);
  void start(workflow::ConfirmationJob job);
  // The outcomes that came since last time, as inputs, in the order the analyses ended.
  std::vector<workflow::Input> finished();

 private:
  void loop();

  protocol::WaitSet& waitset_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::optional<workflow::FiducialDetectionJob> queued_detection_;
  std::optional<workflow::ConfirmationJob> queued_confirmation_;
  std::deque<workflow::Input> done_;
  bool stopping_ = false;
  std::thread thread_;  // last: it starts once everything above is built
};

}  // namespace ignav::server
