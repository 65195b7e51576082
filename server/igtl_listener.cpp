#include "igtl_listener.hpp"

#include <netinet/in.h>
#include <netinet/tcp.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <boost/asio.hpp>

namespace ignav::server {
namespace asio = boost::asio;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;

struct IgtlListener::Impl {
  struct Connection {
    std::uint64_t id = 0;
    std::string peer;
    tcp::socket socket;
    igtl::Decoder decoder;
    std::array<char, 16 * 1024> read_buffer{};
    std::deque<std::shared_ptr<const igtl::Wire>> outbox;
    std::size_t outbox_bytes = 0;  // of ordinary messages (bulk ones are counted in slots)
    // Where in outbox.front() writing has got to: its segment, and bytes of that segment.
    std::size_t front_segment = 0, front_written = 0;
    // Images and surfaces being encoded for it or waiting, in slots (bulkCost); which outbox
    // entries are bulk, and their slots.
    std::size_t bulk = 0;
    std::map<const igtl::Wire*, std::size_t> bulk_wires;
    bool large_send_buffer = false;
    bool writing = false;
    // STT_TDATA asked for the tip: at least this long between two frames (STP_TDATA: none).
    std::optional<std::chrono::milliseconds> tdata_interval;
    Clock::time_point tdata_last;
    // The header version it spoke: answered in the highest it used (1 until it sends a 2).
    std::uint16_t header_version = 1;
    std::string closing;              // why it is let go once what it was sent has gone out
    Clock::time_point write_started;  // of the chunk being written: progress, not the message
    explicit Connection(tcp::socket s) : socket(std::move(s)) {}
  };

  IgtlListenerOptions options;
  std::function<void()> wake;
  std::atomic<std::size_t>& client_count;
  asio::io_context io;
  tcp::acceptor acceptor{io};
  asio::steady_timer watchdog{io};
  std::map<std::uint64_t, std::shared_ptr<Connection>> connections;
  std::uint64_t next_id = 1;
  std::uint32_t next_message_id = 1;  // version-2 messages' ids, unique on this listener
  std::thread thread;
  std::mutex mutex;
  std::vector<IgtlEvent> events;
  // The encoder thread's queue: (client, message in its header version).
  std::thread encoder;
  std::mutex encoder_mutex;
  std::condition_variable encoder_wake;
  std::deque<std::pair<std::uint64_t, igtl::Message>> encoder_queue;
  bool encoder_stop = false;
  struct VoxelCrc {
    std::weak_ptr<const char> owner;  // expired: the volume is gone, the entry with it
    std::size_t bytes = 0;
    std::uint64_t crc = 0;
  };
  std::map<const char*, VoxelCrc> voxel_crcs;  // the encoder thread's
  // The tip stream: the latest pose the event thread published, and the timer that sends it.
  struct Tip {
    Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
    double measured_s = 0;
    bool moving = false;
    std::uint64_t seq = 0;  // 0: none yet
  };
  std::mutex tip_mutex;
  Tip tip;
  std::uint64_t tip_sent = 0;  // the seq last streamed
  asio::steady_timer tip_timer{io};
  Clock::time_point tip_deadline;
  static constexpr std::size_t kWriteChunkBytes = 1 << 20;
  // Slots of bulk messages per client: two images (a CT each, up to a few hundred megabytes) or a
  // scene's surfaces (a megabyte or so each), at once.
  static constexpr std::size_t kMaxBulkSlots = 32;
  static std::size_t bulkCost(const igtl::Message& m) { return m.type == "IMAGE" ? 16 : 1; }

  Impl(IgtlListenerOptions o, std::function<void()> w, std::atomic<std::size_t>& count)
      : options(std::move(o)), wake(std::move(w)), client_count(count) {}

