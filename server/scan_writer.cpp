#include "scan_writer.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <ctime>
#include <system_error>
#include <utility>

#include "ignav/volume/image_io.hpp"

namespace ignav::server {

namespace fs = std::filesystem;

ScanWriter::ScanWriter(fs::path folder, std::function<void()> wake)
    : folder_(std::move(folder)), wake_(std::move(wake)), thread_([this] { loop(); }) {}

ScanWriter::~ScanWriter() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  ready_.notify_all();
  thread_.join();
}

bool ScanWriter::write(igtl::ReceivedScan scan) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (waiting_.size() >= kMaxWaiting) return false;
    waiting_.push_back(std::move(scan));
  }
  ready_.notify_one();
  return true;
}

std::vector<ScanWriter::Written> ScanWriter::take() {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::exchange(written_, {});
}

void ScanWriter::loop() {
  for (;;) {
    igtl::ReceivedScan scan;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      ready_.wait(lock, [&] { return stopping_ || !waiting_.empty(); });
      if (waiting_.empty()) return;  // stopping, and everything written
      scan = std::move(waiting_.front());
      waiting_.pop_front();
    }
    Written done = writeOne(std::move(scan));
    {
      std::lock_guard<std::mutex> lock(mutex_);
      written_.push_back(std::move(done));
    }
    wake_();
  }
}

ScanWriter::Written ScanWriter::writeOne(igtl::ReceivedScan scan) {
  Written out;
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  fs::create_directories(folder_, ec);
  if (ec) {
    out.error = fmt::format("cannot create {}: {}", folder_.string(), ec.message());
  } else {
    // <name>_<UTC time>[_<n>].nrrd: never over a scan received before.
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    gmtime_r(&now, &utc);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
    fs::path path = folder_ / fmt::format("{}_{}.nrrd", scan.device, stamp);
    for (int n = 2; fs::exists(path); ++n)
      path = folder_ / fmt::format("{}_{}_{}.nrrd", scan.device, stamp, n);
    const auto written = volume::writeNrrdVoxels(scan.geometry, scan.type, scan.voxels.get(),
                                                 scan.bytes, path.string());
    if (written.ok()) {
      out.path = path.string();
    } else {
      out.error = written.error().message;
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (out.error.empty()) {
    spdlog::info("OpenIGTLink client {}: {} ({} x {} x {}, {:.1f} MiB) kept as {} in {:.2f} s",
                 scan.client, scan.device, scan.geometry.dims[0], scan.geometry.dims[1],
                 scan.geometry.dims[2], static_cast<double>(scan.bytes) / (1 << 20), out.path,
                 out.seconds);
  } else {
    spdlog::error("OpenIGTLink client {}: {} could not be kept: {}", scan.client, scan.device,
                  out.error);
  }
  scan.voxels.reset();  // the voxels go as soon as they are on disk
  out.scan = std::move(scan);
  return out;
}

}  // namespace ignav::server
