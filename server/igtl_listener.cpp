#include "igtl_listener.hpp"

#include <netinet/in.h>
#include <netinet/tcp.h>

#include <chrono>
#include <deque>
#include <map>
#include <mutex>
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
    std::deque<std::string> outbox;
    std::size_t outbox_bytes = 0;
    bool writing = false;
    Clock::time_point write_started;
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
  std::thread thread;
  std::mutex mutex;
  std::vector<IgtlEvent> events;

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
              push({IgtlEvent::Kind::kMessage, c->id, c->peer, std::move(next->value()), {}});
              continue;
            }
            push({IgtlEvent::Kind::kBadMessage, c->id, c->peer, {}, next->error().message});
            if (next->error().reason == "header_version") {
              drop(c, "not an OpenIGTLink version 1 stream: " + next->error().message);
              return;
            }
          }
          read(c);
        });
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

  void enqueue(const std::shared_ptr<Connection>& c, std::shared_ptr<const std::string> bytes) {
    if (c->outbox_bytes + bytes->size() > options.max_outbox_bytes) {
      drop(c, fmt::format("not reading: {} bytes waiting to be sent", c->outbox_bytes));
      return;
    }
    c->outbox_bytes += bytes->size();
    c->outbox.push_back(*bytes);
    if (!c->writing) write(c);
  }

  void write(const std::shared_ptr<Connection>& c) {
    c->writing = true;
    c->write_started = Clock::now();
    asio::async_write(c->socket, asio::buffer(c->outbox.front()),
                      [this, c](boost::system::error_code ec, std::size_t) {
                        c->writing = false;
                        if (ec) {
                          if (ec != asio::error::operation_aborted) drop(c, ec.message());
                          return;
                        }
                        c->outbox_bytes -= c->outbox.front().size();
                        c->outbox.pop_front();
                        if (!c->outbox.empty()) write(c);
                      });
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
      for (auto& [id, c] : impl_->connections)
        c->socket.close(ec);
      impl_->connections.clear();
    });
    impl_->io.stop();
    impl_->thread.join();
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
  impl_->thread = std::thread([this] { impl_->io.run(); });
  return port;
}

std::vector<IgtlEvent> IgtlListener::take() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  std::vector<IgtlEvent> out;
  out.swap(impl_->events);
  return out;
}

void IgtlListener::send(std::uint64_t client, const igtl::Message& message) {
  auto bytes = igtl::encode(message);
  if (!bytes) {
    spdlog::error("OpenIGTLink: not sent: {}", bytes.error().message);
    return;
  }
  auto shared = std::make_shared<const std::string>(std::move(bytes).value());
  asio::post(impl_->io, [this, client, shared] {
    const auto it = impl_->connections.find(client);
    if (it != impl_->connections.end()) impl_->enqueue(it->second, shared);
  });
}

void IgtlListener::broadcast(const igtl::Message& message) {
  auto bytes = igtl::encode(message);
  if (!bytes) {
    spdlog::error("OpenIGTLink: not sent: {}", bytes.error().message);
    return;
  }
  auto shared = std::make_shared<const std::string>(std::move(bytes).value());
  asio::post(impl_->io, [this, shared] {
    std::vector<std::shared_ptr<Impl::Connection>> all;
    for (auto& [id, c] : impl_->connections)
      all.push_back(c);
    for (auto& c : all)
      impl_->enqueue(c, shared);
  });
}

}  // namespace ignav::server
