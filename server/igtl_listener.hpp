// OpenIGTLink connections for the BRP bridge: an Asio thread accepts clients, reassembles their
// messages and queues them for the server's event thread, which answers through send(). Transport
// only: what the messages mean is modules/igtl's business (brp.hpp). A message that cannot be read
// is answered STATUS(BAD_MESSAGE) naming why, and the connection goes on; a stream that is not
// OpenIGTLink is let go once that answer has gone out. A socket error costs that one connection,
// never the server.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/igtl/message.hpp"

namespace ignav::server {

struct IgtlListenerOptions {
  std::string address = "127.0.0.1";  // loopback unless a site opens it
  int port = 18944;                   // 0: any free port (tests)
  // A client is dropped when its socket fails, when TCP keep-alive probes go unanswered, or when
  // something we send it stays unread for this long (a client that stopped reading).
  double timeout_s = 5.0;
  std::size_t max_clients = 16;
  std::size_t max_outbox_bytes = 4 * 1024 * 1024;  // of ordinary messages waiting
  double tip_rate_hz = 20.0;  // the TDATA stream's rate (STT_TDATA asks for at most this)
  // The largest IMAGE a client may send (0: as any other message): a scanner bridge's scan
  // (openigtlink.max_scan_mb). A client holds at most one while it arrives.
  std::uint64_t max_image_bytes = 0;
};

struct IgtlEvent {
  enum class Kind { kConnected, kMessage, kBadMessage, kDisconnected };
  Kind kind = Kind::kMessage;
  std::uint64_t client = 0;
  std::string peer;       // "127.0.0.1:53122"
  igtl::Message message;  // kMessage
  std::string error;      // kBadMessage: what was wrong (already answered); kDisconnected: why
};

class IgtlListener {
 public:
  // `wake` is called (from the Asio thread) whenever events are waiting.
  IgtlListener(IgtlListenerOptions options, std::function<void()> wake);
  ~IgtlListener();
  IgtlListener(const IgtlListener&) = delete;
  IgtlListener& operator=(const IgtlListener&) = delete;

  // Binds and starts the thread; returns the port listened on. Errors name the address.
  Expected<int> start();
  std::vector<IgtlEvent> take();  // thread-safe
  // Queues a message (thread-safe), encoded on the listener's thread in the header version the
  // client speaks (the highest it sent; version-2 messages get an id); unknown or gone clients
  // are ignored.
  void send(std::uint64_t client, igtl::Message message);
  // IMAGE and POLYDATA are bulk: encoded on the listener's encoder thread, at most two images or
  // a scene's surfaces (32) on their way per client (beyond: STATUS busy), written a megabyte at
  // a time. Not for broadcast.
  void broadcast(igtl::Message message);
  static bool isBulk(const igtl::Message& message);
  // The needle tip now (RAS, its pose), read at `measured_s` (Unix s), the robot `moving` or not:
  // clients that sent STT_TDATA get it as TDATA ("NeedleTip") at the tip rate from the listener's
  // own timer (deadline by deadline, so the stream keeps time whatever the event thread does),
  // while it moves and once more when it comes to rest. Thread-safe.
  void publishTip(const Eigen::Matrix4d& pose_ras, double measured_s, bool moving);
  std::size_t clientCount() const { return client_count_.load(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<std::size_t> client_count_{0};
};

}  // namespace ignav::server
