#include "ignav/actuation/galil.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <sstream>

#include <fmt/format.h>

namespace ignav::actuation {
namespace {

constexpr const char* kAxes = "ABC";

Error lost(const std::string& why) {
  return makeError(ErrorCode::kIo, "controller connection lost: " + why, "connection_lost");
}

}  // namespace

GalilController::GalilController(GalilOptions options) : options_(std::move(options)) {}

GalilController::~GalilController() {
  if (fd_ >= 0) ::close(fd_);
}

Status GalilController::connect() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return makeError(ErrorCode::kIo, std::string("socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  if (::inet_pton(AF_INET, options_.host.c_str(), &addr.sin_addr) != 1) {
    return makeError(ErrorCode::kInvalidArgument,
                     "controller host '" + options_.host + "' is not an IPv4 address");
  }
  if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    return makeError(ErrorCode::kIo,
                     fmt::format("controller {}:{}: {}", options_.host, options_.port, why),
                     "disconnected");
  }
  for (const std::string& setup :
       {fmt::format("SP {0},{0},{0}", options_.speed_steps_s),
        fmt::format("AC {0},{0},{0}", options_.acceleration_steps_s2),
        fmt::format("DC {0},{0},{0}", options_.acceleration_steps_s2), std::string("SH ABC")}) {
    if (auto r = command(setup); !r) return r.error();
  }
  return Ok{};
}

Status GalilController::ensureConnected() {
  if (fd_ < 0) return makeError(ErrorCode::kIo, "controller not connected", "disconnected");
  return Ok{};
}

Expected<std::string> GalilController::command(const std::string& text) {
  if (auto ok = ensureConnected(); !ok) return ok.error();
  const std::string line = text + "\r";
  if (::send(fd_, line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size())) {
    ::close(fd_);
    fd_ = -1;
    return lost(std::strerror(errno));
  }
  std::string reply;
  for (;;) {
    pollfd p{fd_, POLLIN, 0};
    const int ready = ::poll(&p, 1, options_.timeout_ms);
    if (ready == 0) {
      return makeError(
          ErrorCode::kIo,
          fmt::format("controller did not answer '{}' within {} ms", text, options_.timeout_ms),
          "timeout");
    }
    char c = 0;
    const ssize_t n = ready > 0 ? ::recv(fd_, &c, 1, 0) : -1;
    if (n <= 0) {
      ::close(fd_);
      fd_ = -1;
      return lost(n == 0 ? "closed by the controller" : std::strerror(errno));
    }
    if (c == ':') break;
    if (c == '?') {
      // The controller refused the command: ask it why (TC1 -> "code text").
      std::string why = "rejected";
      if (text != "TC1") {
        if (auto tc = command("TC1"); tc) why = *tc;
      }
      while (!why.empty() && (why.back() == '\r' || why.back() == '\n'))
        why.pop_back();
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("controller refused '{}': {}", text, why), "refused");
    }
    reply += c;
  }
  return reply;
}

Status GalilController::home() {
  if (auto r = command("DP 0,0,0"); !r) return r.error();
  return Ok{};
}

Status GalilController::move(const Steps& increments) {
  if (!fault_.empty()) {
    return makeError(ErrorCode::kInvalidArgument, "controller in fault: " + fault_, "fault");
  }
  const auto& m = increments.motor;
  if (auto r = command(fmt::format("PR {},{},{}", m[0], m[1], m[2])); !r) return r.error();
  if (auto r = command("BG ABC"); !r) return r.error();
  limit_cleared_ = false;  // a new move: its own stop codes count again
  return Ok{};
}

Status GalilController::stop() {
  if (auto r = command("ST ABC"); !r) return r.error();
  return Ok{};
}

Status GalilController::abort() {
  if (auto r = command("AB"); !r) return r.error();
  return Ok{};
}

Expected<ControllerStatus> GalilController::poll() {
  ControllerStatus s;
  auto numbers = [&](const std::string& cmd) -> Expected<std::array<double, 3>> {
    auto r = command(cmd);
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
  fault_.clear();
  // The stop code stays 2 or 3 until the next move; the operator has seen it.
  limit_cleared_ = true;
  return Ok{};
}

}  // namespace ignav::actuation
