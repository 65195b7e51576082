#include "ignav/actuation/galil.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <sstream>

#include <fmt/format.h>

namespace ignav::actuation {
namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kAxes = "ABC";

Error lost(const std::string& why) {
  return makeError(ErrorCode::kIo, "controller connection lost: " + why, "connection_lost");
}

void closeFd(int& fd) {
  if (fd >= 0) ::close(fd);
  fd = -1;
}

// Milliseconds left until `deadline` (at least 0).
int leftMs(Clock::time_point deadline) {
  const auto left =
      std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left > 0 ? static_cast<int>(left) : 0;
}

}  // namespace

GalilController::GalilController(GalilOptions options) : options_(std::move(options)) {}

GalilController::~GalilController() {
  closeFd(fd_);
  closeFd(halt_fd_);
}

Expected<int> GalilController::open() const {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  if (::inet_pton(AF_INET, options_.host.c_str(), &addr.sin_addr) != 1) {
    return makeError(ErrorCode::kInvalidArgument,
                     "controller host '" + options_.host + "' is not an IPv4 address");
  }
  int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return makeError(ErrorCode::kIo, std::string("socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  auto fail = [&](const std::string& why) -> Expected<int> {
    closeFd(fd);
    return makeError(ErrorCode::kIo,
                     fmt::format("controller {}:{}: {}", options_.host, options_.port, why),
                     "disconnected");
  };
  // Non-blocking connect, then wait for it at most the timeout (an unreachable host would
  // otherwise hold the caller for the kernel's minutes).
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    if (errno != EINPROGRESS) return fail(std::strerror(errno));
    pollfd p{fd, POLLOUT, 0};
    const int ready = ::poll(&p, 1, options_.timeout_ms);
    if (ready == 0) {
      return fail(fmt::format("no connection within {} ms", options_.timeout_ms));
    }
    int error = 0;
    socklen_t len = sizeof error;
    if (ready < 0 || ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &len) != 0) {
      return fail(std::strerror(errno));
    }
    if (error != 0) return fail(std::strerror(error));
  }
  return fd;
}

Status GalilController::connect() {
  {
    std::lock_guard<std::mutex> lock(main_mutex_);
    closeFd(fd_);
    auto fd = open();
    if (!fd) return fd.error();
    fd_ = *fd;
  }
  {
    std::lock_guard<std::mutex> lock(halt_mutex_);
    closeFd(halt_fd_);
    auto fd = open();
    if (!fd) return fd.error();
    halt_fd_ = *fd;
  }
  std::lock_guard<std::mutex> lock(main_mutex_);
  return setup();
}

// The motion profile. A controller that is moving refuses it (a server restarted mid-move): the
// connection stands and the profile is sent again before the next move.
Status GalilController::setup() {
  setup_pending_ = false;
  for (const std::string& text :
       {fmt::format("SP {0},{0},{0}", options_.speed_steps_s),
        fmt::format("AC {0},{0},{0}", options_.acceleration_steps_s2),
        fmt::format("DC {0},{0},{0}", options_.acceleration_steps_s2), std::string("SH ABC")}) {
    auto r = exchange(fd_, text);
    if (r) continue;
    if (r.error().reason != "refused") return r.error();
    setup_pending_ = true;
  }
  return Ok{};
}

Expected<std::string> GalilController::exchange(int& fd, const std::string& text) {
  if (fd < 0) return makeError(ErrorCode::kIo, "controller not connected", "disconnected");
  const auto deadline = Clock::now() + std::chrono::milliseconds(options_.timeout_ms);
  auto timeout = [&]() -> Error {
    // A reply that comes later would be taken for the next command's: this handle is done.
    closeFd(fd);
    return makeError(
        ErrorCode::kIo,
        fmt::format("controller did not answer '{}' within {} ms", text, options_.timeout_ms),
        "timeout");
  };
  const std::string line = text + "\r";
  for (std::size_t sent = 0; sent < line.size();) {
    const ssize_t n = ::send(fd, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd, POLLOUT, 0};
      if (::poll(&p, 1, leftMs(deadline)) <= 0) return timeout();
      continue;
    }
    const std::string why = std::strerror(errno);
    closeFd(fd);
    return lost(why);
  }
  std::string reply;
  for (;;) {
    char c = 0;
    const ssize_t n = ::recv(fd, &c, 1, MSG_DONTWAIT);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd, POLLIN, 0};
      const int ready = ::poll(&p, 1, leftMs(deadline));
      if (ready == 0) return timeout();
      if (ready > 0) continue;
    }
    if (n <= 0) {
      const std::string why = n == 0 ? "closed by the controller" : std::strerror(errno);
      closeFd(fd);
      return lost(why);
    }
    if (c == ':') break;
    if (c == '?') {
      // The controller refused the command: ask it why (TC1 -> "code text").
      std::string why = "rejected";
      if (text != "TC1") {
        if (auto tc = exchange(fd, "TC1"); tc) why = *tc;
      }
      while (!why.empty() && (why.back() == '\r' || why.back() == '\n'))
        why.pop_back();
      while (!why.empty() && why.front() == ' ')
        why.erase(why.begin());
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("controller refused '{}': {}", text, why), "refused");
    }
    reply += c;
  }
  return reply;
}