  void push(IgtlEvent e) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      events.push_back(std::move(e));
    }
    wake();
  }

  void accept() {
    acceptor.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
      if (ec == asio::error::operation_aborted) return;
      if (!ec) admit(std::move(socket));
      accept();
    });
  }

  void admit(tcp::socket socket) {
    boost::system::error_code ec;
    const auto remote = socket.remote_endpoint(ec);
    const std::string peer =
        ec ? "unknown" : fmt::format("{}:{}", remote.address().to_string(), remote.port());
    if (connections.size() >= options.max_clients) {
      spdlog::warn("OpenIGTLink: refusing {}: already {} clients", peer, connections.size());
      socket.close(ec);
      return;
    }
    // Keep-alive probes notice a peer that vanished without closing (cable, crash of its host);
    // the user timeout bounds how long sent data may stay unacknowledged.
    const int timeout_s = std::max(1, static_cast<int>(options.timeout_s));
    const int idle_s = std::max(1, timeout_s / 2);
    const int interval_s = std::max(1, (timeout_s - idle_s) / 3);
    const int probes = 3;
    const unsigned user_timeout_ms = static_cast<unsigned>(options.timeout_s * 1000.0);
    const int on = 1;
    const int fd = socket.native_handle();
    ::setsockopt(fd, SOL_SOCKET, SO_KEEPALIVE, &on, sizeof on);
    ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPIDLE, &idle_s, sizeof idle_s);
    ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPINTVL, &interval_s, sizeof interval_s);
    ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPCNT, &probes, sizeof probes);
    ::setsockopt(fd, IPPROTO_TCP, TCP_USER_TIMEOUT, &user_timeout_ms, sizeof user_timeout_ms);
    // A small send buffer: a client that stops reading stalls our writes within a few dozen
    // messages, and the watchdog lets it go after the timeout instead of buffering for minutes.
    const int send_buffer_bytes = 64 * 1024;
    ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &send_buffer_bytes, sizeof send_buffer_bytes);
    socket.set_option(tcp::no_delay(true), ec);
    auto c = std::make_shared<Connection>(std::move(socket));
    c->decoder = igtl::Decoder(64 * 1024, options.max_image_bytes);
    c->id = next_id++;
    c->peer = peer;
    connections[c->id] = c;
    client_count = connections.size();
    spdlog::info("OpenIGTLink: client {} connected from {}", c->id, peer);
    push({IgtlEvent::Kind::kConnected, c->id, peer, {}, {}});
    read(c);
  }

  void read(const std::shared_ptr<Connection>& c) {
    c->socket.async_read_some(
        asio::buffer(c->read_buffer), [this, c](boost::system::error_code ec, std::size_t n) {
          if (ec) {
            if (ec != asio::error::operation_aborted) {
              drop(c, ec == asio::error::eof ? "closed by the client" : ec.message());
            }
            return;
          }
          c->decoder.feed(c->read_buffer.data(), n);
          while (auto next = c->decoder.next()) {
            if (next->ok()) {
              c->header_version = std::max(c->header_version, next->value().header_version);
              streamControl(c, next->value());
              push({IgtlEvent::Kind::kMessage, c->id, c->peer, std::move(next->value()), {}});
              continue;
            }
            const Error& e = next->error();
            push({IgtlEvent::Kind::kBadMessage, c->id, c->peer, {}, e.message});
            // The client learns why, in its own header version, before anything else of it.
            enqueue(c, igtl::statusMessage("BAD_MESSAGE", igtl::StatusCode::kUnknownInstruction,
                                           e.message, "bad_message"));
            if (e.reason == "header_version") {
              // Nothing after it can be framed: let the client go once the reason has gone out.
              closeAfterSending(c, "not an OpenIGTLink stream: " + e.message);
              return;
            }
          }
          read(c);
        });
  }

  // STT_TDATA / STP_TDATA: the tip stream is the listener's to pace (the bridge ignores them).
  void streamControl(const std::shared_ptr<Connection>& c, const igtl::Message& m) {
    if (m.type == "STT_TDATA") {
      c->tdata_interval = std::chrono::milliseconds(m.stream_interval_ms);
      c->tdata_last = {};
      spdlog::info("OpenIGTLink: client {} streams the tip (at least {} ms apart; at most {} Hz)",
                   c->id, m.stream_interval_ms, options.tip_rate_hz);
    } else if (m.type == "STP_TDATA") {
      c->tdata_interval.reset();
    }
  }

  // Every tip period: the latest tip to every client streaming it, while the robot moves and
  // once when it has come to rest. The next deadline is this one plus the period (not "now plus":
  // a late tick does not delay the ones after it); after a stall it starts again from now.
  void tick() {
    const auto period = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / options.tip_rate_hz));
    tip_deadline += period;
    const auto now = Clock::now();
    if (tip_deadline < now) tip_deadline = now + period;
    tip_timer.expires_at(tip_deadline);
    tip_timer.async_wait([this](boost::system::error_code ec) {
      if (!ec) tick();
    });
    Tip latest;
    {
      std::lock_guard<std::mutex> lock(tip_mutex);
      latest = tip;
    }
    if (latest.seq == 0 || (!latest.moving && latest.seq == tip_sent)) return;
    tip_sent = latest.seq;
    igtl::Message m = igtl::trackingMessage("NeedleTip", latest.pose);
    m.timestamp_s = latest.measured_s;
    m.metadata.push_back({"Units", igtl::kUsAscii, "mm"});
    std::shared_ptr<const igtl::Wire> encoded[3];
    std::vector<std::shared_ptr<Connection>> due;
    for (const auto& [id, c] : connections) {
      // Half a period of slack: a client asking for the full rate gets every tick.
      if (c->tdata_interval && c->closing.empty() &&
          now - c->tdata_last + period / 2 >= *c->tdata_interval) {
        due.push_back(c);
      }
    }
    for (const auto& c : due) {
      auto& bytes = encoded[std::min<std::uint16_t>(c->header_version, 2)];
      if (!bytes) {
        m.header_version = c->header_version;
        m.message_id = m.header_version >= 2 ? next_message_id++ : 0;
        auto e = igtl::encodeWire(m);
        if (!e) {
          spdlog::error("OpenIGTLink: tip not sent: {}", e.error().message);
          return;
        }
        bytes = std::make_shared<const igtl::Wire>(std::move(e).value());
      }
      c->tdata_last = now;
      enqueue(c, bytes);
    }
  }

  void closeAfterSending(const std::shared_ptr<Connection>& c, const std::string& why) {
    c->closing = why;
    boost::system::error_code ec;
    c->socket.shutdown(tcp::socket::shutdown_receive, ec);
    if (c->outbox.empty()) drop(c, why);
  }

  void drop(const std::shared_ptr<Connection>& c, const std::string& why) {
    if (connections.erase(c->id) == 0) return;
    boost::system::error_code ec;
    c->socket.shutdown(tcp::socket::shutdown_both, ec);
    c->socket.close(ec);
    // Why first, then the count that Health publishes: whoever sees the client gone can read why.
    spdlog::info("OpenIGTLink: client {} ({}) dropped: {}", c->id, c->peer, why);
    client_count = connections.size();
    push({IgtlEvent::Kind::kDisconnected, c->id, c->peer, {}, why});
  }

  // Encodes `m` in the client's header version and queues it.
  void enqueue(const std::shared_ptr<Connection>& c, igtl::Message m) {
    m.header_version = c->header_version;
    if (m.header_version >= 2) m.message_id = next_message_id++;
    auto wire = igtl::encodeWire(m);
    if (!wire) {
      spdlog::error("OpenIGTLink: not sent to client {}: {}", c->id, wire.error().message);
      return;
    }
    enqueue(c, std::make_shared<const igtl::Wire>(std::move(wire).value()));
  }

  void enqueue(const std::shared_ptr<Connection>& c, std::shared_ptr<const igtl::Wire> wire,
               std::size_t bulk_slots = 0) {
    const std::size_t size = wire->size();
    if (bulk_slots > 0) {
      c->bulk_wires[wire.get()] = bulk_slots;
    } else if (c->outbox_bytes + size > options.max_outbox_bytes) {
      drop(c, fmt::format("not reading: {} bytes waiting to be sent", c->outbox_bytes));
      return;
    } else {
      c->outbox_bytes += size;
    }
    c->outbox.push_back(std::move(wire));
    if (!c->writing) write(c);
  }

  // The kernel's send buffer: small, so that a client that stops reading stalls our writes
  // within a few dozen messages and the watchdog lets it go; large while an image goes out
  // (loopback then moves ~0.5 GB/s instead of ~0.4).
  void sendBuffer(const std::shared_ptr<Connection>& c, bool large) {
    if (c->large_send_buffer == large) return;
    c->large_send_buffer = large;
    const int bytes = large ? 4 * 1024 * 1024 : 64 * 1024;
    ::setsockopt(c->socket.native_handle(), SOL_SOCKET, SO_SNDBUF, &bytes, sizeof bytes);
  }

  // A chunk at a time: the watchdog sees progress, and a large image does not count as stalled
  // for as long as it keeps moving.
  void write(const std::shared_ptr<Connection>& c) {
    c->writing = true;
    c->write_started = Clock::now();
    const igtl::Wire& front = *c->outbox.front();
    sendBuffer(c, c->bulk_wires.count(&front) > 0);
    const igtl::WireSegment& segment = front.segments[c->front_segment];
    const std::size_t chunk =
        std::min<std::size_t>(kWriteChunkBytes, segment.size - c->front_written);
    asio::async_write(c->socket, asio::buffer(segment.data.get() + c->front_written, chunk),
                      [this, c](boost::system::error_code ec, std::size_t written) {
                        c->writing = false;
                        if (ec) {
                          if (ec != asio::error::operation_aborted) drop(c, ec.message());
                          return;
                        }
                        const igtl::Wire* done = c->outbox.front().get();
                        c->front_written += written;
                        if (c->front_written == done->segments[c->front_segment].size) {
                          c->front_written = 0;
                          ++c->front_segment;
                        }
                        if (c->front_segment == done->segments.size()) {
                          if (const auto bulk = c->bulk_wires.find(done);
                              bulk != c->bulk_wires.end()) {
                            c->bulk -= bulk->second;
                            c->bulk_wires.erase(bulk);
                          } else {
                            c->outbox_bytes -= done->size();
                          }
                          c->outbox.pop_front();
                          c->front_segment = 0;
                        }
                        if (!c->outbox.empty()) {
                          write(c);
                        } else {
                          sendBuffer(c, false);
                          if (!c->closing.empty()) drop(c, c->closing);
                        }
                      });
  }

  // Images and surfaces are encoded (their voxels' CRC: ~0.1 s for a CT, then kept) on the
  // encoder thread, never here, where an EMERGENCY from a client is read. At most
  // kMaxBulkSlots per client.
  bool sendBulk(const std::shared_ptr<Connection>& c, igtl::Message m) {
    if (c->bulk + bulkCost(m) > kMaxBulkSlots) return false;
    c->bulk += bulkCost(m);
    m.header_version = c->header_version;
    if (m.header_version >= 2) m.message_id = next_message_id++;
    {
      std::lock_guard<std::mutex> lock(encoder_mutex);
      encoder_queue.push_back({c->id, std::move(m)});
    }
    encoder_wake.notify_one();
    return true;
  }

  void encodeLoop() {
    for (;;) {
      std::pair<std::uint64_t, igtl::Message> job;
      {
        std::unique_lock<std::mutex> lock(encoder_mutex);
        encoder_wake.wait(lock, [&] { return encoder_stop || !encoder_queue.empty(); });
        if (encoder_stop) return;
        job = std::move(encoder_queue.front());
        encoder_queue.pop_front();
      }
      // An image's voxels' CRC is kept while they live: the same CT asked for again costs
      // nothing but the writing.
      const igtl::Image& image = job.second.image;
      for (auto it = voxel_crcs.begin(); it != voxel_crcs.end();) {  // volumes that are gone
        it = it->second.owner.expired() ? voxel_crcs.erase(it) : std::next(it);
      }
      const std::uint64_t* known = nullptr;
      auto cached = voxel_crcs.find(image.data.get());
      if (cached != voxel_crcs.end() && cached->second.bytes != image.data_bytes) {
        voxel_crcs.erase(cached);
        cached = voxel_crcs.end();
      }
      if (cached != voxel_crcs.end()) known = &cached->second.crc;
      auto wire = igtl::encodeWire(job.second, known);
      std::shared_ptr<const igtl::Wire> shared;
      if (wire) {
        if (!known && wire->voxel_crc && !image.rescaled()) {
          voxel_crcs[image.data.get()] = {image.data, image.data_bytes, *wire->voxel_crc};
        }
        shared = std::make_shared<const igtl::Wire>(std::move(wire).value());
      } else {
        spdlog::error("OpenIGTLink: not sent to client {}: {}", job.first, wire.error().message);
      }
      asio::post(io, [this, client = job.first, shared, slots = bulkCost(job.second)] {
        const auto it = connections.find(client);
        if (it == connections.end()) return;
        if (!shared) {
          it->second->bulk -= slots;
          return;
        }
        enqueue(it->second, shared, slots);
      });
    }
  }

  // A write that does not finish within the timeout: the client stopped reading (or vanished
  // with our data unacknowledged, which TCP_USER_TIMEOUT reports as an error anyway).
  void watch() {
    watchdog.expires_after(std::chrono::milliseconds(100));
    watchdog.async_wait([this](boost::system::error_code ec) {
      if (ec) return;
      const auto limit = std::chrono::duration<double>(options.timeout_s);
      std::vector<std::shared_ptr<Connection>> stalled;
      for (const auto& [id, c] : connections) {
        if (c->writing && Clock::now() - c->write_started > limit) stalled.push_back(c);
      }
      for (const auto& c : stalled) {
        drop(c, fmt::format("nothing we sent was read for {:.1f} s", options.timeout_s));
      }
      watch();
    });
  }
};

