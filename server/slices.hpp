// The slices clients ask for (SliceRequest -> SliceReply, docs/PROTOCOL.md), rendered on a
// thread of their own, the "slices" thread (issue 22.2): the event thread hands over the request
// with an immutable snapshot of the session and never waits; the slices thread reslices the CT,
// draws the overlays, encodes the PNG and writes the reply itself. docs/ARCHITECTURE.md draws it.
//
// Requests are answered in the order they came, one at a time, each from the session as it was
// when the request was taken (as when the event thread drew them). The queue is bounded: a
// request that finds kMaxQueued waiting is refused at once with a reply that says so (the client
// asks again), never queued and never waited for. At destruction the slice being drawn is
// finished and the ones still waiting are answered that the server is stopping.
//
// The 3D view's scene (SceneRequest -> SceneReply, scene.hpp) is made here too, in the same
// queue: what a view shows is drawn on one thread, off the event thread, in the order asked.
#pragma once

#include <Eigen/Core>

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "ignav/core/expected.hpp"
#include "ignav/protocol/types.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/volume/render.hpp"
#include "ignav/workflow/session.hpp"
#include "scene.hpp"

namespace ignav::server {

class Slices {
 public:
  using Snapshot = std::shared_ptr<const workflow::Session>;
  // A few per client of a busy viewer (three views, each fetching ahead), for a few clients.
  static constexpr std::size_t kMaxQueued = 32;

  explicit Slices(const protocol::Participant& participant);
  ~Slices();  // finishes the slice being drawn, refuses the rest, joins
  Slices(const Slices&) = delete;
  Slices& operator=(const Slices&) = delete;

  // Queues `request`, to be drawn from `session`; refuses it at once if the queue is full.
  void request(const protocol::SliceRequest& request, Snapshot session);
  // Queues a part of the 3D view's scene, the same way.
  void request(const protocol::SceneRequest& request, Snapshot session);
  // The scene's surfaces for another edge (OpenIGTLink's POLYDATA), the same kept meshes, queued
  // the same way: `done` is called on the slices thread with them, or with why not (the queue is
  // full, the server stops).
  void surfaces(Snapshot session, SurfacesDone done);

 private:
  struct Job {
    Snapshot session;
    std::string client_id, view;
    std::uint64_t request_id = 0;
    Eigen::Vector3d centre_lps = Eigen::Vector3d::Zero();
    std::uint32_t size_px = 0;
    double pixel_mm = 0.0, window = 0.0, level = 0.0;
    bool overlays = false, region_only = false;
    std::optional<protocol::SceneRequest> scene;  // set: a part of the scene, not a slice
    SurfacesDone surfaces_done;                   // set: the scene's surfaces for another edge
  };
  struct Result {
    std::string client_id, message;
    std::uint64_t request_id = 0;
    bool ok = false;
    std::uint32_t width = 0, height = 0;
    Eigen::Matrix4d pixel_to_lps = Eigen::Matrix4d::Identity();
    std::vector<std::uint8_t> png;
  };

  void enqueue(Job job);
  void loop();
  Result render(const Job& job);
  void send(Result& result) const;
  void refuse(const Job& job, const std::string& why) const;

  protocol::TopicWriter<protocol::SliceReply> replies_;
  protocol::TopicWriter<protocol::SceneReply> scene_replies_;
  SceneBuilder scene_;              // the slices thread's alone, as the renderer
  volume::SliceRenderer renderer_;  // the slices thread's alone: its buffers serve every slice
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> queue_;
  bool stopping_ = false;
  std::uint64_t done_ = 0, refused_ = 0;  // for the log at shutdown
  std::thread thread_;                    // last: it starts once everything above is built
};

}  // namespace ignav::server
