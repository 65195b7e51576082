// A TCP proxy between a controller driver and a controller (the dmc-emulator) on loopback that
// holds every reply for a while, or swallows them (a slow or silent controller link), and records
// when each command line from the driver arrived: when it was "on the wire". One thread; every
// handle the driver opens gets its own upstream connection.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <deque>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace ignav::test {

class DelayProxy {
 public:
  using Clock = std::chrono::steady_clock;
  struct Command {
    std::string text;  // one line, without its terminator
    Clock::time_point at;
  };

  explicit DelayProxy(int upstream_port) : upstream_port_(upstream_port) {
    listener_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const int one = 1;
    ::setsockopt(listener_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in addr = loopback(0);
    socklen_t len = sizeof addr;
    if (::bind(listener_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
        ::listen(listener_, 16) != 0 ||
        ::getsockname(listener_, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
      throw std::runtime_error("delay proxy: cannot listen on loopback");
    }
    port_ = ntohs(addr.sin_port);
    if (::pipe(wake_) != 0) throw std::runtime_error("delay proxy: pipe");
    thread_ = std::thread([this] { loop(); });
  }
  ~DelayProxy() {
    stop_ = true;
    const char c = 0;
    (void)!::write(wake_[1], &c, 1);
    thread_.join();
    for (auto& l : links_) {
      ::close(l.client);
      ::close(l.upstream);
    }
    ::close(listener_);
    ::close(wake_[0]);
    ::close(wake_[1]);
  }
  DelayProxy(const DelayProxy&) = delete;
  DelayProxy& operator=(const DelayProxy&) = delete;

  int port() const { return port_; }
  // Replies from now on are held this long (those already held keep their time).
  void setDelay(std::chrono::milliseconds delay) { delay_ms_ = static_cast<int>(delay.count()); }
  // Replies from now on are dropped (the commands still reach the controller).
  void setSilent(bool silent) { silent_ = silent; }

  // Every connection is closed (a pulled cable, then plugged in again: new ones are accepted).
  void cut() { cut_ = true; }

  std::vector<Command> commands() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return commands_;
  }
  // When the first command starting with `prefix` arrived at or after `since`.
  std::optional<Clock::time_point> arrival(const std::string& prefix,
                                           Clock::time_point since = {}) const {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& c : commands_) {
      if (c.at >= since && c.text.rfind(prefix, 0) == 0) return c.at;
    }
    return std::nullopt;
  }
  // Waits up to `timeout` for such a command.
  std::optional<Clock::time_point> waitFor(const std::string& prefix, Clock::time_point since,
                                           std::chrono::milliseconds timeout) const {
    const auto end = Clock::now() + timeout;
    for (;;) {
      if (auto at = arrival(prefix, since)) return at;
      if (Clock::now() > end) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }

 private:
  struct Held {
    Clock::time_point release;
    std::string bytes;
  };
  struct Link {
    int client = -1, upstream = -1;
    std::string line;       // the command being received
    std::deque<Held> held;  // replies waiting for their time
    bool closed = false;
  };

  static sockaddr_in loopback(int port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return a;
  }

  void loop() {
    while (!stop_) {
      std::vector<pollfd> fds{{wake_[0], POLLIN, 0}, {listener_, POLLIN, 0}};
      for (const auto& l : links_) {
        fds.push_back({l.client, POLLIN, 0});
        fds.push_back({l.upstream, POLLIN, 0});
      }
      int timeout = 50;
      const auto now = Clock::now();
      for (const auto& l : links_) {
        if (l.held.empty()) continue;
        const auto left =
            std::chrono::duration_cast<std::chrono::milliseconds>(l.held.front().release - now)
                .count();
        timeout = std::min<int>(timeout, static_cast<int>(std::max<long>(0, left + 1)));
      }
      ::poll(fds.data(), fds.size(), timeout);
      // The links polled (accept() below may add one, and move the others).
      for (std::size_t i = 0; 2 * i + 3 < fds.size(); ++i) {
        Link& l = links_[i];
        if (fds[2 + 2 * i].revents & (POLLIN | POLLHUP | POLLERR)) fromClient(l);
        if (fds[3 + 2 * i].revents & (POLLIN | POLLHUP | POLLERR)) fromUpstream(l);
      }
      if (fds[1].revents & POLLIN) accept();
      if (cut_.exchange(false)) {
        for (auto& l : links_)
          l.closed = true;
      }
      const auto t = Clock::now();
      for (auto& l : links_) {
        while (!l.closed && !l.held.empty() && l.held.front().release <= t) {
          if (::send(l.client, l.held.front().bytes.data(), l.held.front().bytes.size(),
                     MSG_NOSIGNAL) < 0) {
            l.closed = true;
          }
          l.held.pop_front();
        }
      }
      for (auto& l : links_) {
        if (!l.closed) continue;
        ::close(l.client);
        ::close(l.upstream);
      }
      links_.erase(
          std::remove_if(links_.begin(), links_.end(), [](const Link& l) { return l.closed; }),
          links_.end());
    }
  }

  void accept() {
    const int client = ::accept4(listener_, nullptr, nullptr, SOCK_CLOEXEC);
    if (client < 0) return;
    const int upstream = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a = loopback(upstream_port_);
    if (::connect(upstream, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(upstream);
      ::close(client);
      return;
    }
    const int one = 1;
    ::setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ::setsockopt(upstream, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    links_.push_back({client, upstream, {}, {}, false});
  }

  void fromClient(Link& l) {
    char buf[512];
    const ssize_t n = ::recv(l.client, buf, sizeof buf, MSG_DONTWAIT);
    if (n <= 0) {
      if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) l.closed = true;
      return;
    }
    const auto at = Clock::now();
    for (ssize_t k = 0; k < n; ++k) {
      const char c = buf[k];
      if (c == '\r' || c == '\n' || c == ';') {
        if (!l.line.empty()) {
          std::lock_guard<std::mutex> lock(mutex_);
          commands_.push_back({l.line, at});
        }
        l.line.clear();
      } else {
        l.line += c;
      }
    }
    if (::send(l.upstream, buf, static_cast<std::size_t>(n), MSG_NOSIGNAL) < 0) l.closed = true;
  }

  void fromUpstream(Link& l) {
    char buf[512];
    const ssize_t n = ::recv(l.upstream, buf, sizeof buf, MSG_DONTWAIT);
    if (n <= 0) {
      if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) l.closed = true;
      return;
    }
    if (silent_) return;
    auto release = Clock::now() + std::chrono::milliseconds(delay_ms_.load());
    if (!l.held.empty()) release = std::max(release, l.held.back().release);
    l.held.push_back({release, std::string(buf, static_cast<std::size_t>(n))});
  }

  int upstream_port_;
  int listener_ = -1;
  int port_ = 0;
  int wake_[2] = {-1, -1};
  std::atomic<bool> stop_{false};
  std::atomic<int> delay_ms_{0};
  std::atomic<bool> silent_{false};
  std::atomic<bool> cut_{false};
  std::vector<Link> links_;  // the proxy thread's
  mutable std::mutex mutex_;
  std::vector<Command> commands_;
  std::thread thread_;
};

}  // namespace ignav::test