IgtlListener::IgtlListener(IgtlListenerOptions options, std::function<void()> wake)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(wake), client_count_)) {}

IgtlListener::~IgtlListener() {
  if (impl_->thread.joinable()) {
    asio::post(impl_->io, [this] {
      boost::system::error_code ec;
      impl_->acceptor.close(ec);
      impl_->watchdog.cancel();
      impl_->tip_timer.cancel();
      for (auto& [id, c] : impl_->connections)
        c->socket.close(ec);
      impl_->connections.clear();
    });
    impl_->io.stop();
    impl_->thread.join();
  }
  if (impl_->encoder.joinable()) {
    {
      std::lock_guard<std::mutex> lock(impl_->encoder_mutex);
      impl_->encoder_stop = true;
    }
    impl_->encoder_wake.notify_one();
    impl_->encoder.join();
  }
}

Expected<int> IgtlListener::start() {
  auto& o = impl_->options;
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(o.address, ec);
  if (ec) {
    return makeError(ErrorCode::kConfig,
                     fmt::format("openigtlink.address '{}': {}", o.address, ec.message()));
  }
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(o.port));
  auto& a = impl_->acceptor;
  a.open(endpoint.protocol(), ec);
  if (!ec) a.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) a.bind(endpoint, ec);
  if (!ec) a.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    return makeError(ErrorCode::kIo, fmt::format("OpenIGTLink: cannot listen on {}:{}: {}",
                                                 o.address, o.port, ec.message()));
  }
  const int port = a.local_endpoint().port();
  impl_->accept();
  impl_->watch();
  impl_->tip_deadline = Clock::now();
  impl_->tick();
  impl_->thread = std::thread([this] { impl_->io.run(); });
  impl_->encoder = std::thread([this] { impl_->encodeLoop(); });
  return port;
}

