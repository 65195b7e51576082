// OpenIGTLink protocol 3 from a running ignav-server, measured at a loopback client (issue 44;
// docs/PERFORMANCE.md "OpenIGTLink 3"): starts its own server, then
//  1. IMAGE: a 512 x 512 x 300 int16 CT (written here as NRRD and loaded over DDS) asked for with
//     GET_IMAGE in header version 2, timed from the request until the whole message is read and
//     its CRC checked; median and worst of ROUNDS;
//  2. TDATA: the phantom registered and a target approved over DDS, the tip streamed at 100 Hz
//     (STT_TDATA) while the robot moves: the frames' inter-arrival times at the client, their
//     deviation from 10 ms (median, p99, max), and how long after the reading each arrived;
//  3. IMAGE in: the same CT sent as ConfirmationCT (a scanner bridge's scan), timed until the
//     server says it is kept and taken (and until its last byte was sent); another client's
//     GET_STATUS round trips meanwhile.
//   bench_igtl3 [--rounds 10] [--domain 93] [--size 512,512,300]
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <poll.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/LU>

#include "child_process.hpp"
#include "ignav/igtl/message.hpp"
#include "ignav/protocol/client.hpp"

namespace {

using ignav::bench::Child;
using ignav::protocol::Client;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

double wallS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

class Peer {
 public:
  explicit Peer(int port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)), decoder_(1 << 20, 1ULL << 31) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      throw std::runtime_error("cannot connect to the OpenIGTLink port");
    }
    const int on = 1;
    ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  }
  ~Peer() { ::close(fd_); }
  Clock::time_point first_byte, last_byte;  // of the message being read
  void sendRaw(const std::string& bytes) {
    for (std::size_t sent = 0; sent < bytes.size();) {
      const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) throw std::runtime_error("send failed");
      sent += static_cast<std::size_t>(n);
    }
  }
  // The next message read as the bare socket reads (into one reused buffer, nothing decoded or
  // kept): when its last byte came. What the server's delivery costs, without the client's.
  std::uint64_t drained_bytes = 0;  // the body drain() read last
  Clock::time_point drain() {
    std::string header;
    std::uint64_t left = 0;
    for (bool have_header = false;;) {
      const ssize_t n = ::recv(fd_, buffer_.data(),
                               have_header ? std::min<std::uint64_t>(left, buffer_.size())
                                           : ignav::igtl::kHeaderBytes - header.size(),
                               0);
      if (n <= 0) throw std::runtime_error("the server closed the connection");
      if (have_header) {
        left -= static_cast<std::uint64_t>(n);
        if (left == 0) return Clock::now();
        continue;
      }
      header.append(buffer_.data(), static_cast<std::size_t>(n));
      if (header.size() == ignav::igtl::kHeaderBytes) {
        have_header = true;
        const auto h = ignav::igtl::readHeader(header.data());
        if (h.type != "IMAGE") throw std::runtime_error("drain: a " + h.type + " came first");
        left = drained_bytes = h.body_size;
      }
    }
  }
  void send(ignav::igtl::Message m) {
    m.header_version = 2;
    const auto bytes = ignav::igtl::encode(m);
    if (!bytes || ::send(fd_, bytes->data(), bytes->size(), MSG_NOSIGNAL) < 0) {
      throw std::runtime_error("send failed");
    }
  }
  // The next message of `type` (others are skipped) and the time it was whole; nothing when none
  // came for 3 s.
  std::optional<std::pair<ignav::igtl::Message, Clock::time_point>> until(const std::string& type) {
    for (;;) {
      while (auto next = decoder_.next()) {
        if (!next->ok()) throw std::runtime_error(next->error().message);
        if (next->value().type == type)
          return std::make_pair(std::move(next->value()), Clock::now());
      }
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 3000) <= 0) return std::nullopt;
      const ssize_t n = ::recv(fd_, buffer_.data(), buffer_.size(), 0);
      if (n <= 0) throw std::runtime_error("the server closed the connection");
      if (decoder_.buffered() == 0) first_byte = Clock::now();
      decoder_.feed(buffer_.data(), static_cast<std::size_t>(n));
      last_byte = Clock::now();
    }
  }

 private:
  int fd_;
  ignav::igtl::Decoder decoder_;
  std::vector<char> buffer_ = std::vector<char>(4 << 20);
};