Expected<std::string> GalilController::command(const std::string& text) {
  std::lock_guard<std::mutex> lock(main_mutex_);
  return exchange(fd_, text);
}

Status GalilController::home() {
  std::lock_guard<std::mutex> lock(main_mutex_);
  if (auto r = exchange(fd_, "DP 0,0,0"); !r) return r.error();
  return Ok{};
}

Status GalilController::move(const Steps& increments) {
  std::lock_guard<std::mutex> lock(main_mutex_);
  if (!fault_.empty()) {
    return makeError(ErrorCode::kInvalidArgument, "controller in fault: " + fault_, "fault");
  }
  if (setup_pending_) {
    if (auto ok = setup(); !ok) return ok;
    if (setup_pending_) {
      return makeError(ErrorCode::kInvalidArgument,
                       "the controller refused the motion profile (SP/AC/DC)", "refused");
    }
  }
  const auto halts = halts_.load();
  const auto& m = increments.motor;
  if (auto r = exchange(fd_, fmt::format("PR {},{},{}", m[0], m[1], m[2])); !r) return r.error();
  // A halt that came while PR waited for its reply: the move does not begin.
  if (halts_.load() != halts) {
    return makeError(ErrorCode::kInvalidArgument, "move not begun: a halt came first", "halted");
  }
  if (auto r = exchange(fd_, "BG ABC"); !r) return r.error();
  limit_cleared_ = false;  // a new move: its own stop codes count again
  return Ok{};
}

// A halt on its own handle. If that handle was lost, one attempt to open it again: a halt is
// worth it.
Status GalilController::halt(const std::string& text) {
  ++halts_;
  std::lock_guard<std::mutex> lock(halt_mutex_);
  if (halt_fd_ < 0) {
    auto fd = open();
    if (!fd) return fd.error();
    halt_fd_ = *fd;
  }
  if (auto r = exchange(halt_fd_, text); !r) return r.error();
  return Ok{};
}

Status GalilController::stop() {
  return halt("ST ABC");
}

Status GalilController::abort() {
  return halt("AB");
}

Expected<ControllerStatus> GalilController::poll() {
  std::lock_guard<std::mutex> lock(main_mutex_);
  ControllerStatus s;
  auto numbers = [&](const std::string& cmd) -> Expected<std::array<double, 3>> {
    auto r = exchange(fd_, cmd);
    if (!r) return r.error();
    std::string text = *r;
    for (char& c : text) {
      if (c == ',') c = ' ';
    }
    std::istringstream in(text);
    std::array<double, 3> v{};
    for (double& x : v) {
      if (!(in >> x)) {
        return makeError(ErrorCode::kFormat,
                         fmt::format("controller answered '{}' with '{}'", cmd, *r));
      }
    }
    return v;
  };
  // Motion flags first, position last: an axis that finishes between the two queries then
  // reports its final position, never "idle" at a position read while it was still moving.
  auto bg = numbers("MG _BGA,_BGB,_BGC");
  if (!bg) return bg.error();
  auto sc = numbers("MG _SCA,_SCB,_SCC");
  if (!sc) return sc.error();
  auto tp = numbers("TP");
  if (!tp) return tp.error();
  for (int a = 0; a < 3; ++a) {
    const auto i = static_cast<std::size_t>(a);
    s.position.motor[i] = static_cast<std::int64_t>((*tp)[i]);
    s.moving[i] = (*bg)[i] != 0.0;
    // DMC stop codes 2 and 3: stopped by the forward or reverse limit switch.
    const int code = static_cast<int>((*sc)[i]);
    if (!s.moving[i] && (code == 2 || code == 3) && fault_.empty() && !limit_cleared_) {
      fault_ = fmt::format("motor {} ({}) stopped by its {} limit switch at {} steps", a + 1,
                           kAxes[a], code == 2 ? "forward" : "reverse", s.position.motor[i]);
    }
  }
  s.fault = fault_;
  const bool moving = s.moving[0] || s.moving[1] || s.moving[2];
  s.state = !fault_.empty() ? ControllerState::kFault
            : moving        ? ControllerState::kMoving
                            : ControllerState::kIdle;
  return s;
}

Status GalilController::clearFault() {
  std::lock_guard<std::mutex> lock(main_mutex_);
  fault_.clear();
  // The stop code stays 2 or 3 until the next move; the operator has seen it.
  limit_cleared_ = true;
  return Ok{};
}

}  // namespace ignav::actuation