std::vector<IgtlEvent> IgtlListener::take() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  std::vector<IgtlEvent> out;
  out.swap(impl_->events);
  return out;
}

void IgtlListener::send(std::uint64_t client, igtl::Message message) {
  asio::post(impl_->io, [this, client, m = std::move(message)]() mutable {
    const auto it = impl_->connections.find(client);
    if (it == impl_->connections.end() || !it->second->closing.empty()) return;
    if (!isBulk(m)) {
      impl_->enqueue(it->second, std::move(m));
      return;
    }
    const std::string device = m.device_name;
    if (!impl_->sendBulk(it->second, std::move(m))) {
      // Asked again before the last ones left: this one is not made at all.
      impl_->enqueue(it->second,
                     igtl::statusMessage(device, igtl::StatusCode::kBusy,
                                         "images or surfaces still on their way to you; ask again "
                                         "once they have come",
                                         "busy"));
    }
  });
}

void IgtlListener::publishTip(const Eigen::Matrix4d& pose_ras, double measured_s, bool moving) {
  std::lock_guard<std::mutex> lock(impl_->tip_mutex);
  impl_->tip.pose = pose_ras;
  impl_->tip.measured_s = measured_s;
  impl_->tip.moving = moving;
  ++impl_->tip.seq;
}

bool IgtlListener::isBulk(const igtl::Message& m) {
  return m.type == "IMAGE" || m.type == "POLYDATA";
}

void IgtlListener::broadcast(igtl::Message message) {
  asio::post(impl_->io, [this, m = std::move(message)]() mutable {
    // Encoded once per header version, and the same bytes queued to each client of it.
    std::shared_ptr<const igtl::Wire> encoded[3];
    std::vector<std::shared_ptr<Impl::Connection>> all;
    for (auto& [id, c] : impl_->connections) {
      if (c->closing.empty()) all.push_back(c);
    }
    for (auto& c : all) {
      auto& bytes = encoded[std::min<std::uint16_t>(c->header_version, 2)];
      if (!bytes) {
        m.header_version = c->header_version;
        m.message_id = m.header_version >= 2 ? impl_->next_message_id++ : 0;
        auto e = igtl::encodeWire(m);
        if (!e) {
          spdlog::error("OpenIGTLink: not sent: {}", e.error().message);
          return;
        }
        bytes = std::make_shared<const igtl::Wire>(std::move(e).value());
      }
      impl_->enqueue(c, bytes);
    }
  });
}

}  // namespace ignav::server
