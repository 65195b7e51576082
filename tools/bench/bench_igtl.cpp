// Round trips through the OpenIGTLink bridge of a running ignav-server (tools/bench/bench_igtl.sh):
// a query answered by the bridge alone, a BRP command through the workflow core (receipt and
// result), and a calibration that the journal must hold before it is answered. Prints medians and
// 99th percentiles over ROUNDS each. REVISION: the server's openigtlink.protocol (slicer|brp2013).
//   bench_igtl PORT [ROUNDS] [REVISION]
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "ignav/igtl/message.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using ignav::igtl::Message;

class Connection {
 public:
  explicit Connection(int port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      std::perror("connect");
      std::exit(1);
    }
    const int on = 1;
    ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  }
  ~Connection() { ::close(fd_); }
  void send(const Message& m) {
    const auto bytes = ignav::igtl::encode(m);
    if (!bytes || ::send(fd_, bytes->data(), bytes->size(), 0) < 0) std::exit(1);
  }
  // The next message with this device name (others are skipped).
  Message until(const std::string& device) {
    for (;;) {
      while (auto next = decoder_.next()) {
        if (next->ok() && next->value().device_name == device) return next->value();
      }
      char buf[65536];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        std::fprintf(stderr, "connection closed\n");
        std::exit(1);
      }
      decoder_.feed(buf, static_cast<std::size_t>(n));
    }
  }

 private:
  int fd_;
  ignav::igtl::Decoder decoder_;
};

void report(const char* what, std::vector<double> us) {
  std::sort(us.begin(), us.end());
  std::printf("%-52s median %8.1f us   p99 %8.1f us   (n=%zu)\n", what, us[us.size() / 2],
              us[us.size() * 99 / 100], us.size());
}

double since_us(Clock::time_point t0) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_igtl PORT [ROUNDS] [slicer|brp2013]\n");
    return 2;
  }
  const int port = std::atoi(argv[1]);
  const int rounds = argc > 2 ? std::atoi(argv[2]) : 1000;
  // The 2013 revision says nothing on connect and answers GET_STATUS with STATUS(<workphase>).
  const bool brp2013 = argc > 3 && std::string(argv[3]) == "brp2013";
  Connection c(port);
  if (!brp2013) c.until("CURRENT_STATUS");  // the greeting
  const std::string status_answer = brp2013 ? "START_UP" : "CURRENT_STATUS";

  std::vector<double> query, receipt, result, calibration;
  for (int i = 0; i < rounds; ++i) {
    auto t0 = Clock::now();
    c.send(ignav::igtl::queryMessage("GET_STATUS", "CURRENT_STATUS"));
    c.until(status_answer);
    query.push_back(since_us(t0));

    const std::string id = std::to_string(i);
    t0 = Clock::now();
    c.send(ignav::igtl::stringMessage("CMD_" + id, "START_UP"));
    c.until("ACK_" + id);
    receipt.push_back(since_us(t0));
    c.until(brp2013 ? "CURRENT_STATUS" : "START_UP");  // 2013: the workphase, then the result
    if (brp2013) c.until("START_UP");
    result.push_back(since_us(t0));
  }
  // Re-registrations: each is journaled (fsync) before it is answered.
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topRightCorner<3, 1>() << 10, -20, -40;
  for (int i = 0; i < rounds; ++i) {
    m(0, 3) = 10.0 + 0.001 * i;
    const auto t0 = Clock::now();
    c.send(ignav::igtl::transformMessage("CLB_" + std::to_string(i), m));
    c.until("CALIBRATION");
    calibration.push_back(since_us(t0));
  }
  report("GET_STATUS -> STATUS (the bridge alone)", query);
  report("CMD START_UP -> ACK (receipt)", receipt);
  report("CMD START_UP -> STATUS(START_UP) (check_ready)", result);
  report("CLB -> STATUS(CALIBRATION) (journaled, fsync)", calibration);
  return 0;
}
