// The session's files for people: the procedure report (report.md and the slices in report/), the
// exports 3D Slicer opens (fiducials.mrk.json, targets.mrk.json, image_to_robot.tfm) and the
// closed loop's (verification/: seeds.mrk.json, the targeting figure; tissues_fitted.yaml). They
// are rendered on a thread of their own, the "reports" thread (issue 22.2): the event thread
// hands over an immutable snapshot of the session and never waits. docs/ARCHITECTURE.md draws it.
//
// Jobs run in the order given. A newer job of the same kind replaces a queued older one (the
// report and the exports depend on the newest session only; the slices at a lock replace every
// queued slice job, as a lock starts the report's pictures afresh). At destruction the queue is
// drained: every state handed over is written before the process ends.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "ignav/volume/render.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

// The navigation overlays of a slice: fiducials, the robot's feasible region, the targets.
volume::Overlays overlaysFor(const workflow::Session& session);

class Reports {
 public:
  using Snapshot = std::shared_ptr<const workflow::Session>;

  explicit Reports(std::filesystem::path session_dir);
  ~Reports();  // drains the queue, then joins
  Reports(const Reports&) = delete;
  Reports& operator=(const Reports&) = delete;

  // The Slicer files (rewritten whenever the registration or the targets change).
  void exports(Snapshot session);
  // report.md, listing the slices rendered so far.
  void report(Snapshot session);
  // Slices through every target (at most 12; at a lock: the earlier pictures are dropped) or
  // through the target just reached (`reached_id`), with the tip where the verified steps put it.
  void slices(Snapshot session, bool all_targets, std::uint32_t reached_id);
  // The confirmation CT's seeds for Slicer, the targeting figure, and the fitted tissues as a
  // configs/tissues.yaml the next session can use.
  void verification(Snapshot session);

 private:
  enum class Kind { kExports, kReport, kSlices, kVerification };
  struct Job {
    Kind kind = Kind::kReport;
    Snapshot session;
    bool all_targets = false;
    std::uint32_t reached_id = 0;
  };

  void submit(Job job);
  void loop();
  void run(const Job& job);
  void writeExports(const workflow::Session& session);
  void writeReport(const workflow::Session& session) const;
  void writeSlices(const workflow::Session& session, bool all_targets, std::uint32_t reached_id);
  void writeVerification(const workflow::Session& session) const;

  const std::filesystem::path session_dir_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> queue_;
  bool stopping_ = false;
  std::uint64_t done_ = 0, replaced_ = 0;  // for the log at shutdown
  // The reports thread's own: the slice files per target id, listed by the report.
  std::map<std::uint32_t, std::vector<std::string>> images_;
  // What structures.seg.nrrd holds (the set and the roles the plan gave it), so that it is written
  // again only when they change.
  std::shared_ptr<const anatomy::StructureSet> exported_structures_;
  std::vector<workflow::StructureRoleChoice> exported_roles_;
  std::thread thread_;  // last: it starts once everything above is built
};

}  // namespace ignav::server
