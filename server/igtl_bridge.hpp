// The OpenIGTLink bridge for 3D Slicer (docs/OPENIGTLINK.md): the listener's thread does the
// sockets (igtl_listener.hpp), igtl::BrpBridge translates, and the inputs it makes go through the
// reducer like any client's, on the event thread, which alone calls this class.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "clock.hpp"
#include "ignav/actuation/controller.hpp"
#include "ignav/core/expected.hpp"
#include "ignav/igtl/brp.hpp"
#include "ignav/protocol/types.hpp"
#include "igtl_listener.hpp"
#include "scan_writer.hpp"
#include "scene.hpp"
#include "server_options.hpp"

namespace ignav::server {

class IgtlBridge {
 public:
  // Listens as `options` say; `wake` is called from the listener's thread when something came,
  // and from the scan writer's when a received scan is kept (in `session_dir`/received).
  // Never fatal: null when it cannot listen (logged); the server then runs without it.
  static std::unique_ptr<IgtlBridge> start(const OpenIgtlinkOptions& options,
                                           const std::filesystem::path& session_dir,
                                           std::function<void()> wake);

  int port() const { return port_; }
  std::size_t clientCount() const { return listener_->clientCount(); }
  // "" unless a weakened safeguard must be said (motion approval over OpenIGTLink).
  const std::string& safetyNotice() const { return safety_notice_; }

  // What the clients sent, answered from `session` (read again after each input: it is the
  // event thread's, which `run` changes) and `position` (the motors' latest). The inputs a
  // message makes go to `run` before the next message is looked at. `clients_changed` when a
  // client came or went. Counts the events.
  void serve(const workflow::Session& session, const actuation::Steps& position,
             const std::function<void(workflow::Input)>& run,
             const std::function<void()>& clients_changed, std::size_t& handled);

  // After every step (and every replayed record).
  void onState(const workflow::Session& session);
  // The motors' position, told as it is (a replayed record).
  void onPosition(const workflow::Session& session, const actuation::Steps& position);
  // A new reading, taken at `measured_s` (Unix s): Slicer sees the tip move (TRANSFORM at most at
  // the tip rate, and where it comes to rest); the listener streams it as TDATA to those asking.
  void onReading(const workflow::Session& session, const actuation::ControllerStatus& now,
                 const actuation::ControllerStatus& before, double measured_s);
  // The core's reply to one of the bridge's inputs, told to its client; false for anyone else's.
  bool reply(const workflow::Reply& reply, const workflow::Session& session);
  // Where POLYDATA's surfaces come from: made off the event thread (the slices thread's scene),
  // `done` called there. Without it, GET_POLYDATA has the planned paths only.
  void setSurfaceSource(std::function<void(SurfacesDone)> source) {
    surface_source_ = std::move(source);
  }
  ~IgtlBridge();
  // A replay: scans are refused before anything is written (the recorded folder stays as it was).
  void setReadOnly() { read_only_ = true; }

 private:
  IgtlBridge(const OpenIgtlinkOptions& options, std::unique_ptr<IgtlListener> listener, int port,
             std::unique_ptr<ScanWriter> scans, std::function<void()> wake);
  // Stamps each message with the server's clock and the session's metadata, then queues it.
  void send(igtl::BrpOutput out, const workflow::Session& session);

  // Surfaces made for a client, handed back from the slices thread: it outlives the bridge if it
  // must (the slices thread may answer after the bridge has gone: then nothing is woken).
  struct SurfaceMailbox {
    std::mutex mutex;
    bool open = true;
    std::function<void()> wake;
    std::deque<igtl::BrpOutput> made;  // POLYDATA (or why none), made on the slices thread
  };
  void sendSurfaces(const workflow::Session& session);

  igtl::BrpBridge bridge_;
  std::function<void(SurfacesDone)> surface_source_;
  std::shared_ptr<SurfaceMailbox> surfaces_ = std::make_shared<SurfaceMailbox>();
  std::deque<workflow::Input> inputs_;  // the bridge's inputs, run in order after its message
  std::string safety_notice_;
  Clock::time_point last_position_;
  Clock::duration tip_period_;
  actuation::Steps last_steps_;
  int port_ = 0;
  bool read_only_ = false;
  std::unique_ptr<ScanWriter> scans_;       // writes what is waiting when the bridge goes
  std::unique_ptr<IgtlListener> listener_;  // last: its thread stops first
};

}  // namespace ignav::server
