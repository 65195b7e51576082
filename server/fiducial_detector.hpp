// auto_fiducials' marker detections (registration::findFiducials: up to seconds on a large CT) on
// a thread of their own, the detector thread (issue 22): the event thread hands over a job (the
// CT as a shared_ptr<const Volume>, the search, the robot's feature points) and never waits; the
// outcome comes back as an input (fiducials_detected with the matched image points, or
// fiducial_detection_failed) through finished(), with the waitset woken.
//
// One detection at a time, in the order handed over. A newer job replaces one still queued (the
// session awaits one detection at most: an older job's result would be ignored anyway). At
// destruction the detection under way is finished (it cannot be interrupted); queued ones are
// dropped: a restarted server runs the detection its journal awaits again.
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

class FiducialDetector {
 public:
  explicit FiducialDetector(protocol::WaitSet& waitset);
  ~FiducialDetector();
  FiducialDetector(const FiducialDetector&) = delete;
  FiducialDetector& operator=(const FiducialDetector&) = delete;

  // Queues a detection (replacing one still queued); returns at once.
  void start(workflow::FiducialDetectionJob job);
  // The outcomes that came since last time, as inputs, in the order the detections ended.
  std::vector<workflow::Input> finished();

 private:
  void loop();

  protocol::WaitSet& waitset_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::optional<workflow::FiducialDetectionJob> queued_;
  std::deque<workflow::Input> done_;
  bool stopping_ = false;
  std::thread thread_;  // last: it starts once everything above is built
};

}  // namespace ignav::server
