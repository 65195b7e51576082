// Scans received over OpenIGTLink (IMAGE ConfirmationCT / IntermittentCT), written into the
// session folder on a thread of their own: a CT of a few hundred megabytes takes a second or so to
// write, which neither the event thread (emergency stops) nor the listener's (every client's
// messages) may spend. Kept as they came (igtl::ReceivedScan), so that the measurement reads the
// file like any other and a replay of the session finds it. One at a time, in the order given.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "ignav/igtl/brp.hpp"

namespace ignav::server {

class ScanWriter {
 public:
  // Each waiting scan holds its voxels: a client sends one at a time, and this many at most wait.
  static constexpr std::size_t kMaxWaiting = 4;

  struct Written {
    igtl::ReceivedScan scan;
    std::string path;   // the file, when written
    std::string error;  // why not, otherwise
    double seconds = 0.0;
  };

  // Writes into `folder` (created when the first scan comes); `wake` is called from the writer's
  // thread after each scan.
  ScanWriter(std::filesystem::path folder, std::function<void()> wake);
  ~ScanWriter();  // writes what is waiting (nothing received is lost), then joins
  ScanWriter(const ScanWriter&) = delete;
  ScanWriter& operator=(const ScanWriter&) = delete;

  // False when kMaxWaiting scans wait already (the sender is told busy).
  bool write(igtl::ReceivedScan scan);
  std::vector<Written> take();  // what has been written since the last take

 private:
  void loop();
  Written writeOne(igtl::ReceivedScan scan);

  std::filesystem::path folder_;
  std::function<void()> wake_;
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<igtl::ReceivedScan> waiting_;
  std::vector<Written> written_;
  bool stopping_ = false;
  std::thread thread_;  // last: it starts once everything above is built
};

}  // namespace ignav::server