// A raw little-endian int16 NRRD (LPS, 0.7 x 0.7 x 1.0 mm): soft tissue with a gradient.
void writeCt(const std::filesystem::path& path, const std::array<int, 3>& size) {
  std::ofstream out(path, std::ios::binary);
  out << "NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: " << size[0]
      << " " << size[1] << " " << size[2]
      << "\nspace directions: (0.7,0,0) (0,0.7,0) (0,0,1)\nspace origin: (-179,-179,-300)\n"
         "encoding: raw\nendian: little\n\n";
  std::vector<std::int16_t> slice(static_cast<std::size_t>(size[0]) * size[1]);
  for (int k = 0; k < size[2]; ++k) {
    for (std::size_t n = 0; n < slice.size(); ++n)
      slice[n] = static_cast<std::int16_t>(40 + (n % 512) / 8 + k);
    out.write(reinterpret_cast<const char*>(slice.data()),
              static_cast<std::streamsize>(slice.size() * 2));
  }
}

// The same number of bytes through a fresh bare loopback connection, written from one buffer and
// read into another that is reused (no protocol, no CRC, no copy kept). Not a floor: a fresh
// connection's buffers have not grown yet, and the server's connection to the client has.
double bareSocketMs(std::size_t total) {
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof a;
  if (::bind(listener, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::listen(listener, 1) != 0 ||
      ::getsockname(listener, reinterpret_cast<sockaddr*>(&a), &length) != 0) {
    throw std::runtime_error("bare socket");
  }
  std::vector<char> data(total, 'x');
  std::thread writer([&] {
    const int c = ::accept(listener, nullptr, nullptr);
    for (std::size_t sent = 0; sent < total;) {
      const ssize_t n =
          ::send(c, data.data() + sent, std::min<std::size_t>(1 << 20, total - sent), MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += static_cast<std::size_t>(n);
    }
    ::close(c);
  });
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0)
    throw std::runtime_error("bare");
  std::vector<char> buffer(4 << 20);
  const auto t0 = Clock::now();
  for (std::size_t got = 0; got < total;) {
    const ssize_t n = ::recv(s, buffer.data(), buffer.size(), 0);
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  writer.join();
  ::close(s);
  ::close(listener);
  return ms;
}

struct Stats {
  std::vector<double> v;
  double at(double q) {
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_igtl3: IMAGE and TDATA from ignav-server over OpenIGTLink protocol 3"};
  int rounds = 10;
  std::uint32_t domain = 93;
  std::vector<int> size{512, 512, 300};
  std::string server_exe = IGNAV_SERVER_EXE, source = IGNAV_SOURCE_DIR;
  app.add_option("--rounds", rounds, "images to time");
  app.add_option("--domain", domain, "DDS domain id");
  app.add_option("--size", size, "the CT's voxels along i, j, k")->delimiter(',')->expected(3);
  app.add_option("--server", server_exe, "ignav-server");
  CLI11_PARSE(app, argc, argv);

  const auto dir =
      std::filesystem::temp_directory_path() / ("ignav_bench_igtl3_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  int status = 0;
  try {
    const auto ct = dir / "ct.nrrd";
    writeCt(ct, {size[0], size[1], size[2]});
    Child server({server_exe, "--config", source + "/configs/server.yaml", "--domain",
                  std::to_string(domain), "--dds-config", source + "/configs/dds/loopback.xml",
                  "--session-dir", (dir / "session").string(), "--insecure", "--igtl-port", "0",
                  "--igtl-tip-rate", "100", "--controller-speed", "4000"},
                 "ignav-server ready", (dir / "server.log").string());
    const auto at = server.line().find("igtl_port=");
    const int port = std::atoi(server.line().c_str() + at + 10);
    const std::string xml = ignav::protocol::readConfigFile(source + "/configs/dds/loopback.xml");
    const std::string robot = ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s);
    Client op(domain, xml, "operator", nullptr, robot);
    if (!op.waitForServer(10s)) throw std::runtime_error("no server");
    op.waitFor([](const json& s) { return s.contains("workflow"); }, 10s);
    if (!op.send("load_volume", {ct.string(), {}, {}}).accepted) {
      throw std::runtime_error("load_volume refused");
    }
    op.waitFor(
        [](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; },
        120s);

    // 1. IMAGE.
    Peer peer(port);
    peer.send(ignav::igtl::queryMessage("GET_STATUS", "CURRENT_STATUS"));  // speaks version 2
    if (!peer.until("STATUS")) throw std::runtime_error("no STATUS");
    Stats image_ms, first_ms, last_ms;
    std::size_t image_bytes = 0;
    for (int r = 0; r < rounds; ++r) {
      const auto t0 = Clock::now();
      peer.send(ignav::igtl::queryMessage("GET_IMAGE", "PlanningCT"));
      auto got = peer.until("IMAGE");
      if (!got) throw std::runtime_error("no IMAGE within 3 s of the last bytes");
      image_ms.v.push_back(std::chrono::duration<double, std::milli>(got->second - t0).count());
      image_bytes = got->first.image.data_bytes;
      first_ms.v.push_back(std::chrono::duration<double, std::milli>(peer.first_byte - t0).count());
      last_ms.v.push_back(std::chrono::duration<double, std::milli>(peer.last_byte - t0).count());
    }
    Stats drained_ms;  // read as the bare socket reads
    for (int r = 0; r < std::max(3, rounds / 2); ++r) {
      const auto t0 = Clock::now();
      peer.send(ignav::igtl::queryMessage("GET_IMAGE", "PlanningCT"));
      drained_ms.v.push_back(std::chrono::duration<double, std::milli>(peer.drain() - t0).count());
    }
    std::printf("IMAGE rounds in order (whole and CRC-checked, ms):");
    for (const double ms : image_ms.v)
      std::printf(" %.0f", ms);
    std::printf("\n");
    const double worst = *std::max_element(image_ms.v.begin(), image_ms.v.end());
    const double first_request_ms = first_ms.v.front();  // the voxels' CRC not yet kept
    Stats floor_ms;
    for (int r = 0; r < std::max(3, rounds / 2); ++r)
      floor_ms.v.push_back(bareSocketMs(image_bytes));
    std::printf(
        "the same bytes through a fresh bare loopback connection (its buffers not grown yet): "
        "median %.1f ms; the IMAGE read the same way (into one reused buffer, nothing kept): "
        "last byte median %.1f ms (%.1f MB)\n",
        floor_ms.at(0.5), drained_ms.at(0.5), static_cast<double>(peer.drained_bytes) / 1e6);
    std::printf(
        "IMAGE %d x %d x %d int16 (%.1f MB of voxels), GET_IMAGE -> first byte at the "
        "client median %.1f ms (the first request %.1f ms), last byte median %.1f ms, "
        "whole and CRC-checked median %.1f ms, max %.1f ms (%d rounds)\n",
        size[0], size[1], size[2], static_cast<double>(image_bytes) / 1e6, first_ms.at(0.5),
        first_request_ms, last_ms.at(0.5), image_ms.at(0.5), worst, rounds);

    // 2. TDATA while the robot moves.
    if (!op.send("load_volume", {"phantom:", {}, {}}).accepted) {
      throw std::runtime_error("load_volume phantom refused");
    }
    op.waitFor(
        [](const json& s) {
          return s["volume"]["status"] == "loaded" && s["volume"]["source"] == "phantom:";
        },
        60s);
    if (!op.send("auto_fiducials").accepted) throw std::runtime_error("auto_fiducials refused");
    op.waitFor([](const json& s) { return s["registration"]["status"] == "registered"; }, 20s);
    const Eigen::Matrix4d to_robot =
        ignav::protocol::matrixFromState(op.state()["registration"]["image_to_robot"]);
    const Eigen::Vector3d lps = (to_robot.inverse() * Eigen::Vector4d(-10, 15, -190, 1)).head<3>();
    if (!op.send("add_target", {"", {lps}, {}}).accepted) throw std::runtime_error("add_target");
    if (!op.send("lock_plan").accepted) throw std::runtime_error("lock_plan refused");
    op.waitFor([](const json& s) { return s["approval"]["status"] == "pending"; }, 20s);
    ignav::igtl::Message start = ignav::igtl::queryMessage("STT_TDATA", "NeedleTip");
    start.type = "STT_TDATA";
    peer.send(start);  // resolution 0: every frame the server streams
    const json a = op.state()["approval"];
    if (!op.approve(a["plan_id"].get<std::uint64_t>(), a["digest"].get<std::string>()).accepted) {
      throw std::runtime_error("approval refused");
    }
    std::vector<Clock::time_point> arrivals;
    Stats late_ms;
    // Frames until the stream ends (3 s without one: the robot has come to rest).
    while (auto got = peer.until("TDATA")) {
      late_ms.v.push_back((wallS() - got->first.timestamp_s) * 1e3);
      arrivals.push_back(got->second);
    }
    if (arrivals.size() < 10) throw std::runtime_error("fewer than 10 TDATA frames");
    Stats jitter_ms, interval_ms;
    for (std::size_t i = 1; i + 1 < arrivals.size(); ++i) {  // the at-rest frame is not a period
      const double dt =
          std::chrono::duration<double, std::milli>(arrivals[i] - arrivals[i - 1]).count();
      interval_ms.v.push_back(dt);
      jitter_ms.v.push_back(std::abs(dt - 10.0));
    }
    std::printf(
        "TDATA at 100 Hz during motion: %zu frames; interval median %.2f ms; |interval - "
        "10 ms| median %.3f ms, p99 %.3f ms, max %.3f ms; reading -> client median %.2f "
        "ms, p99 %.2f ms\n",
        arrivals.size(), interval_ms.at(0.5), jitter_ms.at(0.5), jitter_ms.at(0.99),
        jitter_ms.at(1.0), late_ms.at(0.5), late_ms.at(0.99));

    // 3. IMAGE in (last: the scans it writes leave the disk busy a while): the same CT sent as a
    // scanner bridge sends a scan, timed from its first byte until the server answers that it is
    // kept and taken (STATUS ConfirmationCT); meanwhile another client's GET_STATUS round trips,
    // which the listener's thread answers between the scan's reads.
    {
      auto voxels = std::make_shared<std::vector<std::int16_t>>(static_cast<std::size_t>(size[0]) *
                                                                size[1] * size[2]);
      for (std::size_t n = 0; n < voxels->size(); ++n)
        (*voxels)[n] = static_cast<std::int16_t>(40 + (n % 512) / 8);
      ignav::igtl::Image image;
      image.size = {size[0], size[1], size[2]};
      image.ijk_to_mm.topLeftCorner<3, 3>() = Eigen::Vector3d(-0.7, -0.7, 1.0).asDiagonal();
      image.ijk_to_mm.topRightCorner<3, 1>() = Eigen::Vector3d(179, 179, -300);
      image.data =
          std::shared_ptr<const char>(voxels, reinterpret_cast<const char*>(voxels->data()));
      image.data_bytes = voxels->size() * 2;
      ignav::igtl::Message scan = ignav::igtl::imageMessage("ConfirmationCT", image);
      scan.header_version = 2;
      const auto bytes = ignav::igtl::encode(scan);
      if (!bytes) throw std::runtime_error(bytes.error().message);
      Stats upload_ms, sent_ms, ping_ms;
      int code = 0;
      for (int r = 0; r < std::max(1, std::min(3, rounds)); ++r) {
        Peer uploader(port), pinger(port);
        pinger.send(ignav::igtl::queryMessage("GET_STATUS", "CURRENT_STATUS"));
        if (!pinger.until("STATUS")) throw std::runtime_error("no STATUS");
        std::atomic<bool> sent{false};
        const auto t0 = Clock::now();
        std::atomic<bool> failed{false};
        std::thread upload([&] {
          try {
            uploader.sendRaw(*bytes);
          } catch (const std::exception&) {
            failed = true;
          }
          sent = true;
        });
        while (!sent) {
          const auto p0 = Clock::now();
          pinger.send(ignav::igtl::queryMessage("GET_STATUS", "CURRENT_STATUS"));
          if (!pinger.until("STATUS")) throw std::runtime_error("no STATUS during the upload");
          ping_ms.v.push_back(std::chrono::duration<double, std::milli>(Clock::now() - p0).count());
          std::this_thread::sleep_for(5ms);
        }
        upload.join();
        if (failed) throw std::runtime_error("the scan could not be sent");
        sent_ms.v.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        for (;;) {
          auto got = uploader.until("STATUS");
          if (!got) throw std::runtime_error("no answer to the scan");
          if (got->first.device_name != "ConfirmationCT") continue;
          upload_ms.v.push_back(
              std::chrono::duration<double, std::milli>(got->second - t0).count());
          code = got->first.status.code;
          break;
        }
      }
      std::printf(
          "IMAGE in: %.1f MB sent as ConfirmationCT: last byte sent (about when the server "
          "has read it) median %.1f ms; -> STATUS (code %d: kept, and taken or refused by the "
          "core) median %.1f ms, max %.1f ms (%zu rounds); another client's GET_STATUS "
          "meanwhile: median %.2f ms, p99 %.2f ms, max %.2f ms (%zu)\n",
          static_cast<double>(bytes->size()) / 1e6, sent_ms.at(0.5), code, upload_ms.at(0.5),
          upload_ms.at(1.0), upload_ms.v.size(), ping_ms.at(0.5), ping_ms.at(0.99), ping_ms.at(1.0),
          ping_ms.v.size());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_igtl3: %s (logs in %s)\n", e.what(), dir.c_str());
    status = 1;
  }
  if (status == 0) std::filesystem::remove_all(dir);
  return status;
}
