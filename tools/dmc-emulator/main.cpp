// dmc-emulator: a small Galil DMC look-alike on 127.0.0.1 for tests and demos. It speaks the
// subset GalilController uses (SP AC DC SH MO PR BG ST AB TP DP MG _BGn/_SCn TC1), answering ':'
// or '?', and moves a SimulatedController in real time. Several clients may be connected at
// once (a DMC accepts several handles).
//   dmc-emulator [--port 0] [--limit-max STEPS]    prints "listening on 127.0.0.1:PORT"
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "ignav/actuation/controller.hpp"

namespace {

using ignav::actuation::SimulatedController;

std::vector<double> numbers(const std::string& args) {
  std::vector<double> out;
  std::stringstream in(args);
  for (std::string item; std::getline(in, item, ',');) {
    out.push_back(item.empty() ? 0.0 : std::stod(item));
  }
  return out;
}

class Emulator {
 public:
  explicit Emulator(std::int64_t limit_max) {
    std::array<ignav::actuation::SimulatedAxis, 3> axes{};
    for (auto& a : axes)
      a.max_steps = limit_max;
    sim_ = SimulatedController(axes);
    (void)sim_.connect();
  }

  // One command -> the bytes to send back.
  std::string handle(const std::string& raw) {
    sim_.advanceTo(std::chrono::duration<double>(Clock::now() - start_).count());
    const std::string cmd = raw.substr(0, 2);
    const std::string args = raw.size() > 2 ? raw.substr(2) : "";
    auto refuse = [&](int code, const std::string& why) {
      last_error_ = std::to_string(code) + " " + why;
      return std::string("?");
    };
    try {
      if (cmd == "SP" || cmd == "AC" || cmd == "DC") {
        const auto v = numbers(args);
        for (std::size_t a = 0; a < v.size() && a < 3; ++a) {
          if (cmd == "SP") speed_[a] = v[a];
          if (cmd == "AC") accel_[a] = v[a];
          if (!sim_.setProfile(static_cast<int>(a), speed_[a], accel_[a]).ok()) {
            return refuse(7, "Command not valid while running");
          }
        }
        return ":";
      }
      if (cmd == "SH" || cmd == "MO") return ":";
      if (cmd == "PR") {
        const auto v = numbers(args);
        for (std::size_t a = 0; a < 3; ++a)
          pending_.motor[a] = a < v.size() ? std::llround(v[a]) : 0;
        return ":";
      }
      if (cmd == "BG") {
        if (!sim_.move(pending_).ok()) return refuse(7, "Command not valid while running");
        stop_code_ = {0, 0, 0};
        return ":";
      }
      if (cmd == "ST") {
        (void)sim_.stop();
        stop_code_ = {4, 4, 4};
        return ":";
      }
      if (cmd == "AB") {
        (void)sim_.abort();
        stop_code_ = {6, 6, 6};
        return ":";
      }
      if (cmd == "DP") {
        if (!sim_.home().ok()) return refuse(7, "Command not valid while running");
        return ":";
      }
      auto status = sim_.poll();
      if (!status) return refuse(1, status.error().message);
      if (cmd == "TP") {
        const auto& p = status->position.motor;
        return " " + std::to_string(p[0]) + ", " + std::to_string(p[1]) + ", " +
               std::to_string(p[2]) + "\r\n:";
      }
      if (raw.rfind("MG _BG", 0) == 0 || raw.rfind("MG _SC", 0) == 0) {
        const bool bg = raw.rfind("MG _BG", 0) == 0;
        std::string out;
        for (std::size_t a = 0; a < 3; ++a) {
          int v = 0;
          if (bg) {
            v = status->moving[a] ? 1 : 0;
          } else if (status->moving[a]) {
            v = 0;
          } else if (status->fault.find("motor " + std::to_string(a + 1) + " hit its limit") !=
                     std::string::npos) {
            v = 2;  // forward limit
          } else {
            v = stop_code_[a] == 0 ? 1 : stop_code_[a];
          }
          out += (a ? " " : " ") + std::to_string(v) + ".0000";
        }
        return out + "\r\n:";
      }
      if (raw == "TC1") return " " + last_error_ + "\r\n:";
    } catch (const std::exception&) {
      return refuse(2, "Bad argument");
    }
    return refuse(1, "Unrecognized command");
  }

 private:
  using Clock = std::chrono::steady_clock;
  SimulatedController sim_;
  Clock::time_point start_ = Clock::now();
  ignav::actuation::Steps pending_;
  std::array<double, 3> speed_{2000, 2000, 2000}, accel_{8000, 8000, 8000};
  std::array<int, 3> stop_code_{1, 1, 1};
  std::string last_error_ = "0 No error";
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"dmc-emulator: a Galil DMC look-alike on loopback"};
  int port = 0;
  std::int64_t limit_max = 1'000'000;
  app.add_option("--port", port, "TCP port on 127.0.0.1 (0 = any free one)");
  app.add_option("--limit-max", limit_max, "forward limit switch of every axis (steps)");
  CLI11_PARSE(app, argc, argv);

  const int server = ::socket(AF_INET, SOCK_STREAM, 0);
  const int one = 1;
  ::setsockopt(server, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);  // loopback only
  if (::bind(server, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(server, 16) != 0) {
    std::perror("dmc-emulator");
    return 1;
  }
  socklen_t len = sizeof addr;
  ::getsockname(server, reinterpret_cast<sockaddr*>(&addr), &len);
  std::cout << "dmc-emulator listening on 127.0.0.1:" << ntohs(addr.sin_port) << std::endl;

  // Several TCP handles at once, as a DMC has (the driver halts on a handle of its own): one
  // thread, commands taken in the order they arrive on any handle.
  Emulator emulator(limit_max);
  struct Handle {
    int fd;
    std::string line;
  };
  std::vector<Handle> handles;
  for (;;) {
    std::vector<pollfd> fds{{server, POLLIN, 0}};
    for (const auto& h : handles)
      fds.push_back({h.fd, POLLIN, 0});
    if (::poll(fds.data(), fds.size(), -1) < 0) continue;
    if (fds[0].revents & POLLIN) {
      const int client = ::accept(server, nullptr, nullptr);
      if (client >= 0) handles.push_back({client, {}});
    }
    for (std::size_t i = 1; i < fds.size(); ++i) {
      if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      Handle& h = handles[i - 1];
      char buf[256];
      const ssize_t n = ::recv(h.fd, buf, sizeof buf, 0);
      bool gone = n <= 0;
      for (ssize_t k = 0; k < n && !gone; ++k) {
        const char c = buf[k];
        if (c != '\r' && c != '\n' && c != ';') {
          h.line += c;
          continue;
        }
        if (h.line.empty()) continue;
        const std::string reply = emulator.handle(h.line);
        h.line.clear();
        if (::send(h.fd, reply.data(), reply.size(), MSG_NOSIGNAL) < 0) gone = true;
      }
      if (gone) {
        ::close(h.fd);
        h.fd = -1;
      }
    }
    handles.erase(
        std::remove_if(handles.begin(), handles.end(), [](const Handle& h) { return h.fd < 0; }),
        handles.end());
  }
}
