// ignav-igtl: a scripted OpenIGTLink client for the BRP bridge (docs/OPENIGTLINK.md), for a site
// without 3D Slicer at hand, or a script. Sends the given messages in order and prints every
// message sent and received as a JSON line (RAS, mm), waiting after each for the answers to settle.
//   ignav-igtl [--host H] [--port P] [--settle S] MESSAGE...
//   MESSAGE: cmd:PHASE | clb:M00,...,M33 | tgt:R,A,S | get-status | get:NAME | wait:S
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "ignav/igtl/message.hpp"

namespace {

using ignav::igtl::Message;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::vector<double> numbers(const std::string& text, std::size_t count) {
  std::vector<double> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || *end != '\0' || !std::isfinite(v)) break;
    out.push_back(v);
  }
  if (out.size() != count) {
    throw UsageError("'" + text + "': expected " + std::to_string(count) + " numbers");
  }
  return out;
}

json describe(const Message& m) {
  json j{{"type", m.type}, {"device", m.device_name}};
  if (m.type == "STRING") j["text"] = m.text;
  if (m.type == "STATUS") {
    j["code"] = m.status.code;
    j["error_name"] = m.status.error_name;
    j["status"] = m.status.status_string;
  }
  if (m.type == "TRANSFORM") {
    json rows = json::array();
    for (int r = 0; r < 4; ++r)
      rows.push_back({m.matrix(r, 0), m.matrix(r, 1), m.matrix(r, 2), m.matrix(r, 3)});
    j["matrix"] = rows;
  }
  if (m.type == "POINT") {
    json points = json::array();
    for (const auto& p : m.points)
      points.push_back(
          {{"name", p.name}, {"ras", {p.position_mm.x(), p.position_mm.y(), p.position_mm.z()}}});
    j["points"] = points;
  }
  return j;
}

class Connection {
 public:
  Connection(const std::string& host, int port) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0 || !found) {
      throw std::runtime_error("cannot resolve " + host);
    }
    fd_ = ::socket(found->ai_family, found->ai_socktype, found->ai_protocol);
    const int ok = fd_ >= 0 ? ::connect(fd_, found->ai_addr, found->ai_addrlen) : -1;
    ::freeaddrinfo(found);
    if (ok != 0) {
      throw std::runtime_error("cannot connect to " + host + ":" + std::to_string(port) +
                               " (is ignav-server running with its OpenIGTLink bridge on?)");
    }
    const int on = 1;
    ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  }
  ~Connection() {
    if (fd_ >= 0) ::close(fd_);
  }
  void send(const Message& m) {
    auto bytes = ignav::igtl::encode(m);
    if (!bytes) throw UsageError(bytes.error().message);
    if (::send(fd_, bytes->data(), bytes->size(), MSG_NOSIGNAL) < 0) {
      throw std::runtime_error("the server closed the connection");
    }
  }
  // Prints what arrives until nothing has come for `settle` (or `total` has passed).
  void receive(std::chrono::milliseconds settle, std::chrono::milliseconds total,
               const Clock::time_point& start) {
    const auto end = Clock::now() + total;
    auto quiet_since = Clock::now();
    while (Clock::now() < end && Clock::now() - quiet_since < settle) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      char buf[65536];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) throw std::runtime_error("the server closed the connection");
      decoder_.feed(buf, static_cast<std::size_t>(n));
      while (auto next = decoder_.next()) {
        json j = next->ok() ? describe(next->value()) : json{{"error", next->error().message}};
        j["t_s"] = std::chrono::duration<double>(Clock::now() - start).count();
        std::cout << j.dump() << "\n" << std::flush;
      }
      quiet_since = Clock::now();
    }
  }

 private:
  int fd_ = -1;
  ignav::igtl::Decoder decoder_;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ignav-igtl: a scripted OpenIGTLink (BRP) client for ignav-server"};
  std::string host = "127.0.0.1";
  int port = 18944;
  double settle_s = 0.3;
  std::vector<std::string> script;
  app.add_option("--host", host, "the server (loopback unless the site opened the bridge)");
  app.add_option("--port", port, "its OpenIGTLink port (the ready line's igtl_port)");
  app.add_option("--settle", settle_s, "seconds without a message that end each wait");
  app.add_option("messages", script,
                 "cmd:PHASE, clb:16 numbers (RAS -> robot, row-major), tgt:R,A,S, get-status, "
                 "get:NAME (a transform), wait:SECONDS")
      ->required();
  CLI11_PARSE(app, argc, argv);
  try {
    const auto start = Clock::now();
    const auto settle = std::chrono::milliseconds(static_cast<long>(settle_s * 1000));
    Connection c(host, port);
    c.receive(settle, std::chrono::seconds(5), start);  // the greeting
    int id = 0;
    for (const std::string& item : script) {
      const auto colon = item.find(':');
      const std::string verb = item.substr(0, colon);
      const std::string arg = colon == std::string::npos ? "" : item.substr(colon + 1);
      if (verb == "wait") {
        c.receive(std::chrono::hours(1),
                  std::chrono::milliseconds(static_cast<long>(numbers(arg, 1)[0] * 1000)), start);
        continue;
      }
      char name[16];
      std::snprintf(name, sizeof name, "%04d", ++id);
      Message m;
      if (verb == "cmd") {
        m = ignav::igtl::stringMessage(std::string("CMD_") + name, arg);
      } else if (verb == "clb") {
        const auto v = numbers(arg, 16);
        Eigen::Matrix4d matrix;
        for (int k = 0; k < 16; ++k)
          matrix(k / 4, k % 4) = v[k];
        m = ignav::igtl::transformMessage(std::string("CLB_") + name, matrix);
      } else if (verb == "tgt") {
        const auto v = numbers(arg, 3);
        Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
        matrix.topRightCorner<3, 1>() << v[0], v[1], v[2];
        m = ignav::igtl::transformMessage(std::string("TGT_") + name, matrix);
      } else if (verb == "get-status") {
        m = ignav::igtl::queryMessage("GET_STATUS", "CURRENT_STATUS");
      } else if (verb == "get") {
        m = ignav::igtl::queryMessage("GET_TRANS", arg);
      } else {
        throw UsageError("'" + item + "' is not cmd:, clb:, tgt:, get-status, get: or wait:");
      }
      json sent = describe(m);
      sent["sent"] = true;
      sent["t_s"] = std::chrono::duration<double>(Clock::now() - start).count();
      std::cout << sent.dump() << "\n" << std::flush;
      c.send(m);
      c.receive(settle, std::chrono::seconds(60), start);
    }
    return 0;
  } catch (const UsageError& e) {
    std::cerr << "ignav-igtl: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "ignav-igtl: " << e.what() << "\n";
    return 1;
  }
}
